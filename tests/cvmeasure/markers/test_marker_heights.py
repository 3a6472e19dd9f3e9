"""Markers at their heights above the plate (issue 14): through a plane pose, and without one.

Photos: :mod:`cvmeasure_datasets.discs3d` (each disc a 3D circle at its kit height,
projected forwards through the lens: no geometry code shared with the measurement,
which intersects pixel rays with height planes).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from cvmeasure.contracts import PlaneModel
from cvmeasure.kit import ROLES, default_kit
from cvmeasure.markers import measure_machine_photo
from cvmeasure.markers.heights import height_parallax
from cvmeasure.warning import codes, has_code

pytest.importorskip("cvmeasure_datasets.discs3d")

from cvmeasure_datasets import Pose, default_camera  # noqa: E402
from cvmeasure_datasets.discs3d import DiscScene, render_discs_at_heights  # noqa: E402

SCALE = 1 / 3  # 1536 x 1024 px; discs 8-10 mm are 17-21 px in radius at 550 mm
#: Angle tolerance at this scale (a third of the seed camera's resolution), deg.
TOL_DEG = 0.03
SQUARE = Pose(distance_mm=550.0, offset_mm=(-10.0, 0.0))
TILTED = Pose(distance_mm=520.0, offset_mm=(20.0, 30.0), yaw_deg=40.0, tilt_deg=8.0,
              tilt_direction_deg=120.0)  # fmt: skip


def _camera():
    return default_camera().scaled(SCALE)


@functools.cache
def _photo(pin, bend, pose, seed=0, flat=False):
    return render_discs_at_heights(
        DiscScene(pin, bend, pose=pose, flat=flat), camera=_camera(), seed=seed
    )


def true_plane(camera, pose) -> PlaneModel:
    """The plate's plane from the renderer's own pose, in a board frame (z away from the camera)."""
    rot, t_mm = pose.extrinsics("machine")
    rot_b = rot @ np.diag([1.0, -1.0, -1.0])  # board (x, y, z) = machine (x, -y, -z)
    h = camera.camera_matrix @ np.column_stack((rot_b[:, 0], rot_b[:, 1], t_mm))
    nan = float("nan")
    return PlaneModel(
        camera, np.linalg.inv(h), cv2.Rodrigues(rot_b)[0], t_mm, nan, nan, nan, nan, nan, nan, 0
    )


def _err(res, truth):
    return (
        res.pin_angle_deg - truth["pin_angle_deg"],
        res.bend_angle_deg - truth["bend_angle_deg"],
    )


@pytest.mark.parametrize("pose", [SQUARE, TILTED], ids=["square", "tilted"])
def test_heights_applied_through_the_plane_pose(pose):
    bgr, truth = _photo(-60.0, -50.0, pose)
    plane = true_plane(_camera(), pose)
    res = measure_machine_photo(bgr, default_kit(), plane=plane)
    assert res.heights == "plane"
    # nominal heights: what caps 10 % off them could do is bounded beside the sigma
    assert has_code(res.warnings, "heights_nominal") and res.height_bound_deg["pin_angle_deg"] > 0
    stated = replace(
        default_kit(),
        markers=tuple(replace(m, height_sigma_mm=0.2) for m in default_kit().markers),
    )
    known = measure_machine_photo(bgr, stated, plane=plane)
    assert known.height_bound_deg is None and not has_code(known.warnings, "heights_nominal")
    assert known.uncertainty_deg["pin_angle_deg"] > res.uncertainty_deg["pin_angle_deg"]
    # heights stated exact (height_sigma_mm 0): neither a bound nor a heights share
    exact = replace(
        default_kit(),
        markers=tuple(replace(m, height_sigma_mm=0.0) for m in default_kit().markers),
    )
    assert exact.heights_stated and not default_kit().heights_stated
    got = measure_machine_photo(bgr, exact, plane=plane)
    assert got.height_bound_deg is None and not has_code(got.warnings, "heights_nominal")
    assert got.uncertainty_deg == res.uncertainty_deg
    pin_err, bend_err = _err(res, truth)
    assert abs(pin_err) < TOL_DEG and abs(bend_err) < TOL_DEG, (pin_err, bend_err)
    # each disc measured at its own height has the kit's size and is round on the plate
    assert not codes(res.warnings) & {"plane_scale", "plane_tilt", "kit_heights_mismatch"}
    # the same photo measured flat: the pin (6 mm above the origin disc) is off, and said so
    flat = measure_machine_photo(bgr, default_kit().flat(), plane=plane)
    assert flat.heights == "flat"
    assert abs(_err(flat, truth)[0]) > 0.1
    (said,) = [w for w in flat.warnings if w.code == "kit_heights_mismatch"]
    assert "stand at heights" in said.message and "height_mm" in said.message


def test_a_plane_json_without_its_pose_gets_it_from_the_homography():
    bgr, truth = _photo(-60.0, -50.0, TILTED)
    plane = true_plane(_camera(), TILTED)
    d = plane.to_dict()
    del d["rvec"], d["tvec_mm"]  # a plane JSON written before the pose was saved
    old = PlaneModel.from_dict(d)
    pts = np.array([[300.0, 200.0], [900.0, 700.0]])
    np.testing.assert_allclose(
        old.image_to_plane_mm(pts, height_mm=18.0),
        plane.image_to_plane_mm(pts, height_mm=18.0),
        atol=1e-6,
    )
    res = measure_machine_photo(bgr, default_kit(), plane=old)
    assert max(abs(e) for e in _err(res, truth)) < TOL_DEG


def test_a_flat_scene_measured_flat_agrees():
    bgr, truth = _photo(35.0, 30.0, TILTED, flat=True)
    res = measure_machine_photo(bgr, default_kit().flat(), plane=true_plane(_camera(), TILTED))
    assert max(abs(e) for e in _err(res, truth)) < TOL_DEG


@pytest.mark.parametrize("pose", [SQUARE, TILTED], ids=["square", "tilted"])
def test_without_a_pose_the_bound_holds_the_error(pose):
    bgr, truth = _photo(-60.0, -50.0, pose)
    camera = _camera()
    res = measure_machine_photo(bgr, default_kit(), camera=camera)
    assert res.heights == "none"
    said = [w for w in res.warnings if w.code == "heights_not_applied"]
    assert said and "height_bound_deg" in said[0].message
    pin_err, bend_err = _err(res, truth)
    assert abs(pin_err) > 0.1  # the heights matter: origin 12 mm, pin 18 mm
    assert abs(pin_err) <= res.height_bound_deg["pin_angle_deg"]
    # wire_a and wire_b share a height, axis and origin too: the bend is unaffected
    assert res.height_bound_deg["bend_angle_deg"] < 1e-6
    if pose.tilt_deg == 0:
        assert abs(bend_err) < TOL_DEG
    # image pixels only (no focal length): a conservative bound, still holding the error
    raw = measure_machine_photo(bgr, default_kit())
    assert raw.height_bound_deg["pin_angle_deg"] >= res.height_bound_deg["pin_angle_deg"]
    assert abs(_err(raw, truth)[0]) <= raw.height_bound_deg["pin_angle_deg"]


def test_parallel_correction_on_a_square_camera():
    bgr, truth = _photo(-60.0, -50.0, SQUARE)
    res = measure_machine_photo(bgr, default_kit(), camera=_camera(), heights="parallel")
    assert res.heights == "parallel"
    assert has_code(res.warnings, "heights_parallel")
    pin_err, bend_err = _err(res, truth)
    assert abs(pin_err) < TOL_DEG and abs(bend_err) < TOL_DEG
    assert abs(pin_err) <= res.height_bound_deg["pin_angle_deg"]
    with pytest.raises(ValueError, match="needs a camera"):
        measure_machine_photo(bgr, default_kit(), heights="parallel")


def test_height_parallax_is_the_homothety_about_the_foot_point():
    """Exact pinhole numbers: a camera square to the plate, 500 mm above it, f 4000 px."""
    kit = default_kit()
    f, d_mm, pp = 4000.0, 500.0, np.array([800.0, 500.0])
    plate = {r: np.array(v) for r, v in
             {"origin": (0, 0), "axis": (-70, 0), "pin": (10, 15), "wire_a": (30, 20),
              "wire_b": (60, 45)}.items()}  # fmt: skip
    seen, radii = {}, {}
    for r in ROLES:
        z = d_mm - kit.height_mm(r)
        seen[r] = pp + f * plate[r] / z
        radii[r] = f * kit.by_role(r).diameter_mm / 2 / z
    par = height_parallax(
        seen, {r: np.eye(2) for r in ROLES}, radii, kit, focal_px=f, principal_point_px=pp
    )
    assert par.distance_mm == pytest.approx(d_mm, rel=1e-9)
    for r in ROLES:
        np.testing.assert_allclose(par.centres[r], pp + f * plate[r] / d_mm, atol=1e-9)
    # the bound of the uncorrected angles holds their error; the corrected ones have none
    from cvmeasure.markers.angles import machine_angles

    raw = machine_angles(seen)
    true = machine_angles({r: pp + f * plate[r] / d_mm for r in ROLES})
    err = abs(raw.pin_angle_deg - true.pin_angle_deg)
    assert 0 < err <= par.bound_none_deg["pin_angle_deg"]
    # a foot point off by f tan(3 deg) moves a disc 6 mm higher by 6/500 of ~200 px
    assert par.bound_parallel_deg["pin_angle_deg"] == pytest.approx(
        math.degrees(6 / 500 * f * math.tan(math.radians(3)) / (f * 18 / 500)), rel=0.35
    )


def test_cli_heights_parallel_and_the_record(tmp_path, capsys):
    from cvmeasure.camera_model import save_camera
    from cvmeasure.cli import main
    from cvmeasure.contracts import MachinePhotoResult

    bgr, truth = _photo(-60.0, -50.0, SQUARE)
    photo = tmp_path / "square.png"
    cv2.imwrite(str(photo), bgr)
    camera = save_camera(tmp_path / "camera.json", _camera())
    assert main(["measure", str(photo), "--heights", "parallel", "--json"]) == 2
    assert "--heights parallel" in capsys.readouterr().err
    argv = ["measure", str(photo), "--camera", str(camera), "--json"]
    assert main([*argv, "--heights", "parallel"]) == 0
    rec = json.loads(capsys.readouterr().out.splitlines()[0])
    assert rec["heights"] == "parallel"
    assert abs(rec["pin_angle_deg"] - truth["pin_angle_deg"]) < TOL_DEG
    back = MachinePhotoResult.from_dict(rec)
    assert back.heights == "parallel" and back.height_bound_deg == rec["height_bound_deg"]


def test_stated_uncertainty_holds_at_heights():
    """Random poses (500-600 mm, tilted 0-8 deg, die up to 40 mm off axis), heights applied."""
    kit, camera = default_kit(), _camera()
    z, errs = [], []
    for i in range(8):
        rng = np.random.default_rng([14, i])
        pin = float(rng.uniform(-110, 110))
        bend = float(np.clip(pin * rng.uniform(0.8, 0.95), -100, 100))
        pose = Pose(
            yaw_deg=float(rng.uniform(-180, 180)),
            tilt_deg=float(rng.uniform(0, 8)),
            tilt_direction_deg=float(rng.uniform(0, 360)),
            distance_mm=float(rng.uniform(500, 600)),
            offset_mm=(float(rng.uniform(-40, 10)), float(rng.uniform(-20, 20))),
        )
        bgr, truth = render_discs_at_heights(DiscScene(pin, bend, pose=pose), camera=camera, seed=i)
        res = measure_machine_photo(bgr, kit, plane=true_plane(camera, pose))
        for key in ("pin_angle_deg", "bend_angle_deg"):
            err = getattr(res, key) - truth[key]
            errs.append(err)
            z.append(abs(err) / res.uncertainty_deg[key])
    assert np.percentile(np.abs(errs), 95) < TOL_DEG
    assert np.mean(np.asarray(z) < 2.0) >= 0.9 and max(z) < 3.0, z
