import numpy as np

from cvmeasure.geometry import direction_deg, wrap_deg


def test_wrap_deg_range_is_half_open():
    a = wrap_deg(np.array([180.0, -180.0, 190.0, -190.0, 0.0, 720.0, 539.0]))
    np.testing.assert_allclose(a, [180, 180, -170, 170, 0, 0, 179])
    assert wrap_deg(-180.0) == 180.0


def test_direction_deg_quadrants():
    assert direction_deg((0, 0), (1, 1)) == 45.0
    assert direction_deg((0, 0), (-1, 0)) == 180.0
    assert direction_deg((1, 1), (1, 0)) == -90.0
