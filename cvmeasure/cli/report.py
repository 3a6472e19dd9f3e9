"""``cvmeasure report``: one self-contained HTML page for a results file."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cvmeasure.cli.options import non_negative_int, positive_float

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "report",
        help="self-contained HTML report of a results file (plots, tables, overlay thumbnails)",
        description="Write one HTML file for a results JSON Lines file: summary, warnings, "
        "plots of angles, springback, parts, residuals (and agreement with --manual), and a "
        "table of every photo with an overlay thumbnail, each value with its standard "
        "uncertainty and a verdict against the tolerance where there is a target. A session "
        "log (session.jsonl) is reported as its bends' photos; a calibration JSON gives the "
        "calibration's report. Everything is embedded; it needs no network.",
    )
    p.add_argument(
        "results",
        type=Path,
        help="results JSON Lines (cvmeasure batch/measure), a session.jsonl or a calibration JSON",
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="the HTML file to write")
    p.add_argument("--manual", type=Path, help="MANUAL.csv: add the agreement section")
    p.add_argument(
        "--photos",
        type=Path,
        action="append",
        default=[],
        help="folder to look for photos in (repeatable)",
    )
    p.add_argument("--title", help="page title (default: the results file name)")
    p.add_argument("--no-thumbnails", action="store_true", help="leave out the photo overlays")
    p.add_argument(
        "--max-thumbnails",
        type=non_negative_int,
        default=500,
        help="overlays for the first N records (default 500)",
    )
    p.add_argument(
        "--tolerance-deg",
        type=positive_float,
        default=0.5,
        help="a bend with a target is within tolerance when its error is (default 0.5 deg)",
    )
    p.add_argument(
        "--tolerance-mm",
        type=positive_float,
        default=1.0,
        help="a part compared with its design: the largest deviation allowed (default 1 mm)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_text
    from cvmeasure.provenance import provenance
    from cvmeasure.report import build_report
    from cvmeasure.report.sources import read_report_input

    given = read_report_input(args.results)
    if given.kind == "calibration":
        return _calibration_report(args)
    records = given.records
    result = None
    if args.manual:
        from cvmeasure.agreement import agreement, load_manual, vision_angles

        try:
            result = agreement(
                load_manual(args.manual), vision_angles(records, source=str(args.results))
            )
        except InputError as exc:
            raise InputError(args.manual, exc.problem) from None
    stamp = provenance()
    bar = tqdm(
        total=0, unit="photo", file=sys.stderr, disable=args.quiet or None, desc="thumbnails"
    )

    def progress(done: int, total: int) -> None:
        bar.total = total
        bar.update(done - bar.n)

    try:
        text = build_report(
            records,
            title=args.title or f"cvmeasure results: {args.results.name}",
            source=str(args.results),
            photo_roots=[*args.photos, args.results.resolve().parent],
            agreement=result,
            thumbnails=not args.no_thumbnails,
            max_thumbnails=args.max_thumbnails,
            stamp={k: stamp[k] for k in ("generated_by", "time_utc", "command")},
            progress=progress,
            tolerance_deg=args.tolerance_deg,
            tolerance_mm=args.tolerance_mm,
        )
    finally:
        bar.close()
    path = atomic_write_text(args.output, text)
    if not args.quiet:
        print(f"wrote {path} ({len(records)} records, {len(text) / 1e6:.1f} MB)")
    return 0


def _calibration_report(args: argparse.Namespace) -> int:
    """A calibration JSON: the calibration's own report (curves, scores, bends, warnings)."""
    from cvmeasure.driver.session_report import write_session_report
    from cvmeasure.material.bender_calibration import load_calibration

    calibration = load_calibration(args.results)
    path = write_session_report(args.output, calibration)
    if not args.quiet:
        print(f"wrote {path} (calibration {calibration.name}, {len(calibration.samples)} bends)")
    return 0
