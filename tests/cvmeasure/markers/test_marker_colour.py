"""White balance, chromatic adaptation and the colour models (LAB and RGB)."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.kit import ROLES, MarkerKit, MarkerSpec, default_kit
from cvmeasure.markers.colour import (
    ColourModel,
    bgr8_to_space,
    classify_bgr8,
    estimate_white,
    kit_colour_model,
    learnt_colour_model,
)


def _cast(srgb8: np.ndarray, gain_rgb: tuple[float, float, float]) -> np.ndarray:
    """Light the colours with a per-channel (von Kries) gain in linear RGB; 8-bit BGR out."""
    v = np.asarray(srgb8, dtype=np.float64) / 255
    lin = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4) * np.asarray(gain_rgb)
    lin = np.clip(lin, 0, 1)
    enc = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    return np.round(enc * 255).astype(np.uint8)[..., ::-1]


#: Linear RGB gains of a warm (about 2700 K) and a cool (about 6500 K+) light, un-balanced.
WARM = (1.0, 0.72, 0.38)
COOL = (0.82, 0.9, 1.0)


def _patch_image(kit: MarkerKit, gain) -> np.ndarray:
    colours = [m.srgb for m in kit.markers] + [(236, 236, 232), (150, 152, 156), (62, 56, 50)]
    img = np.concatenate([np.tile(np.asarray(c, float), (20, 20, 1)) for c in colours], axis=1)
    return _cast(img, gain)


@pytest.mark.parametrize("gain", [(1.0, 1.0, 1.0), WARM, COOL], ids=["d65", "warm", "cool"])
def test_white_comes_from_the_whitest_pixels(gain):
    img = _patch_image(default_kit(), gain)
    white = estimate_white(img, top_fraction=0.05)
    expected = _cast(np.array([236.0, 236.0, 232.0]), gain)[::-1]
    assert np.allclose(white.srgb8, expected, atol=1.0)
    assert white.clipped_fraction == 0.0


def test_clipped_pixels_are_not_the_white():
    img = _patch_image(default_kit(), (1.0, 1.0, 1.0))
    img[:5, :5] = 255
    white = estimate_white(img, top_fraction=0.05)
    assert max(white.srgb8) < 240
    assert white.clipped_fraction > 0


@pytest.mark.parametrize("space", ["lab", "rgb"])
@pytest.mark.parametrize("gain", [(1.0, 1.0, 1.0), WARM, COOL], ids=["d65", "warm", "cool"])
def test_every_role_is_classified_under_warm_and_cool_light(space, gain):
    kit = default_kit()
    img = _patch_image(kit, gain)
    white = estimate_white(img, top_fraction=0.05)
    labels = classify_bgr8(img, kit_colour_model(kit, space), white)
    for k, marker in enumerate(kit.markers):
        patch = labels[:, 20 * k : 20 * k + 20]
        assert (patch == ROLES.index(marker.role)).mean() == 1.0, marker.role
    assert (labels[:, 100:] == -1).all()  # white, plate grey and table are no marker


@pytest.mark.parametrize("space", ["lab", "rgb"])
@pytest.mark.parametrize(("adaptation", "worst"), [("rgb-gain", 0.5), ("cat02", 5.0)])
def test_white_balance_brings_warm_colours_back(space, adaptation, worst):
    # the seed paper's observation: unbalanced warm light moves colours away from the kit
    kit = default_kit()
    img = _patch_image(kit, WARM)
    model = kit_colour_model(kit, space)
    white = estimate_white(img, top_fraction=0.05)
    colours = img[0, ::20][:5]
    own = np.arange(5)
    raw = model.distances(bgr8_to_space(colours, space, None, adaptation))[own, own]
    balanced = model.distances(bgr8_to_space(colours, space, white, adaptation))[own, own]
    assert raw.max() > 2.5  # the warm cast alone moves blue and magenta far away
    assert balanced.max() < worst


@pytest.mark.parametrize(("adaptation", "tol"), [("rgb-gain", 3.0), ("cat02", 22.0)])
def test_adapted_colours_land_on_the_kit_lab(adaptation, tol):
    kit = default_kit()
    img = _patch_image(kit, WARM)
    white = estimate_white(img, top_fraction=0.05)
    lab = bgr8_to_space(img[0, ::20][:5], "lab", white, adaptation)
    for k, marker in enumerate(kit.markers):
        assert np.linalg.norm(lab[k] - marker.lab_d65) < tol, marker.role


def test_learnt_model_and_unknown_space():
    rng = np.random.default_rng(3)
    samples = {
        r: rng.normal(loc=[10.0 * i, 0, 0], scale=1.0, size=(50, 3)) for i, r in enumerate(ROLES)
    }
    model = learnt_colour_model(samples, "lab")
    d = model.distances(np.array([[20.0, 0.0, 0.0]]))
    assert int(np.argmin(d)) == 2
    assert model.means[2] == pytest.approx([20.0, 0, 0], abs=0.5)
    with pytest.raises(ValueError, match="at least 10"):
        learnt_colour_model({"origin": np.zeros((3, 3))}, "lab")
    with pytest.raises(ValueError, match="unknown colour space"):
        ColourModel("hsv", ("origin",), np.zeros((1, 3)), np.eye(3)[None])


def test_kit_sigmas_are_used():
    kit = default_kit()
    tight = MarkerKit(
        kit.name,
        tuple(
            MarkerSpec(m.role, m.name, m.srgb, m.diameter_mm, m.ring_mm, lab_sigma=(1.0, 1.0, 1.0))
            for m in kit.markers
        ),
    )
    model = kit_colour_model(tight, "lab")
    assert np.allclose(np.diag(model.covariances[0]), 1.0)
    assert MarkerKit.from_dict(tight.to_dict()).markers[0].lab_sigma == (1.0, 1.0, 1.0)


def test_white_colour_survives_clipped_rings_under_a_strong_cast(render):
    pytest.importorskip("cvmeasure_datasets.bender")
    from cvmeasure_datasets.lighting import Lighting

    def white_ratios(exposure: float) -> tuple[np.ndarray, float]:
        light = Lighting(cct_k=2700.0, wb_error_k=-600.0, exposure=exposure)
        white = estimate_white(render(light=light, seed=1).bgr, recover_clipped=True)
        v = np.asarray(white.srgb8) / 255
        lin = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
        return lin / lin[1], white.clipped_fraction

    truth, truth_clipped = white_ratios(0.12)  # the same scene dimmed: nothing clips
    got, clipped = white_ratios(1.15)
    assert truth_clipped < 0.05
    assert clipped > 0.9  # the rings' blue is clipped
    assert truth[2] > 3.0  # a strong blue cast: B/G of the white in linear light
    np.testing.assert_allclose(got, truth, rtol=0.15)
    default = estimate_white(
        render(light=Lighting(cct_k=2700.0, wb_error_k=-600.0, exposure=1.15), seed=1).bgr
    )
    v = np.asarray(default.srgb8) / 255
    lin = np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)
    assert lin[2] / lin[1] < 0.5 * truth[2]  # the bias recover_clipped removes
