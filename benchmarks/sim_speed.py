"""Simulation speed: 10,000 bends forward and inverse, vectorised (issue 6)."""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks import Metric, Table, finish
from cvmeasure.sim import Effect, SimParams, pin_command_for_angle, simulate

SECTION = "Simulation speed"


def _best_of(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times))


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.sim_speed", description=__doc__)
    p.add_argument("--quick", action="store_true", help="fewer repeats")
    args = p.parse_args(argv)
    repeats = 5 if args.quick else 25
    rng = np.random.default_rng(7)
    n = 10_000
    commands = rng.uniform(-140.0, 140.0, n)
    targets = rng.uniform(-130.0, 130.0, n)
    all_effects = (
        Effect("backlash", 1.0),
        Effect("offset", 0.5),
        Effect("scale", 0.02),
        Effect("drift", 0.01),
        Effect("springback_asymmetry", 0.2),
        Effect("camera_tilt", 10.0),
        Effect("axis_offset", 0.2),
        Effect("compliance", 0.3),
    )
    rows = []
    for law in ("epp", "bilinear", "power"):
        params = SimParams(hardening=law)
        t_plain = _best_of(lambda p=params: simulate(commands, p), repeats)
        t_eff = _best_of(lambda p=params: simulate(commands, p, all_effects), repeats)
        t_inv = _best_of(lambda p=params: pin_command_for_angle(targets, p), max(repeats // 5, 1))
        rows.append([law, round(1e3 * t_plain, 2), round(1e3 * t_eff, 2), round(1e3 * t_inv, 1)])
    worst_forward = max(max(r[1], r[2]) for r in rows) / 1e3
    worst_inverse = max(r[3] for r in rows) / 1e3
    # round trip accuracy of the inverse on the same targets
    cmd = pin_command_for_angle(targets)
    err = np.abs(simulate(cmd).unloaded_bend_deg - targets)
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=[
            Metric(
                "simulate 10,000 bends (slowest law, all effects)",
                round(worst_forward, 4),
                "s",
                "< 1",
                bool(worst_forward < 1.0),
            ),
            Metric("inverse for 10,000 targets (slowest law)", round(worst_inverse, 3), "s"),
            Metric("inverse round-trip error, max", float(err.max()), "deg"),
        ],
        tables=[
            Table(
                "median time per call, 10,000 bends",
                ["hardening", "simulate ms", "simulate + 8 effects ms", "inverse ms"],
                rows,
            )
        ],
        notes=[f"median of {repeats} runs; commands uniform in +-140 deg, seed 7"],
    )


if __name__ == "__main__":
    main()
