"""Parameters of the simulated bender and wire, and their params JSON.

:class:`SimParams` holds every number the forward model uses: the wire
(diameter, elastic modulus, yield and ultimate strength, hardening law) and the
bending head (die edge, pin, head axis, approach travel). Defaults describe
3 mm low-carbon steel on a DIWire-like head. The params JSON is the flat
``to_dict()`` of this class plus an optional ``"effects"`` list (see
:mod:`cvmeasure.sim.effects`), so a diagnosis can save an *extended* model
that the compensation and the G-code generator read back.

Frames (see :mod:`cvmeasure.sim.kinematics`): the wire leaves the die along
+x from x = 0; a counter-clockwise (positive) bend wraps it on a die-edge
circle centred at ``(0, die_radius_mm + r_wire)``; the pin orbits the head
axis ``(head_axis_x_mm, head_axis_y_mm)`` at ``pin_orbit_mm``. Clockwise bends
use the mirror image (y -> -y).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, fields
from os import PathLike
from pathlib import Path
from typing import Any, Literal

from cvmeasure.errors import InputError
from cvmeasure.fileio import atomic_write_json, read_json
from cvmeasure.sim.effects import check_effect_bounds, effects_from_dicts

__all__ = ["HardeningLaw", "HARDENING_LAWS", "SimParams", "params_from_json", "params_to_json"]

HardeningLaw = Literal["epp", "bilinear", "power"]
HARDENING_LAWS: tuple[str, ...] = ("epp", "bilinear", "power")


@dataclass(frozen=True)
class SimParams:
    """Wire material and bending-head geometry of the forward model.

    Parameters
    ----------
    wire_diameter_mm : float
        Wire diameter d.
    youngs_modulus_mpa, yield_mpa, uts_mpa : float
        Elastic modulus E, yield stress and (engineering) ultimate strength.
    hardening : {"epp", "bilinear", "power"}
        Stress-strain law beyond yield: elastic-perfectly-plastic, linear
        hardening with ``tangent_modulus_mpa``, or Swift power law
        ``sigma = K (eps0 + eps_p)^n`` with ``n = hardening_exponent`` and K
        chosen so the engineering UTS is reached at necking (true strain n).
    hardening_exponent : float
        Swift exponent n (power law only).
    tangent_modulus_mpa : float
        Hardening slope H of the bilinear law.
    die_radius_mm : float
        Radius of the die edge the wire wraps on (0 = sharp edge).
    pin_orbit_mm : float
        Radius of the pin centre's orbit about the head axis.
    pin_radius_mm : float
        Radius of the bending pin.
    head_axis_x_mm, head_axis_y_mm : float
        Head (pin rotation) axis in the die frame; (0, 0) is on the wire axis at
        the die exit. ``head_axis_y_mm`` is a lateral offset towards +y.
    approach_deg : float
        Head rotation from home to first contact with the straight wire (the
        dead zone; DIWire firmware: 220 steps = 13.2 deg).
    span_factor : float
        c in the free-span springback term ``c * M * l / EI``: 1/2 when the
        leg beyond the pin is measured, 1/3 for the chord of the span.
    span_bow_share : float
        Share of the free span's elastic bow added to the loaded leg: the leg
        beyond the pin leads the tangent construction's chord by
        ``share * min(M l / (6 EI), theta / 2)`` (beam theory, moment falling
        linearly from the die to the pin). 0 (default): a straight leg.
    """

    wire_diameter_mm: float = 3.0
    youngs_modulus_mpa: float = 200_000.0
    yield_mpa: float = 280.0
    uts_mpa: float = 400.0
    hardening: HardeningLaw = "power"
    hardening_exponent: float = 0.15
    tangent_modulus_mpa: float = 800.0
    die_radius_mm: float = 1.5
    pin_orbit_mm: float = 12.0
    pin_radius_mm: float = 2.5
    head_axis_x_mm: float = 0.0
    head_axis_y_mm: float = 0.0
    approach_deg: float = 13.2
    span_factor: float = 0.5
    span_bow_share: float = 0.0

    def __post_init__(self) -> None:
        if self.hardening not in HARDENING_LAWS:
            raise ValueError(
                f"hardening must be one of {', '.join(HARDENING_LAWS)}, got {self.hardening!r}"
            )
        positive = ("wire_diameter_mm", "youngs_modulus_mpa", "yield_mpa", "pin_orbit_mm")
        for name in positive:
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        for name, value in vars(self).items():  # the fields, set by __init__ (no fields() call)
            if isinstance(value, float) and not math.isfinite(value):
                raise ValueError(f"{name} must be finite, got {value!r}")
        if self.uts_mpa < self.yield_mpa:
            raise ValueError("uts_mpa must be at least yield_mpa")
        if not 0.0 <= self.hardening_exponent < 1.0:
            raise ValueError("hardening_exponent must be in [0, 1)")
        if self.die_radius_mm < 0 or self.pin_radius_mm < 0 or self.tangent_modulus_mpa < 0:
            raise ValueError("die_radius_mm, pin_radius_mm and tangent_modulus_mpa must be >= 0")
        if self.span_bow_share < 0:
            raise ValueError(
                f"span_bow_share must be >= 0 (a share of the bow), got {self.span_bow_share!r}"
            )
        reach = self.pin_radius_mm + self.wire_diameter_mm / 2 + abs(self.head_axis_y_mm)
        if reach >= self.pin_orbit_mm:
            raise ValueError("pin_orbit_mm too small: the pin can never reach the wire")

    @property
    def wire_radius_mm(self) -> float:
        """Wire radius r_w = d / 2."""
        return self.wire_diameter_mm / 2.0

    def replace(self, **changes: Any) -> SimParams:
        """A copy with some fields changed (validated)."""
        return dataclasses.replace(self, **changes)

    def to_dict(self) -> dict[str, Any]:
        """The params JSON object (flat, units in the keys)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SimParams:
        """Build from a params JSON object; unknown keys raise ``ValueError``.

        Keys that are absent take their defaults; an ``"effects"`` key is
        ignored here (read it with :func:`cvmeasure.sim.effects.effects_from_dicts`).
        """
        known = {f.name: f for f in fields(cls)}
        unknown = sorted(set(data) - set(known) - {"effects", "provenance", "diagnosis"})
        if unknown:
            raise ValueError(f"unknown parameter(s) {', '.join(unknown)}")
        kwargs: dict[str, Any] = {}
        for name in known:
            if name not in data:
                continue
            value = data[name]
            if name == "hardening":
                kwargs[name] = str(value)
            elif isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ValueError(f"{name} must be a number, got {value!r}")
            else:
                kwargs[name] = float(value)
        return cls(**kwargs)


def params_from_json(path: str | PathLike[str]) -> tuple[SimParams, tuple[Any, ...]]:
    """Read a params JSON file; return ``(params, effects)``.

    Raises
    ------
    InputError
        When the file is missing, corrupt, or holds an unknown or invalid value.
    """

    data = read_json(path, what="params JSON")
    if not isinstance(data, dict):
        raise InputError(path, "params JSON must be an object")
    try:
        params = SimParams.from_dict(data)
        effects = effects_from_dicts(data.get("effects", []))
        check_effect_bounds(effects, params)
    except (TypeError, ValueError) as exc:
        raise InputError(path, f"invalid params JSON: {exc}") from None
    return params, effects


def params_to_json(
    path: str | PathLike[str],
    params: SimParams,
    effects: tuple[Any, ...] = (),
    *,
    extra: dict[str, Any] | None = None,
) -> Path:
    """Write params (and effects, and any ``extra`` keys) to a params JSON, atomically."""

    obj: dict[str, Any] = params.to_dict()
    obj["effects"] = [e.to_dict() for e in effects]
    if extra:
        obj.update(extra)
    return atomic_write_json(path, obj)
