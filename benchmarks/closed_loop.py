"""Closed loop in simulation: bend, photograph, measure, correct, bend the next part (issue 15).

The machine is the TinyG double (:class:`cvmeasure.driver.double.FakeTinyG`) with
effects hidden from the tool: gear backlash, a home offset, lost steps bend
after bend (drift) and a wire whose yield stress differs from the model's
(springback not the calibrated one). The tool starts from a default
calibration (the nominal simulated bender, ``high`` mode angles, no effects),
streams each job to the double, and the photo lab renders the part the double
actually bent (:meth:`FakeTinyG.wire_shape_mm`, through
``cvmeasure_datasets.render_part_photo``); ``measure_part`` measures it through
a camera calibrated from rendered board photos (``benchmarks/_calibrated.py``)
and :func:`cvmeasure.material.correct.correct_from_part` corrects the
calibration and the job for the next part. The double's executed bends are
the truth that scores every part; the tool never sees them.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from benchmarks import Metric, Table, finish

SECTION = "Closed loop: measure the finished part, correct the next one"

#: Every vertex within this of the design (deg) after at most 2 corrections.
TARGET_DEG = 0.1
#: On at least this share of random designs.
TARGET_SHARE = 0.95
#: The seed paper's half circle and saddle (relative %, absolute deg of the bend per chord).
SEED_BASELINE = {"half circle": (7.14, 0.64), "saddle": (45.68, 1.59)}


def default_calibration():
    """The calibration a fresh machine starts from: the nominal simulated bender, no effects."""
    from cvmeasure.contracts import Trial
    from cvmeasure.driver.session import nominal_pin_for_loaded_deg
    from cvmeasure.material.calibration import MODES, fit_calibration
    from cvmeasure.sim import simulate

    angles = MODES["high"]
    pins = [nominal_pin_for_loaded_deg(a, d) for d in ("ccw", "cw") for a in angles]
    r = simulate(pins)
    samples = [
        Trial(
            trial=str(i),
            commanded_pin_deg=float(p),
            loaded_bend_deg=float(r.loaded_bend_deg[i]),
            unloaded_bend_deg=float(r.unloaded_bend_deg[i]),
            target_deg=float(angles[i % len(angles)]),
        )
        for i, p in enumerate(pins)
    ]
    return fit_calibration(samples, mode="high", name="default (nominal machine)")


def hidden_machine(rng: np.random.Generator) -> tuple[object, tuple]:
    """A machine unlike the model: wire, backlash, home offset, drift (drawn)."""
    from cvmeasure.sim import Effect, SimParams

    params = SimParams(yield_mpa=float(rng.uniform(240.0, 330.0)))
    effects = (
        Effect("backlash", float(rng.uniform(0.5, 2.0))),
        Effect("offset", float(rng.uniform(-1.5, 1.5))),
        Effect("drift", float(rng.uniform(0.005, 0.04))),
    )
    return params, effects


def random_design(rng: np.random.Generator) -> np.ndarray:
    """Equal chords (16-22 mm, 6-10 of them) with bends of 3-25 deg of either sign."""
    n = int(rng.integers(6, 11))
    chord = float(rng.uniform(16.0, 22.0))
    bends = rng.uniform(3.0, 25.0, n - 1) * rng.choice([-1.0, 1.0], n - 1)
    heading = np.concatenate([[0.0], np.cumsum(np.radians(bends))])
    steps = chord * np.column_stack([np.cos(heading), np.sin(heading)])
    pts = np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])
    return pts - pts.mean(axis=0)


def bend_on_double(lines, params, effects) -> tuple[np.ndarray, np.ndarray]:
    """Stream a job to a freshly homed double; (executed final bends (machine deg), wire shape)."""
    from cvmeasure.driver.double import FakeTinyG
    from cvmeasure.driver.stream import stream_job
    from cvmeasure.driver.transport import open_link

    with FakeTinyG(speedup=2000.0, sim_params=params, sim_effects=effects) as board:
        link = open_link(board.port)
        try:
            stream_job(link, list(lines), source="job")
        finally:
            link.close()
        bends = np.array([b.unloaded_bend_deg for b in board.machine_state().bends])
        return bends, board.wire_shape_mm()


def run_design(name, vertices_mm, parts, *, params, effects, camera, scale, seed):
    """Bend ``parts`` parts of one design, correcting after each; per-part records."""
    import cvmeasure_datasets
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.design import DesignPath
    from cvmeasure.driver.gcode import bend_list, gcode_lines
    from cvmeasure.material.correct import (
        correct_from_part,
        corrected_pin_commands,
        job_vertex_offsets,
    )
    from cvmeasure.part.measure import measure_part

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    design = DesignPath(vertices_mm, closed=False, kind="polyline", element=name)
    bl = bend_list(design.chords(len(vertices_mm) - 1), source=name)
    target = bl.bends_deg
    cal = default_calibration()
    pins = corrected_pin_commands(cal, target)
    records = []
    for k in range(parts):
        made, shape = bend_on_double(gcode_lines(bl, pins, title=name), params, effects)
        photo = cvmeasure_datasets.render_part_photo(
            # the part lies design face up: the board frame has y down, the design y up
            part=cvmeasure_datasets.polyline_part(shape * np.array([1.0, -1.0])),
            board=board,
            seed=seed * 1000 + k,
            scale=scale,
        )
        # the tool knows the job it sent: its chord count (the photo's may miss tiny bends)
        m = measure_part(
            photo.bgr,
            board,
            camera,
            divisions=len(target) + 1,
            design=design,
            source=f"{name} part {k}",
            allow_mirror=False,  # the part lies as it left the machine
        )
        cal, corr, job = correct_from_part(cal, m, design, design_name=name)
        measured = np.asarray(corr.measured_deg)
        bends = m.comparison.bends
        records.append(
            {
                "design": name,
                "part": k,
                "true_err_deg": (made - target).tolist(),
                "worst_true_err_deg": float(np.max(np.abs(made - target))),
                "meas_err_deg": (measured - made).tolist(),
                "made_deg": made.tolist(),
                "seed_relative_pct": abs(bends.seed_relative_error_pct),
                "seed_absolute_deg": abs(bends.seed_absolute_error_deg),
                "response_ratio": corr.response_ratio,
            }
        )
        pins = job.pin_deg
        assert np.allclose(
            pins, corrected_pin_commands(cal, target, job_vertex_offsets(cal, name, len(target)))
        )
    return records


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.closed_loop", description=__doc__)
    p.add_argument("--quick", action="store_true", help="fewer designs and parts (< 2 min)")
    p.add_argument("--seed", type=int, default=15, help="seed of the machines and designs")
    args = p.parse_args(argv)
    import cvmeasure_datasets
    from benchmarks._calibrated import calibrated_camera

    scale = 0.5
    camera, calibration = calibrated_camera(scale)
    randoms = 5 if args.quick else 40
    stability = 4 if args.quick else 20
    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    seed_parts = {
        "half circle": cvmeasure_datasets.arc_part(85.0, 180.0, 20).vertices_mm,
        "saddle": cvmeasure_datasets.saddle_part(200.0, 20.0, 13).vertices_mm,
    }
    runs: dict[str, list[dict]] = {}
    for i, (name, verts) in enumerate(seed_parts.items()):
        params, effects = hidden_machine(rng)
        runs[name] = run_design(
            name,
            verts,
            3 + 4 + stability,
            params=params,
            effects=effects,
            camera=camera,
            scale=scale,
            seed=i,
        )
    random_runs = []
    for j in range(randoms):
        params, effects = hidden_machine(rng)
        random_runs.append(
            run_design(
                f"random {j}",
                random_design(rng),
                3,
                params=params,
                effects=effects,
                camera=camera,
                scale=scale,
                seed=100 + j,
            )
        )
    seconds = time.perf_counter() - t0
    within = [r[2]["worst_true_err_deg"] <= TARGET_DEG for r in random_runs]
    share = float(np.mean(within))
    meas = np.concatenate(
        [np.abs(rec["meas_err_deg"]) for run in [*runs.values(), *random_runs] for rec in run]
    )
    noise_p95 = float(np.percentile(meas, 95))
    # stability: parts 7.. of the seed designs against part 6 (converged after 6 corrections)
    changes = []
    for run in runs.values():
        ref = np.asarray(run[6]["made_deg"])
        changes += [float(np.max(np.abs(np.asarray(r["made_deg"]) - ref))) for r in run[7:]]
    stab = max(changes)
    metrics = [
        Metric(
            "random designs with every vertex within 0.1 deg after 2 corrections",
            100.0 * share,
            "%",
            target=f">= {100 * TARGET_SHARE:.0f}",
            met=share >= TARGET_SHARE,
        ),
        Metric(
            "half circle (20 chords, 9 deg): worst vertex after 2 corrections",
            runs["half circle"][2]["worst_true_err_deg"],
            "deg",
            target=f"<= {TARGET_DEG}",
            met=runs["half circle"][2]["worst_true_err_deg"] <= TARGET_DEG,
        ),
        Metric(
            "saddle (13 chords, 3.48 deg): worst vertex after 2 corrections",
            runs["saddle"][2]["worst_true_err_deg"],
            "deg",
            target=f"<= {TARGET_DEG}",
            met=runs["saddle"][2]["worst_true_err_deg"] <= TARGET_DEG,
        ),
        Metric(
            f"stability: largest change of any vertex over {stability} further corrections",
            stab,
            "deg",
            target=f"<= measurement noise (p95 {noise_p95:.3f} deg)",
            met=stab <= noise_p95,
        ),
        Metric("measurement noise of a vertex bend, p95 |measured - executed|", noise_p95, "deg"),
        Metric("wall time", seconds, "s"),
    ]
    seed_rows = []
    for name, run in runs.items():
        rel, ab = SEED_BASELINE[name]
        seed_rows.append(
            [
                name,
                rel,
                ab,
                run[0]["seed_relative_pct"],
                run[0]["seed_absolute_deg"],
                run[2]["seed_relative_pct"],
                run[2]["seed_absolute_deg"],
                run[0]["worst_true_err_deg"],
                run[1]["worst_true_err_deg"],
                run[2]["worst_true_err_deg"],
            ]
        )
    random_rows = [
        [
            run[0]["design"],
            len(run[0]["made_deg"]),
            run[0]["worst_true_err_deg"],
            run[1]["worst_true_err_deg"],
            run[2]["worst_true_err_deg"],
            run[1]["response_ratio"],
        ]
        for run in random_runs
    ]
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[
            Table(
                "the seed's parts: the seed's errors (its Table, bend per chord) beside ours; "
                "worst vertex |executed - design| per part (deg)",
                [
                    "part",
                    "seed_rel_%",
                    "seed_abs_deg",
                    "ours_part0_rel_%",
                    "ours_part0_abs_deg",
                    "ours_part2_rel_%",
                    "ours_part2_abs_deg",
                    "worst_part0",
                    "worst_part1",
                    "worst_part2",
                ],
                seed_rows,
            ),
            Table(
                "random designs: worst vertex |executed - design| (deg) per part",
                ["design", "bends", "part0", "part1", "part2", "response_ratio"],
                random_rows,
            ),
        ],
        notes=[
            "hidden machine per design (seeded): wire yield 240-330 MPa (model 280), backlash "
            "0.5-2 deg, home offset -1.5..1.5 deg, drift 0.005-0.04 deg/bend; a fresh double "
            "(homed) per part",
            "part 0 is bent with the default calibration, part 1 after 1 correction, part 2 "
            "after 2; the errors are the double's executed final bends against the design "
            "(truth), never shown to the tool",
            f"photos rendered at scale {scale}, measured through a camera calibrated from "
            f"{calibration['views']} rendered board photos (RMS {calibration['rms_px']:.3f} px); "
            "the seed's relative/absolute errors are of the bend per chord (arc / N) as in its "
            "Source code 1, measured by our part measurement on our parts",
            "stability: the executed bends of parts 7.. compared with part 6 of the same job",
        ],
    )


if __name__ == "__main__":
    main()
