"""Calibration session end to end (TinyG double + rendered photos): springback and part accuracy (issue 7).

Runs ``run_session`` against the TinyG double on a pty (its machine is
cvmeasure.sim), driven through the streamer, with the
simulated camera (cvmeasure_datasets.render_bender_photo) and the marker measurement,
then checks (a) each measured springback against the simulation's, and (b)
that the calibration's compensation bends the seed paper's half circle (R 100
mm, 20 chords, 9 deg per segment) and saddle (200 x 20 mm, 13 chords, 3.48 deg
per segment) within 0.1 deg per segment when the pin commands are simulated.
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from benchmarks import Metric, Table, finish

SECTION = "Calibration session: springback and compensated parts (simulation)"


def _segment_bend_deg(height_mm: float, chord_mm: float, divisions: int) -> float:
    """The seed's ``bending_angle``: arc from height and chord, divided into equal segments."""
    radius = height_mm / 2 + chord_mm**2 / (8 * height_mm)
    return math.degrees(2 * math.asin(chord_mm / (2 * radius))) / divisions


#: Calibration angles of the --quick run (wanted loaded angles, deg).
QUICK_ANGLES = (2.5, 5.0, 10.0, 20.0, 45.0, 90.0, 130.0)

PARTS = {
    "half circle": (_segment_bend_deg(100.0, 200.0, 20), 20),
    "saddle": (_segment_bend_deg(20.0, 200.0, 13), 13),
}


def _part_errors(calibration, target_deg: float, segments: int, outside: str, effects=()):
    """Per-segment final-angle errors (deg) of a part bent with the calibration, both directions.

    ``calibration`` is anything with ``compensate(target, outside=...)``; the
    pin commands are executed by the simulation with the machine's ``effects``.
    """
    from cvmeasure.material.compensation import CompensationRangeError
    from cvmeasure.sim import simulate

    errors = []
    for sign in (1.0, -1.0):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                pin = calibration.compensate(sign * target_deg, outside=outside)
            except CompensationRangeError as exc:
                return None, str(exc)
        commands = np.full(segments, pin)
        final = simulate(commands, effects=effects).unloaded_bend_deg
        errors.append(final - sign * target_deg)
    note = "; ".join(str(w.message) for w in caught) if caught else ""
    return np.concatenate(errors), note


class _Nominal:
    """No calibration: the simulation's own inverse with nominal parameters (no effects)."""

    def compensate(self, target_deg: float, outside: str = "raise") -> float:
        from cvmeasure.sim import pin_command_for_angle

        return float(pin_command_for_angle(target_deg))


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.session", description=__doc__)
    p.add_argument("--quick", action="store_true", help="one 7-angle session at 0.25 render scale")
    args = p.parse_args(argv)

    from cvmeasure.driver.session import (
        SessionConfig,
        run_session,
    )
    from cvmeasure.material.compensation import SPRINGBACK_MODELS
    from cvmeasure.sim import parse_effect, simulate
    from cvmeasure.testing.bender import simulated_bender
    from cvmeasure_datasets.simcapture import SimulatedCapture, double_photo_state

    scale = 0.25 if args.quick else 0.5
    quick_config = SessionConfig(mode="custom", angles_deg=QUICK_ANGLES)
    if args.quick:
        sessions = {
            "2.5..130 (7 angles)": (quick_config, ()),
            "2.5..130, backlash 0.8 deg": (quick_config, ("backlash=0.8",)),
        }
    else:
        sessions = {
            "quick": (SessionConfig(mode="quick"), ()),
            "standard": (SessionConfig(mode="standard"), ()),
            "high": (SessionConfig(mode="high"), ()),
            "high, backlash 0.8 deg": (SessionConfig(mode="high"), ("backlash=0.8",)),
        }
    rows_sb, rows_parts, notes = [], [], []
    worst_sb, worst_part, seconds_per_bend = 0.0, {}, []
    for label, (config, effect_texts) in sessions.items():
        effects = tuple(parse_effect(t) for t in effect_texts)
        with tempfile.TemporaryDirectory() as tmp:
            bender = simulated_bender(speedup=200.0, effects=effects)
            camera = SimulatedCapture(
                Path(tmp) / "photos",
                lambda b=bender: double_photo_state(b.double),
                scale=scale,
                seed=11,
            )
            t0 = time.perf_counter()
            try:
                result = run_session(bender, camera, tmp, config=config, model="linear")
            finally:
                bender.close()
            elapsed = time.perf_counter() - t0
        steps = result.steps
        seconds_per_bend.append(elapsed / len(steps))
        truth = simulate([s.commanded_pin_deg for s in steps], effects=effects).springback_deg
        measured = np.array([s.springback_deg for s in steps])
        err = measured - truth
        worst_sb = max(worst_sb, float(np.max(np.abs(err))))
        rows_sb.append(
            [
                label,
                len(steps),
                scale,
                float(np.sqrt(np.mean(err**2))),
                float(np.max(np.abs(err))),
                elapsed,
            ]
        )
        for part, (target, segments) in PARTS.items():
            errors, _ = _part_errors(_Nominal(), target, segments, "raise", effects)
            rows_parts.append(
                [
                    label,
                    "none (nominal sim inverse)",
                    part,
                    round(target, 3),
                    "-",
                    float(np.max(np.abs(errors))),
                ]
            )
        for model in SPRINGBACK_MODELS:
            try:
                cal = result.calibration.refit(model)  # type: ignore[arg-type]
            except ValueError as exc:
                notes.append(f"{label}/{model}: {exc}")
                continue
            for part, (target, segments) in PARTS.items():
                errors, note = _part_errors(cal, target, segments, "raise", effects)
                status = "in range"
                if errors is None:
                    notes.append(f"{label}/{model}/{part}: refused: {note}")
                    errors, _ = _part_errors(cal, target, segments, "warn", effects)
                    status = "extrapolated (refused by default)"
                worst = float(np.max(np.abs(errors)))
                if status == "in range":
                    worst_part[(label, model, part)] = worst
                rows_parts.append([label, model, part, round(target, 3), status, worst])
    linear_in_range = {k: v for k, v in worst_part.items() if k[1] == "linear"}
    worst_linear = max(linear_in_range.values()) if linear_in_range else float("nan")
    covered = {k[2] for k in linear_in_range}
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=[
            Metric(
                "max |springback - simulation|, all sessions",
                worst_sb,
                "deg",
                target="<= 0.05",
                met=worst_sb <= 0.05,
            ),
            Metric(
                "max per-segment error, linear model, parts inside the calibrated range",
                worst_linear,
                "deg",
                target="<= 0.1",
                met=bool(worst_linear <= 0.1) and covered == set(PARTS),
            ),
            Metric(
                "session time per bend (2 renders + 2 measurements)",
                float(np.mean(seconds_per_bend)),
                "s",
                target=None,
                met=None,
            ),
        ],
        tables=[
            Table(
                "Springback measured in the session vs the simulation",
                ["session", "bends", "render scale", "rms_err_deg", "max_err_deg", "seconds"],
                rows_sb,
            ),
            Table(
                "Compensated parts: worst per-segment final-angle error (both directions)",
                ["session", "model", "part", "segment_deg", "range", "max_err_deg"],
                rows_parts,
            ),
        ],
        notes=[
            "bender = the TinyG double on a pty behind the streamer (speedup 200), its machine "
            "= cvmeasure.sim defaults (3 mm steel, DIWire-like head), no effects;"
            " photos rendered by cvmeasure_datasets.render_bender_photo and measured by "
            "cvmeasure.markers.measure_machine_photo with the render's lens model",
            "backlash sessions: the double's machine loses 0.8 deg of pin travel per bend "
            "(cvmeasure.sim effect); the calibration absorbs it, the nominal inverse does not",
            "calibration angles are wanted loaded angles; the saddle's 3.48 deg segment lies "
            "below the final angle of the smallest standard bend (5 deg loaded -> ~4.05 deg "
            "final), so it is refused unless a smaller angle is calibrated (mode high adds 2.5 "
            "and 7.5 deg)",
            *notes,
        ],
    )


if __name__ == "__main__":
    main()
