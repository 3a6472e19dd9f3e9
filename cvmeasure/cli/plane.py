"""``cvmeasure plane``: the affine plane check from a board lying on the measurement plane."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cvmeasure.cli.options import positive_float

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "plane",
        help="plane tilt, scale, affine verdict and rectifying homography from one photo",
        description="From a photo of the board lying on the measurement plane: the plane's "
        "tilt against the image plane and its direction, the scale in mm per pixel, "
        "whether ignoring the tilt keeps angle errors within --tolerance-deg, and the "
        "homography from undistorted image pixels to board millimetres. The tilt direction "
        "is in the image frame: where the plane recedes from the camera, degrees "
        "counter-clockwise from +x as seen in the photo (a render's truth JSON gives the "
        "same figure as pose.tilt_direction_image_deg).",
    )
    p.add_argument("photo", type=Path, help="photo of the board on the plane")
    p.add_argument("--board", type=Path, required=True, help="board JSON (spec)")
    p.add_argument("--camera", type=Path, required=True, help="camera JSON (cvmeasure calibrate)")
    p.add_argument(
        "--tolerance-deg",
        type=positive_float,
        default=0.05,
        help="worst angle error (deg) an affine model may cause (default 0.05)",
    )
    p.add_argument("-o", "--out", type=Path, help="also write the result JSON here")
    p.add_argument(
        "--rectified",
        type=Path,
        help="also write the photo rectified to the plane (top view, PNG/JPEG/TIFF)",
    )
    p.add_argument(
        "--px-per-mm",
        type=positive_float,
        default=4.0,
        help="resolution of --rectified (default 4)",
    )
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.board import load_board
    from cvmeasure.camera_model import load_camera
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_bytes, atomic_write_json, to_jsonable
    from cvmeasure.imageio import read_photo
    from cvmeasure.lens.plane import estimate_plane, rectify_image
    from cvmeasure.provenance import provenance

    board = load_board(args.board)
    camera = load_camera(args.camera)
    photo = read_photo(args.photo)
    plane = estimate_plane(
        photo.gray8(), board, camera, tolerance_deg=args.tolerance_deg, source=str(args.photo)
    )
    result = plane.to_dict()
    result["provenance"] = provenance(
        [
            "cvmeasure",
            "plane",
            str(args.photo),
            "--board",
            str(args.board),
            "--camera",
            str(args.camera),
            "--tolerance-deg",
            str(args.tolerance_deg),
        ]
    )
    if args.rectified is not None:
        import cv2

        try:
            img = rectify_image(photo.bgr, plane, px_per_mm=args.px_per_mm)
        except ValueError as exc:
            raise InputError(
                "--px-per-mm", f"{args.px_per_mm:g} px/mm is too fine for this plane: {exc}"
            ) from None
        ok, buf = cv2.imencode(args.rectified.suffix or ".png", img)
        if not ok:
            raise InputError(args.rectified, "cannot encode an image with this file suffix")
        atomic_write_bytes(args.rectified, buf.tobytes())
        result["rectified"] = {"path": str(args.rectified), "px_per_mm": args.px_per_mm}
    if args.out is not None:
        atomic_write_json(args.out, result)
    if args.json:
        print(json.dumps(to_jsonable(result), indent=2))
        return 0
    verdict = "affine model OK" if plane.affine_ok else "affine model NOT enough"
    print(
        f"tilt {plane.tilt_deg:.3f} deg, receding towards {plane.tilt_direction_deg:.1f} deg "
        "(image frame, counter-clockwise as seen), "
        f"{plane.mm_per_px:.5f} mm/px"
    )
    print(
        f"worst angle error from ignoring the tilt: {plane.worst_angle_error_deg:.4f} deg "
        f"(tolerance {plane.tolerance_deg:g}): {verdict}"
    )
    lens = plane.lens_uncertainty_mm()
    if lens["cross_validation_mm"] is not None:
        print(
            f"lens calibration on this plane: cross-validation {lens['cross_validation_mm']:.4f} mm, "
            f"noise sigma {lens['sigma_mm']:.4f} mm"
        )
    return 0
