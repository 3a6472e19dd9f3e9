"""The NumPy colour formulas agree with colour-science, the reference."""

import colour
import numpy as np

from cvmeasure.colorimetry import (
    SRGB8_TO_LINEAR,
    srgb8_to_lab_d65,
    srgb_decode,
    srgb_encode,
    srgb_encode_floats,
    xyz_to_lab_d65,
)


def test_transfer_functions_match_colour_science_and_invert():
    v = np.linspace(0.0, 1.0, 1001)
    np.testing.assert_allclose(srgb_decode(v), colour.models.eotf_sRGB(v), atol=1e-12)
    np.testing.assert_allclose(srgb_encode(srgb_decode(v)), v, atol=1e-12)
    np.testing.assert_allclose(SRGB8_TO_LINEAR, srgb_decode(np.arange(256) / 255), atol=1e-7)
    assert srgb_decode(np.float32([0.5])).dtype == np.float32
    assert srgb_encode(np.array([2.0]), clip=False)[0] > 1.0


def test_the_scalar_encode_is_the_array_encode():
    """srgb_encode_floats (a few Python floats, the marker refinement's disc and ring
    colours) agrees with srgb_encode, clipping included, to 1e-15."""
    v = np.concatenate(([-0.5, 0.0, 0.0031308, 1.0, 1.7], np.linspace(0.0, 1.0, 997)))
    np.testing.assert_allclose(srgb_encode_floats(v.tolist()), srgb_encode(v), rtol=0, atol=1e-15)


def test_lab_matches_colour_science_on_random_colours():
    rng = np.random.default_rng(4)
    rgb8 = rng.integers(0, 256, (500, 3))
    d65 = colour.CCS_ILLUMINANTS["CIE 1931 2 Degree Standard Observer"]["D65"]
    reference = colour.XYZ_to_Lab(colour.sRGB_to_XYZ(rgb8 / 255.0), d65)
    # colour-science derives its sRGB matrix from the primaries; the standard's 4-digit
    # matrix differs from it by < 1e-4, i.e. a few hundredths of a Lab unit at most
    np.testing.assert_allclose(srgb8_to_lab_d65(rgb8), reference, atol=0.05)
    xyz = rng.uniform(0, 1, (100, 3))
    np.testing.assert_allclose(xyz_to_lab_d65(xyz), colour.XYZ_to_Lab(xyz, d65), atol=0.05)
