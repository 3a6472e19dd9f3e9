"""``cvmeasure markers``: the marker kit's colours (``learn`` them from a reference photo)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

__all__ = ["register", "run_learn"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "markers",
        help="learn the marker kit's colours from a reference photo",
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
