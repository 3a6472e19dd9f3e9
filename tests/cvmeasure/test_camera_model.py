import json

import numpy as np
import pytest

from cvmeasure.camera_model import CameraModel, load_camera, save_camera
from cvmeasure.errors import InputError


def _cam():
    return CameraModel.ideal((4608, 3072), 6000.0, dist_coeffs=(-0.12, 0.08, 0.0004, -0.0003, 0.0))


def test_roundtrip_keeps_calibration_record(tmp_path):
    cam = CameraModel(
        _cam().image_size_px, _cam().camera_matrix, _cam().dist_coeffs, {"rms_px": 0.2}
    )
    path = save_camera(tmp_path / "camera.json", cam)
    back = load_camera(path)
    np.testing.assert_array_equal(back.camera_matrix, cam.camera_matrix)
    np.testing.assert_array_equal(back.dist_coeffs, cam.dist_coeffs)
    assert back.lens_record == {"rms_px": 0.2}
    assert json.loads(path.read_text())["image_size"] == [4608, 3072]


def test_project_then_undistort_recovers_ideal_pixels():
    cam = _cam()
    rng = np.random.default_rng(1)
    pts = np.column_stack(
        (rng.uniform(-200, 200, 50), rng.uniform(-130, 130, 50), np.full(50, 500.0))
    )
    distorted = cam.project(pts)
    ideal = pts[:, :2] / pts[:, 2:] * 6000.0 + np.array(cam.principal_point_px)
    np.testing.assert_allclose(cam.undistort_px(distorted), ideal, atol=1e-6)
    np.testing.assert_allclose(cam.normalized(distorted), pts[:, :2] / pts[:, 2:], atol=1e-9)


def test_scaled_keeps_pixel_centre_convention():
    cam = _cam().scaled(0.5)
    assert cam.image_size_px == (2304, 1536)
    # pixel-centre convention: continuous coordinate u+0.5 scales by the factor
    assert cam.principal_point_px[0] == pytest.approx((4607 / 2 + 0.5) * 0.5 - 0.5)
    assert cam.fx == pytest.approx(3000.0)


def test_scaled_carries_the_lens_uncertainty_in_its_own_pixels():
    record = {
        "rms_px": 0.2,
        "projection_uncertainty": {"median_px": 0.12, "p95_px": 0.3},
        "cross_validation": {"central_60pct_rms_px": 0.4},
    }
    cam = CameraModel(_cam().image_size_px, _cam().camera_matrix, _cam().dist_coeffs, record)
    half = cam.scaled(0.5)
    assert half.lens_record == {
        "projection_uncertainty": {"median_px": pytest.approx(0.06)},
        "cross_validation": {"central_60pct_rms_px": pytest.approx(0.2)},
    }
    assert _cam().scaled(0.5).lens_record == {}  # nothing stated, nothing made up


@pytest.mark.parametrize(
    "payload, message",
    [
        ("[]", "must be an object"),
        ('{"image_size": [10, 10]}', "lacks 'camera_matrix'"),
        ('{"image_size": [10, 10], "camera_matrix": [[1, 0], [0, 1]]}', "3x3"),
        (
            '{"image_size": [10, 10], "camera_matrix": [[1,0,0],[0,1,0],[0,0,1]], "dist_coeffs": [1,2,3]}',
            "dist_coeffs",
        ),
    ],
)
def test_schema_errors_name_the_file(tmp_path, payload, message):
    p = tmp_path / "bad.json"
    p.write_text(payload)
    with pytest.raises(InputError, match=message) as info:
        load_camera(p)
    assert str(p) in str(info.value)
