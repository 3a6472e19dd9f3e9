"""``cvmeasure diagnose``: what the simulation gets wrong on measured trials."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cvmeasure.cli.options import int_in
from cvmeasure.cli.startup import libraries_loading

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "diagnose",
        help="find what the simulation gets wrong on measured trials and name the cause",
        description="Compare measured trials (trials CSV: trial, commanded_pin_deg, "
        "loaded_bend_deg, unloaded_bend_deg; optional measured_pin_deg, part, bend_index) "
        "with the simulation, try every named effect with grouped cross-validation, and "
        "report the cause (and a second one if the data need it), its parameter with a "
        "95 % interval, baseline and extended held-out RMSE, every candidate's held-out "
        "error, an identifiability check and the experiment that would separate "
        "confounded causes.",
    )
    p.add_argument("trials", type=Path, help="trials CSV")
    p.add_argument("--params", type=Path, help="params JSON of the simulation (default built in)")
    p.add_argument("--json", action="store_true", help="print the result as one JSON object")
    p.add_argument("--plot", type=Path, metavar="PNG", help="write residual plots before/after")
    p.add_argument(
        "--save-params",
        type=Path,
        metavar="JSON",
        help="write the extended model (params JSON with the fitted strength and the named effect)",
    )
    p.add_argument(
        "--follow-up-csv",
        type=Path,
        metavar="PLAN",
        help="when the result reports a tie, write the bends proposed to separate the tied "
        "explanations as a plan CSV (trial, commanded_pin_deg; rows in the order to run, "
        "after the trials), as `cvmeasure simulate` reads; not written when there is no tie",
    )
    p.add_argument(
        "--folds", type=int_in(2, 100), default=5, help="K of grouped K-fold CV (default 5)"
    )
    p.add_argument(
        "--max-causes",
        type=int,
        choices=(1, 2),
        default=2,
        help="name at most this many causes (default 2)",
    )
    p.set_defaults(func=run)


def _summary(result: dict) -> str:
    lines = [f"cause: {result['cause']}"]
    if len(result["causes"]) > 1:
        lines.append(f"causes: {', '.join(result['causes'])}")
    for key, value in result["params"].items():
        if key not in result["intervals"]:
            # a cause's shape (e.g. the camera tilt's axis): it has no interval of its own;
            # its uncertainty is carried in the other parameters' ones
            lines.append(f"  {key} = {value:.4g}  (the cause's shape; no interval of its own)")
            continue
        lo, hi = result["intervals"][key]
        lines.append(f"  {key} = {value:.4g}  (95 % interval {lo:.4g} .. {hi:.4g})")
    lines.append(
        f"held-out RMSE: baseline {result['baseline_rmse_deg']:.3f} deg -> extended "
        f"{result['extended_rmse_deg']:.3f} deg (gain {100 * result['gain']:.0f} %)"
    )
    lines.append("candidates (held-out RMSE, deg):")
    for c in result["candidates"]:
        mark = "accepted" if c["accepted"] else ""
        lines.append(
            f"  {c['cause']:<22} {c['cv_rmse_deg']:.4f}  dBIC {c['delta_bic']:8.1f} {mark}"
        )
    for note in result["notes"]:
        lines.append(f"note: {note}")
    # the follow-up itself is one of the notes above; only where its plan went is new
    if result.get("follow_up_csv"):
        lines.append(f"follow-up plan written to {result['follow_up_csv']}")
    if result["recommended_experiment"]:
        lines.append(f"recommended experiment: {result['recommended_experiment']}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    with libraries_loading():  # numpy and scipy.optimize: most of the start-up
        from cvmeasure.contracts import TrialTable
        from cvmeasure.diagnose import diagnose
        from cvmeasure.errors import InputError
        from cvmeasure.fileio import atomic_write_bytes, to_jsonable
        from cvmeasure.provenance import provenance
        from cvmeasure.sim import SimParams, params_from_json, params_to_json

    trials = TrialTable.read_csv(args.trials)
    params, effects = params_from_json(args.params) if args.params else (SimParams(), ())
    try:
        result = diagnose(
            trials, params, base_effects=effects, folds=args.folds, max_causes=args.max_causes
        )
    except ValueError as exc:
        raise InputError(args.trials, str(exc)) from None
    out = to_jsonable(result.to_dict())
    if args.plot:
        from cvmeasure.diagnose.plot import residual_plot_png

        atomic_write_bytes(args.plot, residual_plot_png(result, trials))
        out["plot"] = str(args.plot)
    if args.save_params:
        params_to_json(
            args.save_params,
            result.extended_params(),
            result.extended_effects(effects),
            extra={
                "diagnosis": {
                    "cause": result.cause.primary,
                    "causes": list(result.causes),
                    "params": out["params"],
                    "intervals": out["intervals"],
                    "baseline_rmse_deg": out["baseline_rmse_deg"],
                    "extended_rmse_deg": out["extended_rmse_deg"],
                    "trials": str(args.trials),
                },
                "provenance": provenance(),
            },
        )
        out["saved_params"] = str(args.save_params)
    if args.follow_up_csv:
        out["follow_up_csv"] = None
        if result.follow_up is not None:
            from cvmeasure.fileio import write_csv_rows

            write_csv_rows(
                args.follow_up_csv, result.follow_up.rows(), ("trial", "commanded_pin_deg")
            )
            out["follow_up_csv"] = str(args.follow_up_csv)
    if args.json:
        print(json.dumps(out, indent=2))
    else:
        print(_summary(out))
        if args.follow_up_csv and out["follow_up_csv"] is None:  # asked for, nothing to write
            print(
                f"no follow-up plan written to {args.follow_up_csv}: "
                "no tie between catalogue causes to separate"
            )
    return 0
