"""``cvmeasure gcode``: a wire design (SVG/DXF) -> TinyG G-code for the DIWire."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.design_options import add_job_rule_options, add_plan_options, plan_from_args

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "gcode",
        help="turn an SVG/DXF wire design into bender G-code",
        description="Read one open wire path from an SVG or DXF design (in its own physical "
        "units), keep its drawn corners, divide its curves into equal chords of at least "
        "--min-segment-mm, check the bender's rules (one connected open path, no gaps, no "
        "self-contact, straight segments >= 12 mm, bends within range), compensate springback "
        "through the calibration (--material) or the simulation's model, and write numbered "
        "TinyG G-code (G21; X pin deg, Y feed mm relative, Z pin duck) whose header keeps the "
        "polygon bent. Nothing is written when the design breaks a rule (exit 2, the element "
        "and the number named); --rechord / --scale change it on request, printing the "
        "before/after bend table.",
    )
    p.add_argument("design", type=Path, help="design drawing (.svg or .dxf)")
    p.add_argument("-o", "--out", type=Path, required=True, help="G-code file to write")
    p.add_argument("--material", type=Path, help="calibration JSON (cvmeasure fit / session)")
    p.add_argument(
        "--params", type=Path, help="simulation params JSON, used when there is no --material"
    )
    add_plan_options(p, job=False)
    add_job_rule_options(p)
    p.add_argument("--json", action="store_true", help="print the bend list as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from dataclasses import replace

    from cvmeasure import __version__
    from cvmeasure.fileio import atomic_write_text
    from cvmeasure.gcode import SimCompensator, design_job, job_header

    plan = plan_from_args(args, args.design)
    if args.material is not None:
        from cvmeasure.material.bender_calibration import load_calibration

        compensation = load_calibration(args.material)
    elif args.params is not None:
        from cvmeasure.sim import params_from_json

        params, effects = params_from_json(args.params)
        compensation = SimCompensator(params, tuple(effects))
    else:
        compensation = SimCompensator()
    job = design_job(
        plan.vertices_mm,
        source=str(args.design),
        compensation=compensation,
        min_segment_mm=args.min_segment_mm,
        max_bend_deg=args.max_bend_deg,
        bend_radius_mm=args.bend_radius_mm,
    )
    model = f"calibration {args.material.name}" if args.material else "simulation model"
    title = f"; cvmeasure {__version__} gcode from {args.design.name}"
    job = replace(job, header=job_header(title, job, model=model, plan_lines=plan.header_lines()))
    for w in job.warnings:
        print(f"warning: {w}", file=sys.stderr)
    atomic_write_text(args.out, job.text())
    if args.json:
        print(json.dumps({"out": str(args.out), **job.to_dict(), "plan": plan.to_dict()}, indent=2))
    else:
        if plan.requested_change or plan.changes:
            print("\n".join(plan.table_lines()))
        print(
            f"wrote {args.out}: {len(job.lines)} lines, {len(job.pin_deg)} bends, "
            f"{job.bends.total_feed_mm:.1f} mm of wire"
        )
    return 0
