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
