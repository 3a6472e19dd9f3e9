"""The diagnosis' predictions: the batched residuals a fit's forward differences use."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.diagnose.predict import residual_rows, residuals
from cvmeasure.sim import Effect, SimParams


@pytest.mark.parametrize(
    ("causes", "values", "shapes"),
    [
        (("camera_tilt",), (1.5,), ((("tilt_axis_deg", 20.0),),)),
        (("springback_asymmetry",), (0.04,), ((),)),
        (("backlash", "compliance"), (0.6, 0.002), ((), ())),
    ],
)
def test_residual_rows_are_residuals_at_each_point(bent_session, causes, values, shapes):
    # a forward difference's points: the strength, the die's radius, each cause's value;
    # each row the very numbers of residuals at its point (a session bent with an offset
    # and the die's radius off nominal as the fitted nuisance)
    trials = bent_session((Effect("offset", 0.4),), seed=3)
    params, nuisance = SimParams(), (1.7,)  # the die's radius (mm)
    points = [(1.0, values, nuisance), (1.0 + 1.5e-8, values, nuisance), (1.0, values, (1.71,))]
    for k in range(len(values)):
        stepped = list(values)
        stepped[k] += 1e-8 * max(1.0, abs(values[k]))
        points.append((1.0, tuple(stepped), nuisance))
    rows = residual_rows(trials, params, (), causes, points, shapes=shapes)
    assert rows.shape == (len(points), 3 * len(trials))
    for row, (strength, v, die) in zip(rows, points, strict=True):
        one = residuals(trials, params, (), causes, strength, v, nuisance=die, shapes=shapes)
        np.testing.assert_array_equal(row, one)
