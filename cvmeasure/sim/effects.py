"""Named effects: what a simulation can get wrong, as parametrised modifiers of the model.

Each effect has one parameter, physical bounds, a stage where it enters the
forward model (not added to its output) and a typical size used to draw
synthetic test data. The spec's names keep their meaning:

=======================  ==========================  =====================================
name                     parameter                   enters the model as
=======================  ==========================  =====================================
``none``                 -                           nothing
``backlash``             ``backlash_deg`` (>= 0)     lost head travel: ``|r| -> |r| - b``
``offset``               ``offset_deg``              zero error: ``r -> r + c`` (signed)
``scale``                ``scale``                   ``r -> r (1 + s)``
``drift``                ``drift_deg_per_bend``      loss growing with bend index k:
                                                     ``|r| -> |r| - d k`` (the helix)
``springback_asymmetry`` ``asymmetry``               springback ``* (1 + s_dir alpha)``
``camera_tilt``          ``tilt_deg``                measured angles foreshortened about the
                                                     feed axis: ``tan t' = tan t cos(tau)``
``axis_offset``          ``axis_offset_mm``          lateral head-axis offset e (tangent
                                                     construction), about ``+-(e/l) cos t``
``compliance``           ``compliance_deg_per_nm``   drive wind-up: the head lags by
                                                     ``k * (M / l) * R_p`` (grows as the
                                                     lever l shortens)
=======================  ==========================  =====================================

``r`` is the signed head rotation from home (the pin command); ``s_dir`` is the
bend direction (+1 counter-clockwise, -1 clockwise).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any, Literal

__all__ = [
    "EffectStage",
    "EffectSpec",
    "Effect",
    "EFFECTS",
    "EFFECT_NAMES",
    "parse_effect",
    "effects_from_dicts",
]

EffectStage = Literal["none", "command", "geometry", "springback", "measurement"]


@dataclass(frozen=True)
class EffectSpec:
    """Catalogue entry of one named effect."""

    name: str
    param: str  # key of its parameter in JSON (unit in the name)
    unit: str
    lower: float  # physical bounds of the parameter
    upper: float
    stage: EffectStage
    typical: tuple[float, float]  # |value| range used for synthetic draws
    signed: bool  # whether synthetic draws take both signs
    description: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "param": self.param,
            "unit": self.unit,
            "bounds": [self.lower, self.upper],
            "stage": self.stage,
            "typical": list(self.typical),
            "description": self.description,
        }


EFFECTS: dict[str, EffectSpec] = {
    spec.name: spec
    for spec in (
        EffectSpec("none", "", "", 0.0, 0.0, "none", (0.0, 0.0), False, "nothing hidden"),
        EffectSpec(
            "backlash",
            "backlash_deg",
            "deg",
            0.0,
            6.0,
            "command",
            (0.6, 3.0),
            False,
            "gearbox play: every bend loses b of head travel",
        ),
        EffectSpec(
            "offset",
            "offset_deg",
            "deg",
            -6.0,
            6.0,
            "command",
            (0.6, 3.0),
            True,
            "zero (home) error of the head: actual = commanded + c",
        ),
        EffectSpec(
            "scale",
            "scale",
            "1",
            -0.15,
            0.15,
            "command",
            (0.015, 0.06),
            True,
            "steps per degree wrong: actual = commanded * (1 + s)",
        ),
        EffectSpec(
            "drift",
            "drift_deg_per_bend",
            "deg/bend",
            0.0,
            0.5,
            "command",
            (0.015, 0.06),
            False,
            "lost steps accumulate bend after bend (the seed paper's helix)",
        ),
        EffectSpec(
            "springback_asymmetry",
            "asymmetry",
            "1",
            -0.8,
            0.8,
            "springback",
            (0.25, 0.6),
            True,
            "springback differs by direction (coil set, Bauschinger): *(1 + dir * alpha)",
        ),
        EffectSpec(
            "camera_tilt",
            "tilt_deg",
            "deg",
            0.0,
            35.0,
            "measurement",
            (12.0, 25.0),
            False,
            "photos not parallel to the bending plane: angles foreshortened",
        ),
        EffectSpec(
            "axis_offset",
            "axis_offset_mm",
            "mm",
            -1.0,
            1.0,
            "geometry",
            (0.15, 0.5),
            True,
            "head axis off the wire axis: cw and ccw differ, about +-(e/l) cos(theta)",
        ),
        EffectSpec(
            "compliance",
            "compliance_deg_per_nm",
            "deg/(N m)",
            0.0,
            2.0,
            "command",
            (0.2, 0.6),
            False,
            "drive and frame wind up under the pin load: under-bend growing as the lever shortens",
        ),
    )
}

#: Every effect name, ``none`` first.
EFFECT_NAMES: tuple[str, ...] = tuple(EFFECTS)


@dataclass(frozen=True)
class Effect:
    """One named effect with its parameter value (units of ``EFFECTS[name].unit``)."""

    name: str
    value: float = 0.0

    def __post_init__(self) -> None:
        if self.name not in EFFECTS:
            raise ValueError(f"unknown effect {self.name!r}; known: {', '.join(EFFECT_NAMES)}")
        spec = EFFECTS[self.name]
        if self.name != "none" and not spec.lower <= self.value <= spec.upper:
            raise ValueError(
                f"{self.name}: {spec.param} = {self.value} is outside its physical bounds "
                f"[{spec.lower}, {spec.upper}] {spec.unit}"
            )

    @property
    def spec(self) -> EffectSpec:
        return EFFECTS[self.name]

    def to_dict(self) -> dict[str, Any]:
        if self.name == "none":
            return {"name": "none"}
        return {"name": self.name, self.spec.param: self.value}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Effect:
        if not isinstance(data, Mapping) or "name" not in data:
            raise ValueError(f"an effect must be an object with a name, got {data!r}")
        name = str(data["name"])
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
        if name == "none":
            return cls("none")
        key = EFFECTS[name].param
        if key not in data:
            raise ValueError(f"effect {name} needs its parameter {key}")
        return cls(name, float(data[key]))


def parse_effect(text: str) -> Effect:
    """Parse ``NAME=VALUE`` (or ``none``) as given to ``cvmeasure simulate --effect``."""
    name, sep, value = text.partition("=")
    name = name.strip()
    if name == "none" and not sep:
        return Effect("none")
    if not sep:
        raise ValueError(f"effect {text!r} must be NAME=VALUE")
    try:
        number = float(value)
    except ValueError:
        raise ValueError(f"effect {name}: value {value!r} is not a number") from None
    return Effect(name, number)


def effects_from_dicts(items: Iterable[Mapping[str, Any]]) -> tuple[Effect, ...]:
    """Effects from the ``"effects"`` list of a params JSON."""
    if isinstance(items, (str, bytes)) or not isinstance(items, Iterable):
        raise ValueError("effects must be a list of objects")
    return tuple(Effect.from_dict(item) for item in items)
