import numpy as np
import pytest

from cvmeasure.geometry import direction_deg, fit_circle_taubin, wrap_deg


def test_wrap_deg_range_is_half_open():
    a = wrap_deg(np.array([180.0, -180.0, 190.0, -190.0, 0.0, 720.0, 539.0]))
    np.testing.assert_allclose(a, [180, 180, -170, 170, 0, 0, 179])
    assert wrap_deg(-180.0) == 180.0


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
