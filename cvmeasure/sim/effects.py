"""Named effects: what a simulation can get wrong, as parametrised modifiers of the model.

Each effect has one main parameter, physical bounds, a stage where it enters the
forward model (not added to its output) and a typical size used to draw
synthetic test data. Three effects have *shape* parameters that make their
physically general form (defaults in brackets give the narrow form):

- ``backlash``: ``same_direction_share`` [1]: share of the play lost by a bend in
  the same direction as the one before (a pure play operator with return to
  home loses it only on direction reversals: 0);
- ``drift``: ``load_exponent`` [0]: the steps lost per bend grow with the pin
  torque as ``d_j = d (T_j / T_ref)^p`` (``T_ref`` 3 N m for a 3 mm wire, in
  proportion to the wire's diameter cubed); ``home_shift`` [0]: the share of the
  accumulated loss that shifts home instead of shortening every later bend. The
  narrow form (0, the spec's helix) shortens bend k by ``d k`` whatever its
  direction; a home shift (1) under-bends a later bend in the same direction and
  over-bends one in the other (``h_k = -sum_{j<k} s_j d_j``; both agree when all
  bends go one way); ``step_deg`` [0]: steps are lost whole, the run's accumulated
  loss rounded to this head step (a bend loses ``q (round(D_k / q) - round(D_{k-1} /
  q))``, ``D_k`` the continuous loss up to and including bend k). The general form
  (any shape parameter non-zero) follows the rows in the order executed; a re-home
  (bend_index back to 0) resets it;
- ``camera_tilt``: ``tilt_axis_deg`` [0]: the tilt is about an axis at this
  azimuth in the bending plane (0: the feed axis); angles are measured from the
  image of the feed leg.

The spec's names keep their meaning:

=======================  ==========================  =====================================
name                     parameter                   enters the model as
=======================  ==========================  =====================================
``none``                 -                           nothing
``backlash``             ``backlash_deg`` (>= 0)     lost head travel: ``|r| -> |r| - b w_k``,
                                                     ``w_k = 1`` on a reversal, else the share
``offset``               ``offset_deg``              zero error: ``r -> r + c`` (signed)
``scale``                ``scale``                   ``r -> r (1 + s)``
``drift``                ``drift_deg_per_bend``      loss growing with bend index k:
                                                     ``|r| -> |r| - d k`` (the helix); general
                                                     form: home shift ``r -> r + h_k``
``springback_asymmetry`` ``asymmetry``               springback ``* (1 + s_dir alpha)``
``camera_tilt``          ``tilt_deg``                measured angles foreshortened about an
                                                     axis at ``tilt_axis_deg`` (feed axis:
                                                     ``tan t' = tan t cos(tau)``)
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

import dataclasses
import functools
import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    from cvmeasure.sim.params import SimParams

__all__ = [
    "EffectStage",
    "ShapeSpec",
    "EffectSpec",
    "Effect",
    "EFFECTS",
    "EFFECT_NAMES",
    "parse_effect",
    "effects_from_dicts",
    "SIZE_SCALED",
    "size_factor",
    "effect_spec_for",
    "effect_bounds_for",
    "check_effect_bounds",
]

EffectStage = Literal["none", "command", "geometry", "springback", "measurement"]


@dataclass(frozen=True)
class ShapeSpec:
    """A shape parameter of an effect's general form; ``default`` gives the narrow form."""

    key: str  # JSON key (unit in the name where it has one)
    unit: str
    lower: float
    upper: float
    default: float
    description: str

    def to_dict(self) -> dict[str, Any]:
        return {
            "key": self.key,
            "unit": self.unit,
            "bounds": [self.lower, self.upper],
            "default": self.default,
            "description": self.description,
        }


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
    shape: tuple[ShapeSpec, ...] = ()  # parameters of the general form

    def shape_spec(self, key: str) -> ShapeSpec:
        for s in self.shape:
            if s.key == key:
                return s
        raise ValueError(f"{self.name} has no shape parameter {key!r}")

    def to_dict(self) -> dict[str, Any]:
        return {
            "name": self.name,
            "param": self.param,
            "unit": self.unit,
            "bounds": [self.lower, self.upper],
            "stage": self.stage,
            "typical": list(self.typical),
            "description": self.description,
            "shape": [s.to_dict() for s in self.shape],
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
            "gearbox play: a bend loses b of head travel on a direction reversal, "
            "the share of b on a bend in the same direction",
            (
                ShapeSpec(
                    "same_direction_share",
                    "1",
                    0.0,
                    1.0,
                    1.0,
                    "share of b lost when the bend goes the same way as the one before",
                ),
            ),
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
            "lost steps shift home bend after bend (the seed paper's helix)",
            (
                ShapeSpec(
                    "load_exponent",
                    "1",
                    0.0,
                    3.0,
                    0.0,
                    "steps lost per bend grow with the pin torque as (T / T_ref)^p, T_ref 3 N m "
                    "for a 3 mm wire, as its diameter cubed",
                ),
                ShapeSpec(
                    "home_shift",
                    "1",
                    0.0,
                    1.0,
                    0.0,
                    "share of the accumulated loss that shifts home (signed by the "
                    "direction of the bends that lost it) instead of shortening every bend",
                ),
                ShapeSpec(
                    "step_deg",
                    "deg",
                    0.0,
                    1.0,
                    0.0,
                    "steps are lost whole: the accumulated loss of the run is rounded to "
                    "this head step (0: a continuous loss)",
                ),
            ),
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
            (
                ShapeSpec(
                    "loaded_deg",
                    "deg",
                    -3.0,
                    3.0,
                    0.0,
                    "the loaded leg moves too, by this much per unit of asymmetry (bend "
                    "magnitude, + with the stronger direction): the span's curvature follows "
                    "the wire's strength",
                ),
            ),
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
            (
                ShapeSpec(
                    "tilt_axis_deg",
                    "deg",
                    -90.0,
                    90.0,
                    0.0,
                    "azimuth of the tilt axis in the bending plane from the feed axis",
                ),
            ),
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

#: Effects whose parameter has a size: the catalogue's bounds and typical values are a
#: DIWire's, and a machine the params describe at another size has them scaled by
#: ``(params.key / reference) ** exponent``. The compliance (deg per N m) against the pin
#: torque, which grows as the wire diameter cubed (the same law as the drift's reference
#: torque, :func:`cvmeasure.sim.model.drift_reference_torque_nm`): the same wind-up in
#: degrees is a compliance 8 times larger on a machine bending wire half as thick. The
#: axis offset (mm) against the head's lever, the pin orbit: the same ``e / l``.
SIZE_SCALED: dict[str, tuple[str, float, float]] = {
    "compliance": ("wire_diameter_mm", 3.0, -3.0),
    "axis_offset": ("pin_orbit_mm", 12.0, 1.0),
}


def size_factor(name: str, params: SimParams | None) -> float:
    """The factor on effect ``name``'s bounds and typical values on the machine ``params``
    describes (1 for an effect without a size, or for ``params`` None: a DIWire's)."""
    if params is None or name not in SIZE_SCALED:
        return 1.0
    key, reference, exponent = SIZE_SCALED[name]
    return float((float(getattr(params, key)) / reference) ** exponent)


@functools.lru_cache(maxsize=256)
def _scaled_spec(name: str, factor: float) -> EffectSpec:
    spec = EFFECTS[name]
    if factor == 1.0:
        return spec
    return dataclasses.replace(
        spec,
        lower=spec.lower * factor,
        upper=spec.upper * factor,
        typical=(spec.typical[0] * factor, spec.typical[1] * factor),
    )


def effect_spec_for(name: str, params: SimParams | None) -> EffectSpec:
    """``EFFECTS[name]`` on the machine ``params`` describes: bounds and typical values of
    an effect with a size (:data:`SIZE_SCALED`) in proportion to the machine, the rest as
    catalogued (``params`` None: the catalogue's, a DIWire's).

    The one source of the bounds the diagnosis fits, clips, widens and names with, so
    that two descriptions of one machine at different sizes get the same diagnosis.
    """
    if name not in EFFECTS:
        raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
    return _scaled_spec(name, size_factor(name, params))


def effect_bounds_for(params: SimParams | None) -> dict[str, tuple[float, float]]:
    """Each effect's ``(lower, upper)`` on the machine ``params`` describes."""
    return {n: (s.lower, s.upper) for n in EFFECTS for s in (effect_spec_for(n, params),)}


def check_effect_bounds(effects: Iterable[Effect], params: SimParams | None) -> None:
    """Raise ValueError when an effect lies outside its bounds on the machine ``params``
    describes (:class:`Effect` itself checks only what holds at every size)."""
    for e in effects:
        spec = effect_spec_for(e.name, params)
        if e.name != "none" and not spec.lower <= e.value <= spec.upper:
            raise ValueError(
                f"{e.name}: {spec.param} = {e.value} is outside its physical bounds "
                f"[{spec.lower:.4g}, {spec.upper:.4g}] {spec.unit} on this machine"
            )


@dataclass(frozen=True)
class Effect:
    """One named effect with its parameter value (units of ``EFFECTS[name].unit``)."""

    name: str
    value: float = 0.0
    shape: tuple[tuple[str, float], ...] = ()  # (key, value) of shape parameters given

    def __post_init__(self) -> None:
        if self.name not in EFFECTS:
            raise ValueError(f"unknown effect {self.name!r}; known: {', '.join(EFFECT_NAMES)}")
        spec = EFFECTS[self.name]
        lower, upper = spec.lower, spec.upper
        if self.name in SIZE_SCALED:
            # its bounds are the machine's (check_effect_bounds); here only its sign, which
            # holds at every size
            lower, upper = (0.0 if spec.lower == 0.0 else -math.inf), math.inf
        if self.name != "none" and not lower <= self.value <= upper:
            raise ValueError(
                f"{self.name}: {spec.param} = {self.value} is outside its physical bounds "
                f"[{spec.lower}, {spec.upper}] {spec.unit}"
            )
        shape = tuple((str(k), float(v)) for k, v in dict(self.shape).items())
        for key, value in shape:
            sspec = spec.shape_spec(key)
            if not sspec.lower <= value <= sspec.upper:
                raise ValueError(
                    f"{self.name}: {key} = {value} is outside its bounds "
                    f"[{sspec.lower}, {sspec.upper}] {sspec.unit}"
                )
        object.__setattr__(self, "shape", shape)

    @property
    def spec(self) -> EffectSpec:
        return EFFECTS[self.name]

    def shape_value(self, key: str) -> float:
        """The shape parameter ``key`` (its default, the narrow form, when not given)."""
        return dict(self.shape).get(key, self.spec.shape_spec(key).default)

    def to_dict(self) -> dict[str, Any]:
        if self.name == "none":
            return {"name": "none"}
        return {"name": self.name, self.spec.param: self.value, **dict(self.shape)}

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> Effect:
        if not isinstance(data, Mapping) or "name" not in data:
            raise ValueError(f"an effect must be an object with a name, got {data!r}")
        name = str(data["name"])
        if name not in EFFECTS:
            raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
        if name == "none":
            return cls("none")
        spec = EFFECTS[name]
        if spec.param not in data:
            raise ValueError(f"effect {name} needs its parameter {spec.param}")
        unknown = set(data) - {"name", spec.param, *(s.key for s in spec.shape)}
        if unknown:
            raise ValueError(f"effect {name}: unknown key(s) {', '.join(sorted(unknown))}")
        shape = tuple((s.key, float(data[s.key])) for s in spec.shape if s.key in data)
        return cls(name, float(data[spec.param]), shape)


def parse_effect(text: str) -> Effect:
    """Parse ``NAME=VALUE[,KEY=VALUE...]`` (or ``none``) as given to ``simulate --effect``.

    >>> parse_effect("camera_tilt=15,tilt_axis_deg=30").shape
    (('tilt_axis_deg', 30.0),)
    """
    head, *rest = text.split(",")
    name, sep, value = head.partition("=")
    name = name.strip()
    if name == "none" and not sep and not rest:
        return Effect("none")
    if not sep:
        raise ValueError(f"effect {text!r} must be NAME=VALUE")
    shape = []
    for item in rest:
        key, sep2, v = item.partition("=")
        if not sep2:
            raise ValueError(f"effect {name}: shape parameter {item!r} must be KEY=VALUE")
        shape.append((key.strip(), v))
    try:
        number = float(value)
        shape_values = tuple((k, float(v)) for k, v in shape)
    except ValueError:
        raise ValueError(f"effect {name}: value in {text!r} is not a number") from None
    return Effect(name, number, shape_values)


def effects_from_dicts(items: Iterable[Mapping[str, Any]]) -> tuple[Effect, ...]:
    """Effects from the ``"effects"`` list of a params JSON."""
    if isinstance(items, (str, bytes)) or not isinstance(items, Iterable):
        raise ValueError("effects must be a list of objects")
    return tuple(Effect.from_dict(item) for item in items)
