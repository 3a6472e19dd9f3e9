"""``cvmeasure measure``: bender photos -> signed pin, bend and springback angles (JSON Lines)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from cvmeasure.method_names import MARKER_METHOD_ALIASES, MARKER_METHODS, marker_method

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "measure",
        help="signed pin and bend angles (and springback) from bender photos",
        description="Measure each bender photo: the five kit markers' centres, the signed pin "
        "and bend angles in the machine frame, one standard uncertainty for each, and "
        "warnings. One JSON Lines record per photo (spec). A photo with a missing or "
        "ambiguous marker is named on stderr with the role and why; the others go on, "
        "and the exit code is 2.",
    )
    p.add_argument("photos", nargs="*", type=Path, metavar="PHOTO", help="photos to measure")
    p.add_argument(
        "--kit",
        type=Path,
        help="kit JSON (spec; `targets markers --format json` prints the built-in one, "
        "`markers learn` fits your print's colours); default the built-in kit, whose "
        "markers stand at heights above the plate",
    )
    p.add_argument(
        "--flat-kit",
        action="store_true",
        help="the markers are flat stickers on the plate: measure with the kit's heights "
        "removed (a kit JSON without height_mm means the same)",
    )
    p.add_argument("--camera", type=Path, help="camera JSON: remove lens distortion")
    g = p.add_mutually_exclusive_group()
    g.add_argument(
        "--plane",
        type=Path,
        help="plane JSON (`cvmeasure plane -o`, which saves its camera): compute angles on "
        "the rectified plane",
    )
    g.add_argument(
        "--board",
        type=Path,
        help="board JSON: find this board in each photo and rectify to its plane (needs --camera)",
    )
    p.add_argument(
        "--pair",
        nargs=2,
        action="append",
        type=Path,
        metavar=("LOADED", "UNLOADED"),
        help="a trial: loaded and unloaded photo of one bend -> springback_deg (repeatable)",
    )
    p.add_argument(
        "--trials",
        type=Path,
        help="trials manifest CSV: trial, photo_loaded, photo_unloaded [, commanded_pin_deg]",
    )
    p.add_argument(
        "-o",
        "--out",
        type=Path,
        help="also write the records: .jsonl (all records) or .csv (trials CSV of the spec)",
    )
    p.add_argument(
        "--overlay",
        type=Path,
        help="draw markers, frame and angles: a PNG for one photo, a folder for several",
    )
    p.add_argument(
        "--method",
        choices=(*MARKER_METHODS, *MARKER_METHOD_ALIASES),
        default=MARKER_METHODS[0],
        metavar="{" + ",".join(MARKER_METHODS) + "}",
        help=f"default {MARKER_METHODS[0]} (the older names ours, seed are read too)",
    )
    p.add_argument("--space", choices=("lab", "rgb"), default="lab", help="default lab")
    p.add_argument(
        "--edge",
        choices=("luma", "green", "colour", "shade"),
        help="image the disc edges are found in (default: luma for JPEG/8-bit photos, shade "
        "when the kit's markers have a step_mm (faces standing on their rings); green for "
        "RAW/16-bit ones and for any lens with strong lateral colour)",
    )
    p.add_argument(
        "--heights",
        choices=("none", "parallel"),
        default="none",
        help="without --plane/--board, the kit's marker heights cannot be applied exactly: "
        "none (default) measures in the image and states the bound in height_bound_deg; "
        "parallel (needs --camera) corrects them assuming the camera looks square onto the "
        "plate (bound: what a 3 deg tilt leaves). With a plane they are always applied",
    )
    p.add_argument("--json", action="store_true", help="print JSON Lines (default: a table)")
    p.set_defaults(func=run)


def _trials_manifest(path: Path) -> list[tuple[str, Path, Path, dict[str, str]]]:
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import read_csv_rows

    rows = read_csv_rows(path, required=("photo_loaded", "photo_unloaded"))
    out = []
    for i, row in enumerate(rows, start=1):
        loaded, unloaded = row["photo_loaded"], row["photo_unloaded"]
        if not loaded or not unloaded:
            raise InputError(path, f"row {i}: empty photo_loaded or photo_unloaded")
        trial = row.get("trial") or str(i)
        out.append((trial, path.parent / loaded, path.parent / unloaded, row))
    return out


def _measure_setup(args: argparse.Namespace) -> tuple[Any, Any, Any, Any]:
    """The kit, camera, plane and board the options name, refusing options wrong together."""
    from cvmeasure.board import load_board
    from cvmeasure.camera_model import load_camera
    from cvmeasure.contracts import PlaneModel
    from cvmeasure.errors import InputError
    from cvmeasure.kit import default_kit, load_kit

    kit = load_kit(args.kit) if args.kit else default_kit()
    if args.flat_kit:
        kit = kit.flat()
    camera = load_camera(args.camera) if args.camera else None
    args.method = marker_method(args.method)
    if args.method == "seed_hough" and (camera is not None or args.plane or args.board):
        raise InputError(
            "--method seed_hough",
            "the seed_hough method measures in image pixels: it takes no --camera, --plane or --board",
        )
    plane = PlaneModel.load(args.plane, camera=camera) if args.plane else None
    if args.heights == "parallel" and (camera is None or args.plane or args.board):
        raise InputError(
            "--heights parallel",
            "corrects a camera-only measurement: it needs --camera and no --plane/--board "
            "(a plane applies the heights exactly)",
        )
    board = None
    if args.board is not None:
        if camera is None:
            raise InputError("--board", "rectifying to a board's plane needs --camera")
        board = load_board(args.board)
    return kit, camera, plane, board


def _photos_and_trials(
    args: argparse.Namespace,
) -> tuple[list[Path], list[tuple[str, Path, Path, dict[str, str]]]]:
    """Every photo to measure (each once) and the loaded/unloaded pairs among them."""
    from cvmeasure.errors import InputError

    trials: list[tuple[str, Path, Path, dict[str, str]]] = []
    for i, (loaded, unloaded) in enumerate(args.pair or [], start=1):
        trials.append((str(i), loaded, unloaded, {}))
    if args.trials is not None:
        trials.extend(_trials_manifest(args.trials))
    photos: list[Path] = list(args.photos)
    for _, loaded, unloaded, _ in trials:
        photos.extend(p for p in (loaded, unloaded) if p not in photos)
    if not photos:
        raise InputError("measure", "no photos given (PHOTO..., --pair or --trials)")
    if args.overlay is not None and len(photos) > 1 and args.overlay.suffix:
        raise InputError(args.overlay, "several photos: --overlay must be a folder")
    return photos, trials


def _write_overlay(args: argparse.Namespace, path: Path, photo: Any, res: Any, kit: Any) -> None:
    import cv2

    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_bytes
    from cvmeasure.markers.overlay import draw_overlay

    target = args.overlay if args.overlay.suffix else args.overlay / f"{path.stem}.overlay.png"
    ok, buf = cv2.imencode(".png", draw_overlay(photo.bgr8(), res, kit))
    if not ok:
        raise InputError(target, "cannot encode the overlay PNG")
    atomic_write_bytes(target, buf.tobytes())


def _measure_photos(
    args: argparse.Namespace, photos: list[Path], setup: tuple[Any, Any, Any, Any]
) -> tuple[dict[Path, Any], list[dict[str, Any]], int]:
    """Measure each photo (a bad one is reported and skipped): results, records, failures."""
    from cvmeasure.errors import InputError
    from cvmeasure.imageio import read_photo
    from cvmeasure.markers.measure import measure_photo_file

    kit, camera, plane, board = setup
    results: dict[Path, Any] = {}
    records: list[dict[str, Any]] = []
    failed = 0
    for path in photos:
        try:
            photo = read_photo(path)
            res = measure_photo_file(  # what cvmeasure.api's verb calls, without its imports
                photo,
                kit,
                camera=camera,
                plane=plane,
                board=board,
                method=args.method,
                space=args.space,
                edge=args.edge,
                heights=args.heights,
            )
        except InputError as exc:
            print(f"cvmeasure measure: {exc}", file=sys.stderr)
            failed += 1
            continue
        results[path] = res
        records.append(res.to_dict())
        _emit(res.to_dict(), args.json)
        if args.overlay is not None:
            _write_overlay(args, path, photo, res, kit)
    return results, records, failed


def _measure_trials(
    args: argparse.Namespace,
    trials: list[tuple[str, Path, Path, dict[str, str]]],
    results: dict[Path, Any],
    records: list[dict[str, Any]],
) -> list[Any]:
    """Springback of each pair whose two photos were measured (records appended)."""
    from cvmeasure.errors import InputError
    from cvmeasure.markers.measure import measure_trial

    measured = []
    for trial, loaded, unloaded, row in trials:
        if loaded not in results or unloaded not in results:
            print(
                f"cvmeasure measure: trial {trial}: no springback (a photo of the pair failed)",
                file=sys.stderr,
            )
            continue
        commanded = row.get("commanded_pin_deg", "")
        try:
            commanded_deg = float(commanded) if commanded.strip() else math.nan
        except ValueError:
            raise InputError(
                args.trials, f"trial {trial}: commanded_pin_deg {commanded!r}"
            ) from None
        t = measure_trial(
            results[loaded], results[unloaded], trial, commanded_pin_deg=commanded_deg
        )
        records.append(t.to_dict())
        _emit(records[-1], args.json)
        measured.append(t)
    return measured


def run(args: argparse.Namespace) -> int:
    from cvmeasure.contracts import TrialTable
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_text
    from cvmeasure.report.console import warning_summary

    setup = _measure_setup(args)
    photos, trials = _photos_and_trials(args)
    results, records, failed = _measure_photos(args, photos, setup)
    measured_trials = _measure_trials(args, trials, results, records)
    if args.out is not None:
        if args.out.suffix.lower() == ".csv":
            if not trials:
                raise InputError(
                    args.out, "a .csv output is the trials CSV: give --pair or --trials"
                )
            TrialTable(tuple(measured_trials)).write_csv(args.out)
        else:
            atomic_write_text(args.out, "".join(json.dumps(r) + "\n" for r in records))
    summary = warning_summary(
        ((str(p), w) for p, r in results.items() for w in r.warnings), n_photos=len(photos)
    )
    for line in summary:
        print(line, file=sys.stderr if args.json else sys.stdout)
    return 2 if failed else 0


def _emit(record: dict[str, Any], as_json: bool) -> None:
    if as_json:
        print(json.dumps(record), flush=True)
        return
    if "springback_deg" in record:
        print(
            f"trial {record.get('trial', '-')}: loaded {record['loaded_bend_deg']:+.3f}  "
            f"unloaded {record['unloaded_bend_deg']:+.3f}  springback "
            f"{record['springback_deg']:+.3f} +- {record['uncertainty_deg']['springback_deg']:.3f} deg"
        )
        return
    from cvmeasure.warning import StageWarning

    u = record["uncertainty_deg"]
    print(
        f"{record.get('photo', '-')}: pin {record['pin_angle_deg']:+.3f} +- {u['pin_angle_deg']:.3f}"
        f"  bend {record['bend_angle_deg']:+.3f} +- {u['bend_angle_deg']:.3f} deg"
        " (one standard uncertainty)"
    )
    for w in record["warnings"]:
        print(f"  ! {StageWarning.from_json(w)}")
