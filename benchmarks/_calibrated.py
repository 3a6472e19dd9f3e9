"""The camera and planes the accuracy benchmarks measure through: calibrated from photos.

A benchmark never measures through the renderer's true lens or pose (that would
hide every calibration error a user has). Instead, as a user would:

* :func:`calibrated_camera`: 12 ChArUco views (14x10, 20/15 mm) are rendered with
  the renderer's lens, written as JPEG, read back, and calibrated by
  :mod:`cvmeasure.lens` (the same code as ``cvmeasure calibrate``);
* :func:`plane_for_pose`: a photo of the same board lying on the measurement
  plane, taken from the bender photo's camera pose, gives the plane
  (:func:`cvmeasure.lens.plane.estimate_plane` with the calibrated camera).

The renderer's truth is used only to score the errors.
"""

from __future__ import annotations

import functools
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.board import CharucoBoardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.contracts import PlaneModel

__all__ = ["BOARD", "CALIBRATION_VIEWS", "calibrated_camera", "plane_for_pose"]

#: The calibration and plane board (the spec's example board).
BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
#: Views per calibration (as a user following docs/lens-calibration.md would take).
CALIBRATION_VIEWS = 12


@functools.lru_cache(maxsize=4)
def calibrated_camera(scale: float, *, seed: int = 7) -> tuple[CameraModel, dict[str, Any]]:
    """The renderer's lens at ``scale``, calibrated from rendered board photos.

    Returns the camera and a summary (views used, RMS px, focal length error vs the
    renderer's lens in %) for the benchmark's notes.
    """
    import cvmeasure_datasets
    from cvmeasure.lens.pipeline import calibrate_detections, detect_photos
    from cvmeasure_datasets.demo.calibration import planned_poses

    true_camera = cvmeasure_datasets.default_camera().scaled(scale)
    poses = planned_poses(CALIBRATION_VIEWS, seed, BOARD, true_camera)
    with tempfile.TemporaryDirectory() as tmp:
        paths = []
        for i, pose in enumerate(poses):
            photo = cvmeasure_datasets.render_board_view(
                board=BOARD, camera=true_camera, pose=pose, seed=seed + i
            )
            paths.append(photo.save(Path(tmp) / f"view{i:02d}")[0])
        report = calibrate_detections(detect_photos(paths, BOARD), true_camera.image_size_px)
    camera = report.camera
    summary = {
        "views": len(paths),
        "rms_px": float(report.result.rms_px),
        "focal_error_pct": float(100.0 * (camera.fx / true_camera.fx - 1.0)),
        "principal_point_error_px": float(
            np.hypot(
                *(
                    np.asarray(camera.principal_point_px)
                    - np.asarray(true_camera.principal_point_px)
                )
            )
        ),
    }
    return camera, summary


def plane_for_pose(
    pose: Any, camera: CameraModel, *, scale: float, seed: int, frame: str = "machine"
) -> PlaneModel:
    """The measurement plane seen from ``pose``, measured from a photo of the board on it.

    The board lies on the plane (z = 0 of ``frame``), centred where the camera looks,
    its x along the frame's x; it is rendered from the very camera pose of the photo
    it serves (the renderer's lens), written as JPEG, read back and measured with the
    calibrated ``camera``.
    """
    import cv2

    import cvmeasure_datasets
    from cvmeasure.imageio import read_photo
    from cvmeasure.lens.plane import estimate_plane
    from cvmeasure_datasets.optics import Pose

    rot, t_mm = pose.extrinsics(frame)
    # the board frame has z away from the camera: board (x, y, z) = frame (x, -y, -z)
    flip = np.diag([1.0, -1.0, -1.0]) if frame == "machine" else np.eye(3)
    sx, sy = BOARD.squares_x * BOARD.square_mm, BOARD.squares_y * BOARD.square_mm
    target = np.array([pose.offset_mm[0], pose.offset_mm[1], 0.0])
    origin = target - flip @ np.array([sx / 2, sy / 2, 0.0])  # board centre at the target
    board_pose = Pose.from_extrinsics(rot @ flip, rot @ origin + t_mm, "board")
    true_camera = cvmeasure_datasets.default_camera().scaled(scale)
    view = cvmeasure_datasets.render_board_view(
        board=BOARD, camera=true_camera, pose=board_pose, seed=seed
    )
    with tempfile.TemporaryDirectory() as tmp:
        path = view.save(Path(tmp) / "plane")[0]
        photo = read_photo(path)
        gray = cv2.cvtColor(photo.bgr8(), cv2.COLOR_BGR2GRAY)
    return estimate_plane(gray, BOARD, camera, source="board on the plate")
