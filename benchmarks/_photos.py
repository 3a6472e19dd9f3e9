"""What several benchmarks share: the real photo sets and their boards, rendered photos,
and the one-core process settings of the timing benchmarks."""

from __future__ import annotations

import os
from dataclasses import replace
from pathlib import Path
from typing import Any

__all__ = [
    "CHARUCO_5X7",
    "CHESS_LEFT",
    "CHESS_SLAM",
    "LIFECAM",
    "REAL",
    "THREAD_ENV",
    "one_thread_env",
    "pin_one_core",
    "random_bender_photo",
]

#: The real photos and RAW files (../shared/data/real from the repository; may be absent).
REAL = Path(__file__).resolve().parents[2] / "shared" / "data" / "real"

# Board JSONs (cvmeasure.board.board_from_dict) of the real calibration sets under REAL.
#: OpenCV samples' left/right 9x6 chessboard, 25 mm squares.
CHESS_LEFT = {"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_mm": 25.0}
#: OpenCV contrib SimpleSLAM 9x6 chessboard, 20 mm squares.
CHESS_SLAM = {"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_mm": 20.0}
#: OpenCV contrib ArUco tutorial ChArUco 5x7.
CHARUCO_5X7 = {
    "type": "charuco",
    "squares_x": 5,
    "squares_y": 7,
    "square_mm": 40.0,
    "marker_mm": 20.0,
    "dictionary": "DICT_6X6_250",
}
#: PhotonVision LifeCam ChArUco 8x8.
LIFECAM = {
    "type": "charuco",
    "squares_x": 8,
    "squares_y": 8,
    "square_mm": 25.4,
    "marker_mm": 19.05,
    "dictionary": "DICT_4X4_1000",
}

#: The thread-pool variables of OpenMP, OpenBLAS, MKL and numexpr.
THREAD_ENV = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "NUMEXPR_NUM_THREADS")


def one_thread_env() -> None:
    """Set every :data:`THREAD_ENV` variable to 1: call before numpy/OpenCV load their pools."""
    for var in THREAD_ENV:
        os.environ[var] = "1"


def pin_one_core() -> str:
    """Pin this process (and its children) to one core; say which."""
    try:
        core = min(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {core})
        return f"core {core} (os.sched_setaffinity)"
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return "all cores (no sched_setaffinity here)"


def random_bender_photo(size: tuple[int, int], seed: int, *, jpeg: bool = True) -> Any:
    """One rendered bender photo at ``size`` (w, h, px): random light, angles and yaw.

    ``jpeg=False`` leaves the photo uncompressed (the lighting's ``jpeg_quality`` None).
    """
    import numpy as np

    from cvmeasure_datasets import Lighting, Pose, render_bender_photo

    rng = np.random.default_rng(seed)
    pin = float(rng.uniform(-120.0, 120.0))
    light = Lighting.random(seed)
    return render_bender_photo(
        pin_angle_deg=pin,
        bend_angle_deg=float(np.clip(pin * rng.uniform(0.8, 0.95), -110, 110)),
        lighting=light if jpeg else replace(light, jpeg_quality=None),
        pose=Pose(yaw_deg=float(rng.uniform(-180.0, 180.0)), distance_mm=850.0),
        seed=seed,
        image_size_px=size,
    )
