"""Machines and hidden effects of the held-out bender model.

A machine is the bender's geometry and the wire it bends; the effects are what the
real machine does that a nominal model of it would not. Catalogue effects keep the
meanings of the project's contract (docs/conventions.md "Effect names"); the others
are mechanisms outside the catalogue, for judging the diagnosis on causes it does
not name. All lengths mm, angles deg.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from benchmarks.heldout.wire_section import MATERIALS, Material


@dataclass(frozen=True)
class Machine:
    """Bender geometry and wire.

    Frame: the machine frame of the contract (origin at the head axis, +x the feed
    direction, counter-clockwise positive). The wire leaves the die at
    ``x = die_exit_x_mm`` and wraps the die's edge (radius ``die_radius_mm``) on the
    side it is bent to. The pin (diameter ``pin_diameter_mm``) rides an orbit of radius
    ``pin_orbit_radius_mm`` about the head axis. At home (head rotation 0) the pin is
    parked ``park_angle_deg`` round the orbit from the wire line, on the side opposite
    the bend (a duck move switches sides); it touches the wire after the dead angle
    ``park_angle_deg - asin((pin_diameter + wire_diameter) / 2 / orbit)``, so a thicker
    wire has a shorter dead angle. With ``orbit_about_die`` the head turns about the
    die edge's centre instead (a rotary-draw or rebar bender: a central mandrel, the
    bar laid on the side of it that it bends to).

    Attributes
    ----------
    marker_distance_mm : float
        Mean distance along the bent leg from the die exit to the two wire markers
        (what a coil set of the leg adds to a measured bend angle).
    pinion_turns_per_rev : float
        Turns of the drive pinion per head revolution (the period of its runout).
    head_step_deg : float
        One motor full step at the head (whole steps are what a stepper loses).
    max_head_deg : float
        Largest head rotation the machine takes (beyond it the pin would reach the
        feed guide): a larger command is refused.
    """

    name: str
    wire_diameter_mm: float
    material: str
    die_radius_mm: float
    pin_orbit_radius_mm: float
    pin_diameter_mm: float
    park_angle_deg: float
    die_exit_x_mm: float = 0.0
    marker_distance_mm: float = 40.0
    pinion_turns_per_rev: float = 5.0
    head_step_deg: float = 0.36
    spool_diameter_mm: float = 300.0
    orbit_about_die: bool = False
    max_head_deg: float = 170.0

    @property
    def wire_material(self) -> Material:
        """The wire's material."""
        return MATERIALS[self.material]

    def dead_angle_deg(self) -> float:
        """Head rotation from home to first contact with the straight wire (nominal axis)."""
        import math

        reach = (self.pin_diameter_mm + self.wire_diameter_mm) / 2.0
        if self.orbit_about_die:
            reach += self.die_radius_mm + self.wire_diameter_mm / 2.0
        return self.park_angle_deg - math.degrees(
            math.asin(min(reach / self.pin_orbit_radius_mm, 1.0))
        )


MACHINES: dict[str, Machine] = {
    # DIWire-class desktop bender, 3 mm low-carbon steel; parked so that the dead angle
    # is 13.2 deg, the +220 steps the DIWire firmware adds to absorb it.
    "diwire": Machine("diwire", 3.0, "low_carbon_steel", 1.5, 12.0, 5.0, 32.67),
    # A small jewellery / model bender, 1 mm half-hard copper.
    "jewel": Machine(
        "jewel",
        1.0,
        "copper_h02",
        0.5,
        4.0,
        1.5,
        27.0,
        marker_distance_mm=14.0,
        pinion_turns_per_rev=8.0,
        head_step_deg=0.225,
        spool_diameter_mm=120.0,
    ),
    # A 2 mm stainless spring-wire bender.
    "stainless2": Machine(
        "stainless2",
        2.0,
        "stainless_304",
        1.0,
        9.0,
        4.0,
        29.0,
        marker_distance_mm=28.0,
        spool_diameter_mm=250.0,
    ),
    # A rebar shop bender: 12 mm B500 bar on a 24 mm radius mandrel (2 d), the turntable
    # turning about the mandrel's centre, a 30 mm pin on a 70 mm orbit.
    "rebar": Machine(
        "rebar",
        12.0,
        "rebar_b500",
        24.0,
        70.0,
        30.0,
        56.0,
        marker_distance_mm=160.0,
        pinion_turns_per_rev=3.0,
        head_step_deg=0.12,
        spool_diameter_mm=1500.0,
        orbit_about_die=True,
    ),
}


@dataclass(frozen=True)
class Effects:
    """Hidden effects, each zero (off) by default.

    Catalogue (contract names and meanings):

    - ``backlash_deg``: gear play; the head is ``b`` short of the motor after every
      reversal, and every bend starts after the release reversed the drive:
      ``|actual| = |commanded| - b``.
    - ``offset_deg``: home switch error, ``actual = commanded + c``.
    - ``scale``: steps-per-degree error, ``actual = commanded * (1 + s)``.
    - ``drift_deg``: whole motor steps slip under the load of every bend that touches
      the wire (``drift_deg`` per bend, rounded to whole head steps as a run); the
      count never learns it, so the zero walks against the load: a run of bends one
      way closes more and more (the helix), a bend the other way gains it back.
    - ``springback_asymmetry``: a residual back stress from the wire's drawing and
      straightening, ``share * yield * sign(y)`` across the section, makes the flow
      stress ``1 + share`` times the yield for counter-clockwise bends and
      ``1 - share`` for clockwise ones, so the springback differs by direction
      (positive: counter-clockwise bends spring back more).
    - ``camera_tilt_deg`` (with ``tilt_axis_deg``, the tilt axis's azimuth from +x): the
      photo is foreshortened by ``cos(tilt)`` across the tilt axis; every angle read
      from it (bends, pin) is distorted.
    - ``axis_offset_mm`` (with ``axis_offset_along_mm``): the head axis sits this far
      from the die centre, across (+y) and along the feed.
    - ``compliance_deg_per_nm``: the drive winds up by ``k T`` under the pin torque
      ``T`` (N m) about the head axis, so the loaded head lags the motor.

    Outside the catalogue:

    - ``step_loss_deg`` / ``step_loss_torque_share``: whole steps slip only on bends
      whose torque exceeds this share of the machine's die-wrapping torque (big
      bends), accumulating like drift.
    - ``coil_set_per_m``: the fed wire keeps this curvature (1/m) from its spool: it
      was coiled (spool diameter of the machine), straightened by a reverse bend, and
      carries the straightening's Bauschinger state into every bend.
    - ``thermal_softening``: share of the flow stress lost as the die and wire warm with
      the plastic work of a run: the steady state of repeated 90 deg head rotations
      (warmth follows each bend's plastic work with a time constant of
      ``thermal_bends`` bends).
    - ``feed_slip``: share of every commanded feed the rolls do not deliver (parts only).
    - ``die_radius_error_mm``: the die edge radius off its nominal value.
    - ``orbit_eccentricity_mm``: the head's bearing runs out: the orbit centre wobbles
      by this much as the head turns.
    - ``gear_runout_deg``: the pinion's runout, a transmission error of this amplitude
      at the pinion's period (``360 / pinion_turns_per_rev`` of head rotation).
    """

    backlash_deg: float = 0.0
    offset_deg: float = 0.0
    scale: float = 0.0
    drift_deg: float = 0.0
    springback_asymmetry: float = 0.0
    camera_tilt_deg: float = 0.0
    tilt_axis_deg: float = 0.0
    axis_offset_mm: float = 0.0
    axis_offset_along_mm: float = 0.0
    compliance_deg_per_nm: float = 0.0
    step_loss_deg: float = 0.0
    step_loss_torque_share: float = 0.8
    coil_set_per_m: float = 0.0
    thermal_softening: float = 0.0
    thermal_bends: float = 12.0
    feed_slip: float = 0.0
    die_radius_error_mm: float = 0.0
    orbit_eccentricity_mm: float = 0.0
    gear_runout_deg: float = 0.0

    def active(self) -> dict[str, float]:
        """The effects switched on, by field name."""
        defaults = Effects()
        return {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if getattr(self, f.name) != getattr(defaults, f.name)
        }


# CLI name -> (main field, {option key -> field}); the catalogue names come first.
EFFECT_NAMES: dict[str, tuple[str, dict[str, str]]] = {
    "backlash": ("backlash_deg", {}),
    "offset": ("offset_deg", {}),
    "scale": ("scale", {}),
    "drift": ("drift_deg", {}),
    "springback_asymmetry": ("springback_asymmetry", {}),
    "camera_tilt": ("camera_tilt_deg", {"tilt_axis_deg": "tilt_axis_deg"}),
    "axis_offset": ("axis_offset_mm", {"along_mm": "axis_offset_along_mm"}),
    "compliance": ("compliance_deg_per_nm", {}),
    "step_loss": ("step_loss_deg", {"torque_share": "step_loss_torque_share"}),
    "coil_set": ("coil_set_per_m", {}),
    "thermal_softening": ("thermal_softening", {"bends": "thermal_bends"}),
    "feed_slip": ("feed_slip", {}),
    "die_radius_error": ("die_radius_error_mm", {}),
    "orbit_eccentricity": ("orbit_eccentricity_mm", {}),
    "gear_runout": ("gear_runout_deg", {}),
}
CATALOGUE = (
    "backlash",
    "offset",
    "scale",
    "drift",
    "springback_asymmetry",
    "camera_tilt",
    "axis_offset",
    "compliance",
)


def parse_effects(specs: list[str]) -> Effects:
    """Effects from ``NAME=VALUE[,KEY=VALUE...]`` strings (ValueError names the bad one)."""
    values: dict[str, float] = {}
    for spec in specs:
        parts = [p.strip() for p in spec.split(",") if p.strip()]
        if not parts or "=" not in parts[0]:
            raise ValueError(f"effect {spec!r}: expected NAME=VALUE")
        name, value = parts[0].split("=", 1)
        if name not in EFFECT_NAMES:
            raise ValueError(
                f"effect {spec!r}: unknown name {name!r} (known: {', '.join(EFFECT_NAMES)})"
            )
        main, options = EFFECT_NAMES[name]
        values[main] = _number(spec, value)
        for part in parts[1:]:
            key, _, val = part.partition("=")
            if key not in options:
                raise ValueError(f"effect {spec!r}: unknown option {key!r} for {name}")
            values[options[key]] = _number(spec, val)
    return Effects(**values)


def machine_with(machine: Machine, specs: list[str]) -> Machine:
    """The machine with ``KEY=VALUE`` overrides of its fields (ValueError on a bad one)."""
    fields = {f.name: f for f in dataclasses.fields(machine)}
    changes: dict[str, object] = {}
    for spec in specs:
        key, _, value = spec.partition("=")
        if key not in fields or key == "name":
            raise ValueError(f"machine parameter {spec!r}: unknown key {key!r}")
        if key == "material":
            if value not in MATERIALS:
                raise ValueError(
                    f"machine parameter {spec!r}: unknown material (known: {', '.join(MATERIALS)})"
                )
            changes[key] = value
        else:
            changes[key] = _number(spec, value)
    return dataclasses.replace(machine, **changes)


def _number(spec: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise ValueError(f"{spec!r}: {text!r} is not a number") from None
    if value != value or value in (float("inf"), float("-inf")):
        raise ValueError(f"{spec!r}: {text!r} is not finite")
    return value
