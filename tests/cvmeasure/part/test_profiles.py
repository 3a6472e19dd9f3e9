"""The profile kernels computed without full-size temporaries equal their direct definitions."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter1d

from cvmeasure.part.profiles import (
    asymmetry_costs,
    edge_gradient,
    least_cost_path,
    sample_across,
    sample_image,
    symmetric_centres,
    zero_mean_correlation,
)


def test_asymmetry_costs_equal_the_definition() -> None:
    rng = np.random.default_rng(11)
    p = rng.normal(100.0, 30.0, (150, 301))  # more profiles than one block
    mid, kc, ku = 150, 40, 60
    u = np.arange(1, ku + 1)
    want = np.stack(
        [np.mean((p[:, mid + c + u] - p[:, mid + c - u]) ** 2, axis=1) for c in range(-kc, kc + 1)],
        axis=1,
    )
    np.testing.assert_allclose(asymmetry_costs(p, mid, kc, ku), want, rtol=1e-12)


def test_symmetric_centres_find_a_known_axis() -> None:
    """Gaussian ridges centred at known shifts (0.05 px samples): found to 0.01 px."""
    rng = np.random.default_rng(12)
    x = (np.arange(801) - 400) * 0.05
    truth = rng.uniform(-2.0, 2.0, 60)
    p = 200.0 * np.exp(-(((x[None, :] - truth[:, None]) / 4.0) ** 2)) + 20.0
    shift, _ = symmetric_centres(p, rho_px=5.0, search_px=4.0)
    np.testing.assert_allclose(shift, truth, atol=0.01)


@pytest.mark.parametrize("trim_share", [0.25, 0.4])
def test_trimmed_asymmetry_costs_equal_the_definition(trim_share: float) -> None:
    """Per shift, the mean of the smallest (1 - trim_share) squared differences over the
    offsets taken every 4 samples (ku, ku - 4, ...)."""
    rng = np.random.default_rng(15)
    p = rng.normal(100.0, 30.0, (90, 301))  # more profiles than one block
    mid, kc, ku = 150, 30, 41
    u = np.arange(ku, 0, -4)[::-1]
    keep = round((1.0 - trim_share) * len(u))
    want = np.stack(
        [
            np.mean(np.sort((p[:, mid + c + u] - p[:, mid + c - u]) ** 2, axis=1)[:, :keep], axis=1)
            for c in range(-kc, kc + 1)
        ],
        axis=1,
    )
    got = asymmetry_costs(p, mid, kc, ku, trim_share=trim_share)
    np.testing.assert_allclose(got, want, rtol=1e-12)


def _glinting_profiles(truth: np.ndarray, half_width: float, at: float, wide: float) -> np.ndarray:
    """A polished round wire on a dark card (0.05 px samples): a crest on the axis, dark
    valleys at the limbs, and a lamp's narrow glint on one flank only (``at`` half-widths
    out on the + side, ``wide`` half-widths wide)."""
    x = (np.arange(801) - 400) * 0.05
    u = (x[None, :] - truth[:, None]) / half_width
    crest = 170.0 * np.exp(-((u / 0.33) ** 2))
    limbs = -20.0 * (np.exp(-(((u - 0.85) / 0.15) ** 2)) + np.exp(-(((u + 0.85) / 0.15) ** 2)))
    glint = 150.0 * np.exp(-(((u - at) / wide) ** 2))
    return 50.0 + crest + limbs + glint


@pytest.mark.parametrize(("at", "wide"), [(0.7, 0.1), (0.8, 0.08)])
def test_trimmed_symmetry_is_not_pulled_by_a_glint_on_one_flank(at: float, wide: float) -> None:
    """The whole window's centre moves by more than 0.05 px for a narrow glint on one flank
    (a 3.6 px half-width); the trimmed one stays on the axis within 0.02 px."""
    rng = np.random.default_rng(16)
    half_width = 3.6
    truth = np.linspace(-1.0, 1.0, 40)  # profiles in order along a wire, 1 px apart
    p = _glinting_profiles(truth, half_width, at, wide) + rng.normal(0.0, 1.0, (40, 801))
    kw = {"rho_px": 0.85 * half_width, "search_px": 2.5, "max_slope_px": 0.4}
    whole, _ = symmetric_centres(p, **kw)
    trimmed, _ = symmetric_centres(p, **kw, trim_share=0.4)
    assert abs(float(np.median(whole - truth))) > 0.05
    np.testing.assert_allclose(trimmed, truth, atol=0.02)


def test_a_valley_barred_from_the_symmetric_search_leaves_the_crest() -> None:
    """A flank's dark valley on a flat sheet is more symmetric than a crest a lamp lights
    a little more on one side: the search finds the valley 7 px out, and with valleys
    barred (``valley_reach_px``) the crest within 0.3 px of the axis."""
    rng = np.random.default_rng(17)
    x = (np.arange(801) - 400) * 0.05
    crest = 150.0 * np.exp(-((x / 2.0) ** 2)) * (1.0 + 0.15 * np.tanh(x))
    valley = -100.0 * np.exp(-(((x - 7.0) / 2.0) ** 2))
    p = 100.0 + crest + valley + rng.normal(0.0, 1.0, (40, 801))
    kw = {"rho_px": 2.5, "search_px": 9.0, "max_slope_px": 0.4}
    free, _ = symmetric_centres(p, **kw)
    barred, _ = symmetric_centres(p, **kw, valley_reach_px=2.0)
    np.testing.assert_allclose(free, 7.0, atol=0.2)
    np.testing.assert_allclose(barred, 0.0, atol=0.3)


def test_zero_mean_correlation_equals_pearsons() -> None:
    """Against numpy's Pearson correlation, whatever the rows' level and scale; a flat row
    correlates 0 and has no contrast."""
    rng = np.random.default_rng(18)
    template = rng.normal(0.0, 1.0, 40)
    rows = 50.0 + 3.0 * (0.7 * template + rng.normal(0.0, 1.0, (6, 40)))
    rows[-1] = 80.0
    corr, contrast = zero_mean_correlation(rows, template)
    want = [np.corrcoef(r, template)[0, 1] for r in rows[:-1]]
    np.testing.assert_allclose(corr[:-1], want, rtol=1e-12)
    np.testing.assert_allclose(contrast[:-1], np.sqrt(40) * np.std(rows[:-1], axis=1), rtol=1e-12)
    assert corr[-1] == 0.0 and contrast[-1] == 0.0


def test_least_cost_path_is_the_least_total_within_reach() -> None:
    """Against an exhaustive search over every path of a small table."""
    import itertools

    rng = np.random.default_rng(13)
    cost = rng.random((5, 6))
    path = least_cost_path(cost, 1)
    c = (cost - cost.min(axis=1, keepdims=True)) / np.ptp(cost, axis=1, keepdims=True)
    best = min(
        (sum(c[i, k] for i, k in enumerate(ks)), ks)
        for ks in itertools.product(range(6), repeat=5)
        if all(abs(a - b) <= 1 for a, b in zip(ks, ks[1:], strict=False))
    )
    assert tuple(path) == best[1]


def test_sample_across_equals_sample_image() -> None:
    rng = np.random.default_rng(14)
    gray = rng.uniform(0, 255, (60, 80)).astype(np.float32)
    centres = rng.uniform(5, 55, (20, 2))
    ang = rng.uniform(0, 2 * np.pi, 20)
    normals = np.column_stack((np.cos(ang), np.sin(ang)))
    offsets = np.arange(-40, 41) * 0.25
    pts = centres[:, None, :] + offsets[None, :, None] * normals[:, None, :]
    np.testing.assert_array_equal(
        sample_across(gray, centres, normals, offsets), sample_image(gray, pts)
    )


@pytest.mark.parametrize("n", [401, 1201])
def test_edge_gradient_equals_the_filtered_profiles_read_at_the_edge(n: int) -> None:
    rng = np.random.default_rng(n)
    p = np.cumsum(rng.normal(0, 3, (300, n)), axis=1)
    offsets = (np.arange(n) - n // 2) * 0.05
    edge = rng.uniform(offsets[0] - 1, offsets[-1] + 1, 300)  # some beyond either end
    edge[::7] = np.nan
    g = np.abs(gaussian_filter1d(p, 10.0, axis=1, order=1)) / 0.05
    k = np.clip(np.round((np.nan_to_num(edge) - offsets[0]) / 0.05).astype(int), 0, n - 1)
    want = np.where(np.isfinite(edge), g[np.arange(300), k], 0.0)
    np.testing.assert_allclose(edge_gradient(p, offsets, edge), want, rtol=1e-12, atol=1e-9)
