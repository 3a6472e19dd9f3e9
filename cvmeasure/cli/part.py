"""``cvmeasure part``: measure a finished part from a photo and compare it with its design."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.options import int_in, non_negative_float

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
    p.add_argument("--board", type=Path, required=True, help="board JSON (spec)")
    p.add_argument("--camera", type=Path, required=True, help="camera JSON (cvmeasure calibrate)")
    p.add_argument(
        "--divisions", type=int_in(1, 1000), help="number of chords the part was bent in"
    )
    p.add_argument("--design", type=Path, help="the design the part was bent from (.svg or .dxf)")
    p.add_argument(
        "--method",
        choices=("ours", "ellipse", "sagitta"),
        default="ours",
        help="method of the headline values (default ours; all are reported under 'methods')",
    )
    p.add_argument(
        "--axis-height-mm",
        type=non_negative_float,
        default=0.0,
        help="height of the wire's axis above the board's plane, e.g. the wire's radius when "
        "part and board lie on the same surface (default 0)",
    )
    p.add_argument(
        "--ends",
        choices=("round", "flat"),
        default="round",
        help="shape of the wire's ends: round (hemispherical, default) or flat (square-cut)",
    )
    p.add_argument("--overlay", type=Path, help="write the photo with the found centreline (PNG)")
    p.add_argument("--plot", type=Path, help="write the deviation plot (PNG; needs --design)")
    p.add_argument("-o", "--out", type=Path, help="also write the result JSON here")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import cv2

    from cvmeasure.board import load_board
    from cvmeasure.camera import load_camera
    from cvmeasure.design import load_design
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_bytes, atomic_write_json, to_jsonable
    from cvmeasure.imageio import read_photo
    from cvmeasure.part.measure import measure_part
    from cvmeasure.provenance import provenance

    if args.plot and not args.design:
        raise InputError("--plot", "the deviation plot needs --design")
    board = load_board(args.board)
    camera = load_camera(args.camera)
    design = load_design(args.design).wire() if args.design else None
    photo = read_photo(args.photo)
    m = measure_part(
        photo.bgr,
        board,
        camera,
        divisions=args.divisions,
        design=design,
        design_source=str(args.design) if args.design else "design",
        method=args.method,
        axis_height_mm=args.axis_height_mm,
        end_shape=args.ends,
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
    r = m.result
    chords = {
        "--divisions": f"{r.divisions} chords (--divisions)",
        "photo": f"{r.divisions} chords (vertices found in the photo)",
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
    for w in m.warnings:
        print(f"  warning: {w}", file=out)
