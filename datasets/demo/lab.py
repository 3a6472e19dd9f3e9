"""Demo step of the photo lab: render a few small photos and check them against their truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cvmeasure.board import CharucoBoardSpec
from cvmeasure_datasets.bender import render_bender_photo
from cvmeasure_datasets.boards import random_board_poses, render_board_view
from cvmeasure_datasets.checks import check_charuco_corners, check_disc_centre
from cvmeasure_datasets.demo.report import DemoRow, DemoSection
from cvmeasure_datasets.lighting import Lighting
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.parts import arc_part, render_part_photo

__all__ = ["demo_step"]

_BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0, "DICT_5X5_100")


def demo_step(out_dir: Path, *, seed: int) -> DemoSection:
    """Render a board view, a bender photo and a part photo (1152 x 768) and check them.

    Rows: ChArUco corners found by OpenCV against the rendered truth (median
    px), disc centres from sub-pixel edge ellipse fits against the truth
    (worst px), the truth's bend and pin angles against what was asked.
    """
    lab = Path(out_dir) / "lab"
    section = DemoSection("synthetic photo lab")

    pose = random_board_poses(2, seed=seed, board=_BOARD)[1]
    view = render_board_view(
        board=_BOARD, pose=pose, lighting=Lighting.clean(), seed=seed, scale=0.25
    )
    corners = check_charuco_corners(view, _BOARD)
    section.files += [str(p) for p in view.save(lab / "board_view")]
    section.rows.append(
        DemoRow("ChArUco corners, median |detected - true|", corners.median_px, 0.0, "px", 0.1)
    )
    section.rows.append(
        DemoRow(
            "ChArUco corners detected",
            float(len(corners.ids)),
            float(_BOARD.corner_count),
            "",
            12.0,
        )
    )

    rng = np.random.default_rng(seed)
    bend = float(np.round(rng.uniform(20.0, 80.0), 1))
    pin = float(np.round(rng.uniform(-120.0, -60.0), 1))
    tilted = Pose(
        tilt_deg=30.0,
        tilt_direction_deg=200.0,
        yaw_deg=10.0,
        distance_mm=500.0,
        offset_mm=(-5.0, 0.0),
    )
    bender = render_bender_photo(
        pin_angle_deg=pin,
        bend_angle_deg=bend,
        pose=tilted,
        lighting=Lighting.clean(blur_px=0.0),
        seed=seed,
        scale=0.25,
        linear=True,
    )
    discs = [
        check_disc_centre(bender, role) for role in ("origin", "axis", "pin", "wire_a", "wire_b")
    ]
    section.files += [str(p) for p in bender.save(lab / "bender_tilted")]
    section.rows.append(
        DemoRow(
            "disc centre (edge ellipse fit), worst error",
            max(d.error_px for d in discs),
            0.0,
            "px",
            0.05,
        )
    )
    section.rows.append(
        DemoRow("bender truth bend_angle_deg", bender.truth["bend_angle_deg"], bend, "deg", 1e-9)
    )
    section.rows.append(
        DemoRow("bender truth pin_angle_deg", bender.truth["pin_angle_deg"], pin, "deg", 1e-9)
    )

    part = render_part_photo(part=arc_part(70.0, 120.0, 8), seed=seed, scale=0.25)
    section.files += [str(p) for p in part.save(lab / "part_arc")]
    section.notes.append(
        "photos and their .truth.json in lab/; the disc check compares ellipse fits with the "
        "truth's ellipse centre (the projected disc centre differs by "
        f"{max(d.perspective_shift_px for d in discs):.3f} px at this 30 deg tilt)"
    )
    return section
