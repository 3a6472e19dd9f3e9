"""Sub-pixel edge points and robust circle fits on drawn discs with exact centres."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from cvmeasure.geometry import fit_circle_robust
from cvmeasure.markers.refine import CORRELATION_FACTOR, disc_edge_points

SS = 8  # supersampling of the drawn discs


def _disc_image(centre, r_px, *, ring_ratio=1.4, colour=(70, 110, 0), noise=0.0, seed=0, size=96):
    """An anti-aliased BGR disc of ``colour`` on a white ring on grey, exact centre (px)."""
    n = size * SS
    yy, xx = np.mgrid[0:n, 0:n]
    # pixel-centre convention: full-res pixel (i, j) covers [i - 0.5, i + 0.5)
    d = np.hypot((xx + 0.5) / SS - 0.5 - centre[0], (yy + 0.5) / SS - 0.5 - centre[1])
    img = np.empty((n, n, 3), np.float32)
    img[:] = (120, 118, 115)
    img[d < r_px * ring_ratio] = (232, 236, 236)
    img[d < r_px] = colour
    small = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
    small = cv2.GaussianBlur(small, (0, 0), 0.7)
    if noise:
        small = small + np.random.default_rng(seed).normal(0, noise, small.shape)
    return np.clip(np.round(small), 0, 255).astype(np.uint8)


def test_robust_fit_exact_points():
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    pts = np.column_stack((12.3 + 7.0 * np.cos(t), -4.5 + 7.0 * np.sin(t)))
    fit = fit_circle_robust(pts)
    assert fit.centre == pytest.approx((12.3, -4.5), abs=1e-9)
    assert fit.radius == pytest.approx(7.0, abs=1e-9)
    assert fit.coverage == 1.0


def test_robust_fit_ignores_an_occluded_arc():
    rng = np.random.default_rng(5)
    t = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    r = np.full_like(t, 30.0) + rng.normal(0, 0.05, t.size)
    r[(t > 1.0) & (t < 1.9)] -= 6.0  # a straight occluder edge cuts into 15 % of the disc
    pts = np.column_stack((50 + r * np.cos(t), 40 + r * np.sin(t)))
    fit = fit_circle_robust(pts)
    assert fit.centre == pytest.approx((50, 40), abs=0.02)
    assert fit.n_inliers < fit.n_points
    assert fit.coverage < 1.0
    with pytest.raises(ValueError):
        fit_circle_robust(pts[:2])


@pytest.mark.parametrize("r_px", [9.0, 20.0, 33.0])
def test_edge_points_give_centres_to_a_few_hundredths_of_a_pixel(r_px):
    rng = np.random.default_rng(int(r_px))
    errs, zs = [], []
    for k in range(6):
        c = (48 + rng.uniform(-0.5, 0.5), 47 + rng.uniform(-0.5, 0.5))
        img = _disc_image(c, r_px, noise=2.0, seed=k, size=int(2 * r_px * 1.6) + 20)
        c = (c[0] - 48 + img.shape[1] / 2, c[1] - 47 + img.shape[0] / 2)
        img = _disc_image(c, r_px, noise=2.0, seed=k, size=img.shape[0])
        start = (c[0] + rng.uniform(-1, 1), c[1] + rng.uniform(-1, 1))
        edges = disc_edge_points(img, start, r_px * 1.05, 1.4)
        fit = fit_circle_robust(edges.points_px, correlation_factor=CORRELATION_FACTOR)
        err = np.subtract(fit.centre, c)
        errs.append(np.hypot(*err))
        zs.extend(err / np.sqrt(np.diag(fit.covariance)))
        assert fit.radius == pytest.approx(r_px, abs=0.4)  # the drawing blurs in gamma space
        assert edges.contrast > 100
    assert max(errs) < 0.03
    assert np.sqrt(np.mean(np.square(zs))) < 2.0  # stated covariance not over-optimistic


def test_edge_points_report_missing_contrast():
    img = np.full((60, 60, 3), 200, np.uint8)
    edges = disc_edge_points(img, (30.0, 30.0), 10.0, 1.4)
    assert edges.points_px.shape == (0, 2)
    assert edges.contrast == 0.0
    edge = disc_edge_points(img, (1.0, 1.0), 0.5, 1.4)
    assert edge.points_px.shape == (0, 2)


def test_clipped_ring_is_reported():
    img = _disc_image((40.0, 40.0), 15.0, size=80)
    img[img > 225] = 255
    edges = disc_edge_points(img, (40.0, 40.0), 15.0, 1.4)
    assert edges.clipped_fraction > 0.9
    # one channel of a few ring pixels at 254: the share counts exactly those pixels
    img = _disc_image((40.0, 40.0), 15.0, size=80)
    img[40, 57:59, 1] = 254
    assert disc_edge_points(img, (40.0, 40.0), 15.0, 1.4).clipped_fraction > 0.0
    assert disc_edge_points(_disc_image((40.0, 40.0), 15.0, size=80), (40.0, 40.0), 15.0,
                            1.4).clipped_fraction == 0.0  # fmt: skip
    fit = fit_circle_robust(edges.points_px, correlation_factor=CORRELATION_FACTOR)
    assert math.hypot(fit.centre[0] - 40, fit.centre[1] - 40) < 0.03


def test_green_edges_ignore_lateral_chromatic_aberration():
    # red and blue drawn 1 px off (lateral CA far from the lens centre); green is the truth
    c = (40.3, 39.8)
    img_g = _disc_image(c, 15.0, colour=(0, 140, 240), size=80)  # orange-yellow disc, BGR
    img_rb = _disc_image((c[0] + 1.0, c[1]), 15.0, colour=(0, 140, 240), size=80)
    img = img_g.copy()
    img[..., 0] = img_rb[..., 0]
    img[..., 2] = img_rb[..., 2]
    green = fit_circle_robust(disc_edge_points(img, c, 15.0, 1.4, edge="green").points_px)
    colour = fit_circle_robust(disc_edge_points(img, c, 15.0, 1.4, edge="colour").points_px)
    assert np.hypot(green.centre[0] - c[0], green.centre[1] - c[1]) < 0.03
    assert colour.centre[0] - c[0] > 0.3  # the blue step dominates the colour difference
    luma = fit_circle_robust(disc_edge_points(img, c, 15.0, 1.4, edge="luma").points_px)
    assert 0.0 < luma.centre[0] - c[0] < 0.25  # blue has 7 % of the luminance weight
    with pytest.raises(ValueError, match="unknown edge mode"):
        disc_edge_points(img, c, 15.0, 1.4, edge="hue")


def test_levels_from_histograms_are_numpys_medians():
    """The disc and ring levels from uint8 histograms equal np.median of the linear pixels,
    and the count of channel values at 254 or 255 is the masked pixels' own."""
    from cvmeasure.colorimetry import SRGB8_TO_LINEAR
    from cvmeasure.markers.refine import _median_levels

    rng = np.random.default_rng(19)
    raw = rng.integers(0, 256, (41, 37, 3), dtype=np.uint8)
    lin = SRGB8_TO_LINEAR[raw]
    for n_wanted in (1, 2, 7, 300, 1516):  # odd and even counts
        mask = np.zeros(raw.shape[:2], bool)
        mask.flat[rng.choice(mask.size, n_wanted, replace=False)] = True
        got, n_top = _median_levels(raw, SRGB8_TO_LINEAR, mask.view(np.uint8), n_wanted)
        np.testing.assert_array_equal(got, np.median(lin[mask], axis=0))
        assert n_top == np.count_nonzero(raw[mask] >= 254)
    dark = raw // 2  # no value above 127: none at 254 or 255
    assert _median_levels(dark, SRGB8_TO_LINEAR, mask.view(np.uint8), n_wanted)[1] == 0


def test_ring_spread_is_the_percentile_range_of_the_rays_ring_medians():
    from cvmeasure.markers.refine import EdgePoints, _row_medians, _sorted_percentile

    rng = np.random.default_rng(3)
    for shape in ((200, 21), (64, 20), (9, 1)):
        samples = rng.normal(size=shape).astype(np.float32)
        np.testing.assert_array_equal(_row_medians(samples), np.median(samples, axis=1))
        ring = np.median(samples, axis=1)
        expected = np.percentile(ring, 95) - np.percentile(ring, 5)
        edges = EdgePoints(np.zeros((0, 2)), (0, 0, 0), (0, 0, 0), 0.0, 0.0, samples)
        assert edges.ring_spread == pytest.approx(expected, rel=1e-12, abs=1e-12)
        assert _sorted_percentile(np.sort(ring), 50.0) == pytest.approx(np.median(ring))
    assert EdgePoints(np.zeros((0, 2)), (0, 0, 0), (0, 0, 0), 0.0, 0.0).ring_spread == 0.0


def test_discs_refined_together_as_each_alone():
    """refine_candidates: every disc's circle (or failure) is refine_candidate's for it alone."""
    from cvmeasure.markers.detect import MarkerCandidate
    from cvmeasure.markers.measure import refine_candidate, refine_candidates

    tiles = [
        _disc_image((63.3, 64.6), 20.0, noise=2.0, seed=1, size=128),
        _disc_image((64.1, 63.2), 19.0, noise=2.0, seed=2, size=128),
        np.full((128, 128, 3), 120, np.uint8),  # no disc: no edge
        _disc_image((62.8, 65.1), 24.0, noise=2.0, seed=4, size=128),
    ]
    img = np.ascontiguousarray(np.hstack(tiles))
    truth = [(63.3, 64.6), (128 + 64.1, 63.2), (256 + 64.0, 64.0), (384 + 62.8, 65.1)]
    radii = [20.0, 19.0, 18.0, 24.0]
    # starts off by 0.4 to 3.6 px (several passes for some), radii 10 % off
    offsets = [(0.3, -0.2), (2.0, 1.5), (1.0, 1.0), (-3.0, 2.0)]
    cands = [
        MarkerCandidate("x", (t[0] + o[0], t[1] + o[1]), 1.1 * r, math.pi * r * r, 0.78, 0.9)
        for t, o, r in zip(truth, offsets, radii, strict=True)
    ]
    together = refine_candidates(img, cands, [1.4] * 4)
    for cand, got, t in zip(cands, together, truth, strict=True):
        alone = refine_candidate(img, cand, 1.4)
        if isinstance(alone, str):
            assert got == alone
            continue
        fit, fit_alone = got[0], alone[0]
        assert fit.centre == pytest.approx(fit_alone.centre, abs=1e-9)
        assert fit.radius == pytest.approx(fit_alone.radius, abs=1e-9)
        np.testing.assert_allclose(fit.covariance, fit_alone.covariance, rtol=1e-9)
        assert math.dist(fit.centre, t) < 0.05  # and right: the drawn centre
    assert isinstance(together[2], str) and "no clear edge" in together[2]
    assert sum(not isinstance(g, str) for g in together) == 3, together
