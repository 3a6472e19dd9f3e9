"""RAW decoding: linear, camera white balance, scanner NEFs; linear files of any type."""

import cv2
import numpy as np
import pytest
import rawpy

from cvmeasure.errors import InputError
from cvmeasure.imageio import PHOTO_SUFFIXES, is_linear_name, is_raw, read_photo


def test_real_dng_has_camera_white_balance(shared_real):
    path = shared_real / "raw" / "Blackmagic.dng"
    photo = read_photo(path, half_size=True)
    assert photo.linear and photo.bgr.dtype == np.uint16
    assert photo.bgr.shape == (1088, 2064, 3)

    def decode(wb):
        with rawpy.imread(str(path)) as raw:
            wb = list(raw.camera_whitebalance) if wb is None else wb
            rgb = raw.postprocess(
                gamma=(1, 1),
                no_auto_bright=True,
                user_wb=wb,
                output_bps=16,
                user_flip=0,
                half_size=True,
            )
        return rgb.reshape(-1, 3).astype(float)

    ours = photo.bgr[:, :, ::-1].reshape(-1, 3).astype(float)
    # identical (to one code) to a decode with the as-shot multipliers given explicitly ...
    assert np.abs(ours - decode(None)).max() <= 1
    # ... and far from a unity white balance: red/green gain about 2.2 (the camera's 2.206)
    unity = decode([1.0, 1.0, 1.0, 1.0])
    ok = (ours.max(axis=1) < 60000) & (unity.max(axis=1) < 60000)
    r_over_g = (ours[ok, 0].mean() / ours[ok, 1].mean()) / (
        unity[ok, 0].mean() / unity[ok, 1].mean()
    )
    assert r_over_g > 1.5
    # linear: no gamma, no auto-brightening (the mean stays a small share of full scale)
    assert ours.mean() < 0.25 * 65535


def test_real_scanner_nef_is_not_clipped(shared_real):
    """The Nikon scan is 3-channel 'Stack' data: taken as stored, not clipped by LibRaw's scaling."""
    path = shared_real / "raw" / "Nikon_uncompressed.nef"
    photo = read_photo(path)
    assert photo.linear and photo.bgr.shape == (593, 869, 3)
    with rawpy.imread(str(path)) as raw:
        stored = raw.raw_image_visible[..., :3].copy()
    # white 255 is declared but the data reach 55000: full 16-bit scale, no WB (scanner)
    np.testing.assert_array_equal(photo.bgr[:, :, ::-1], stored)
    assert (photo.bgr == 65535).mean() < 0.001


def test_linear_rgb_is_the_same_scene_for_jpeg_and_linear_16_bit(tmp_path):
    rng = np.random.default_rng(11)
    linear = rng.uniform(0.02, 0.95, size=(24, 32, 3)).astype(np.float32)
    srgb = np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * linear ** (1 / 2.4) - 0.055)
    cv2.imwrite(str(tmp_path / "scene.png"), np.round(srgb * 255).astype(np.uint8))
    cv2.imwrite(str(tmp_path / "scene.linear.png"), np.round(linear * 65535).astype(np.uint16))
    gamma_photo = read_photo(tmp_path / "scene.png")
    linear_photo = read_photo(tmp_path / "scene.linear.png")
    assert not gamma_photo.linear and linear_photo.linear
    # 8-bit quantisation in sRGB: at most half a code step, at most 0.45 % of full scale at the top
    np.testing.assert_allclose(gamma_photo.linear_rgb(), linear, atol=0.005)
    np.testing.assert_allclose(linear_photo.linear_rgb(), linear, atol=1e-4)
    # and the display-referred 8-bit view of the linear file is the sRGB file
    diff = np.abs(linear_photo.bgr8().astype(int) - gamma_photo.bgr.astype(int))
    assert diff.max() <= 1
    # an explicit choice overrides the name
    assert not read_photo(tmp_path / "scene.linear.png", linear=False).linear


def test_suffixes():
    assert is_raw("a/B.NEF") and is_raw("x.dng") and not is_raw("x.jpg")
    assert is_linear_name("r.linear.tiff") and not is_linear_name("r.tiff")
    assert not is_linear_name("r.linear.jpg")
    assert {".jpg", ".nef", ".png"} <= PHOTO_SUFFIXES


def test_corrupt_raw_is_an_input_error(tmp_path):
    bad = tmp_path / "cut.nef"
    bad.write_bytes(b"II*\x00" + bytes(200))
    with pytest.raises(InputError, match=r"cut\.nef: unreadable RAW photo"):
        read_photo(bad)
