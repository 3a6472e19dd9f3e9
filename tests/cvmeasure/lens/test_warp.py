"""Board warp solved with the lens (cvmeasure.lens.warp), on synthetic corners.

The warped corners are generated here from mrcal's published formula written out
independently (``z = wx 4 xr (1 - xr) + wy 4 yr (1 - yr)``), not with the module's code.
"""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from _calib_synth import random_poses

from cvmeasure.board import ChessboardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.lens.detect import BoardDetection
from cvmeasure.lens.pipeline import calibrate_detections
from cvmeasure.lens.solve import calibrate_views
from cvmeasure.lens.uncertainty import parameter_covariance
from cvmeasure.lens.warp import warp_test

BOARD = ChessboardSpec(inner_x=9, inner_y=6, square_mm=25.0)
CAMERA = CameraModel(
    (1280, 960),
    np.array([[1000.0, 0.0, 645.0], [0.0, 1002.0, 478.0], [0.0, 0.0, 1.0]]),
    np.array([-0.2, 0.08, 1e-4, -2e-4, -0.01]),
)
NOISE_PX = 0.2


def _corners(warp_mm, seed, *, transposed=False, n_views=20, camera=CAMERA):
    """Noisy corners of a board bowed by ``warp_mm`` (mrcal's parabola), flat object_mm."""
    rng = np.random.default_rng(seed)
    obj = BOARD.corners_mm()
    ix = np.round(obj[:, 0] / BOARD.square_mm) - 1  # 0 .. inner_x - 1
    iy = np.round(obj[:, 1] / BOARD.square_mm) - 1
    xr, yr = ix / (BOARD.inner_x - 1), iy / (BOARD.inner_y - 1)
    bowed = obj.copy()
    bowed[:, 2] = warp_mm[0] * 4 * xr * (1 - xr) + warp_mm[1] * 4 * yr * (1 - yr)
    ids = np.arange(len(obj))
    out = []
    for k, (rvec, tvec) in enumerate(random_poses(BOARD, n_views, seed, distance_mm=500)):
        proj, _ = cv2.projectPoints(bowed, rvec, tvec, camera.camera_matrix, camera.dist_coeffs)
        pts = proj.reshape(-1, 2) + rng.normal(0.0, NOISE_PX, (len(obj), 2))
        described = obj[:, [1, 0, 2]] if transposed else obj.copy()
        out.append(BoardDetection(f"view{k:02d}", CAMERA.image_size_px, pts, ids, described))
    return out


def test_known_warp_is_recovered_within_its_sigma_and_unbiases_the_lens():
    warp_true = (0.5, -0.3)
    dets = _corners(warp_true, seed=3)
    flat = calibrate_views(dets, CAMERA.image_size_px, model="5")
    bowed = calibrate_views(dets, CAMERA.image_size_px, model="5", board_warp=True)
    bw = bowed.board_warp
    for got, true, sd in zip(bw.warp_mm, warp_true, bw.sigma_mm, strict=True):
        assert abs(got - true) <= 3.0 * sd, (got, true, sd)
        assert sd < 0.05  # mm: well determined by 20 views at 0.2 px
    # with the warp solved the intrinsics hold the truth within 3 sigma; assuming a flat
    # board the focal length is off by many sigmas
    truth = {"fx": CAMERA.fx, "fy": CAMERA.fy, "cx": 645.0, "cy": 478.0}
    got = {"fx": bowed.camera.fx, "fy": bowed.camera.fy}
    got.update(zip(("cx", "cy"), bowed.camera.principal_point_px, strict=True))
    for name, value in truth.items():
        assert abs(got[name] - value) <= 3.0 * bowed.std_devs[name], name
    assert abs(flat.camera.fx - CAMERA.fx) > 4.0 * flat.std_devs["fx"]
    # the residuals drop to the noise
    assert bowed.rms_px == pytest.approx(NOISE_PX * np.sqrt(2), rel=0.1)
    assert flat.rms_px > 1.15 * bowed.rms_px
    test = warp_test(bw)
    assert test.significant and test.p < 1e-20
    # the covariance the uncertainty uses carries the warp (marginalised): same sigmas
    assert parameter_covariance(bowed).std_devs()["fx"] == pytest.approx(
        bowed.std_devs["fx"], rel=1e-6
    )


def test_flat_board_finds_no_warp_and_auto_leaves_it_out():
    dets = _corners((0.0, 0.0), seed=5)
    res = calibrate_views(dets, CAMERA.image_size_px, model="5", board_warp=True)
    bw = res.board_warp
    for got, sd in zip(bw.warp_mm, bw.sigma_mm, strict=True):
        assert abs(got) <= 3.0 * sd
    rep = calibrate_detections(dets, CAMERA.image_size_px, model="5", cross_check=False)
    assert rep.board_warp is not None and rep.board_warp["used"] is False
    assert rep.result.board_warp is None  # the flat solve is kept
    assert rep.board_warp["extension_model"] == "rational"
    assert rep.board_warp["extension_p"] >= 0.0027
    assert "flat within noise" in rep.board_warp["text"]
    off = calibrate_detections(
        dets, CAMERA.image_size_px, model="5", cross_check=False, board_warp="off"
    )
    assert off.board_warp is None
    assert off.camera.fx == rep.camera.fx  # auto without a warp is the plain solve
    on = calibrate_detections(
        dets, CAMERA.image_size_px, model="5", cross_check=False, board_warp="on"
    )
    assert on.board_warp["used"] is True and on.result.board_warp is not None


def test_a_warp_that_absorbs_lens_model_error_is_not_kept():
    """A flat board seen through a lens with tangential distortion, fitted with model 2
    (k1 k2): the warp solved with model 2 takes up the model's error (chi-square p 6e-06,
    the former rule kept it), but with model 2's extension (model 5) the board is flat."""
    lens = CameraModel(CAMERA.image_size_px, CAMERA.camera_matrix, [-0.2, 0.08, 5e-3, -5e-3, 0])
    dets = _corners((0.0, 0.0), seed=5, camera=lens)
    rep = calibrate_detections(dets, CAMERA.image_size_px, model="2", cross_check=False)
    info = rep.board_warp
    assert info["p"] < 1e-4  # the warp with model 2 alone looks significant
    assert info["extension_model"] == "5" and info["extension_p"] > 0.01
    assert info["used"] is False and rep.result.board_warp is None
    assert "not kept" in info["text"]


def test_auto_keeps_a_significant_warp_and_says_so():
    dets = _corners((0.4, 0.2), seed=7)
    rep = calibrate_detections(dets, CAMERA.image_size_px, model="5")
    assert rep.board_warp["used"] is True
    info = rep.board_warp
    # the evidence: the lens model's extension sees it, so does every group of views,
    # and it moves the lens beyond noise
    assert info["extension_p"] < 1e-10 and info["jackknife_p"] < 0.0027
    assert info["lens_shift_sigma"] > 1.0
    assert "kept" in info["text"] and "does not explain" in info["text"]
    wx, wy = rep.result.board_warp.warp_mm
    assert wx == pytest.approx(0.4, abs=0.08) and wy == pytest.approx(0.2, abs=0.08)
    # the halves of the cross-validation are solved with the warp too: no model error
    assert rep.cross_validation is not None and rep.cross_validation.ratio < 3.0
    assert rep.summary()["board_warp"]["sigma_mm"][0] > 0


def test_warp_follows_the_board_described_transposed():
    a = calibrate_views(_corners((0.5, -0.3), 11), CAMERA.image_size_px, board_warp=True)
    b = calibrate_views(
        _corners((0.5, -0.3), 11, transposed=True), CAMERA.image_size_px, board_warp=True
    )
    # x and y swap; so does the sign: (y, x, z) is a mirror image, so the transposed
    # board frame's z axis (a proper rotation from the camera) points the other way
    assert b.board_warp.warp_mm[0] == pytest.approx(-a.board_warp.warp_mm[1], abs=1e-6)
    assert b.board_warp.warp_mm[1] == pytest.approx(-a.board_warp.warp_mm[0], abs=1e-6)
    assert b.board_warp.sigma_mm[0] == pytest.approx(a.board_warp.sigma_mm[1], rel=1e-6)
    assert b.camera.fx == pytest.approx(a.camera.fx, rel=1e-8)
    # what is printed is the same: each side's bow by its length, towards or away from the camera
    ta, tb = warp_test(a.board_warp, a).text(), warp_test(b.board_warp, b).text()
    assert ta == tb and "200 mm side" in ta and "125 mm side" in ta
    assert b.std_devs["cx"] == pytest.approx(a.std_devs["cx"], rel=1e-6)


def test_bad_board_warp_mode_is_refused():
    with pytest.raises(ValueError, match="board_warp"):
        calibrate_detections(_corners((0, 0), 1, n_views=6), CAMERA.image_size_px, board_warp="x")
