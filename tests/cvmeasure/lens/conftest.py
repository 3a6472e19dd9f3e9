"""Fixtures for the calibration tests: a known lens, a board, and rendered views."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from _calib_synth import random_poses, render_view  # noqa: E402

from cvmeasure.board import board_from_dict  # noqa: E402
from cvmeasure.camera_model import CameraModel  # noqa: E402

#: The lens every synthetic test tries to recover (960x640, mild barrel distortion).
TRUE_CAMERA = CameraModel.ideal(
    (960, 640), 900.0, (-0.12, 0.08, 0.0004, -0.0003, 0.0), principal_point_px=(486.0, 316.0)
)


@pytest.fixture(scope="session")
def charuco_board():
    return board_from_dict(
        {
            "type": "charuco",
            "squares_x": 10,
            "squares_y": 7,
            "square_mm": 20.0,
            "marker_mm": 15.0,
            "dictionary": "DICT_5X5_100",
        }
    )


@pytest.fixture(scope="session")
def true_camera() -> CameraModel:
    return TRUE_CAMERA


@pytest.fixture(scope="session")
def rendered_views(charuco_board):
    """12 rendered views (image, rvec, tvec) of the ChArUco board, seed 11."""
    poses = random_poses(charuco_board, 12, 11, distance_mm=380.0)
    return [
        (render_view(charuco_board, TRUE_CAMERA, r, t, seed=i, noise_sigma=1.0), r, t)
        for i, (r, t) in enumerate(poses)
    ]
