"""``cvmeasure markers``: the marker kit's colours (``learn``) and heights (``heights``)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from cvmeasure.warning import StageWarning

__all__ = ["register", "run_learn", "run_heights"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "markers",
        help="learn the marker kit's colours, measure its heights",
        description="Tools for the colour marker kit.",
    )
    msub = p.add_subparsers(dest="markers_command", metavar="ACTION")
    msub.required = True
    learn = msub.add_parser(
        "learn",
        help="learn the kit's colours (and spreads) from a reference photo",
        description="Find the five markers in a reference photo with the kit's nominal "
        "colours, white-balance each disc on the white rings, and write a kit JSON whose "
        "colours are the measured ones and whose lab_sigma/rgb_sigma are their spreads. "
        "Use it with `cvmeasure measure --kit`.",
    )
    learn.add_argument("photo", type=Path, help="reference photo with all five markers")
    learn.add_argument("-o", "--out", type=Path, required=True, help="learnt kit JSON to write")
    learn.add_argument("--kit", type=Path, help="nominal kit JSON (default: the built-in kit)")
    learn.add_argument(
        "--flat",
        action="store_true",
        help="the markers are flat stickers on the plate: write the kit without heights "
        "(default: the nominal kit's heights are kept)",
    )
    learn.add_argument("--space", choices=("lab", "rgb"), default="lab", help="default lab")
    learn.add_argument("--name", help="name of the learnt kit (default <kit>-learnt)")
    learn.add_argument("--json", action="store_true", help="print the result as JSON")
    learn.set_defaults(func=run_learn)
    _register_heights(msub)


def _register_heights(msub: argparse._SubParsersAction) -> None:
    from cvmeasure.cli.options import positive_float

    h = msub.add_parser(
        "heights",
        help="measure each marker's height above the plate from photos of a bend sweep",
        description="Measure the height of each marker's face above the top plate from "
        "photos taken from the plane's pose: bend photos at several pin angles (the pin "
        "holding the wire against the die; both directions, 6 or more) and, recommended, "
        "photos of the straight wire (--straight). The pin and wire markers turn about the "
        "die's axis, where the origin marker sits: only the true heights keep their "
        "distances from it over the sweep, and the straight wire parallel to the axis. "
        "Writes the kit JSON with the measured height_mm, height_sigma_mm and "
        "height_covariance_mm2; `measure --kit` carries those uncertainties into every "
        "angle's.",
    )
    h.add_argument("photos", nargs="*", type=Path, metavar="PHOTO", help="bend photos")
    h.add_argument(
        "--session",
        type=Path,
        help="a calibration session's folder (or its session.jsonl): its loaded photos are "
        "the bend photos (the session photographs them from one pose)",
    )
    h.add_argument(
        "--plane",
        type=Path,
        required=True,
        help="plane JSON (`cvmeasure plane -o`) measured from the same camera pose",
    )
    h.add_argument(
        "--straight",
        type=Path,
        action="append",
        default=[],
        metavar="PHOTO",
        help="a photo of the straight wire (no bend) from the same pose (repeatable)",
    )
    h.add_argument(
        "--kit", type=Path, help="nominal kit JSON (default: the built-in kit's heights)"
    )
    h.add_argument(
        "--prior-sigma-mm",
        type=positive_float,
        default=None,
        help="standard uncertainty of every nominal height, mm (default: each cap within "
        "10 %% of its nominal height, uniformly: 0.058 x the height; 2 mm without one)",
    )
    h.add_argument("-o", "--out", type=Path, required=True, help="kit JSON to write")
    h.add_argument("--json", action="store_true", help="print the result as JSON")
    h.set_defaults(func=run_heights)


def run_learn(args: argparse.Namespace) -> int:
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure.imageio import read_photo
    from cvmeasure.kit import default_kit, load_kit
    from cvmeasure.markers.learn import learn_kit

    kit = load_kit(args.kit) if args.kit else default_kit()
    photo = read_photo(args.photo)
    if args.flat:
        kit = kit.flat()
    learnt = learn_kit(photo.bgr8(), kit, space=args.space, source=str(args.photo), name=args.name)
    atomic_write_json(args.out, learnt.kit.to_dict())
    if args.json:
        print(json.dumps(learnt.to_dict()))
        return 0
    for marker in learnt.kit.markers:
        print(
            f"{marker.role:<7} {marker.name:<13} srgb {list(marker.srgb)}  "
            f"Delta E {learnt.delta_e[marker.role]:5.1f} from the nominal kit  "
            f"({learnt.n_pixels[marker.role]} px)"
        )
    print(f"heights above the plate: {learnt.kit.heights_text()}")
    print(f"wrote {args.out}")
    return 0


def run_heights(args: argparse.Namespace) -> int:
    import sys

    from cvmeasure.contracts import PlaneModel
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure.imageio import read_photo
    from cvmeasure.kit import ROLES, default_kit, load_kit
    from cvmeasure.markers.kit_heights import SweepPhoto, measure_heights
    from cvmeasure.markers.measure import frame_centres

    kit = load_kit(args.kit) if args.kit else default_kit()
    plane = PlaneModel.load(args.plane)
    sweep, failed, y_down = [], 0, True
    pose_checks: list[tuple[str, StageWarning]] = []
    bends = list(args.photos) + (_session_loaded_photos(args.session) if args.session else [])
    if not bends:
        raise InputError("markers heights", "no bend photos (PHOTO... or --session)")
    shots = [(p, False) for p in bends] + [(p, True) for p in args.straight]
    for path, straight in shots:
        try:
            photo = read_photo(path)
            got = frame_centres(photo.bgr, kit, plane=plane, linear=photo.linear, source=str(path))
        except InputError as exc:
            print(f"cvmeasure markers heights: {exc}", file=sys.stderr)
            failed += 1
            continue
        y_down = got.frame.y_down
        sweep.append(SweepPhoto(got.centres, got.covariances, straight, str(path)))
        pose_checks += [(str(path), w) for w in got.warnings if w.code in POSE_CHECK_CODES]
    try:
        result = measure_heights(
            sweep,
            kit,
            plane.camera_centre_mm,
            y_down=y_down,
            prior_sigma_mm=args.prior_sigma_mm,
            plane_pose=(plane.rvec, plane.tvec_mm),
        )
    except ValueError as exc:
        raise InputError("markers heights", f"{exc} ({failed} photo(s) failed)") from None
    atomic_write_json(args.out, result.kit.to_dict())
    if args.json:
        print(json.dumps(result.to_dict()))
    else:
        print(f"{result.n_photos} photos ({result.n_straight} straight), fit RMS {result.rms:.2f}")
        for role in ROLES:
            print(
                f"{role:<7} {result.heights_mm[role]:7.2f} +- {result.sigma_mm[role]:.2f} mm"
                f"  (nominal {result.nominal_mm[role]:g} mm)"
            )
        for w in result.warnings:
            print(f"! {w}")
        print(f"wrote {args.out}")
    _print_pose_checks(pose_checks, len(sweep))
    return 2 if failed else 0


#: Each photo's plane checks that say the plane or the kit is not this pose's: heights
#: fitted through such a plane come out wrong however well the sweep fits.
POSE_CHECK_CODES = frozenset({"plane_scale", "plane_tilt", "kit_heights_mismatch"})


def _print_pose_checks(checks: list[tuple[str, StageWarning]], n_photos: int) -> None:
    """One stderr line per plane check the photos failed: code, how many, the first."""
    by_code: dict[str, list[tuple[str, StageWarning]]] = {}
    for photo, warning in checks:
        by_code.setdefault(warning.code, []).append((photo, warning))
    for code, hits in by_code.items():
        photo, first = hits[0]
        print(
            f"warning: {code} on {len(hits)} of {n_photos} photos (first {photo}): "
            f"{first.message}; the heights above are not to be trusted",
            file=sys.stderr,
        )


def _session_loaded_photos(path: Path) -> list[Path]:
    """The loaded photos of a calibration session's log (paths relative to its folder)."""
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import read_jsonl

    log = path / "session.jsonl" if path.is_dir() else path
    if not log.is_file():
        raise InputError(path, "no session log here (session.jsonl)")
    records = read_jsonl(log, skip_partial_last=True)
    photos = [
        log.parent / str(r["photo_loaded"])
        for r in records
        if isinstance(r, dict) and r.get("event") == "sample" and r.get("photo_loaded")
    ]
    if not photos:
        raise InputError(log, "not a session log with bends (no 'sample' records)")
    return photos
