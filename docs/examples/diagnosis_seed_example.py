"""Worked example of docs/diagnosis.md on the seed paper's numbers.

0. Fit the head geometry to the DIWire firmware's motion function (target
   angle -> head degrees after the 13.2 deg approach, 10-120 deg).
1. Calibrate the simulation's springback to the seed FEA (1.5 deg at 5 deg,
   2.7 deg at 130 deg of bend) by fitting the wire strength and the span factor.
2. Simulate the seed's calibration plan (5-130 deg, 11 angles, both directions)
   on a machine whose head axis sits 0.3 mm off the wire axis (cw and ccw then
   differ by up to ~3-4 deg, as in the seed's Fig. 8), add 0.1 deg noise, and
   diagnose it: with both directions and loaded photos, with released angles
   only, and with one direction only.

Run: ``python docs/examples/diagnosis_seed_example.py`` (a few seconds).
"""

from __future__ import annotations

import json

import numpy as np
from scipy import optimize

from cvmeasure.diagnose import diagnose
from cvmeasure.sim import Effect, SimParams, pin_command_for_angle, simulate
from cvmeasure_datasets.trials import measure_trials

FEA = {5.0: 1.5, 130.0: 2.7}  # seed FEA: springback (deg) at bend angle (deg)
STANDARD = (5, 10, 15, 20, 30, 45, 60, 75, 90, 110, 130)


def springback_at(params: SimParams, final_deg: float) -> float:
    cmd = pin_command_for_angle(final_deg, params)
    return float(simulate([cmd], params).springback_deg[0])


def calibrate_to_fea(base: SimParams) -> SimParams:
    def resid(x: np.ndarray) -> list[float]:
        p = base.replace(
            yield_mpa=base.yield_mpa * x[0], uts_mpa=base.uts_mpa * x[0], span_factor=x[1]
        )
        return [springback_at(p, angle) - sb for angle, sb in FEA.items()]

    sol = optimize.least_squares(resid, [1.0, 0.5], bounds=([0.3, 0.2], [4.0, 1.0]))
    s, c = sol.x
    return base.replace(yield_mpa=base.yield_mpa * s, uts_mpa=base.uts_mpa * s, span_factor=c)


def firmware_head_deg(angle_deg: np.ndarray) -> np.ndarray:
    """DIWire Arduino.txt: head degrees after the approach for a target angle (<= 120)."""
    a = np.asarray(angle_deg, dtype=float)
    return np.where(
        a <= 90, -0.0012 * a**2 + 0.5959 * a + 0.2452, 0.0044 * a**2 - 0.5481 * a + 57.981
    )


def fit_firmware_geometry() -> tuple[SimParams, np.ndarray]:
    angles = np.arange(10.0, 121.0, 10.0)
    goal = firmware_head_deg(angles)

    def resid(x: np.ndarray) -> np.ndarray:
        p = SimParams(head_axis_x_mm=x[0], pin_orbit_mm=x[1], die_radius_mm=x[2])
        return np.asarray(pin_command_for_angle(angles, p)) - p.approach_deg - goal

    sol = optimize.least_squares(resid, [-5.0, 12.0, 1.5], bounds=([-30, 6, 0], [30, 40, 10]))
    x = sol.x
    return SimParams(head_axis_x_mm=x[0], pin_orbit_mm=x[1], die_radius_mm=x[2]), sol.fun


def main() -> None:
    geo, miss = fit_firmware_geometry()
    print(
        f"DIWire firmware motion function reproduced by: head axis x {geo.head_axis_x_mm:.2f} mm, "
        f"pin orbit {geo.pin_orbit_mm:.2f} mm, die radius {geo.die_radius_mm:.2f} mm; "
        f"rms {np.sqrt(np.mean(miss**2)):.2f} deg, max {np.max(np.abs(miss)):.2f} deg (10-120 deg)"
    )
    nominal = SimParams()
    print(
        "springback of the default model (deg):",
        {a: round(springback_at(nominal, a), 2) for a in (5, 45, 90, 130)},
    )
    fea = calibrate_to_fea(nominal)
    print(
        f"calibrated to the FEA: yield {fea.yield_mpa:.0f} MPa, UTS {fea.uts_mpa:.0f} MPa, "
        f"span factor {fea.span_factor:.3f}"
    )
    print(
        "springback after calibration (deg):",
        {a: round(springback_at(fea, a), 2) for a in (5, 45, 90, 130)},
    )

    rng = np.random.default_rng(2026)
    targets = np.array([s * a for a in STANDARD for s in (1.0, -1.0)], dtype=float)
    commands = np.round(np.asarray(pin_command_for_angle(targets, fea)), 1)
    hidden = Effect("axis_offset", 0.3)
    truth = simulate(commands, fea, (hidden,))
    diff = np.abs(truth.unloaded_bend_deg[0::2]) - np.abs(truth.unloaded_bend_deg[1::2])
    print("ccw - cw final angle (deg) at", STANDARD, ":", np.round(diff, 2).tolist())
    for label, kw, plan in (
        ("both directions, loaded + released photos", {}, commands),
        ("released angles only", {"loaded": False}, commands),
        ("one direction only", {}, commands[commands > 0]),
    ):
        trials = measure_trials(plan, (hidden,), 0.1, rng, fea, **kw)
        d = diagnose(trials, fea).to_dict()
        keep = {
            k: d[k]
            for k in (
                "cause",
                "params",
                "intervals",
                "baseline_rmse_deg",
                "extended_rmse_deg",
                "gain",
                "recommended_experiment",
            )
        }
        keep["candidates"] = {c["cause"]: round(c["cv_rmse_deg"], 3) for c in d["candidates"]}
        keep["notes"] = d["notes"]
        print(f"\n== {label} ({len(trials)} trials)")
        print(json.dumps(keep, indent=1, default=float))


if __name__ == "__main__":
    main()
