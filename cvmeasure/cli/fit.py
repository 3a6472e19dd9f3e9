"""``cvmeasure fit``: trials CSV -> calibration JSON (springback compensation) and a plot."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "fit",
        help="fit springback compensation to trials and write the calibration JSON",
        description="Read a trials CSV (trial, commanded_pin_deg, loaded_bend_deg, "
        "unloaded_bend_deg; optional target_deg, measured_pin_deg, loaded_uncertainty_deg, "
        "unloaded_uncertainty_deg), fit the springback model per direction, score every "
        "model leave-one-angle-out, and write the diwire-material/1 calibration JSON.",
    )
    p.add_argument("trials", type=Path, help="trials CSV")
    p.add_argument(
        "--model",
        choices=("linear", "cubic", "pchip", "physical"),
        default="linear",
        help="springback model used for compensation (default: linear, the seed's winner)",
    )
    p.add_argument(
        "--motion-model", choices=("pchip", "linear"), default="pchip", help="motion function model"
    )
    p.add_argument("--name", default=None, help="calibration name (default: the CSV's stem)")
    p.add_argument("-o", "--out", type=Path, required=True, help="calibration JSON to write")
    p.add_argument("--plot", type=Path, help="PNG of data, every model's fit and residuals")
    p.add_argument("--json", action="store_true", help="print the model scores as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.errors import InputError
    from cvmeasure.material.bender_calibration import (
        fit_calibration,
        read_trials_csv,
        save_calibration,
    )
    from cvmeasure.provenance import provenance

    samples = read_trials_csv(args.trials)
    try:
        calibration = fit_calibration(
            samples,
            model=args.model,
            motion_model=args.motion_model,
            name=args.name or args.trials.stem,
            provenance=provenance(["cvmeasure", "fit", str(args.trials), "--model", args.model]),
        )
    except ValueError as exc:
        raise InputError(args.trials, str(exc)) from None
    png = None
    if args.plot:
        # drawn before anything is written: a plot that cannot be made leaves no half result
        from cvmeasure.driver.session_report import calibration_figure_png

        try:
            png = calibration_figure_png(calibration)
        except (ValueError, RuntimeError) as exc:
            raise InputError(
                "--plot",
                f"cannot plot this calibration ({exc}); nothing written (run without --plot)",
            ) from None
    save_calibration(args.out, calibration)
    if png is not None:
        from cvmeasure.fileio import atomic_write_bytes

        atomic_write_bytes(args.plot, png)
    summary = {
        "out": str(args.out),
        "model": calibration.model,
        "bends": len(calibration.samples),
        "domain_deg": {
            d: list(c.domain_deg) for d, c in calibration.compensation.springback.items()
        },
        "scores": calibration.scores,
        "notes": {d: list(c.notes) for d, c in calibration.compensation.springback.items()},
    }
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        for model, by_dir in calibration.scores.items():
            if "error" in by_dir:
                print(f"{model:9s} not fitted: {by_dir['error']}")
                continue
            text = ", ".join(
                f"{d} LOAO RMS {v['loao_rmse_deg']:.4f} deg"
                if v.get("loao_rmse_deg") is not None
                else f"{d} not scored (fewer than 3 angles)"
                for d, v in by_dir.items()
            )
            print(f"{model:9s} {text}")
        print(f"wrote {args.out} (model {calibration.model})")
    return 0
