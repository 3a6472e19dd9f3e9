"""``cvmeasure batch``: measure every photo of a folder or glob, resumably, on all cores."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.options import int_in

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    from cvmeasure.batch import KINDS, START_METHODS

    p = sub.add_parser(
        "batch",
        help="measure every photo of a folder or glob (resumable, all cores or a Dask cluster)",
        description="Measure every photo (machine or part photo, detected or given by --kind) "
        "and append one JSON object per photo to the results file as soon as it is measured. "
        "Run again with the same -o to resume: photos already in the file (same path, size "
        "and modification time) are not measured again.",
    )
    p.add_argument("photos", nargs="+", help="photo folder(s), glob pattern(s) or file(s)")
    p.add_argument("--camera", type=Path, help="camera JSON (from cvmeasure calibrate)")
    p.add_argument("--kit", type=Path, help="marker kit JSON (default: the built-in kit)")
    p.add_argument("--board", type=Path, help="board JSON of part photos")
    p.add_argument(
        "--plane",
        type=Path,
        help="plane JSON (cvmeasure plane --json): bender photos measured on that plane (needs --camera)",
    )
    p.add_argument(
        "--kind",
        choices=KINDS,
        default="auto",
        help="photo kind (default auto: 'part' when a ChArUco board is seen, else 'machine')",
    )
    p.add_argument(
        "--measure",
        metavar="MODULE:FUNCTION",
        help="measure every photo with this function(photo, context) -> dict instead (kind 'custom')",
    )
    p.add_argument(
        "--divisions", type=int_in(1, 1000), help="part photos: report segment_bend_deg for N"
    )
    p.add_argument("-o", "--output", type=Path, required=True, help="results JSON Lines file")
    p.add_argument(
        "--workers",
        type=int_in(1, 1024),
        help="worker processes (default: every core; 1 = this process)",
    )
    p.add_argument(
        "--scheduler", metavar="tcp://HOST:PORT", help="run on this Dask distributed scheduler"
    )
    p.add_argument(
        "--start-method",
        choices=START_METHODS,
        default="spawn",
        help="how worker processes start (default spawn; forkserver imports the pipeline once "
        "and forks the workers from it: less start-up CPU)",
    )
    p.add_argument("--quiet", action="store_true", help="no progress bar or per-photo messages")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from cvmeasure.batch import (
        MeasureContext,
        list_photos,
        register_measurer,
        resolve_measurer,
        run_batch,
    )
    from cvmeasure.errors import InputError

    kind = args.kind
    if args.measure:
        try:
            register_measurer("custom", args.measure)
            resolve_measurer("custom")
        except (ValueError, ImportError, AttributeError) as exc:
            raise InputError(
                "--measure", f"{args.measure!r} cannot be used as a measurement: {exc}"
            ) from None
        kind = "custom"

    if args.workers is not None and args.workers < 1:
        raise InputError("--workers", f"must be at least 1, got {args.workers}")
    if args.scheduler and not args.scheduler.startswith(("tcp://", "tls://", "inproc://")):
        raise InputError(args.scheduler, "scheduler address must look like tcp://host:port")
    options = (("divisions", args.divisions),) if args.divisions is not None else ()
    context = MeasureContext(
        camera_path=None if args.camera is None else str(args.camera),
        kit_path=None if args.kit is None else str(args.kit),
        board_path=None if args.board is None else str(args.board),
        plane_path=None if args.plane is None else str(args.plane),
        options=options,
    )
    context.validate()
    photos = list_photos(args.photos)
    bar: list[tqdm] = []

    def on_start(todo: int, already: int) -> None:
        if already and not args.quiet:
            print(
                f"resuming: {already} of {todo + already} photos already in {args.output}",
                file=sys.stderr,
            )
        bar.append(
            tqdm(
                total=todo,
                unit="photo",
                file=sys.stderr,
                disable=args.quiet or None,
                dynamic_ncols=True,
            )
        )

    def on_record(record: dict) -> None:
        if not record["ok"] and not args.quiet:
            bar[0].write(f"cvmeasure batch: {record['error']}", file=sys.stderr)
        bar[0].update(1)

    try:
        summary = run_batch(
            photos,
            args.output,
            kind=kind,
            context=context,
            workers=args.workers,
            scheduler=args.scheduler,
            start_method=args.start_method,
            on_start=on_start,
            on_record=on_record,
        )
    finally:
        if bar:
            bar[0].close()
    if args.json:
        print(json.dumps(summary.to_dict(), indent=2))
    elif not args.quiet:
        print(
            f"{summary.measured} measured ({summary.failed} failed), {summary.already_done} "
            f"already done, {summary.seconds:.1f} s, {summary.photos_per_s:.2f} photos/s on "
            f"{summary.workers} worker(s) [{summary.backend}] -> {summary.output}"
        )
    if summary.failed:
        if not args.json:
            first = " ".join(str(summary.failures[0][1]).split())
            more = (
                f" ({summary.failed - 1} more of {summary.measured} photos failed; "
                f'records with "ok": false in {args.output})'
                if summary.failed > 1
                else f' (record with "ok": false in {args.output}; a re-run retries it)'
            )
            print(f"cvmeasure batch: {first}{more}", file=sys.stderr)
        return 2
    return 0
