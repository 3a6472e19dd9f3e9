import numpy as np
import pytest

from cvmeasure.geometry import direction_deg, fit_circle_taubin, mod_positive, wrap_deg


def test_wrap_deg_range_is_half_open():
    a = wrap_deg(np.array([180.0, -180.0, 190.0, -190.0, 0.0, 720.0, 539.0]))
    np.testing.assert_allclose(a, [180, 180, -170, 170, 0, 0, 179])
    assert wrap_deg(-180.0) == 180.0


def test_mod_positive_gives_numpys_remainder_and_wrap_the_same_bits():
    # the fmod form must be numpy's float remainder exactly (the diagnosis' results are
    # pinned byte for byte through wrap_deg and the simulation's wrap_rad)
    rng = np.random.default_rng(5)
    x = np.concatenate(
        [
            rng.normal(0.0, 1e3, 20_000),
            rng.normal(0.0, 1e-15, 2_000),
            np.logspace(-320, 4, 500),
            -np.logspace(-320, 4, 500),
            [0.0, -0.0, 360.0, -360.0, -720.0, 359.99999999999994, -359.99999999999994, 1e300],
        ]
    )
    for period in (360.0, 2 * np.pi):
        np.testing.assert_array_equal(mod_positive(x, period), np.mod(x, period))
    old = 180.0 - np.mod(180.0 - x, 360.0)
    assert np.array_equal(wrap_deg(x).view(np.int64), old.view(np.int64))
    assert np.isnan(wrap_deg(np.nan))


def test_direction_deg_quadrants():
    assert direction_deg((0, 0), (1, 1)) == 45.0
    assert direction_deg((0, 0), (-1, 0)) == 180.0
    assert direction_deg((1, 1), (1, 0)) == -90.0


def test_taubin_fit_exact_points_and_noise():
    t = np.linspace(0, 2 * np.pi, 60, endpoint=False)
    pts = np.column_stack((12.3 + 7.0 * np.cos(t), -4.5 + 7.0 * np.sin(t)))
    centre, r = fit_circle_taubin(pts)
    np.testing.assert_allclose(centre, [12.3, -4.5], atol=1e-9)
    assert r == pytest.approx(7.0, abs=1e-9)
    # a 90 degree arc with 0.01 noise: centre and radius within a few hundredths
    rng = np.random.default_rng(2)
    t = np.radians(np.linspace(0, 90, 200))
    pts = np.column_stack((80 * np.cos(t), 80 * np.sin(t))) + rng.normal(0, 0.01, (200, 2))
    centre, r = fit_circle_taubin(pts)
    assert abs(r - 80.0) < 0.05 and np.hypot(*centre) < 0.05


def test_taubin_fit_refuses_degenerate_input():
    for bad, message in [
        (np.zeros((2, 2)), "at least 3"),
        (np.column_stack((np.arange(5.0), np.zeros(5))), "collinear"),
        (np.array([[0.0, 0.0], [1.0, np.nan], [2.0, 1.0]]), "finite"),
        (np.ones((4, 2)), "same"),
    ]:
        with pytest.raises(ValueError, match=message):
            fit_circle_taubin(bad)


def test_fit_circles_robust_is_each_sets_fit_circle_robust():
    """The vectorised fits equal fit_circle_robust's, set by set (own start, scale, stop)."""
    from cvmeasure.geometry import fit_circle_robust, fit_circles_robust

    rng = np.random.default_rng(7)
    sets, inits = [], []
    for i in range(12):
        n = int(rng.integers(20, 160))
        t = rng.uniform(0, 2 * np.pi if i % 3 else np.pi, n)  # some half circles
        c, r = rng.uniform(-50, 50, 2), rng.uniform(5, 60)
        p = np.column_stack((c[0] + r * np.cos(t), c[1] + r * np.sin(t)))
        p += rng.normal(0, 0.05, (n, 2))
        out = rng.random(n) < 0.15
        p[out] += rng.normal(0, 3, (int(out.sum()), 2))  # outliers the weights drop
        sets.append(p)
        inits.append(None if i % 2 else (c[0] + 0.5, c[1] - 0.3, 1.02 * r))
    sets.append(np.zeros((2, 2)))  # too few points: None, the others unaffected
    inits.append(None)
    factors = [1.0 + 0.1 * i for i in range(len(sets))]
    got = fit_circles_robust(sets, inits=inits, correlation_factors=factors, stop=1e-3)
    assert got[-1] is None
    for p, init, cf, g in zip(sets[:-1], inits, factors, got, strict=False):
        f = fit_circle_robust(p, init=init, correlation_factor=cf, stop=1e-3)
        np.testing.assert_allclose([*g.centre, g.radius], [*f.centre, f.radius], atol=1e-9)
        np.testing.assert_allclose(g.covariance, f.covariance, rtol=1e-9, atol=1e-15)
        assert g.n_inliers == f.n_inliers and g.n_points == f.n_points
        assert g.coverage == f.coverage
        assert g.rms_residual == pytest.approx(f.rms_residual, rel=1e-9)
        assert g.radius_sigma == pytest.approx(f.radius_sigma, rel=1e-9)
