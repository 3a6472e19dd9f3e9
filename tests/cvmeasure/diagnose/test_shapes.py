"""A cause's continuous shape is fitted off the grid of forms: a large camera tilt about
an axis between the grid's points, and an asymmetric wire whose loaded leg moves by an
amount between them, are named (not refused for lack of fit) with the shape measured."""

from __future__ import annotations

import numpy as np

from cvmeasure.diagnose import diagnose
from cvmeasure.diagnose.fitting import fit_model
from cvmeasure.diagnose.rules import MIN_DELTA_BIC, bic_gain
from cvmeasure.sim import Effect, SimParams

NOISE_DEG = 0.035


def test_a_large_tilt_about_an_axis_between_grid_points_is_named_with_its_axis(bent_session):
    # the grid tries the axis every 15 deg; 24.8 deg of tilt about 9.7 deg (5 deg from the
    # nearest point) left a 0.4 deg rms misfit on the grid's axis and was refused
    effect = Effect("camera_tilt", 24.8, (("tilt_axis_deg", 9.7),))
    result = diagnose(bent_session((effect,), noise_deg=NOISE_DEG, seed=3), follow_up=False)
    assert result.causes == ("camera_tilt",)
    assert abs(result.params["tilt_deg"] - 24.8) < 1.5  # deg
    fit = result.extended_fit
    axis = dict(fit.shapes_by_cause()["camera_tilt"])["tilt_axis_deg"]
    assert abs(axis - 9.7) < 2.0  # deg, off the grid's 15
    assert not (result.misfit is not None and result.misfit.refused)


def test_the_loaded_leg_of_an_asymmetric_wire_is_fitted_between_grid_points(bent_session):
    effect = Effect("springback_asymmetry", 0.5, (("loaded_deg", -1.6),))
    trials = bent_session((effect,), noise_deg=NOISE_DEG, seed=5)
    fit = fit_model(trials, SimParams(), "springback_asymmetry")
    shape = dict(fit.shapes_by_cause()["springback_asymmetry"])
    assert (
        abs(shape["loaded_deg"] - (-1.6)) < 0.25
    )  # deg per unit of asymmetry (the grid: -1, 0, 1)
    assert abs(fit.param_values()["asymmetry"] - 0.5) < 0.05
    # the noise is all that is left
    rms = float(np.sqrt(fit.rss_deg2 / (3 * len(trials))))
    assert rms < 1.5 * NOISE_DEG


def test_a_refined_shape_counts_as_a_parameter_of_its_cause(bent_session):
    # the tilt's axis, fitted off the grid, is charged in the BIC like the tilt's size
    tilted = Effect("camera_tilt", 24.8, (("tilt_axis_deg", 9.7),))
    trials = bent_session((tilted,), noise_deg=NOISE_DEG, seed=3)
    base = fit_model(trials, SimParams(), "none", intervals=False)
    tilt = fit_model(trials, SimParams(), "camera_tilt", intervals=False)
    assert "tilt_axis_deg" in dict(tilt.shapes_by_cause()["camera_tilt"])
    assert tilt.n_cause_params == 2  # the tilt and its axis
    assert tilt.n_params - base.n_params == 2


def test_a_tilt_beside_a_second_cause_keeps_the_grid_axis(bent_session):
    # the tilt tried beside the offset as the naming tries a second cause (the offset held
    # at its own fit): its axis stays on the grid (every 15 deg), carried in the intervals
    # as the grid's rounding; refined beside a refitted offset it would take up the
    # offset's own signature and another machine's form error
    trials = bent_session((Effect("offset", 2.0),), noise_deg=NOISE_DEG, seed=11)
    offset = fit_model(trials, SimParams(), "offset")
    pair = fit_model(
        trials,
        SimParams(),
        ("offset", "camera_tilt"),
        known={**offset.param_values_by_cause(), **offset.nuisance_values()},
        known_shapes=offset.shapes_by_cause(),
    )
    axis = dict(pair.shapes_by_cause()["camera_tilt"]).get("tilt_axis_deg", 0.0)
    assert axis % 15.0 == 0.0  # deg: a grid point
    assert bic_gain(offset, pair) < MIN_DELTA_BIC
    assert pair.param_values()["tilt_deg"] < 1.0  # deg: no tilt made up
    result = diagnose(trials, follow_up=False)
    assert result.causes == ("offset",)
    lo, hi = result.intervals["offset_deg"]
    assert lo <= 2.0 <= hi
