"""Measure a bender photo and a finished part with the public API, from files.

The photo lab renders a bender photo and a photo of the seed paper's half circle beside
a ChArUco board, with exact ground truth, and writes the files a user would have: the
photos, the board JSON, the camera JSON and the design SVG. Everything after that is
what a user writes: ``cvmeasure`` verbs on those files. It prints measured vs true.

Run: ``python docs/examples/measure_with_the_api.py [-o FOLDER] [--scale 0.5]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cvmeasure
import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec

HALF_CIRCLE_SVG = (
    '<svg xmlns="http://www.w3.org/2000/svg" width="240mm" height="140mm" viewBox="0 0 240 140">'
    '<path d="M 20 120 A 100 100 0 0 1 220 120" fill="none" stroke="black"/></svg>\n'
)


def make_files(folder: Path, scale: float) -> dict[str, object]:
    """Render the two photos and write every input file; return the ground truth."""
    folder.mkdir(parents=True, exist_ok=True)
    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    cvmeasure.save(folder / "board.json", board)
    (folder / "half-circle.svg").write_text(HALF_CIRCLE_SVG, encoding="utf-8")
    part = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(100.0, 180.0, 20), board=board, seed=7, scale=scale
    )
    part.save(folder / "part")
    cvmeasure.save(folder / "camera.json", part.camera)
    bender = cvmeasure_datasets.render_bender_photo(
        pin_angle_deg=30.0, bend_angle_deg=42.5, seed=7, scale=scale
    )
    bender.save(folder / "bender")
    return {"part": part.truth, "bender": bender.truth}


def main(argv: list[str] | None = None) -> dict[str, tuple[float, float]]:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--out", type=Path, default=Path("api-example"))
    p.add_argument("--scale", type=float, default=0.5, help="photo size, 1 = 4608x3072")
    args = p.parse_args(argv)
    truth = make_files(args.out, args.scale)
    f = args.out

    # --- what a user writes -------------------------------------------------------------
    angles = cvmeasure.measure_bender_photo(f / "bender.jpg")  # image pixels, built-in kit
    job = cvmeasure.gcode_for(f / "half-circle.svg", divisions=20)  # the part's job
    cvmeasure.save(f / "half-circle.gcode", job)
    part = cvmeasure.measure_part(
        f / "part.jpg",
        board=f / "board.json",
        camera=f / "camera.json",
        design=f / "half-circle.svg",
        job=f / "half-circle.gcode",  # compared with the polygon that job bent
    )
    cvmeasure.save(f / "part.json", part)
    # -------------------------------------------------------------------------------------

    rows = {
        "bend angle (deg)": (angles.bend_angle_deg, truth["bender"]["bend_angle_deg"]),
        "pin angle (deg)": (angles.pin_angle_deg, truth["bender"]["pin_angle_deg"]),
        "part radius (mm)": (part.result.radius_mm, truth["part"]["radius_mm"]),
        "part arc angle (deg)": (part.result.arc_angle_deg, truth["part"]["arc_angle_deg"]),
        "worst vertex bend error vs design (deg)": (
            max(abs(e) for e in part.comparison.bends.error_deg),
            0.0,
        ),
        "G-code bends": (float(len(job.pin_deg)), 19.0),
    }
    for name, (measured, true) in rows.items():
        print(f"{name:42s} measured {measured:10.4f}  true {true:10.4f}")
    for w in (*angles.warnings, *part.warnings):
        print(f"warning: {w}")
    return rows


if __name__ == "__main__":
    main()
