"""Corner detection: ChArUco and chessboard, sub-pixel accuracy, every failure reason."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _calib_synth import look_at_pose, render_view

from cvmeasure.board import board_from_dict
from cvmeasure.lens.detect import detect_board, detect_charuco, subpix_half_window_px

CORNER_ATOL_PX = 0.3  # worst corner vs exact projection on the test renderer (~0.06 px RMS)


def _truth(det, camera, rvec, tvec):
    proj, _ = cv2.projectPoints(det.object_mm, rvec, tvec, camera.camera_matrix, camera.dist_coeffs)
    return proj.reshape(-1, 2)


def test_charuco_corners_match_truth(charuco_board, true_camera):
    rvec, tvec = look_at_pose(charuco_board, 380.0, 30.0, -20.0, (5.0, 5.0), 15.0)
    img = render_view(charuco_board, true_camera, rvec, tvec, noise_sigma=1.0, seed=3)
    det = detect_board(img, charuco_board, source="view.png")
    assert det.ok and det.corner_count == charuco_board.corner_count
    err = det.corners_px - _truth(det, true_camera, rvec, tvec)
    assert np.max(np.abs(err)) < CORNER_ATOL_PX
    assert np.sqrt(np.mean(err**2)) < 0.1
    assert det.legacy_pattern is False and det.notes == ()


def test_chessboard_corners_match_truth(true_camera):
    board = board_from_dict({"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_mm": 25.0})
    rvec, tvec = look_at_pose(board, 450.0, 20.0, 15.0, roll_deg=5.0)
    img = render_view(board, true_camera, rvec, tvec, noise_sigma=1.0, seed=4)
    det = detect_board(img, board)
    assert det.ok and det.corner_count == 54
    err = det.corners_px - _truth(det, true_camera, rvec, tvec)
    flipped = det.corners_px[::-1] - _truth(det, true_camera, rvec, tvec)  # 180-degree symmetry
    assert min(np.max(np.abs(err)), np.max(np.abs(flipped))) < CORNER_ATOL_PX


def test_chessboard_on_large_photo_is_searched_reduced_and_refined_full(true_camera):
    board = board_from_dict({"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_mm": 25.0})
    cam = true_camera.scaled(2.0)  # 1920x1280 > the 1600 px search size
    rvec, tvec = look_at_pose(board, 450.0, 10.0, 25.0)
    img = render_view(board, cam, rvec, tvec, supersample=1)
    det = detect_board(img, board)
    assert det.ok
    truth = _truth(det, cam, rvec, tvec)
    err = min(np.max(np.abs(det.corners_px - truth)), np.max(np.abs(det.corners_px[::-1] - truth)))
    assert err < 2 * CORNER_ATOL_PX


@pytest.mark.parametrize(
    ("spec", "reason"),
    [
        (
            {"type": "chessboard", "inner_x": 8, "inner_y": 5, "square_mm": 25.0},
            "no 8x5 chessboard",
        ),
        (
            {
                "type": "charuco",
                "squares_x": 10,
                "squares_y": 7,
                "square_mm": 20.0,
                "marker_mm": 15.0,
                "dictionary": "DICT_6X6_250",
            },
            "no ChArUco board found",
        ),
    ],
)
def test_wrong_board_gives_a_reason(charuco_board, true_camera, spec, reason):
    rvec, tvec = look_at_pose(charuco_board, 400.0, 10.0, 0.0)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    det = detect_board(img, board_from_dict(spec), source="photo.jpg")
    assert not det.ok and reason in det.reason and det.corner_count == 0


def test_too_few_corners_and_blank(charuco_board):
    blank = np.full((480, 640), 128, np.uint8)
    det = detect_board(blank, charuco_board)
    assert not det.ok and "no ChArUco board" in det.reason
    # A board cut down to a corner: only a few ChArUco corners remain.
    small = board_from_dict(
        {
            "type": "charuco",
            "squares_x": 3,
            "squares_y": 3,
            "square_mm": 20.0,
            "marker_mm": 15.0,
            "dictionary": "DICT_5X5_100",
        }
    )
    img = small.cv_board().generateImage((300, 300), marginSize=20)
    det = detect_charuco(img, small, min_corners=6)
    assert det.corner_count == 4 and not det.ok and "too few corners (4 < 6)" in det.reason


def test_subpix_window_follows_corner_spacing():
    xs, ys = np.meshgrid(np.arange(9) * 40.0, np.arange(6) * 40.0)
    grid = np.column_stack((xs.ravel(), ys.ravel()))
    assert subpix_half_window_px(grid, (9, 6)) == 6
    assert subpix_half_window_px(grid * 0.25, (9, 6)) == 2
    assert subpix_half_window_px(grid * 10, (9, 6)) == 10


def test_real_legacy_layout_is_detected_and_named(shared_real):
    folder = shared_real / "photonvision-lifecam-charuco-8x8" / "2024-06-19_lifecam_480_Old_Pattern"
    photo = sorted(folder.glob("*.jpg"))[0]
    gray = cv2.imread(str(photo), cv2.IMREAD_GRAYSCALE)
    spec = {
        "type": "charuco",
        "squares_x": 8,
        "squares_y": 8,
        "square_mm": 25.4,
        "marker_mm": 19.05,
        "dictionary": "DICT_4X4_1000",
    }
    new_layout = board_from_dict(spec)
    det = detect_board(gray, new_layout, source=photo.name)
    assert det.ok and det.legacy_pattern is True
    assert 'set "legacy_pattern": true' in det.notes[0]
    strict = detect_charuco(gray, new_layout, source=photo.name, try_other_layout=False)
    assert not strict.ok and "try legacy_pattern" in strict.reason
    legacy = detect_board(gray, board_from_dict(dict(spec, legacy_pattern=True)))
    assert legacy.ok and legacy.notes == () and legacy.corner_count == det.corner_count


def test_real_charuco_tutorial_photos(shared_real):
    folder = shared_real / "opencv-contrib-aruco-charuco-5x7"
    board = board_from_dict(
        {
            "type": "charuco",
            "squares_x": 5,
            "squares_y": 7,
            "square_mm": 40.0,
            "marker_mm": 20.0,
            "dictionary": "DICT_6X6_250",
        }
    )
    counts = [
        detect_board(cv2.imread(str(folder / f"img_0{i}.jpg")), board).corner_count
        for i in range(4)
    ]
    assert counts == [24, 24, 24, 24]  # data README: all 24 corners in every view
    occluded = detect_board(cv2.imread(str(folder / "chocclusion_original.jpg")), board)
    assert occluded.corner_count == 16


@pytest.mark.parametrize("pattern", [(4, 6), (6, 4), (3, 3)])
def test_a_charuco_photo_is_not_taken_for_a_chessboard(shared_real, pattern):
    """findChessboardCornersSB finds these grids in the real ChArUco photo (4x6: its inner
    corners, squares with markers; 3x3: corners that are not a grid): refused, saying why."""
    img = cv2.imread(str(shared_real / "opencv-contrib-aruco-charuco-5x7" / "img_00.jpg"))
    found, _ = cv2.findChessboardCornersSB(cv2.cvtColor(img, cv2.COLOR_BGR2GRAY), pattern)
    assert found  # what the check has to stop
    spec = {"type": "chessboard", "inner_x": pattern[0], "inner_y": pattern[1], "square_mm": 40.0}
    det = detect_board(img, board_from_dict(spec), source="img_00.jpg")
    assert not det.ok and "chessboard rejected: " in det.reason
    assert ("not a plain chessboard" in det.reason) == (pattern != (3, 3))


def test_real_chessboard_photos_pass_the_check(shared_real):
    """Every photo of OpenCV's left/right sets where either detector finds the 9x6 board."""
    from cvmeasure.lens.detect import verify_chessboard

    files = sorted((shared_real / "opencv-samples-chessboard-9x6").glob("*/*.jpg"))
    checked = 0
    for f in files:
        gray = cv2.imread(str(f), cv2.IMREAD_GRAYSCALE)
        for found, corners in (
            cv2.findChessboardCorners(gray, (9, 6), flags=cv2.CALIB_CB_ADAPTIVE_THRESH),
            cv2.findChessboardCornersSB(gray, (9, 6)),
        ):
            if found:
                checked += 1
                assert verify_chessboard(gray, corners.reshape(-1, 2), (9, 6)) == "", f.name
    assert checked >= 40
