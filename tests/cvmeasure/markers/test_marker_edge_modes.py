"""What a disc's edge read another way (another channel weighting) disagrees on (edge_mode_cov)."""

from __future__ import annotations

import numpy as np

from cvmeasure.geometry import fit_circle_robust
from cvmeasure.kit import default_kit
from cvmeasure.markers import measure_machine_photo
from cvmeasure.markers.circles import edge_mode_cov
from cvmeasure_datasets import render_bender_photo
from cvmeasure_datasets.effects import SceneEffects


def _edge(rng, n=300, r=40.0, noise=0.05, shift=(0.0, 0.0)):
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    rr = r + noise * rng.standard_normal(n)
    return np.column_stack((50 + shift[0] + rr * np.cos(t), 60 + shift[1] + rr * np.sin(t)))


def test_a_shifted_reading_is_counted():
    rng = np.random.default_rng(5)
    fit = fit_circle_robust(_edge(rng))
    # the other channel's edge sits 0.03 px off along x: a bias its residuals cannot see
    other = _edge(rng, shift=(0.03, 0.0))
    cov = edge_mode_cov(other, fit)
    d = fit_circle_robust(other).centre[0] - fit.centre[0]
    assert abs(d - 0.03) < 0.015
    # half of d d^T: each reading's own bias when the two are alike
    assert abs(np.sqrt(cov[0, 0]) - abs(d) / np.sqrt(2)) < 0.005, (cov, d)
    assert np.sqrt(cov[0, 0]) > 3 * np.sqrt(fit.covariance[0, 0])
    assert np.sqrt(cov[1, 1]) < 0.01


def test_two_clean_readings_add_little_to_the_sampling_covariance():
    rng = np.random.default_rng(6)
    extra = [
        np.trace(edge_mode_cov(_edge(rng), fit)) / np.trace(fit.covariance)
        for fit in (fit_circle_robust(_edge(rng)) for _ in range(20))
    ]
    # independent readings without bias differ by their sampling alone, which the
    # term leaves out: what is left is its clipped noise
    assert np.median(extra) < 1.0, extra
    assert np.mean(extra) < 2.0, extra


def test_too_few_points_add_nothing():
    rng = np.random.default_rng(7)
    fit = fit_circle_robust(_edge(rng))
    assert not np.any(edge_mode_cov(_edge(rng, n=5), fit))


def test_centre_sigma_on_demosaiced_photos_holds_the_true_centres():
    z = []
    for seed in (2, 3):
        photo = render_bender_photo(
            pin_angle_deg=40.0 + 10 * seed,
            bend_angle_deg=35.0 + 9 * seed,
            seed=seed,
            scale=0.5,
            effects=SceneEffects.only("bayer"),
        )
        res = measure_machine_photo(photo.bgr, default_kit().flat())
        for role, m in res.markers.items():
            tx, ty = photo.truth["markers"][role]["ellipse_centre_px"]
            # per-axis standard uncertainty: |2D error| / (sigma sqrt 2) has RMS 1 if honest
            z.append(np.hypot(m.x_px - tx, m.y_px - ty) / (m.sigma_px * np.sqrt(2)))
    # ten centres off by 0.01-0.02 px under the mosaic: the stated sigma their size
    # (RMS 0.5-1.5) and none beyond 3.5 sigma
    assert 0.5 < np.sqrt(np.mean(np.square(z))) < 1.5, z
    assert max(z) < 3.5, z
