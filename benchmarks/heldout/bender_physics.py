"""Held-out bender model: drive, wire and camera, written from the physics alone.

Used to judge the project's diagnosis and closed loop on data whose assumptions the
measured code does not share. Code under test must not import this package.

A run executes commanded head rotations (the trials CSV's ``commanded_pin_deg``, the
G-code's ``X``) in order on one wire, each followed by a release to home:

1. drive: the controller's count (shifted by any slipped steps) times
   ``1 + scale``, plus the home error and the pinion's runout, through a gear play of
   ``+-backlash`` (hysteresis), lagging by the wind-up ``k T`` under the pin torque;
2. wire: :mod:`benchmarks.heldout.mechanics` at the pin's orbit angle, with the
   section tables of :mod:`benchmarks.heldout.wire_section` (the wire's material,
   softened as the run warms, with its drawing and coil history);
3. camera: both photos (loaded, released) read through a tilted camera's
   foreshortening plus Gaussian noise per angle.

Usage::

    python -m benchmarks.heldout.bender_physics PLAN.csv --machine diwire \\
        --effect backlash=1.2 --noise-deg 0.05 --seed 3 -o TRIALS.csv

writes ``TRIALS.csv`` (``trial, commanded_pin_deg, loaded_bend_deg,
unloaded_bend_deg, measured_pin_deg``) and ``TRIALS.truth.json`` beside it. Run from
the repository root.
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import io
import json
import math
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.heldout.machine import (
    CATALOGUE,
    EFFECT_NAMES,
    MACHINES,
    Effects,
    Machine,
    machine_with,
    parse_effects,
)
from benchmarks.heldout.mechanics import BendGeometry, BendResult, bend, residual_zone
from benchmarks.heldout.wire_section import SectionTable, section_table

__all__ = [
    "MACHINES",
    "BenderRun",
    "BentZone",
    "Effects",
    "ExecutedBend",
    "Machine",
    "TrialRow",
    "simulate_trials",
]


@dataclass(frozen=True)
class ExecutedBend:
    """One executed bend, true values in the machine frame (deg, N m).

    ``head_deg`` is the head's rotation from its nominal home while loaded;
    ``pin_angle_deg`` the angle of the pin's centre seen from the origin marker (the
    die centre); ``loaded_deg``/``unloaded_deg`` the bent leg's direction from +x
    (the wire's coil set over the markers' distance included); ``bend_deg`` the
    released bend of the zone alone (springback included, coil set not).
    """

    commanded_deg: float
    side: int
    head_deg: float
    pin_angle_deg: float
    loaded_deg: float
    unloaded_deg: float
    contact: bool
    torque_nm: float
    wrap_deg: float
    lever_mm: float
    slipped_deg: float
    bend_deg: float


@dataclass(frozen=True)
class BentZone:
    """The wire a bend formed, released (machine frame, counter-clockwise positive).

    ``curvature_per_mm`` at ``distance_mm`` downstream of the die exit is the residual
    curvature less the wire's own, ``natural_curvature_per_mm`` (its coil set);
    ``rotation_deg`` its integral (the released bend), exact where the samples are not.
    """

    distance_mm: np.ndarray
    curvature_per_mm: np.ndarray
    natural_curvature_per_mm: float
    rotation_deg: float


@dataclass(frozen=True)
class TrialRow:
    """One trials-CSV row (measured values, deg) with the truth behind it."""

    trial: int
    commanded_pin_deg: float
    loaded_bend_deg: float
    unloaded_bend_deg: float
    measured_pin_deg: float
    truth: ExecutedBend


def _wrap180(deg: float) -> float:
    wrapped = (deg + 180.0) % 360.0 - 180.0
    return 180.0 if wrapped == -180.0 else wrapped


class BenderRun:
    """A machine executing bends in order on one wire (state: play, slip, warmth, side)."""

    def __init__(self, machine: Machine, effects: Effects | None = None) -> None:
        self.machine = machine
        self.effects = effects or Effects()
        self._head_deg = 0.0  # play operator output at the last drive position
        self._slip_continuous_deg = 0.0
        self._zero_shift_deg = 0.0
        self._warmth = 0.0
        self._side = 1
        self._reference_torque: float | None = None
        self._reference_work: float | None = None

    # -- machine pieces -------------------------------------------------------------
    def _geometry(self, side: int, head_deg: float) -> BendGeometry:
        m, fx = self.machine, self.effects
        r_w = m.wire_diameter_mm / 2.0
        h = math.radians(head_deg)
        ecc = fx.orbit_eccentricity_mm
        a_d = max(m.die_radius_mm + fx.die_radius_error_mm, 0.0) + r_w
        ox = fx.axis_offset_along_mm + ecc * (math.cos(h) - 1.0)
        oy = side * (fx.axis_offset_mm + ecc * math.sin(h))
        if m.orbit_about_die:  # about the nominal die centre, on the bend's side
            ox, oy = ox + m.die_exit_x_mm, oy + m.die_radius_mm + r_w
        return BendGeometry(
            die_centre_x_mm=m.die_exit_x_mm,
            die_centreline_radius_mm=a_d,
            pin_contact_radius_mm=(m.pin_diameter_mm + m.wire_diameter_mm) / 2.0,
            orbit_centre_mm=(ox, oy),
            pin_orbit_radius_mm=m.pin_orbit_radius_mm,
        )

    def _table(self, side: int, softening: float = 0.0) -> SectionTable:
        m, fx = self.machine, self.effects
        r_w = m.wire_diameter_mm / 2.0
        a_d = max(m.die_radius_mm + fx.die_radius_error_mm, 0.0) + r_w
        factor = round((1.0 - softening) / 0.01) * 0.01  # 1 % steps: few tables
        coil = 2.0 / m.spool_diameter_mm if fx.coil_set_per_m != 0.0 else 0.0
        return section_table(
            m.wire_material.softened(factor),
            r_w,
            1.0 / a_d + 2.0 / m.spool_diameter_mm,
            side,
            fx.springback_asymmetry,
            coil,
            fx.coil_set_per_m / 1000.0,
        )

    def _drive(self, count_deg: float) -> float:
        """Head position the drive chain sets for a controller count (before the play)."""
        fx = self.effects
        motor = (count_deg + self._zero_shift_deg) * (1.0 + fx.scale)
        period = 360.0 / self.machine.pinion_turns_per_rev
        runout = fx.gear_runout_deg * math.sin(2.0 * math.pi * motor / period)
        return motor + fx.offset_deg + runout

    def _play(self, drive_deg: float) -> float:
        b = self.effects.backlash_deg
        return min(max(self._head_deg, drive_deg - b), drive_deg + b)

    def _at(self, side: int, head_deg: float, table: SectionTable) -> tuple[BendResult, float]:
        """Bend result and pin orbit angle (rad, mirrored frame) at a head rotation."""
        park = math.radians(self.machine.park_angle_deg)
        phi = side * math.radians(head_deg) - park
        return bend(self._geometry(side, head_deg), table, phi), phi

    def _loaded_head(
        self, side: int, head_deg: float, table: SectionTable
    ) -> tuple[float, BendResult]:
        """Head rotation under load (the wind-up ``k T`` solved as a fixed point)."""
        k = self.effects.compliance_deg_per_nm
        result, _ = self._at(side, head_deg, table)
        if k == 0.0:
            return head_deg, result
        lagged = head_deg
        for _ in range(30):
            new = head_deg - side * k * result.torque_nmm / 1000.0
            if abs(new - lagged) < 1e-9:
                break
            lagged = 0.5 * (lagged + new)
            result, _ = self._at(side, lagged, table)
        return lagged, result

    def reference_torque_nm(self) -> float:
        """Largest torque of a nominal bend of this machine (N m), over head rotations to 150 deg.

        Also sets the reference plastic work of warming: a nominal 90 deg head rotation's.
        """
        if self._reference_torque is None:
            nominal = BenderRun(self.machine)
            table = nominal._table(1)
            torques = [nominal._at(1, h, table)[0] for h in np.linspace(5.0, 150.0, 30)]
            self._reference_torque = max(r.torque_nmm for r in torques) / 1000.0
            self._reference_work = nominal._at(1, 90.0, table)[0].plastic_work_nmm
        return self._reference_torque

    # -- one bend ---------------------------------------------------------------------
    def execute(self, commanded_deg: float) -> ExecutedBend:
        """Bend to ``commanded_deg`` (head rotation from home, signed), photograph, release."""
        return self.execute_zone(commanded_deg)[0]

    def execute_zone(self, commanded_deg: float) -> tuple[ExecutedBend, BentZone]:
        """:meth:`execute`, with the released curvature of the wire the bend formed."""
        fx, m = self.effects, self.machine
        if not abs(commanded_deg) <= m.max_head_deg:
            raise ValueError(
                f"head rotation {commanded_deg:g} deg is beyond the {m.name} machine's "
                f"{m.max_head_deg:g} deg"
            )
        if commanded_deg != 0.0:
            self._side = 1 if commanded_deg > 0.0 else -1  # a duck move switches the pin's side
        side = self._side
        table = self._table(side, fx.thermal_softening * self._warmth)
        head = self._play(self._drive(commanded_deg))
        loaded_head, result = self._loaded_head(side, head, table)
        slip = 0.0
        if result.contact:
            slip += fx.drift_deg
            if (
                fx.step_loss_deg
                and result.torque_nmm / 1000.0
                > fx.step_loss_torque_share * self.reference_torque_nm()
            ):
                slip += fx.step_loss_deg
        if slip:
            # The stepper slips back against the load; the controller's count never knows.
            self._slip_continuous_deg -= side * slip
            q = m.head_step_deg
            shift = q * round(self._slip_continuous_deg / q) if q > 0 else self._slip_continuous_deg
            applied, self._zero_shift_deg = shift - self._zero_shift_deg, shift
            head = self._play(self._drive(commanded_deg))
            loaded_head, result = self._loaded_head(side, head, table)
            slip = -side * applied
        self._head_deg = head
        pin_abs = self._pin_angle_seen(side, loaded_head)
        coil = math.degrees(table.natural_curvature_per_mm * m.marker_distance_mm)
        executed = ExecutedBend(
            commanded_deg=commanded_deg,
            side=side,
            head_deg=loaded_head,
            pin_angle_deg=pin_abs,
            loaded_deg=_wrap180(side * (result.loaded_deg + coil)),
            unloaded_deg=_wrap180(side * (result.unloaded_deg + coil)),
            contact=result.contact,
            torque_nm=result.torque_nmm / 1000.0,
            wrap_deg=result.wrap_deg,
            lever_mm=result.lever_mm,
            slipped_deg=slip,
            bend_deg=side * result.unloaded_deg,
        )
        distance, curvature = residual_zone(self._geometry(side, loaded_head), table, result)
        zone = BentZone(
            distance, side * curvature, side * table.natural_curvature_per_mm, executed.bend_deg
        )
        self._release()
        self._warm(result)
        return executed, zone

    def _pin_angle_seen(self, side: int, head_deg: float) -> float:
        geom = self._geometry(side, head_deg)
        phi = side * math.radians(head_deg) - math.radians(self.machine.park_angle_deg)
        ox, oy = geom.orbit_centre_mm
        r = geom.pin_orbit_radius_mm
        x, y = ox + r * math.cos(phi), side * (oy + r * math.sin(phi))
        if self.machine.orbit_about_die:  # the origin marker sits on the head axis
            return _wrap180(side * math.degrees(phi))
        return math.degrees(math.atan2(y, x))

    def _release(self) -> None:
        self._head_deg = self._play(self._drive(0.0))

    def _warm(self, result: BendResult) -> None:
        if self.effects.thermal_softening == 0.0:
            return
        self.reference_torque_nm()
        decay = math.exp(-1.0 / max(self.effects.thermal_bends, 1e-6))
        work = result.plastic_work_nmm / max(self._reference_work or 1.0, 1e-9)
        self._warmth = self._warmth * decay + (1.0 - decay) * min(work, 2.0)

    # -- the camera ---------------------------------------------------------------------
    def seen(self, angle_deg: float) -> float:
        """An in-plane direction (deg from +x) as the tilted camera reads it, from its +x."""
        t = math.radians(self.effects.camera_tilt_deg)
        if t == 0.0:
            return angle_deg
        psi = math.radians(self.effects.tilt_axis_deg)

        def project(a: float) -> float:
            return psi + math.atan2(math.sin(a - psi) * math.cos(t), math.cos(a - psi))

        a = math.radians(angle_deg)
        return _wrap180(math.degrees(project(a) - project(0.0)))


def resolve_machine(machine: Machine | str) -> Machine:
    if isinstance(machine, Machine):
        return machine
    if machine not in MACHINES:
        raise ValueError(f"unknown machine {machine!r} (known: {', '.join(MACHINES)})")
    return MACHINES[machine]


def simulate_trials(
    plan_commanded_pin_deg,
    machine: Machine | str = "diwire",
    effects: Effects | None = None,
    noise_deg: float = 0.0,
    seed: int = 0,
) -> list[TrialRow]:
    """Run a calibration plan on the machine and read each bend's two photos.

    Parameters
    ----------
    plan_commanded_pin_deg : sequence of float
        Signed head rotations from home (deg), in the order executed.
    machine : Machine or str
        A :class:`Machine` or the name of one in ``MACHINES``.
    effects : Effects, optional
        Hidden effects (default none).
    noise_deg : float
        Standard deviation of the reading of each angle of each photo (deg).
    seed : int
        Seed of the noise.

    Returns
    -------
    list of TrialRow

    Raises
    ------
    ValueError
        A command beyond the machine's largest head rotation.
        ``measured_pin_deg`` is the pin angle on the loaded photo in the machine frame
        (origin marker to pin, from +x, as the camera reads it); at home the pin sits at
        ``-side * park_angle_deg`` (the head axis on the die centre).
    """
    mach = resolve_machine(machine)
    run = BenderRun(mach, effects or Effects())
    rng = np.random.default_rng(seed)
    rows = []
    for i, cmd in enumerate(plan_commanded_pin_deg, start=1):
        done = run.execute(float(cmd))
        noise = rng.normal(0.0, noise_deg, 3) if noise_deg > 0 else np.zeros(3)
        pin_seen = run.seen(done.pin_angle_deg)
        rows.append(
            TrialRow(
                trial=i,
                commanded_pin_deg=float(cmd),
                loaded_bend_deg=_wrap180(run.seen(done.loaded_deg) + noise[0]),
                unloaded_bend_deg=_wrap180(run.seen(done.unloaded_deg) + noise[1]),
                measured_pin_deg=_wrap180(pin_seen + noise[2]),
                truth=done,
            )
        )
    return rows


def effect_names(effects: Effects) -> dict[str, float]:
    """Active effects by their CLI / catalogue name, with options as ``name.option``."""
    active = effects.active()
    out: dict[str, float] = {}
    for name, (main, options) in EFFECT_NAMES.items():
        if main in active:
            out[name] = active[main]
            for key, field in options.items():
                out[f"{name}.{key}"] = getattr(effects, field)
    return out


def realised_springback_asymmetry(
    machine: Machine, effects: Effects, magnitudes_deg
) -> float | None:
    """Mean ``(sb+ - sb-) / (sb+ + sb-)`` over these head rotations (the contract's alpha).

    Each bend on a fresh wire, the other effects off, so only the direction matters.
    """
    only = Effects(springback_asymmetry=effects.springback_asymmetry)
    ratios = []
    for mag in sorted({abs(float(m)) for m in magnitudes_deg if m}):
        plus = BenderRun(machine, only).execute(mag)
        minus = BenderRun(machine, only).execute(-mag)
        sb_p = plus.loaded_deg - plus.unloaded_deg
        sb_m = minus.unloaded_deg - minus.loaded_deg
        if plus.contact and minus.contact and sb_p + sb_m > 0:
            ratios.append((sb_p - sb_m) / (sb_p + sb_m))
    return float(np.mean(ratios)) if ratios else None


def truth_record(
    rows: list[TrialRow], machine: Machine, effects: Effects, noise_deg: float, seed: int
) -> dict:
    """JSON-ready truth of a simulated run: machine, effects, and every bend's true values."""
    names = effect_names(effects)
    main = [n for n in names if "." not in n]
    contract: dict[str, float | None] = {}
    for name in main:
        contract[name] = names[name]
    if "springback_asymmetry" in contract:
        contract["springback_asymmetry"] = realised_springback_asymmetry(
            machine, effects, [r.commanded_pin_deg for r in rows]
        )
    if "drift" in contract:
        slips = [abs(r.truth.slipped_deg) for r in rows if r.truth.contact]
        contract["drift"] = float(np.mean(slips)) if slips else 0.0
    return {
        "model": "benchmarks.heldout.bender_physics",
        "machine": dataclasses.asdict(machine),
        "material": dataclasses.asdict(machine.wire_material),
        "dead_angle_deg": machine.dead_angle_deg(),
        "effects": names,
        "catalogue_causes": [n for n in main if n in CATALOGUE],
        "outside_catalogue": [n for n in main if n not in CATALOGUE],
        "contract_magnitudes": contract,
        "noise_deg": noise_deg,
        "seed": seed,
        "trials": [
            {"trial": r.trial, **{k: v for k, v in dataclasses.asdict(r.truth).items()}}
            for r in rows
        ],
    }


def atomic_write(path: Path, text: str) -> None:
    fd, tmp = tempfile.mkstemp(dir=path.parent or Path("."), prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="") as fh:
            fh.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def trials_csv(rows: list[TrialRow]) -> str:
    """The trials CSV of the contract (plus ``measured_pin_deg``)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(
        ["trial", "commanded_pin_deg", "loaded_bend_deg", "unloaded_bend_deg", "measured_pin_deg"]
    )
    for r in rows:
        w.writerow(
            [r.trial]
            + [
                f"{v:.6f}"
                for v in (
                    r.commanded_pin_deg,
                    r.loaded_bend_deg,
                    r.unloaded_bend_deg,
                    r.measured_pin_deg,
                )
            ]
        )
    return buf.getvalue()


def read_plan(path: Path) -> list[float]:
    """Commanded head rotations of a plan CSV (``trial, commanded_pin_deg``), in file order."""
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            if reader.fieldnames is None or "commanded_pin_deg" not in reader.fieldnames:
                raise ValueError("no commanded_pin_deg column")
            values = [float(row["commanded_pin_deg"]) for row in reader]
    except (OSError, UnicodeDecodeError) as exc:
        raise ValueError(f"cannot read: {exc}") from None
    except (TypeError, ValueError) as exc:
        raise ValueError(f"bad plan: {exc}") from None
    if not values:
        raise ValueError("no bends in the plan")
    if not all(math.isfinite(v) and abs(v) <= 360.0 for v in values):
        raise ValueError("commanded_pin_deg must be finite and within +-360")
    return values


def main(argv: list[str] | None = None) -> int:
    """CLI: simulate a plan on a held-out machine; write the trials CSV and its truth JSON."""
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.heldout.bender_physics",
        description="Held-out bender model: run a plan CSV (trial, commanded_pin_deg) on a "
        "machine with hidden effects; write the trials CSV and OUT.truth.json beside it.",
    )
    p.add_argument("plan", type=Path, help="plan CSV with columns trial, commanded_pin_deg")
    p.add_argument(
        "--machine", default="diwire", help=f"machine ({', '.join(MACHINES)}; default diwire)"
    )
    p.add_argument(
        "--machine-param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a machine field, e.g. die_radius_mm=2 (repeatable)",
    )
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME=VALUE[,KEY=VALUE]",
        help=f"hidden effect (repeatable): {', '.join(EFFECT_NAMES)}",
    )
    p.add_argument(
        "--noise-deg", type=float, default=0.05, help="per-photo angle noise, deg (default 0.05)"
    )
    p.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    p.add_argument("-o", "--out", type=Path, required=True, help="trials CSV to write")
    args = p.parse_args(argv)
    try:
        plan = read_plan(args.plan)
    except ValueError as exc:
        print(f"{args.plan}: {exc}", file=sys.stderr)
        return 2
    try:
        machine = machine_with(resolve_machine(args.machine), args.machine_param)
        effects = parse_effects(args.effect)
        if not (math.isfinite(args.noise_deg) and args.noise_deg >= 0.0):
            raise ValueError(f"--noise-deg {args.noise_deg}: must be >= 0")
    except ValueError as exc:
        print(f"option: {exc}", file=sys.stderr)
        return 2
    try:
        rows = simulate_trials(plan, machine, effects, args.noise_deg, args.seed)
    except ValueError as exc:
        print(f"{args.plan}: {exc}", file=sys.stderr)
        return 2
    truth = truth_record(rows, machine, effects, args.noise_deg, args.seed)
    truth_path = args.out.with_name(args.out.stem + ".truth.json")
    atomic_write(truth_path, json.dumps(truth, indent=1) + "\n")
    atomic_write(args.out, trials_csv(rows))
    print(f"wrote {args.out} ({len(rows)} trials) and {truth_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
