"""The affine plane check: tilt, direction, scale, verdict, mapping and rectification."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _calib_synth import look_at_pose, render_view

from cvmeasure.errors import InputError
from cvmeasure.lens.detect import detect_board
from cvmeasure.lens.plane import (
    estimate_plane,
    fit_plane,
    rectify_image,
    worst_angle_error_deg,
)

TILT_ATOL_DEG = 0.15  # the test renderer's corners scatter ~0.06 px at 960x640
MAP_ATOL_MM = 0.1


@pytest.mark.parametrize(
    ("tilt_x", "tilt_y", "direction"),
    [(10.0, 0.0, -90.0), (-8.0, 0.0, 90.0), (0.0, 12.0, 180.0), (0.0, -6.0, 0.0)],
)
def test_tilt_and_direction_recovered(charuco_board, true_camera, tilt_x, tilt_y, direction):
    rvec, tvec = look_at_pose(charuco_board, 400.0, tilt_x, tilt_y)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    plane = estimate_plane(img, charuco_board, true_camera)
    assert plane.tilt_deg == pytest.approx(abs(tilt_x) + abs(tilt_y), abs=TILT_ATOL_DEG)
    # Direction in which the plane recedes, CCW from +x as seen in the photo.
    err = (plane.tilt_direction_deg - direction + 180.0) % 360.0 - 180.0
    assert abs(err) < 2.0
    assert not plane.affine_ok  # 6-12 degrees is far beyond 0.05 deg of angle error
    assert plane.worst_angle_error_deg > 0.5


def test_fronto_parallel_is_affine(charuco_board, true_camera):
    rvec, tvec = look_at_pose(charuco_board, 400.0, 0.0, 0.0, roll_deg=17.0)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    plane = estimate_plane(img, charuco_board, true_camera, tolerance_deg=0.05)
    assert plane.tilt_deg < TILT_ATOL_DEG
    assert plane.worst_angle_error_deg < 0.05
    assert plane.affine_ok
    # Scale: 900 px focal at 400 mm -> 400/900 mm per px.
    assert plane.mm_per_px == pytest.approx(400.0 / 900.0, rel=2e-3)


def test_image_to_plane_maps_corners_to_board_mm(charuco_board, true_camera):
    rvec, tvec = look_at_pose(charuco_board, 380.0, 25.0, -15.0, (10.0, -5.0), 30.0)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    det = detect_board(img, charuco_board)
    plane = fit_plane(det, true_camera)
    mm = plane.image_to_plane_mm(det.corners_px)
    assert np.max(np.abs(mm - det.object_mm[:, :2])) < MAP_ATOL_MM
    back = plane.plane_to_image_px(det.object_mm[:, :2])
    assert np.sqrt(np.mean(np.sum((back - det.corners_px) ** 2, axis=1))) < 0.15
    d = plane.to_dict()
    assert d["affine_ok"] is False and len(d["H_board_image"]) == 3
    assert d["lens_uncertainty_mm"] == {"sigma_mm": None, "cross_validation_mm": None}
    from cvmeasure.camera_model import CameraModel

    cal = {
        "projection_uncertainty": {"median_px": 0.1},
        "cross_validation": {"central_60pct_rms_px": 0.5},
    }
    cam2 = CameraModel(
        true_camera.image_size_px, true_camera.camera_matrix, true_camera.dist_coeffs, cal
    )
    lens = fit_plane(det, cam2).lens_uncertainty_mm()
    assert lens["sigma_mm"] == pytest.approx(0.1 * plane.mm_per_px)
    assert lens["cross_validation_mm"] == pytest.approx(0.5 * plane.mm_per_px)
    # a photo resized to half (a reduced JPEG, a half-size RAW) states the same in mm: its
    # plane is the photo's rescaled, and the camera's figures go with it in its pixels
    w, h = true_camera.image_size_px
    half = fit_plane(det, cam2).for_image((w // 2, h // 2))
    assert half.mm_per_px == pytest.approx(2.0 * plane.mm_per_px)
    assert half.lens_uncertainty_mm() == pytest.approx(lens)


def test_plane_to_image_px_of_raised_points_inverts_image_to_plane(charuco_board, true_camera):
    rvec, tvec = look_at_pose(charuco_board, 380.0, 25.0, -15.0, (10.0, -5.0), 30.0)
    det = detect_board(render_view(charuco_board, true_camera, rvec, tvec), charuco_board)
    plane = fit_plane(det, true_camera)
    xy = det.object_mm[:, :2]
    flat = plane.plane_to_image_px(xy)
    np.testing.assert_array_equal(
        plane.plane_to_image_px(np.column_stack((xy, 0 * xy[:, 0]))), flat
    )
    height_mm = 12.0  # above the board: board z points away from the camera
    raised = plane.plane_to_image_px(np.column_stack((xy, np.full(len(xy), -height_mm))))
    assert np.min(np.hypot(*(raised - flat).T)) > 1.0  # the height moves every point
    back = plane.image_to_plane_mm(raised, height_mm=height_mm)
    assert np.max(np.abs(back - xy)) < 1e-6  # the ray intersection undoes the projection
    # (N, 2) points at a height: the same pixels as their (N, 3) form
    np.testing.assert_allclose(plane.plane_to_image_px(xy, height_mm=height_mm), raised, atol=1e-9)
    with pytest.raises(ValueError, match="height_mm"):
        plane.plane_to_image_px(np.column_stack((xy, 0 * xy[:, 0])), height_mm=1.0)


def test_worst_angle_error_of_known_maps():
    pts = np.column_stack(
        [g.ravel() for g in np.meshgrid(np.linspace(0, 600, 7), np.linspace(0, 400, 5))]
    )
    c, s = np.cos(0.3), np.sin(0.3)
    similarity = np.array([[0.5 * c, -0.5 * s, 3.0], [0.5 * s, 0.5 * c, -2.0], [0, 0, 1]])
    worst, scale, rot = worst_angle_error_deg(similarity, pts)
    assert worst < 1e-9
    assert scale == pytest.approx(0.5)
    assert rot == pytest.approx(np.degrees(0.3))
    # Foreshortening by 0.99 along y: worst direction error is atan-based, ~ (1 - 0.99) / 2 rad.
    aniso = np.diag([1.0, 0.99, 1.0])
    phi = np.linspace(0, np.pi, 100001)
    expected = np.degrees(np.max(np.abs(np.arctan2(0.99 * np.sin(phi), np.cos(phi)) - phi)))
    worst, _, _ = worst_angle_error_deg(aniso, pts, n_dirs=720)
    assert worst == pytest.approx(expected, abs=0.01)


def test_rectified_image_is_in_board_mm(charuco_board, true_camera):
    rvec, tvec = look_at_pose(charuco_board, 380.0, 20.0, 10.0, (0.0, 0.0), 12.0)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    plane = estimate_plane(img, charuco_board, true_camera)
    px_per_mm = 3.0
    rect = rectify_image(img, plane, px_per_mm=px_per_mm, region_mm=(-10.0, -10.0, 210.0, 150.0))
    assert rect.shape == (480, 660)
    det = detect_board(rect, charuco_board)
    assert det.ok
    expected = (det.object_mm[:, :2] + 10.0) * px_per_mm  # pixel centre (0, 0) = (x0, y0)
    err = det.corners_px - expected
    assert np.sqrt(np.mean(np.sum(err**2, axis=1))) < 0.3


def test_bad_inputs_raise_input_error(charuco_board, true_camera):
    blank = np.full((640, 960), 255, np.uint8)
    with pytest.raises(InputError, match="blank.png: no ChArUco board"):
        estimate_plane(blank, charuco_board, true_camera, source="blank.png")
    rvec, tvec = look_at_pose(charuco_board, 400.0, 5.0, 0.0)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    small = cv2.resize(img, (480, 480))  # another aspect: not the same camera
    with pytest.raises(InputError, match="other aspect"):
        estimate_plane(small, charuco_board, true_camera, source="small.png")


def test_real_near_frontal_frames(shared_real):
    """SimpleSLAM frames whose tilt the data README gives (2.8, 3.2, 3.5 deg)."""
    from cvmeasure.board import ChessboardSpec
    from cvmeasure.lens.solve import calibrate_views

    folder = shared_real / "opencv-contrib-simpleslam-chessboard-9x6" / "images"
    board = ChessboardSpec(9, 6, 20.0)
    files = sorted(folder.glob("*.png"))
    dets = [
        detect_board(cv2.imread(str(f), cv2.IMREAD_GRAYSCALE), board, source=f.name) for f in files
    ]
    camera = calibrate_views(dets, dets[0].image_size_px).camera
    expected = {"frame-0045.png": 2.8, "frame-0048.png": 3.2, "frame-0009.png": 3.5}
    for name, tilt in expected.items():
        gray = cv2.imread(str(folder / name), cv2.IMREAD_GRAYSCALE)
        plane = estimate_plane(gray, board, camera, source=name)
        assert plane.tilt_deg == pytest.approx(tilt, abs=0.4), name
        assert not plane.affine_ok


def test_plane_model_saves_and_loads_whole(tmp_path, charuco_board, true_camera):
    from cvmeasure.camera_model import CameraModel
    from cvmeasure.contracts import PlaneModel

    rvec, tvec = look_at_pose(charuco_board, 380.0, 12.0, -7.0, (10.0, -5.0), 30.0)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    plane = estimate_plane(img, charuco_board, true_camera, source="board.png")
    path = plane.save(tmp_path / "plane.json")
    back = PlaneModel.load(path)  # no camera needed: the plane carries its own
    pts = np.array([[100.0, 80.0], [480.0, 320.0], [900.0, 600.0]])
    np.testing.assert_allclose(back.image_to_plane_mm(pts), plane.image_to_plane_mm(pts), atol=1e-9)
    np.testing.assert_allclose(back.plane_to_image_px(pts), plane.plane_to_image_px(pts), atol=1e-9)
    assert back.camera.same_lens(true_camera) and back.tilt_deg == plane.tilt_deg
    assert back.corner_count == plane.corner_count and back.source == "board.png"
    assert PlaneModel.load(path, camera=true_camera).camera.same_lens(true_camera)
    other = CameraModel.ideal(true_camera.image_size_px, focal_px=true_camera.fx * 1.01)
    with pytest.raises(InputError, match="another camera model"):
        PlaneModel.load(path, camera=other)


def test_plane_model_rescales_with_the_photo(charuco_board, true_camera):
    rvec, tvec = look_at_pose(charuco_board, 400.0, 9.0, 4.0)
    img = render_view(charuco_board, true_camera, rvec, tvec)
    plane = estimate_plane(img, charuco_board, true_camera)
    w, h = true_camera.image_size_px
    half = plane.for_image((w // 2, h // 2), "half.jpg")
    assert half.camera.image_size_px == (w // 2, h // 2)
    pts = np.array([[50.5, 40.5], [480.5, 320.5], [900.5, 600.5]])  # full-size pixel centres
    pts_half = (pts + 0.5) / 2.0 - 0.5  # the same points in the half-size photo
    np.testing.assert_allclose(
        half.image_to_plane_mm(pts_half), plane.image_to_plane_mm(pts), atol=1e-9
    )
    assert half.mm_per_px == pytest.approx(2 * plane.mm_per_px)
    assert plane.for_image((w, h)) is plane
    with pytest.raises(InputError, match="other aspect"):
        plane.for_image((w, w), "square.jpg")
    # a photo reduced by half is measured on the plane rescaled, not refused
    small = cv2.resize(img, (w // 2, h // 2), interpolation=cv2.INTER_AREA)
    again = estimate_plane(small, charuco_board, true_camera)
    assert again.tilt_deg == pytest.approx(plane.tilt_deg, abs=TILT_ATOL_DEG)


def test_plane_json_bad_files_are_named(tmp_path, true_camera):
    import json

    from cvmeasure.contracts import PlaneModel

    h = np.array([[0.1, 0.002, -3.0], [-0.001, 0.1, 4.0], [1e-6, 2e-6, 1.0]])
    legacy = tmp_path / "legacy.json"  # written before planes carried their camera
    legacy.write_text(json.dumps({"H_board_image": h.tolist(), "tilt_deg": 1.0}))
    np.testing.assert_allclose(PlaneModel.load(legacy, camera=true_camera).H_board_image, h)
    with pytest.raises(InputError, match="legacy.json: plane JSON has no camera"):
        PlaneModel.load(legacy)
    for name, payload, message in [
        ("missing.json", None, "not found"),
        ("corrupt.json", "{", "corrupt plane JSON"),
        ("nomatrix.json", '{"tilt_deg": 1}', "lacks a 3x3"),
        ("singular.json", json.dumps({"H_board_image": np.zeros((3, 3)).tolist()}), "invertible"),
    ]:
        path = tmp_path / name
        if payload is not None:
            path.write_text(payload)
        with pytest.raises(InputError, match=message) as info:
            PlaneModel.load(path, camera=true_camera)
        assert name in str(info.value)
