"""``cvmeasure part``: measure a finished part from a photo and compare it with its design."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.design_options import add_job_rule_options, add_plan_options, plan_from_args
from cvmeasure.cli.options import add_downsample_option, int_in, non_negative_float, positive_float
from cvmeasure.cli.startup import libraries_loading
from cvmeasure.method_names import PART_METHOD_ALIASES, PART_METHODS

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "part",
        help="radius, chord, height, arc angle and bends of a finished part; deviation from its design",
        description="Measure a finished wire part lying on a matte sheet in the plane of a "
        "ChArUco board: radius_mm, chord_width_mm, height_mm (sagitta), arc_angle_deg and, "
        "with --divisions, segment_bend_deg and the bend at every vertex. With --design the "
        "part is registered to the design (best rigid fit) and the deviation profile and "
        "the seed paper's absolute and relative errors are reported.",
    )
    p.add_argument("photo", type=Path, help="photo of the part beside the board")
    g = p.add_mutually_exclusive_group(required=True)
    g.add_argument("--board", type=Path, help="board JSON (spec): the board in the photo")
    g.add_argument(
        "--plane",
        type=Path,
        help="plane JSON (`cvmeasure plane -o`) of the plate the part lies on, measured from "
        "another photo by the same camera in the same pose (no board in this photo)",
    )
    p.add_argument(
        "--camera",
        type=Path,
        help="camera JSON (cvmeasure calibrate); needed with --board (a plane JSON carries "
        "its own camera; given with --plane, it must be that camera)",
    )
    p.add_argument(
        "--divisions",
        type=int_in(1, 1000),
        help="number of chords the part was bent in; with --design, chords per curve of the "
        "design, as cvmeasure gcode's --divisions",
    )
    p.add_argument(
        "--design",
        type=Path,
        help="the design the part was bent from (.svg or .dxf), planned by cvmeasure gcode's "
        "rules: the part is compared with the polygon bent (or --job's)",
    )
    add_plan_options(p, job=True, divisions=False)
    add_job_rule_options(p, feeds=False)
    p.add_argument(
        "--method",
        choices=(*PART_METHODS, *PART_METHOD_ALIASES),
        default=PART_METHODS[0],
        metavar="{" + ",".join(PART_METHODS) + "}",
        help=f"method of the headline values (default {PART_METHODS[0]}; all are reported under "
        "'methods'; the older names ours, ellipse, sagitta are read too)",
    )
    _add_wire_and_lift_options(p)
    p.add_argument("--overlay", type=Path, help="write the photo with the found centreline (PNG)")
    p.add_argument("--plot", type=Path, help="write the deviation plot (PNG; needs --design)")
    p.add_argument("-o", "--out", type=Path, help="also write the result JSON here")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def _add_wire_and_lift_options(p: argparse.ArgumentParser) -> None:
    """The wire's diameter and shape, and how the part's lift off the plate is measured."""
    p.add_argument(
        "--wire-diameter-mm",
        type=positive_float,
        help="the wire's diameter: the centreline then lies between the wire's two silhouette "
        "edges (not on a side-lit highlight or a shadow's edge), the axis at the wire's radius "
        "above the board's plane, and the part's lift off the plate is bounded from the wire's "
        "apparent width (warned about as part_lifted); default: --kit's wire_diameter_mm",
    )
    p.add_argument(
        "--kit",
        type=Path,
        help="kit JSON whose wire_diameter_mm is the wire's diameter (the built-in kit's is 3 mm; "
        "only with --wire-diameter-mm absent)",
    )
    p.add_argument(
        "--moved",
        type=Path,
        metavar="PHOTO2",
        help="a second photo of the same part slid on the plate by tens of mm (same camera, "
        "board in view, the part keeping its pose): the part's lift is measured from the two "
        "views' perspective difference and corrected (needs the wire's diameter); when the "
        "part was not moved, a warning says so and the lift is only bounded",
    )
    shadow = p.add_mutually_exclusive_group()
    shadow.add_argument(
        "--shadow-lift",
        dest="shadow_lift",
        action="store_const",
        const=True,
        default=None,
        help="one photo: measure the part's lift from the wire's cast shadow (lamp and tilt "
        "fitted over the whole wire) and correct it when its 2 sigma is at most 1 mm, or "
        "below the lift bound and consistent with it (its 2 sigma then stated as the lift's "
        "effect), else bound it as without (needs the wire's diameter; not with --moved). The default "
        "with the wire's diameter and one photo; this flag only insists on it",
    )
    shadow.add_argument(
        "--no-shadow-lift",
        dest="shadow_lift",
        action="store_const",
        const=False,
        help="one photo: do not read the lift from the cast shadow; only bound it from the "
        "wire's apparent width (the behaviour before the shadow was the default)",
    )
    p.add_argument(
        "--axis-height-mm",
        "--wire-axis-height-mm",
        dest="axis_height_mm",
        type=non_negative_float,
        default=None,
        help="height of the wire's axis above the board's plane where the part rests (default: "
        "the wire's radius with a diameter, else 0)",
    )
    p.add_argument(
        "--ends",
        choices=("round", "flat"),
        default="round",
        help="shape of the wire's ends: round (hemispherical, default) or flat (square-cut)",
    )
    add_downsample_option(p)


def run(args: argparse.Namespace) -> int:
    with libraries_loading():  # numpy, OpenCV and SciPy: most of the start-up
        import cv2

        from cvmeasure.board import load_board
        from cvmeasure.camera_model import load_camera
        from cvmeasure.contracts import PlaneModel
        from cvmeasure.errors import InputError
        from cvmeasure.fileio import atomic_write_bytes, atomic_write_json, to_jsonable
        from cvmeasure.imageio import read_photo
        from cvmeasure.part.measure import measure_part
        from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
        from cvmeasure.provenance import provenance

    if args.plot and not args.design:
        raise InputError("--plot", "the deviation plot needs --design")
    if args.job and not args.design:
        raise InputError("--job", "comparing with the job's polygon needs --design")
    # the design first: a design the rules refuse is refused before any photo is read
    plan = plan_from_args(args, args.design) if args.design else None
    if args.board and args.camera is None:
        raise InputError("--board", "finding the board's plane needs --camera")
    camera = load_camera(args.camera) if args.camera else None
    board = load_board(args.board) if args.board else None
    plane = PlaneModel.load(args.plane, camera=camera) if args.plane else None
    design = None if plan is None else plan.as_path()
    diameter = args.wire_diameter_mm
    if diameter is None and args.kit:
        from cvmeasure.kit import load_kit

        diameter = load_kit(args.kit).wire_diameter_mm
        if diameter is None:
            raise InputError(
                args.kit, "the kit gives no wire_diameter_mm (pass --wire-diameter-mm)"
            )
    photo = read_photo(args.photo)
    if args.moved and diameter is None:
        raise InputError("--moved", "the lift from a moved photo needs --wire-diameter-mm or --kit")
    if args.shadow_lift and diameter is None:
        raise InputError(
            "--shadow-lift", "the lift from the shadow needs --wire-diameter-mm or --kit"
        )
    if args.shadow_lift and args.moved:
        raise InputError("--shadow-lift", "one photo's lift: not with --moved (two photos)")
    if args.moved and args.plane:
        raise InputError("--moved", "the moved photo's plane comes from its board: use --board")
    moved = read_photo(args.moved).bgr if args.moved else None
    options = PartOptions(
        divisions=args.divisions if plan is None else None,
        method=args.method,
        wire=WireOptions(
            diameter_mm=diameter, end_shape=args.ends, axis_height_mm=args.axis_height_mm
        ),
        lift=LiftOptions(shadow=args.shadow_lift is not False),
        downsample=args.downsample,
    )
    m = measure_part(
        photo.bgr,
        board,
        camera,
        options=options,
        plane=plane,
        design=design,
        design_source=str(args.design) if args.design else "design",
        reference_mm=None if plan is None else plan.vertices_mm,
        moved_image=moved,
        source=str(args.photo),
    )
    result = {"provenance": provenance(), **m.to_dict()}
    if args.overlay:
        from cvmeasure.part.overlay import draw_overlay

        img = draw_overlay(photo.bgr8(), m)
        ok, buf = cv2.imencode(".png", img)
        if not ok:  # pragma: no cover
            raise InputError(args.overlay, "could not encode the overlay")
        atomic_write_bytes(args.overlay, buf.tobytes())
    if args.plot:
        from cvmeasure.part.overlay import deviation_plot_png

        atomic_write_bytes(args.plot, deviation_plot_png(m))
    if args.out:
        atomic_write_json(args.out, result)
    if args.json:
        print(json.dumps(to_jsonable(result), indent=2, allow_nan=False))
    else:
        _print_summary(m, sys.stdout)
    return 0


def _print_summary(m, out) -> None:
    from cvmeasure.part.result import DivisionsSource, LiftSource, LiftUse

    r = m.result
    chords = {
        DivisionsSource.GIVEN: f"{r.divisions} chords (--divisions)",
        DivisionsSource.PHOTO: f"{r.divisions} chords (vertices found in the photo)",
        DivisionsSource.PLAN: f"{r.divisions} chords (the polygon bent, from the design or --job)",
        None: "no chord vertices found (a smooth curve)",
    }[m.divisions_from]
    print(f"{m.source}  (method {r.method}; {chords})", file=out)
    if m.shape == "s-curve":
        print("  an S-curve (saddle): its bends change sign along the wire", file=out)
        print(f"  chord_width_mm  {r.chord_width_mm:10.3f}   end to end", file=out)
        print(f"  height_mm       {r.height_mm:10.3f}   largest distance from that line", file=out)
        print(
            f"  (nearest circle: radius {r.radius_mm:.1f} mm over {r.arc_angle_deg:.1f} deg; "
            "no real arc)",
            file=out,
        )
    else:
        print(
            f"  radius_mm       {r.radius_mm:10.3f}   of the circle through the centreline",
            file=out,
        )
        print(f"  chord_width_mm  {r.chord_width_mm:10.3f}   end to end", file=out)
        print(f"  height_mm       {r.height_mm:10.3f}   sagitta", file=out)
        print(f"  arc_angle_deg   {r.arc_angle_deg:10.3f}   subtended at the centre", file=out)
        if r.segment_bend_deg is not None:
            print(f"  segment_bend_deg{r.segment_bend_deg:10.4f}   arc / chords", file=out)
    if m.vertex_bend_deg is not None and len(m.vertex_bend_deg):
        bends = " ".join(f"{b:+.2f}" for b in m.vertex_bend_deg)
        print(f"  bend at each vertex (deg, CCW +): {bends}", file=out)
    for name, other in m.methods.items():
        if name != r.method:
            print(
                f"  [{name}] radius {other.radius_mm:.3f} mm, arc {other.arc_angle_deg:.3f} deg",
                file=out,
            )
    if m.comparison is not None:
        d = m.comparison.deviation
        print(f"  deviation: max {d.max_mm:.3f} mm, RMS {d.rms_mm:.3f} mm", file=out)
        b = m.comparison.bends
        if b is not None:
            print(
                f"  bends: max error {b.max_abs_error_deg:.3f} deg; seed absolute "
                f"{b.seed_absolute_error_deg:.3f} deg, relative {b.seed_relative_error_pct:.2f} %",
                file=out,
            )
    lift = m.lift
    if lift is not None and lift.used is LiftUse.CORRECTION:
        seen = "the cast shadow" if lift.source is LiftSource.SHADOW else "the moved photo"
        read = lift.lift_mm if lift.read_lift_mm is None else lift.read_lift_mm
        at = "" if read == lift.lift_mm else f" at the lift bound, {lift.lift_mm:.2f} mm"
        print(
            f"  lift off the plate (from {seen}): {read:.2f} +- "
            f"{lift.lift_sigma_mm:.2f} mm, corrected{at}",
            file=out,
        )
    elif lift is not None and lift.lift_mm is not None:
        print(
            f"  lift off the plate (from the wire's width): {lift.lift_mm:.2f} +- "
            f"{lift.lift_sigma_mm:.2f} mm, used as a {lift.used.value}",
            file=out,
        )
    for w in m.warnings:
        print(f"  warning: {w}", file=out)
