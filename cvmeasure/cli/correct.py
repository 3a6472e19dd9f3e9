"""``cvmeasure correct``: a finished part's bend errors correct the calibration and the job."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.design_options import add_job_rule_options, add_plan_options, plan_from_args
from cvmeasure.cli.options import add_downsample_option, non_negative_float, positive_float

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "correct",
        help="correct the calibration and the job from a finished part's per-vertex bends",
        description="Measure a finished part against its design (as `cvmeasure part`), then "
        "feed its per-vertex bend errors back, damped: per direction and angle through the "
        "calibration's springback curve, and per vertex for this job (drift, backlash). "
        "Writes the corrected calibration (its provenance.corrections keeps the history) and "
        "the corrected G-code of the next part.",
    )
    p.add_argument("photo", type=Path, help="photo of the finished part beside the board")
    p.add_argument("--design", type=Path, required=True, help="the part's design (.svg/.dxf)")
    p.add_argument("--material", type=Path, required=True, help="calibration JSON it was bent with")
    p.add_argument("--board", type=Path, required=True, help="board JSON")
    p.add_argument("--camera", type=Path, required=True, help="camera JSON")
    add_plan_options(p, job=True)
    add_job_rule_options(p)
    p.add_argument(
        "--flipped",
        action="store_true",
        help="the part may lie upside down (default: it lies as it left the machine, so a "
        "design symmetric end to end is matched vertex for vertex)",
    )
    p.add_argument(
        "--wire-diameter-mm",
        type=positive_float,
        help="the wire's diameter, as for `cvmeasure part`: the centreline between the wire's "
        "silhouette edges and the part's lift read or bounded (default: none, the profiles' "
        "centre of symmetry)",
    )
    add_downsample_option(p, as_for="as for `cvmeasure part`: ")
    p.add_argument("-o", "--out", type=Path, required=True, help="corrected calibration JSON")
    p.add_argument("--gcode", type=Path, required=True, help="corrected G-code of the next part")
    p.add_argument(
        "--gain",
        type=positive_float,
        default=0.95,
        help="damping gain (0, 1] of a first correction, default 0.95 (from the job's second "
        "part on, the measured response sets the step)",
    )
    p.add_argument(
        "--deadband-sigma",
        type=non_negative_float,
        default=2.5,
        help="pooled errors within this many measurement sigmas are left alone (default 2.5)",
    )
    p.add_argument("--json", action="store_true", help="print the correction as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.board import load_board
    from cvmeasure.camera_model import load_camera
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_text, to_jsonable
    from cvmeasure.imageio import read_photo
    from cvmeasure.material.bender_calibration import load_calibration, save_calibration
    from cvmeasure.material.correct_part import correct_from_part
    from cvmeasure.part.measure import measure_part
    from cvmeasure.part.options import PartOptions, WireOptions

    if args.gain > 1:
        raise InputError("--gain", f"must be in (0, 1], got {args.gain}")
    plan = plan_from_args(args, args.design)
    cal = load_calibration(args.material)
    design = plan.as_path()
    m = measure_part(
        read_photo(args.photo).bgr,
        load_board(args.board),
        load_camera(args.camera),
        design=design,
        design_source=str(args.design),
        source=str(args.photo),
        options=PartOptions(
            allow_mirror=args.flipped,
            wire=WireOptions(diameter_mm=args.wire_diameter_mm),
            downsample=args.downsample,
        ),
        reference_mm=plan.vertices_mm,
    )
    try:
        cal2, corr, job = correct_from_part(
            cal,
            m,
            design_name=args.design.name,
            gain=args.gain,
            deadband_sigma=args.deadband_sigma,
            min_segment_mm=args.min_segment_mm,
            max_bend_deg=args.max_bend_deg,
            bend_radius_mm=args.bend_radius_mm,
            plan_lines=plan.header_lines(),
            flipped=args.flipped,
        )
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(args.material, str(exc)) from None
    for w in corr.warnings:
        print(f"warning: {w}", file=sys.stderr)
    save_calibration(args.out, cal2)
    atomic_write_text(args.gcode, job.text())
    if args.json:
        print(json.dumps(to_jsonable(corr.to_dict()), indent=2, allow_nan=False))
    else:
        # the worst error the measurement resolves; readings within their uncertainty apart
        print(
            f"{corr.bends} vertices, {corr.error_summary()}; "
            f"{len(corr.curve_updates)} curve knot(s) moved; wrote {args.out} and {args.gcode}"
        )
    return 0
