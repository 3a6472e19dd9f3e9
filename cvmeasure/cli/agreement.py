"""``cvmeasure agreement``: vision against manual readings (Bland–Altman, gauge R&R)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cvmeasure.cli.options import non_negative_float, positive_float

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "agreement",
        help="agreement of vision with manual readings (Bland-Altman, gauge R&R, tolerance)",
        description="Compare the bend angles of a vision results file with manual readings "
        "(photos matched by file name): bias and 95 % limits of agreement of vision - manual "
        "with confidence intervals, a proportional-bias check, a gauge R&R split of repeated "
        "manual readings, and a verdict against the accepted tolerance (the seed's 10 % "
        "relative and 1 degree absolute by default).",
    )
    p.add_argument(
        "manual", type=Path, help="MANUAL.csv: photo, bend_angle_deg[, reader, repeat, bend]"
    )
    p.add_argument("vision", type=Path, help="vision results JSON Lines (cvmeasure batch/measure)")
    p.add_argument("--plot", type=Path, help="write a Bland-Altman plot (PNG)")
    p.add_argument(
        "--tol-deg",
        type=positive_float,
        default=1.0,
        help="absolute tolerance, degrees (default 1)",
    )
    p.add_argument(
        "--tol-rel",
        type=non_negative_float,
        default=0.10,
        help="relative tolerance (default 0.10; 0 = none)",
    )
    p.add_argument("-o", "--output", type=Path, help="also write the full result as JSON")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.agreement import Tolerance, agreement, load_manual, vision_angles
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_json, read_jsonl, to_jsonable
    from cvmeasure.provenance import provenance

    if args.tol_deg <= 0 or args.tol_rel < 0:
        raise InputError("--tol-deg/--tol-rel", "tolerances must be positive")
    manual = load_manual(args.manual)
    vision = vision_angles(read_jsonl(args.vision), source=str(args.vision))
    if not vision:
        raise InputError(args.vision, "no photo with a bend_angle_deg in the results")
    try:
        result = agreement(
            manual,
            vision,
            tolerance=Tolerance(relative=args.tol_rel or None, absolute_deg=args.tol_deg),
        )
    except InputError as exc:
        raise InputError(args.manual, exc.problem) from None
    data = to_jsonable(result.to_dict())
    if args.output:
        atomic_write_json(args.output, {**data, "provenance": provenance()})
    if args.plot:
        from cvmeasure.fileio import atomic_write_bytes
        from cvmeasure.report.plots import bland_altman_png

        atomic_write_bytes(args.plot, bland_altman_png(result))
    if args.json:
        print(json.dumps(data, indent=2))
        return 0
    ba, tol = result.bland_altman, result.tolerance
    print(f"photos matched: {ba.n} ({ba.n_readings} manual readings); difference = vision - manual")
    print(
        f"bias: {ba.bias_deg:+.3f} deg  (95 % CI {ba.bias_ci_deg[0]:+.3f} .. {ba.bias_ci_deg[1]:+.3f})"
    )
    print(
        f"95 % limits of agreement: {ba.loa_low_deg:+.3f} .. {ba.loa_high_deg:+.3f} deg  "
        f"(CIs {ba.loa_low_ci_deg[0]:+.3f}..{ba.loa_low_ci_deg[1]:+.3f}, "
        f"{ba.loa_high_ci_deg[0]:+.3f}..{ba.loa_high_ci_deg[1]:+.3f})"
    )
    print(
        f"proportional bias: slope {ba.slope:+.4f} (p = {ba.slope_p:.3g})"
        + ("  SIGNIFICANT" if ba.proportional_bias else "")
    )
    if result.manual_rr is not None:
        rr = result.manual_rr
        print(
            f"manual gauge R&R: repeatability {rr.repeatability_sd_deg:.3f} deg, reproducibility "
            f"{rr.reproducibility_sd_deg:.3f} deg, %GRR {rr.grr_percent:.1f} %, ndc {rr.ndc:.1f}"
        )
    if result.vision_repeatability_sd_deg is not None:
        print(f"vision repeatability (same bend): {result.vision_repeatability_sd_deg:.3f} deg")
    rel = f"{tol.tolerance.relative:.0%} relative and " if tol.tolerance.relative else ""
    print(
        f"tolerance ({rel}{tol.tolerance.absolute_deg:g} deg): {tol.n_within} of {tol.n_pairs} "
        f"readings within; limits of agreement {'within' if tol.loa_within_absolute else 'OUTSIDE'} "
        f"+-{tol.tolerance.absolute_deg:g} deg -> {tol.verdict} ({tol.reason})"
    )
    for w in result.warnings:
        print(f"warning: {w}")
    return 0
