"""``cvmeasure demo``: the main job end to end on embedded data."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.options import non_negative_int

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="run every stage end to end on embedded (rendered) data",
        description="Render photos with exact ground truth, measure them with every stage "
        "that exists, print measured vs true values and write the JSON results.",
    )
    p.add_argument(
        "-o", "--out", type=Path, default=Path("demo-out"), help="output folder (default demo-out)"
    )
    p.add_argument(
        "--seed",
        type=non_negative_int,
        default=7,
        help="random seed of the rendered data (default 7)",
    )
    p.add_argument(
        "--json", action="store_true", help="print the results as JSON instead of a table"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.fileio import atomic_write_json, to_jsonable
    from cvmeasure.provenance import provenance
    from cvmeasure_datasets.demo import format_sections, run_demo

    def progress(msg: str) -> None:
        if not args.json:
            print(msg, file=sys.stderr, flush=True)

    sections = run_demo(args.out, seed=args.seed, progress=progress)
    result = {"provenance": provenance(), "sections": [s.to_dict() for s in sections]}
    path = atomic_write_json(args.out / "demo.json", result)
    if args.json:
        print(json.dumps(to_jsonable(result["sections"]), indent=2, allow_nan=False))
    else:
        print(format_sections(sections))
        print(f"results: {path}")
    failed = [r for s in sections for r in s.rows if r.ok is False]
    return 1 if failed else 0
