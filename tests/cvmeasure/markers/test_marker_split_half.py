"""What the halves of a disc's edge disagree on beyond their sampling (split_half_cov)."""

from __future__ import annotations

import numpy as np

from cvmeasure.geometry import fit_circle_robust
from cvmeasure.markers.circles import split_half_cov


def _edge(rng, n=400, r=20.0, noise=0.05, bump=0.0):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    # a shadow's edge on one side pushes that quarter of the edge outwards by ``bump``
    rr = r + noise * rng.standard_normal(n) + bump * (np.cos(t) > 0.7)
    return np.column_stack((50 + rr * np.cos(t), 60 + rr * np.sin(t)))


def test_a_clean_edge_adds_little_to_its_sampling_covariance():
    rng = np.random.default_rng(3)
    extra = []
    for _ in range(20):
        pts = _edge(rng)
        fit = fit_circle_robust(pts)
        extra.append(np.trace(split_half_cov(pts, fit)) / np.trace(fit.covariance))
    # the mean of d d^T alone is about 6 times the sampling covariance on these edges
    # (counted a second time); what is left beyond the sampling: its clipped noise only
    assert np.mean(extra) < 2.5, extra
    assert np.median(extra) < 1.0, extra


def test_a_one_sided_bias_is_counted():
    rng = np.random.default_rng(4)
    pts = _edge(rng, bump=0.5)
    fit = fit_circle_robust(pts)
    cov = split_half_cov(pts, fit)
    # the centre is pulled about 0.09 px along x: the term says so, the sampling does not
    shift = fit.centre[0] - 50.0
    assert shift > 0.05
    assert np.sqrt(cov[0, 0]) > 0.5 * shift > 3 * np.sqrt(fit.covariance[0, 0])
