"""The calibration stage of ``cvmeasure demo``: a known lens recovered from rendered views.

Also home of :func:`planned_poses`, a calibration "dance" after mrcal's advice
(the board in every part of the image, tilted 25-40 degrees), used by the demo
and by ``benchmarks/lens.py``.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from cvmeasure_datasets.demo.report import DemoRow, DemoSection

__all__ = ["planned_poses", "demo_step"]

#: Demo size: the seed camera scaled to 922 x 614 px.
_SCALE = 0.2


def planned_poses(n: int, seed: int, board, camera) -> list:
    """``n`` poses following mrcal's advice: the board pushed into every part of
    the image (corners, edges, centre), tilted 25-40 deg in varied directions.
    ``cvmeasure_datasets.random_board_poses`` keeps the board 15-18 % away from the image
    edges, which leaves the lens corners to extrapolation."""
    import cvmeasure_datasets
    from cvmeasure_datasets.optics import project_frame_points

    rng = np.random.default_rng([seed, 0x1E45])
    w_mm, h_mm = board.size_mm
    w, h = camera.image_size_px
    m = 0.01 * w
    outline = np.array(
        [[-10, -10], [w_mm + 10, -10], [w_mm + 10, h_mm + 10], [-10, h_mm + 10]], float
    )
    centre = np.array([w_mm / 2, h_mm / 2])
    pulls = [(-1, -1), (1, 1), (1, -1), (-1, 1), (0, 0), (0, -1), (0, 1), (-1, 0), (1, 0)]

    def place(tilt, direction, yaw, dist, target):
        offset = centre.copy()
        for _ in range(5):  # Newton steps: put the board centre on the target pixel

            def proj(o):
                rot, t = cvmeasure_datasets.Pose(tilt, direction, yaw, dist, tuple(o)).extrinsics(
                    "board"
                )
                return project_frame_points(camera, rot, t, centre[None])[0]

            q0 = proj(offset)
            jac = np.column_stack([(proj(offset + d) - q0) for d in np.eye(2)])
            offset = offset + np.linalg.solve(jac, target - q0)
        pose = cvmeasure_datasets.Pose(tilt, direction, yaw, dist, tuple(offset))
        rot, t = pose.extrinsics("board")
        return pose, project_frame_points(camera, rot, t, outline)

    poses = []
    for i in range(n):
        pull = np.array(pulls[i % len(pulls)], float)
        tilt = rng.uniform(25.0, 40.0) if i else 3.0
        direction = (i * 137.5 + rng.uniform(-20, 20)) % 360.0
        yaw = rng.uniform(-20.0, 20.0)
        fill = rng.uniform(0.5, 0.65)
        mid = np.array([(w - 1) / 2, (h - 1) / 2])
        for _ in range(30):
            dist = camera.fx * w_mm / (fill * w)
            pose, px = place(tilt, direction, yaw, dist, mid)
            room = np.array(
                [
                    w - 1 - m - px[:, 0].max() if pull[0] > 0 else px[:, 0].min() - m,
                    h - 1 - m - px[:, 1].max() if pull[1] > 0 else px[:, 1].min() - m,
                ]
            )
            if np.all(room > 0):
                for k in (0.97, 0.85, 0.7, 0.5, 0.0):
                    pose, px = place(tilt, direction, yaw, dist, mid + pull * room * k)
                    if (
                        px[:, 0].min() > m
                        and px[:, 1].min() > m
                        and px[:, 0].max() < w - 1 - m
                        and px[:, 1].max() < h - 1 - m
                    ):
                        break
                else:
                    pose = None
                if pose is not None:
                    break
            fill *= 0.95
        poses.append(pose)
    return poses


def demo_step(out_dir: Path, *, seed: int) -> DemoSection:
    """Calibrate from 8 rendered views (922 x 614), then check a plane tilted 3 degrees."""
    import cvmeasure_datasets
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.camera_model import save_camera
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure.lens.detect import detect_board
    from cvmeasure.lens.pipeline import calibrate_detections
    from cvmeasure.lens.plane import estimate_plane
    from cvmeasure.lens.uncertainty import projection_diff

    t0 = time.perf_counter()
    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    true_cam = cvmeasure_datasets.default_camera().scaled(_SCALE)
    poses = planned_poses(8, seed, board, true_cam)
    dets = []
    for i, pose in enumerate(poses):
        photo = cvmeasure_datasets.render_board_view(
            board=board, camera=true_cam, pose=pose, seed=seed + i
        )
        dets.append(detect_board(photo.bgr, board, source=f"view{i:02d}"))
    report = calibrate_detections(dets, true_cam.image_size_px)
    cam = report.camera
    folder = Path(out_dir) / "calibration"
    cam_path = save_camera(folder / "camera.json", report.camera_model(board))
    tilt_true = 3.0
    plane_pose = cvmeasure_datasets.Pose(
        tilt_deg=tilt_true,
        tilt_direction_deg=40.0,
        yaw_deg=5.0,
        distance_mm=true_cam.fx * 280.0 / (0.75 * true_cam.image_size_px[0]),
        offset_mm=(140.0, 100.0),
    )
    plane_photo = cvmeasure_datasets.render_board_view(
        board=board, camera=true_cam, pose=plane_pose, seed=seed + 99
    )
    plane = estimate_plane(plane_photo.bgr, board, cam, source="plane view")
    plane_path = atomic_write_json(folder / "plane.json", plane.to_dict())
    diff = projection_diff(true_cam, cam, fit_rotation=True)
    f_tol = 1e-3 * true_cam.fx
    cx, cy = cam.principal_point_px
    tcx, tcy = true_cam.principal_point_px
    cv = report.cross_validation
    rows = [
        DemoRow("focal length fx", cam.fx, true_cam.fx, "px", f_tol),
        DemoRow("focal length fy", cam.fy, true_cam.fy, "px", f_tol),
        DemoRow("principal point cx", cx, tcx, "px", 3.0),
        DemoRow("principal point cy", cy, tcy, "px", 3.0),
        DemoRow("RMS reprojection error", report.result.rms_px, None, "px"),
        DemoRow("projection map vs true lens, p95 (rotation refit)", diff.p95_px, 0.0, "px", 0.3),
        DemoRow("plane tilt (one photo)", plane.tilt_deg, tilt_true, "deg", 0.05),
    ]
    notes = [
        f"{len(report.result.views)} of 8 rendered views used, {report.result.corner_count} corners; "
        f"cross-validation diff {cv.diff.central_rms_px:.3f} px in the central 60 %"
        if cv
        else "too few views for cross-validation",
        f"plane: worst angle error from ignoring the {plane.tilt_deg:.2f} deg tilt "
        f"{plane.worst_angle_error_deg:.3f} deg -> affine model {'OK' if plane.affine_ok else 'not enough'}",
    ]
    return DemoSection(
        "lens calibration",
        rows=rows,
        files=[str(cam_path), str(plane_path)],
        notes=notes,
        seconds=time.perf_counter() - t0,
    )
