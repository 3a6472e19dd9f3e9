"""The design options every command that reads a design shares (one set of rules).

``gcode``, ``part --design``, ``correct`` and ``track`` plan a design with the same
options and defaults (:func:`cvmeasure.wireplan.load_plan`), so a part is compared with
the polygon ``gcode`` made from the same design.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from cvmeasure.cli.options import positive_float, positive_int

if TYPE_CHECKING:
    from cvmeasure.wireplan import WirePlan

__all__ = ["add_job_rule_options", "add_plan_options", "plan_from_args"]


def add_plan_options(p: argparse.ArgumentParser, *, job: bool, divisions: bool = True) -> None:
    """Add --units, --min-segment-mm, --rechord, --scale, --join-gap-mm (and --job)."""
    if divisions:
        p.add_argument(
            "--divisions",
            type=positive_int,
            help="chords per curve of the design (default: as many as fit, each >= "
            "--min-segment-mm; drawn straight lines keep their corners)",
        )
    p.add_argument(
        "--min-segment-mm", type=positive_float, default=12.0, help="shortest segment (mm)"
    )
    p.add_argument(
        "--units",
        choices=("mm", "cm", "in", "pt", "px"),
        help="unit of a drawing that declares none (SVG without a physical width, DXF "
        "$INSUNITS 0); such a drawing is refused without it",
    )
    p.add_argument(
        "--rechord",
        action="store_true",
        help="divide runs of segments shorter than --min-segment-mm into longer equal chords "
        "(printed as a before/after bend table); default: refused",
    )
    p.add_argument(
        "--scale", type=positive_float, default=1.0, help="scale the design (printed, kept)"
    )
    p.add_argument(
        "--join-gap-mm",
        type=positive_float,
        default=0.01,
        help="close gaps between elements up to this (default 0.01 mm; wider gaps are refused)",
    )
    if job:
        p.add_argument(
            "--job",
            type=Path,
            help="the G-code the part was bent with: the polygon in its header (written by "
            "cvmeasure gcode / correct) is what the part is compared with",
        )


def add_job_rule_options(p: argparse.ArgumentParser, *, feeds: bool = True) -> None:
    """Add --max-bend-deg (the planner's rule: ``part --design`` and ``track`` plan the
    polygon ``gcode`` bent with it) and, with ``feeds``, --bend-radius-mm: the rules a
    job is fed by, shared by ``gcode`` and ``correct`` (whose next job must feed the
    part's job's lengths)."""
    p.add_argument("--max-bend-deg", type=positive_float, default=135.0, help="largest bend (deg)")
    if feeds:
        p.add_argument(
            "--bend-radius-mm",
            type=float,
            default=0.0,
            help="bend radius for the feed setback (mm)",
        )


def plan_from_args(args: argparse.Namespace, design: Path) -> WirePlan:
    """The plan of ``design`` (or of ``args.job``) with the shared options."""
    from cvmeasure.wireplan import plan_for_part

    return plan_for_part(
        design,
        job=getattr(args, "job", None),
        units=args.units,
        min_segment_mm=args.min_segment_mm,
        divisions=getattr(args, "divisions", None),
        rechord=args.rechord,
        scale=args.scale,
        join_gap_mm=args.join_gap_mm,
        **({"max_bend_deg": args.max_bend_deg} if hasattr(args, "max_bend_deg") else {}),
    )
