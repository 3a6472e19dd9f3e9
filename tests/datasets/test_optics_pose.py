"""Camera, pose and the pixel -> plane trace of the photo lab."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvmeasure_datasets import Pose, default_camera
from cvmeasure_datasets.optics import plane_coords_mm, project_frame_points


def test_default_camera_is_the_seed_camera():
    cam = default_camera()
    assert cam.image_size_px == (4608, 3072)
    assert cam.fx == pytest.approx(7000.0) and cam.fy == pytest.approx(7000.0)
    small = default_camera((1152, 768))
    assert small.image_size_px == (1152, 768)
    assert small.fx == pytest.approx(1750.0)
    # barrel distortion: a corner ray lands closer to the centre than the pinhole image
    corner = cam.project(np.array([[2304 / 7000, 1536 / 7000, 1.0]]))[0]
    cx, cy = cam.principal_point_px
    assert 20.0 < np.hypot(2304, 1536) - np.hypot(corner[0] - cx, corner[1] - cy) < 60.0
    with pytest.raises(ValueError, match="aspect"):
        default_camera((1000, 1000))


@pytest.mark.parametrize("yaw_deg", [0.0, 30.0, -75.0])
def test_machine_frame_is_not_mirrored_and_yaw_turns_ccw(yaw_deg):
    cam = default_camera((1152, 768))
    rot, t = Pose(yaw_deg=yaw_deg, distance_mm=800.0).extrinsics("machine")
    o, px, py = project_frame_points(cam, rot, t, np.array([[0, 0], [10, 0], [0, 10]]))
    # image y points down: negate it to get counter-clockwise-as-seen angles
    ang_x = np.degrees(np.arctan2(-(px - o)[1], (px - o)[0]))
    ang_y = np.degrees(np.arctan2(-(py - o)[1], (py - o)[0]))
    assert ang_x == pytest.approx(yaw_deg, abs=0.05)  # small: distortion off-axis
    assert (ang_y - ang_x) % 360 == pytest.approx(90.0, abs=0.05)


def test_board_frame_appears_x_right_y_down():
    cam = default_camera((1152, 768))
    rot, t = Pose(distance_mm=800.0, offset_mm=(100.0, 50.0)).extrinsics("board")
    o, px, py = project_frame_points(cam, rot, t, np.array([[100, 50], [110, 50], [100, 60]]))
    assert (px - o)[0] > 10 and abs((px - o)[1]) < 0.05
    assert (py - o)[1] > 10 and abs((py - o)[0]) < 0.05


@pytest.mark.parametrize("frame", ["board", "machine"])
def test_tilt_places_the_camera_where_the_pose_says(frame):
    pose = Pose(tilt_deg=30.0, tilt_direction_deg=120.0, distance_mm=600.0, offset_mm=(5.0, -7.0))
    rot, t = pose.extrinsics(frame)
    assert np.allclose(rot @ rot.T, np.eye(3), atol=1e-12) and np.linalg.det(rot) > 0
    centre = -rot.T @ t
    rel = centre - np.array([5.0, -7.0, 0.0])
    assert np.linalg.norm(rel) == pytest.approx(600.0)
    assert np.degrees(np.arccos(abs(rel[2]) / 600.0)) == pytest.approx(30.0)
    assert np.degrees(np.arctan2(rel[1], rel[0])) == pytest.approx(120.0)
    # the camera sits on the side the frame's normal says (machine z up, board z down)
    assert (rel[2] > 0) == (frame == "machine")
    # and looks at the target: it projects to the principal point
    cam = default_camera((1152, 768))
    target_px = project_frame_points(cam, rot, t, np.array([[5.0, -7.0]]))[0]
    assert np.allclose(target_px, cam.principal_point_px, atol=1e-9)


def test_plane_trace_inverts_the_projection():
    cam = default_camera((1152, 768))
    pose = Pose(tilt_deg=35.0, tilt_direction_deg=-40.0, yaw_deg=12.0, distance_mm=500.0)
    rot, t = pose.extrinsics("machine")
    rng = np.random.default_rng(1)
    pts = rng.uniform(-120, 120, (200, 2))
    px = project_frame_points(cam, rot, t, pts)
    keep = (px[:, 0] > 0) & (px[:, 0] < 1151) & (px[:, 1] > 0) & (px[:, 1] < 767)
    u, v = plane_coords_mm(cam, rot, t, px[keep, 0], px[keep, 1])
    err = np.hypot(u - pts[keep, 0], v - pts[keep, 1])
    assert keep.sum() > 50 and err.max() < 1e-7


def test_pose_validates_and_round_trips():
    with pytest.raises(ValueError):
        Pose(tilt_deg=85.0)
    with pytest.raises(ValueError):
        Pose(distance_mm=0.0)
    with pytest.raises(ValueError):
        Pose().extrinsics("table")  # type: ignore[arg-type]
    pose = Pose(
        tilt_deg=10.0, tilt_direction_deg=5.0, yaw_deg=-3.0, distance_mm=700.0, offset_mm=(1, 2)
    )
    assert Pose.from_dict(pose.to_dict()) == pose


def test_render_size_by_scale_or_image_size():
    from cvmeasure_datasets import render_bender_photo
    from cvmeasure_datasets.photo import resolve_camera

    a = resolve_camera(None, 1.0, (576, 384))
    assert a.image_size_px == (576, 384) and a.fx == pytest.approx(875.0)
    assert resolve_camera(None, 0.125).camera_matrix == pytest.approx(a.camera_matrix)
    with pytest.raises(ValueError):
        resolve_camera(None, 1.0, (576, 576))
    with pytest.raises(ValueError):
        resolve_camera(None, 0.0)
    photo = render_bender_photo(pin_angle_deg=0.0, bend_angle_deg=0.0, image_size_px=(288, 192))
    assert photo.bgr.shape == (192, 288, 3)
    # straight down from 850 mm: f / z px per mm
    assert photo.truth["px_per_mm_at_origin"] == pytest.approx(437.5 / 850.0, rel=2e-3)


@settings(max_examples=40, deadline=None)
@given(
    tilt=st.floats(0.0, 60.0),
    direction=st.floats(-180.0, 180.0),
    yaw=st.floats(-180.0, 180.0),
    distance=st.floats(250.0, 1500.0),
    frame=st.sampled_from(["board", "machine"]),
    x=st.floats(-50.0, 50.0),
    y=st.floats(-50.0, 50.0),
)
def test_plane_trace_round_trip_property(tilt, direction, yaw, distance, frame, x, y):
    """Any in-view plane point projects to a pixel that traces back to it (< 1e-6 mm)."""
    cam = default_camera((1152, 768))
    rot, t = Pose(tilt, direction, yaw, distance, (x, y)).extrinsics(frame)
    pts = np.array([[x, y], [x + 15.0, y - 10.0], [x - 20.0, y + 5.0]])
    px = project_frame_points(cam, rot, t, pts)
    keep = (px[:, 0] > 0) & (px[:, 0] < 1151) & (px[:, 1] > 0) & (px[:, 1] < 767)
    u, v = plane_coords_mm(cam, rot, t, px[keep, 0], px[keep, 1])
    assert keep[0]  # the target is always in view (at the principal point)
    assert np.hypot(u - pts[keep, 0], v - pts[keep, 1]).max() < 1e-6


@pytest.mark.parametrize(
    ("tilt_direction_deg", "yaw_deg"), [(0.0, 0.0), (45.0, 3.5), (200.0, -8.0)]
)
def test_truth_gives_the_tilt_direction_plane_reports(tilt_direction_deg, yaw_deg):
    """The render's scene-frame tilt direction and the plane check's image-frame one differ;
    the truth's ``tilt_direction_image_deg`` is what ``cvmeasure plane`` measures."""
    from cvmeasure.board import DEFAULT_BOARD
    from cvmeasure.geometry import wrap_deg
    from cvmeasure.lens.plane import estimate_plane
    from cvmeasure_datasets import Lighting, render_board_view

    pose = Pose(
        tilt_deg=20.0,
        tilt_direction_deg=tilt_direction_deg,
        yaw_deg=yaw_deg,
        distance_mm=700.0,
        offset_mm=(140.0, 100.0),
    )
    view = render_board_view(
        board=DEFAULT_BOARD, pose=pose, lighting=Lighting.clean(), scale=0.25, seed=1
    )
    import cv2

    plane = estimate_plane(cv2.cvtColor(view.bgr, cv2.COLOR_BGR2GRAY), DEFAULT_BOARD, view.camera)
    expected = view.truth["pose"]["tilt_direction_image_deg"]
    assert abs(wrap_deg(plane.tilt_direction_deg - expected)) < 0.5
    assert plane.tilt_deg == pytest.approx(20.0, abs=0.1)


@pytest.mark.parametrize("frame", ["board", "machine"])
@pytest.mark.parametrize(
    "pose",
    [
        (7.0, 123.0, 33.0, 812.0, (12.0, -40.0)),
        (0.0, 0.0, -20.0, 900.0, (5.0, 5.0)),
        (25.0, 300.0, 170.0, 500.0, (0.0, 0.0)),
    ],
)
def test_pose_from_extrinsics_round_trips(frame, pose):
    from cvmeasure_datasets.optics import Pose

    rot, t_mm = Pose(*pose).extrinsics(frame)
    again = Pose.from_extrinsics(rot, t_mm, frame)
    rot2, t2 = again.extrinsics(frame)
    np.testing.assert_allclose(rot2, rot, atol=1e-9)
    np.testing.assert_allclose(t2, t_mm, atol=1e-6)
