"""``cvmeasure calibrate``: lens calibration from board photos -> camera JSON."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "calibrate",
        help="calibrate the lens from photos of a ChArUco board or chessboard",
        description="Detect the board in every photo (JPEG, PNG, TIFF or camera RAW), solve "
        "the lens (OpenCV calibrateCameraExtended, iterative rejection of bad corners and "
        "views), and write the camera JSON with RMS, standard deviations, per-view errors, "
        "views used and rejected, image coverage, projection uncertainty and the "
        "cross-validation difference of two halves. Photos without a usable board are "
        "named and skipped; too few good views exit with code 2.",
    )
    p.add_argument("photos", nargs="+", type=Path, help="calibration photos")
    p.add_argument("--board", type=Path, required=True, help="board JSON (spec)")
    p.add_argument("-o", "--out", type=Path, required=True, help="camera JSON to write")
    p.add_argument(
        "--model",
        choices=("auto", "1", "2", "5", "8", "rational", "thin-prism"),
        default="auto",
        help="distortion model: auto (default: from 1 up through 2, 5, rational, a richer "
        "model is taken when the nested F-test on the same corners rejects the simpler one "
        "at p < 0.0027 and it is well conditioned and no worse held out over the whole image, "
        "centre and edge alike; the output names the choice, why, and how far the next-best "
        "model would move the image corners), 1 (k1), 2 (k1 k2), "
        "5 (k1 k2 p1 p2 k3), 8 / rational (k1..k6), thin-prism (k1..k6, s1..s4)",
    )
    p.add_argument(
        "--board-warp",
        choices=("auto", "on", "off"),
        default="auto",
        help="solve the board's bow out of its plane with the lens (mrcal's two-parameter "
        "calobject_warp): auto (default: kept only when the lens model's next richer model "
        "still sees the bow, every group of views does, and it moves fx fy cx cy by more "
        "than 1 sigma), on (always kept), off (a flat board)",
    )
    p.add_argument(
        "--no-reject", action="store_true", help="keep every corner and view (no rejection loop)"
    )
    p.add_argument("--json", action="store_true", help="print the summary as JSON")
    p.add_argument(
        "-v", "--verbose", action="store_true", help="report each photo's corners on stderr"
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.board import load_board
    from cvmeasure.camera_model import implausible_distortion, save_camera
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import to_jsonable
    from cvmeasure.lens.pipeline import (
        calibrate_detections,
        detect_photos,
    )
    from cvmeasure.provenance import provenance

    board = load_board(args.board)

    def progress(msg: str) -> None:
        if args.verbose:
            print(msg, file=sys.stderr, flush=True)

    detections = detect_photos(args.photos, board, progress=progress)
    sizes = [d.image_size_px for d in detections]
    size = max(set(sizes), key=sizes.count)
    source = (
        f"{len(args.photos)} photo(s) ({args.photos[0]}{', ...' if len(args.photos) > 1 else ''})"
    )
    if not any(d.ok for d in detections):
        first = detections[0]
        raise InputError(
            first.source if len(detections) == 1 else source,
            f"no usable board in any photo ({first.source}: {first.reason})",
        )
    report = calibrate_detections(
        detections,
        size,
        model=args.model,
        reject_outliers=not args.no_reject,
        source=source,
        board_warp=args.board_warp,
    )
    argv = [
        "cvmeasure",
        "calibrate",
        *map(str, args.photos),
        "--board",
        str(args.board),
        "-o",
        str(args.out),
        "--model",
        args.model,
        "--board-warp",
        args.board_warp,
    ]
    camera = report.camera_model(board, provenance=provenance(argv))
    # A model that folds the image is refused by every reader (load_camera): never write one.
    size = (float(camera.image_size_px[0]), float(camera.image_size_px[1]))
    problem = implausible_distortion(camera.camera_matrix, camera.dist_coeffs, size)
    if problem:
        raise InputError(
            args.out,
            f"not written: the fitted model {args.model}'s {problem}; use --model auto or a "
            "simpler model, or add photos with the board in the image's corners",
        )
    path = save_camera(args.out, camera)
    summary = report.summary()
    if args.json:
        print(json.dumps(to_jsonable({"camera_json": str(path), **summary}), indent=2))
        return 0
    _print_report(report, path)
    return 0


def _print_report(report, path: Path) -> None:
    """The human summary: model choice, warp decision, cross-validation, intrinsics, warnings."""
    from cvmeasure.lens.pipeline import model_choice_text

    cv = report.cross_validation
    print(f"camera JSON: {path}")
    if report.model_choice is not None:
        print(model_choice_text(report.model_choice))
    if report.board_warp is not None:
        print(report.board_warp["text"])
    determined = report.uncertainty.max_px <= 10.0 * max(report.camera.image_size_px)
    if cv is not None:
        ratio = f"{cv.ratio:.1f}x what noise explains" if determined else "noise undetermined"
        print(
            f"cross-validation (halves {cv.views[0]}+{cv.views[1]} views): "
            f"{cv.diff.central_rms_px:.3f} px RMS in the central 60 %, "
            f"{cv.diff.rms_px:.3f} px over the image ({ratio})"
        )
    sd = report.result.std_devs
    cam = report.camera
    print(
        f"RMS {report.result.rms_px:.4f} px over {report.result.corner_count} corners, "
        f"{len(report.result.views)} views; dropped {report.result.corners_rejected} outlier "
        f"corners and {len(report.result.rejected)} photos"
    )
    print(
        f"fx {cam.fx:.3f} +- {sd['fx']:.3f}  fy {cam.fy:.3f} +- {sd['fy']:.3f}  "
        f"cx {cam.principal_point_px[0]:.3f} +- {sd['cx']:.3f}  "
        f"cy {cam.principal_point_px[1]:.3f} +- {sd['cy']:.3f} px "
        "(1 sigma, incl. errors a view shares)"
    )
    if determined:
        print(
            f"projection uncertainty (1 sigma): centre {report.uncertainty.centre_px:.3f} px, "
            f"p95 {report.uncertainty.p95_px:.3f} px, max {report.uncertainty.max_px:.3f} px"
        )
    else:
        print(
            "projection uncertainty: more than 10x the image size (the model is not "
            "determined by these views; see the warning)"
        )
    for r in report.result.rejected:
        print(f"skipped {r.source}: {r.reason}")
    for w in report.warnings:
        print(f"warning: {w}")
