"""Light, white balance, noise, JPEG and the 16-bit linear output."""

from __future__ import annotations

import dataclasses

import cv2
import numpy as np
import pytest

from cvmeasure.board import ChessboardSpec
from cvmeasure_datasets import Lighting, Pose, render_bender_photo, render_board_view
from cvmeasure_datasets.bender import RING_SRGB
from cvmeasure_datasets.lighting import illuminant_rgb, srgb8_to_linear
from cvmeasure_datasets.optics import project_frame_points

# close up (2.5 px/mm at 576 x 384): the origin marker's white ring is ~5 px wide
KW = dict(pin_angle_deg=-60.0, bend_angle_deg=35.0, scale=0.125, pose=Pose(distance_mm=350.0))
#: linear albedo of the rings (printed white is slightly warm)
RING = srgb8_to_linear(RING_SRGB)


def _ring_rgb(photo, role="origin") -> np.ndarray:
    """Mean linear RGB of the white ring of a marker (between disc and ring edge)."""
    t = photo.truth["markers"][role]
    x, y = t["centre_px"]
    r_in, r_out = t["r_px"] + 1.5, t["ring_r_px"] - 1.5
    lin = photo.linear_rgb16.astype(np.float64) / 65535
    yy, xx = np.mgrid[0 : lin.shape[0], 0 : lin.shape[1]]
    d = np.hypot(xx - x, yy - y)
    return lin[(d > r_in) & (d < r_out)].mean(axis=0)


def test_warm_light_raises_r_over_b_before_white_balance():
    """With the camera's WB fixed at daylight, 3000 K light makes the white ring orange."""
    fixed = dict(wb_cct_k=6500.0, noise=0.0, vignetting=0.0, jpeg_quality=None)
    warm = render_bender_photo(lighting=Lighting(cct_k=3000.0, **fixed), linear=True, **KW)
    cool = render_bender_photo(lighting=Lighting(cct_k=6500.0, **fixed), linear=True, **KW)
    w, c = _ring_rgb(warm) / RING, _ring_rgb(cool) / RING
    assert c[0] / c[2] == pytest.approx(1.0, abs=0.02)
    expected = (illuminant_rgb(3000.0) / illuminant_rgb(6500.0))[[0, 2]]
    assert w[0] / w[2] == pytest.approx(expected[0] / expected[1], rel=0.03)
    assert w[0] / w[2] > 2.0


@pytest.mark.parametrize("cct_k", [2700.0, 4200.0, 6500.0])
def test_correct_white_balance_gives_neutral_white(cct_k):
    light = Lighting(cct_k=cct_k, wb_error_k=0.0, noise=0.0, vignetting=0.0, jpeg_quality=None)
    rgb = _ring_rgb(render_bender_photo(lighting=light, linear=True, **KW)) / RING
    assert np.ptp(rgb) / rgb.mean() < 0.01


def test_wb_error_tints_the_photo():
    base = dict(cct_k=4000.0, noise=0.0, vignetting=0.0, jpeg_quality=None)
    too_warm = _ring_rgb(
        render_bender_photo(lighting=Lighting(wb_error_k=-800.0, **base), linear=True, **KW)
    )
    too_cool = _ring_rgb(
        render_bender_photo(lighting=Lighting(wb_error_k=800.0, **base), linear=True, **KW)
    )
    # the camera assumes a warmer light than there is -> it over-corrects -> bluish
    assert too_warm[2] > too_warm[0] and too_cool[0] > too_cool[2]


def test_shot_and_read_noise_have_the_stated_size():
    """On flat white paper the noise std matches sqrt(S * full_well + read^2) / full_well."""
    light = Lighting(
        cct_k=6504.0, wb_error_k=0.0, vignetting=0.0, blur_px=0.0, jpeg_quality=None, noise=1.0
    )
    # 5.8 px/mm, looking at the middle of the paper margin left of the board
    kw = dict(
        board=ChessboardSpec(3, 3, 60.0),
        pose=Pose(distance_mm=300.0, offset_mm=(-30.0, 120.0)),
        scale=0.25,
        linear=True,
    )
    patch = render_board_view(lighting=light, **kw).linear_rgb16[364:404, 556:596, 1] / 65535
    signal = patch.mean()
    expected = np.sqrt(signal * light.full_well_e + light.read_noise_e**2) / light.full_well_e
    assert 0.7 < signal < 0.95
    assert patch.std() == pytest.approx(expected, rel=0.1)
    clean = render_board_view(lighting=dataclasses.replace(light, noise=0.0), **kw)
    assert (clean.linear_rgb16[364:404, 556:596, 1] / 65535).std() < 1e-4


def test_vignetting_darkens_the_corners():
    light = Lighting(
        cct_k=6504.0, wb_error_k=0.0, noise=0.0, blur_px=0.0, jpeg_quality=None, vignetting=0.3
    )
    photo = render_board_view(
        board=ChessboardSpec(3, 3, 60.0),
        pose=Pose(distance_mm=300.0, offset_mm=(120.0, 120.0)),  # paper fills the view
        lighting=light,
        scale=0.125,
        linear=True,
    )
    g = photo.linear_rgb16[..., 1].astype(np.float64)
    centre, corner = g[190:194, 2:6].mean(), g[2:6, 2:6].mean()
    assert corner / centre == pytest.approx(1 - 0.3 * 0.99, abs=0.02) or corner < centre


def test_jpeg_and_linear_outputs(tmp_path):
    hi = render_bender_photo(lighting=Lighting(jpeg_quality=95), linear=True, seed=1, **KW)
    lo = render_bender_photo(lighting=Lighting(jpeg_quality=40), seed=1, **KW)
    raw = render_bender_photo(lighting=Lighting(jpeg_quality=None), seed=1, **KW)
    assert hi.jpeg_bytes[:2] == b"\xff\xd8" and raw.jpeg_bytes is None
    assert len(lo.jpeg_bytes) < len(hi.jpeg_bytes)
    assert np.array_equal(
        cv2.imdecode(np.frombuffer(hi.jpeg_bytes, np.uint8), cv2.IMREAD_COLOR), hi.bgr
    )
    # JPEG at 95 stays close to the uncompressed image
    assert np.abs(hi.bgr.astype(int) - raw.bgr.astype(int)).mean() < 2.0
    assert hi.linear_rgb16.dtype == np.uint16 and hi.linear_rgb16.shape == hi.bgr.shape
    assert raw.linear_rgb16 is None
    # the 8-bit image is the sRGB encoding of the linear one (before JPEG)
    lin = render_bender_photo(lighting=Lighting(jpeg_quality=None), linear=True, seed=1, **KW)
    enc = np.round(
        255
        * np.where(
            (v := lin.linear_rgb16 / 65535) <= 0.0031308, 12.92 * v, 1.055 * v ** (1 / 2.4) - 0.055
        )
    )
    assert np.abs(enc[..., ::-1] - lin.bgr).max() <= 1
    tif = lin.save_linear_tiff(tmp_path / "lin.tiff")
    back = cv2.imread(str(tif), cv2.IMREAD_UNCHANGED)
    assert back.dtype == np.uint16 and np.array_equal(back[..., ::-1], lin.linear_rgb16)
    with pytest.raises(ValueError):
        raw.save_linear_tiff(tmp_path / "no.tiff")
    photo, truth = raw.save(tmp_path / "raw")
    assert photo.suffix == ".png" and np.array_equal(cv2.imread(str(photo)), raw.bgr)
    photo, truth = hi.save(tmp_path / "hi")
    assert photo.name == "hi.jpg" and photo.read_bytes() == hi.jpeg_bytes
    assert truth.name == "hi.truth.json"


def test_renders_are_deterministic_by_seed():
    light = Lighting.random(4)
    a = render_bender_photo(lighting=light, seed=11, **KW)
    b = render_bender_photo(lighting=light, seed=11, **KW)
    c = render_bender_photo(lighting=light, seed=12, **KW)
    assert np.array_equal(a.bgr, b.bgr) and a.truth == b.truth
    assert not np.array_equal(a.bgr, c.bgr)
    assert Lighting.random(4) == light and Lighting.random(5) != light
    assert 2700 <= light.cct_k <= 6500


def test_lighting_validates():
    with pytest.raises(ValueError):
        Lighting(cct_k=1000.0)
    with pytest.raises(ValueError):
        Lighting(jpeg_quality=0)


def test_bayer_mosaic_keeps_colours_and_edges():
    """An RGGB mosaic + demosaic keeps flat colours and adds colour fringes only at edges."""
    base = dict(cct_k=6504.0, wb_error_k=0.0, noise=0.0, vignetting=0.0, jpeg_quality=None)
    plain = render_bender_photo(lighting=Lighting(**base), linear=True, **KW)
    mosaic = render_bender_photo(lighting=Lighting(bayer=True, **base), linear=True, **KW)
    # a flat patch of the plate keeps its colour
    rot, t = (
        np.asarray(plain.truth["pose"]["R_cam_frame"]),
        np.asarray(plain.truth["pose"]["tvec_mm"]),
    )
    x, y = np.round(
        project_frame_points(plain.camera, rot, t, np.array([[60.0, -50.0]]))[0]
    ).astype(int)
    patches = [
        p.linear_rgb16[y - 3 : y + 4, x - 3 : x + 4].reshape(-1, 3).mean(axis=0)
        for p in (mosaic, plain)
    ]
    assert np.allclose(patches[0], patches[1], rtol=0.01)
    diff = np.abs(mosaic.bgr.astype(int) - plain.bgr.astype(int)).max(axis=2)
    assert np.median(diff) <= 1 and diff.max() > 10  # flat areas equal, edges differ
    x, y = np.round(plain.truth["markers"]["pin"]["centre_px"]).astype(int)
    assert np.abs(mosaic.bgr[y, x].astype(int) - plain.bgr[y, x].astype(int)).max() <= 3
    noisy = render_bender_photo(lighting=Lighting(bayer=True, **{**base, "noise": 1.0}), **KW)
    assert noisy.bgr.shape == plain.bgr.shape


def test_lateral_chromatic_aberration_shifts_red_out_and_blue_in():
    """Corners found in the red and blue channels differ radially by 2 * ca * r."""
    ca = 2e-3
    board = ChessboardSpec(9, 6, 25.0)
    pose = Pose(distance_mm=650.0, offset_mm=(125.0, 87.5))
    photo = render_board_view(board=board, pose=pose, lighting=Lighting.clean(), scale=0.25)
    fringed = render_board_view(
        board=board,
        pose=pose,
        lighting=dataclasses.replace(Lighting.clean(), lateral_ca=ca),
        scale=0.25,
    )
    truth = np.asarray(photo.truth["corners_px"], dtype=np.float32).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 100, 1e-4)
    found = {
        ch: cv2.cornerSubPix(
            np.ascontiguousarray(fringed.bgr[..., i]), truth.copy(), (5, 5), (-1, -1), crit
        ).reshape(-1, 2)
        for ch, i in (("b", 0), ("g", 1), ("r", 2))
    }
    centre = np.asarray(photo.camera.principal_point_px)
    radius = np.linalg.norm(truth.reshape(-1, 2) - centre, axis=1)
    far = radius > 250
    gap = np.linalg.norm(found["r"] - found["b"], axis=1)
    assert np.allclose(gap[far] / radius[far], 2 * ca, rtol=0.15)
    assert np.median(np.linalg.norm(found["g"] - truth.reshape(-1, 2), axis=1)) < 0.08
