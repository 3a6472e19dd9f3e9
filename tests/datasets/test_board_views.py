"""Board views: detected corners against the truth, and a calibration recovering the lens."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cvmeasure.board import CharucoBoardSpec, ChessboardSpec
from cvmeasure_datasets import Lighting, Pose, default_camera, random_board_poses, render_board_view
from cvmeasure_datasets.checks import check_charuco_corners

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0, "DICT_5X5_100")
SIZE = (1152, 768)
SUBPIX = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)


def _detect(photo, board=BOARD):
    check = check_charuco_corners(photo, board)
    assert len(check.ids) > 0
    return check.detected_px, check.ids


@pytest.fixture(scope="module")
def calibration_views():
    cam = default_camera(SIZE)
    poses = random_board_poses(12, seed=3, board=BOARD, camera=cam)
    return cam, [
        render_board_view(board=BOARD, camera=cam, pose=p, lighting=Lighting.clean(), seed=i)
        for i, p in enumerate(poses)
    ]


def test_detected_charuco_corners_agree_with_the_truth(calibration_views):
    _, views = calibration_views
    errors = []
    for photo in views:
        found, ids = _detect(photo)
        truth = np.asarray(photo.truth["corners_px"])[ids]
        assert len(ids) >= 0.6 * BOARD.corner_count  # small, tilted markers may be missed
        errors.append(np.linalg.norm(found - truth, axis=1))
    err = np.concatenate(errors)
    print(f"corner error median {np.median(err):.4f} px, p95 {np.percentile(err, 95):.4f} px")
    assert np.median(err) < 0.05, np.median(err)
    assert np.percentile(err, 95) < 0.15
    # unbiased: the mean error vector is a small fraction of the spread
    mean_vec = np.mean(np.concatenate([e[:, None] for e in errors]), axis=0)
    assert np.all(np.abs(mean_vec) < 0.1)


def test_calibration_recovers_the_renderers_lens(calibration_views):
    cam, views = calibration_views
    obj, img = [], []
    corners_mm = BOARD.corners_mm().astype(np.float32)
    for photo in views:
        found, ids = _detect(photo)
        obj.append(corners_mm[ids])
        img.append(found.astype(np.float32))
    rms, k, dist, _, _ = cv2.calibrateCamera(obj, img, SIZE, None, None)
    print(
        f"rms {rms:.4f} f {k[0, 0]:.3f} {k[1, 1]:.3f} true {cam.fx} pp {k[0, 2]:.2f} {k[1, 2]:.2f}"
    )
    assert rms < 0.1
    f_true = cam.fx
    assert abs(k[0, 0] / f_true - 1) < 1e-3 and abs(k[1, 1] / f_true - 1) < 1e-3
    cx, cy = cam.principal_point_px
    assert np.hypot(k[0, 2] - cx, k[1, 2] - cy) < 3.0
    # the distortion the lens really has: a corner ray lands where the truth says
    corner = np.array([[0.25, 0.17, 1.0]])
    true_px = cam.project(corner)
    est_px, _ = cv2.projectPoints(corner, np.zeros(3), np.zeros(3), k, dist)
    assert np.linalg.norm(true_px - est_px.reshape(-1, 2)) < 1.0


def test_random_board_poses_keep_the_board_in_view_and_vary():
    poses = random_board_poses(15, seed=5)
    assert len(poses) == 15 and poses == random_board_poses(15, seed=5)
    tilts = np.array([p.tilt_deg for p in poses])
    assert tilts[0] < 5 and np.all(tilts[1:] >= 15)
    directions = np.array([p.tilt_direction_deg for p in poses[1:]]) % 360
    assert np.ptp(directions) > 270  # tilted towards all sides


def test_chessboard_view_corners_in_opencv_order():
    board = ChessboardSpec(9, 6, 25.0)
    photo = render_board_view(
        board=board,
        pose=Pose(
            tilt_deg=20.0,
            tilt_direction_deg=30.0,
            yaw_deg=8.0,
            distance_mm=800.0,
            offset_mm=(125, 87.5),
        ),
        lighting=Lighting.clean(),
        scale=0.25,
    )
    gray = cv2.cvtColor(photo.bgr, cv2.COLOR_BGR2GRAY)
    ok, corners = cv2.findChessboardCorners(gray, (9, 6))
    assert ok
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), SUBPIX).reshape(-1, 2)
    truth = np.asarray(photo.truth["corners_px"])
    err = np.linalg.norm(corners - truth, axis=1)
    if np.median(err) > 5:  # OpenCV may start from the opposite corner
        err = np.linalg.norm(corners[::-1] - truth, axis=1)
    assert np.median(err) < 0.08 and err.max() < 0.25


def test_board_truth_fields():
    photo = render_board_view(board=BOARD, scale=0.125, lighting=Lighting.clean())
    t = photo.truth
    assert t["kind"] == "board_view" and t["board"] == BOARD.to_dict()
    assert len(t["corners_px"]) == BOARD.corner_count and all(t["corners_in_image"])
    assert t["camera"]["image_size"] == [576, 384]


def test_anti_aliased_render_equals_a_supersampled_render():
    """The analytic box filter gives the same corners as a 4 x 4 supersampled render."""
    pose = random_board_poses(3, seed=8)[2]
    bare = Lighting.clean(blur_px=0.0)
    small = render_board_view(board=BOARD, pose=pose, lighting=bare, scale=0.125, linear=True)
    big = render_board_view(board=BOARD, pose=pose, lighting=bare, scale=0.5, linear=True)
    a = small.linear_rgb16.astype(np.float32).mean(axis=2) / 65535
    b = big.linear_rgb16.astype(np.float32).mean(axis=2) / 65535
    b = cv2.resize(b, a.shape[::-1], interpolation=cv2.INTER_AREA)  # box filter, centres kept
    assert np.sqrt(np.mean((a - b) ** 2)) < 3e-3
    truth = np.asarray(small.truth["corners_px"], dtype=np.float32).reshape(-1, 1, 2)
    found = [
        cv2.cornerSubPix(cv2.GaussianBlur(img, (0, 0), 0.6), truth + 0.2, (4, 4), (-1, -1), SUBPIX)
        for img in (a, b)
    ]
    diff = np.linalg.norm(found[0] - found[1], axis=2).ravel()
    assert np.median(diff) < 0.01 and diff.max() < 0.05


def test_legacy_charuco_board_renders_the_old_pattern():
    """OpenCV < 4.6 boards with an even number of rows start with a white square."""
    legacy = CharucoBoardSpec(6, 4, 30.0, 22.0, "DICT_4X4_50", legacy_pattern=True)
    photo = render_board_view(board=legacy, lighting=Lighting.clean(), scale=0.25)
    check = check_charuco_corners(photo, legacy)
    assert len(check.ids) == legacy.corner_count
    assert np.median(check.errors_px) < 0.08
    # the outer top-left square is white on the legacy board, black on the new one
    modern = render_board_view(
        board=CharucoBoardSpec(6, 4, 30.0, 22.0, "DICT_4X4_50"),
        lighting=Lighting.clean(),
        scale=0.25,
    )
    x, y = np.round(np.asarray(photo.truth["corners_px"][0]) - [5, 5]).astype(int)
    assert photo.bgr[y, x].mean() > 150 > modern.bgr[y, x].mean()
