"""``cvmeasure render``: synthetic photos with exact ground truth (the photo lab)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from cvmeasure.cli.options import int_in, non_negative_float, positive_float, positive_int

__all__ = ["register", "run"]


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("-o", "--out", type=Path, required=True, help="output folder")
    p.add_argument("--name", help="file stem (default: the kind, numbered with --count)")
    p.add_argument(
        "--count", type=positive_int, default=1, help="photos to render, seeds seed..seed+N-1"
    )
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--scale", type=positive_float, default=1.0, help="size relative to 4608 x 3072 (default 1)"
    )
    p.add_argument("--camera", type=Path, help="camera JSON at 4608 px (default: the seed camera)")
    p.add_argument("--tilt-deg", type=non_negative_float, help="camera tilt from the plane normal")
    p.add_argument(
        "--tilt-direction-deg",
        type=float,
        default=0.0,
        help="direction the camera is moved to, in the scene frame (from its +x towards +y); "
        "`cvmeasure plane` reports the tilt direction in the image frame instead (where the "
        "plane recedes, counter-clockwise as seen in the photo): the truth JSON gives both "
        "(pose.tilt_direction_deg, pose.tilt_direction_image_deg)",
    )
    p.add_argument("--yaw-deg", type=float, help="camera rotation about its axis")
    p.add_argument("--distance-mm", type=positive_float, help="camera distance to the plane")
    p.add_argument("--cct-k", type=positive_float, help="light colour temperature (2700-6500 K)")
    p.add_argument("--wb-error-k", type=float, help="error of the camera's white balance, K")
    p.add_argument("--jpeg-quality", type=int_in(1, 100), help="JPEG quality 1..100 (default 92)")
    p.add_argument(
        "--clean", action="store_true", help="no noise, vignetting or JPEG; perfect white balance"
    )
    p.add_argument("--random-light", action="store_true", help="lighting drawn from the seed")
    p.add_argument(
        "--bayer", action="store_true", help="sample on an RGGB colour filter array and demosaic"
    )
    p.add_argument(
        "--lateral-ca", type=float, help="lateral chromatic aberration (red 1+x, blue 1-x)"
    )
    p.add_argument(
        "--effects",
        metavar="SPEC",
        help="real-scene effects (bender and part): 'all' or names, comma-separated, optionally "
        "NAME=VALUE, e.g. marker_heights,supports,wire_3d or all,clutter=12,wire_across=wire_b "
        "or wire_3d,part_lift_mm=2 (cvmeasure_datasets.SceneEffects; default: the flat scene, "
        "but `render bender` always draws the discs at the kit's heights)",
    )
    p.add_argument("--linear", action="store_true", help="also write a 16-bit linear RGB TIFF")
    p.add_argument("--json", action="store_true", help="print what was written as JSON")
    p.set_defaults(func=run)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "render",
        help="render synthetic photos with exact ground truth",
        description="Render photos of the photo lab (bender top plate with the marker kit, a "
        "finished part beside a ChArUco board, or calibration board views), each written as "
        "<stem>.jpg (or .png with --clean) plus <stem>.truth.json.",
    )
    rsub = p.add_subparsers(dest="kind", metavar="KIND")
    rsub.required = True
    b = rsub.add_parser("bender", help="the bender's top plate with the five kit markers")
    b.add_argument("--pin-deg", type=float, required=True, help="pin angle from +x, degrees")
    b.add_argument("--bend-deg", type=float, required=True, help="bend angle from +x, degrees")
    b.add_argument(
        "--kit",
        type=Path,
        help="kit JSON (default: the built-in kit); its discs are drawn at the kit's heights "
        "above the plate (a kit without heights: flat stickers)",
    )
    b.add_argument(
        "--flat-kit",
        action="store_true",
        help="draw the kit's markers as flat stickers on the plate (its heights removed)",
    )
    b.add_argument(
        "--occlude",
        action="append",
        default=[],
        metavar="ROLE=FRACTION",
        help="hide that fraction of a marker (repeatable), e.g. wire_b=0.4",
    )
    _common(b)
    pt = rsub.add_parser("part", help="a finished wire part on a matte sheet beside a board")
    shape = pt.add_mutually_exclusive_group(required=True)
    shape.add_argument(
        "--arc",
        nargs=3,
        type=float,
        metavar=("RADIUS_MM", "ANGLE_DEG", "DIVISIONS"),
        help="an arc of N equal chords",
    )
    shape.add_argument(
        "--saddle",
        nargs=3,
        type=float,
        metavar=("WIDTH_MM", "HEIGHT_MM", "DIVISIONS"),
        help="a saddle of N equal chords",
    )
    pt.add_argument("--sheet", choices=("dark", "light"), default="dark", help="sheet colour")
    pt.add_argument("--board", type=Path, help="board JSON (default ChArUco 14x10, 20/15 mm)")
    _common(pt)
    bv = rsub.add_parser("board", help="calibration views of a board at varied poses")
    bv.add_argument("--board", type=Path, help="board JSON (default ChArUco 14x10, 20/15 mm)")
    _common(bv)


def _lighting(args: argparse.Namespace, seed: int):
    import dataclasses

    from cvmeasure_datasets import Lighting

    light = (
        Lighting.clean()
        if args.clean
        else Lighting.random(seed)
        if args.random_light
        else Lighting()
    )
    changes: dict[str, Any] = {}
    if args.cct_k is not None:
        changes["cct_k"] = args.cct_k
    if args.wb_error_k is not None:
        changes["wb_error_k"] = args.wb_error_k
    if args.jpeg_quality is not None:
        changes["jpeg_quality"] = args.jpeg_quality
    if args.bayer:
        changes["bayer"] = True
    if args.lateral_ca is not None:
        changes["lateral_ca"] = args.lateral_ca
    try:
        return dataclasses.replace(light, **changes)
    except ValueError as exc:
        from cvmeasure.errors import InputError

        raise InputError("command line", str(exc)) from None


def _pose(args: argparse.Namespace, default):
    import dataclasses

    changes = {
        k: v
        for k, v in (
            ("tilt_deg", args.tilt_deg),
            ("yaw_deg", args.yaw_deg),
            ("distance_mm", args.distance_mm),
        )
        if v is not None
    }
    if args.tilt_deg is not None:
        changes["tilt_direction_deg"] = args.tilt_direction_deg
    if default is None:
        if not changes:
            return None
        from cvmeasure_datasets import Pose

        default = Pose()
    try:
        return dataclasses.replace(default, **changes)
    except ValueError as exc:
        from cvmeasure.errors import InputError

        raise InputError("command line", str(exc)) from None


def _occlusions(items: list[str]) -> dict[str, float]:
    from cvmeasure.errors import InputError
    from cvmeasure.kit import ROLES

    out = {}
    for item in items:
        role, _, frac = item.partition("=")
        try:
            value = float(frac)
        except ValueError:
            value = -1.0
        if role not in ROLES or not 0.0 <= value <= 1.0:
            raise InputError(
                "--occlude", f"expected ROLE=FRACTION with ROLE in {ROLES}, got {item!r}"
            )
        out[role] = value
    return out


def _bender_kit(args: argparse.Namespace, effects: Any) -> tuple[Any, Any]:
    """The kit to draw and the effects: the discs always at the kit's heights (spec: the
    renderer's default tells the kit's story), flat with ``--flat-kit`` or a flat kit."""
    import dataclasses

    import cvmeasure_datasets
    from cvmeasure.kit import default_kit, load_kit

    kit = load_kit(args.kit) if args.kit else default_kit()
    if args.flat_kit:
        kit = kit.flat()
    effects = effects or cvmeasure_datasets.SceneEffects()
    if kit.has_heights and not effects.marker_heights:
        effects = dataclasses.replace(effects, marker_heights=True)
    return kit, effects


#: Truth keys copied into each written record (when the photo has them).
_TRUTH_KEYS = (
    "pin_angle_deg",
    "bend_angle_deg",
    "radius_mm",
    "arc_angle_deg",
    "chord_width_mm",
    "height_mm",
)


def _render_part(args: argparse.Namespace, board: Any, effects: Any, common: dict[str, Any]):
    import cvmeasure_datasets
    from cvmeasure.errors import InputError

    try:
        if args.arc:
            part = cvmeasure_datasets.arc_part(args.arc[0], args.arc[1], int(args.arc[2]))
        else:
            part = cvmeasure_datasets.saddle_part(
                args.saddle[0], args.saddle[1], int(args.saddle[2])
            )
    except ValueError as exc:
        raise InputError("command line", f"bad part: {exc}") from None
    return cvmeasure_datasets.render_part_photo(
        part=part, board=board, sheet=args.sheet, pose=_pose(args, None), effects=effects, **common
    )


def _scene_effects(args: argparse.Namespace) -> Any:
    import cvmeasure_datasets
    from cvmeasure.errors import InputError

    if args.effects is None:
        return None
    if args.kind == "board":
        raise InputError("--effects", "board views have no scene effects")
    try:
        return cvmeasure_datasets.SceneEffects.parse(args.effects)
    except ValueError as exc:
        raise InputError("--effects", str(exc)) from None


def _print_written(written: list[dict[str, Any]], as_json: bool) -> None:
    if as_json:
        print(json.dumps(written, indent=2))
        return
    for r in written:
        extra = "  ".join(
            f"{k}={r[k]:.6g}"
            for k in _TRUTH_KEYS
            if k in r and not (k == "arc_angle_deg" and "radius_mm" not in r)
        )
        print(f"wrote {r['photo']}  {extra}".rstrip())


def run(args: argparse.Namespace) -> int:
    import cvmeasure_datasets
    from cvmeasure.board import CharucoBoardSpec, load_board
    from cvmeasure.camera_model import load_camera
    from cvmeasure.errors import InputError

    if args.count < 1 or args.scale <= 0:
        raise InputError("command line", "--count must be >= 1 and --scale > 0")
    camera = load_camera(args.camera) if args.camera else None
    stem = args.name or args.kind
    written: list[dict[str, Any]] = []
    board = None
    if args.kind in ("part", "board"):
        board = load_board(args.board) if args.board else CharucoBoardSpec(14, 10, 20.0, 15.0)
    poses = None
    if args.kind == "board":
        poses = cvmeasure_datasets.random_board_poses(args.count, args.seed, board=board)
    occlude = _occlusions(args.occlude) if args.kind == "bender" else {}
    effects = _scene_effects(args)
    kit = None
    if args.kind == "bender":
        kit, effects = _bender_kit(args, effects)
    for i in range(args.count):
        seed = args.seed + i
        common = dict(
            camera=camera,
            lighting=_lighting(args, seed),
            seed=seed,
            scale=args.scale,
            linear=args.linear,
        )
        if args.kind == "bender":
            photo = cvmeasure_datasets.render_bender_photo(
                pin_angle_deg=args.pin_deg,
                bend_angle_deg=args.bend_deg,
                kit=kit,
                occlude=occlude,
                pose=_pose(args, None),
                effects=effects,
                **common,
            )
        elif args.kind == "part":
            photo = _render_part(args, board, effects, common)
        else:
            photo = cvmeasure_datasets.render_board_view(
                board=board, pose=_pose(args, poses[i]), **common
            )
        name = stem if args.count == 1 else f"{stem}_{i:03d}"
        photo_path, truth_path = photo.save(args.out / name)
        record = {"photo": str(photo_path), "truth": str(truth_path), "seed": seed}
        if args.linear:
            record["linear_tiff"] = str(photo.save_linear_tiff(args.out / f"{name}.linear.tiff"))
        for key in _TRUTH_KEYS:
            if photo.truth.get(key) is not None:  # a saddle has no radius
                record[key] = photo.truth[key]
        written.append(record)
    _print_written(written, args.json)
    return 0
