"""A machine whose form the simulation misses: its no-effect relation learned from the
session, the causes tested on what that curve cannot absorb."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import Cause, diagnose
from cvmeasure.diagnose.fitting import discrepancy_form, fit_model, learned_form
from cvmeasure.driver.session import SessionConfig, nominal_pin_for_loaded_deg
from cvmeasure.sim import SimParams, parse_effect, simulate

#: A machine the default description's form does not reach: the loaded leg bowed 2.5
#: times beam theory's share, the springback's span term tripled and a steeper hardening
#: (the bounded discrepancy leaves the no-effect session beyond the noise).
OTHER_FORM = {"span_bow_share": 2.5, "span_factor": 1.5, "hardening_exponent": 0.45}


def _session(effects=(), machine=OTHER_FORM, noise_deg=0.05, seed=8):
    plan = SessionConfig(mode="standard").plan()
    cmd = np.array([round(nominal_pin_for_loaded_deg(a, d), 3) for d, a in plan])
    rng = np.random.default_rng(seed)
    sim = simulate(cmd, SimParams().replace(**machine), effects)
    noisy = [
        v + rng.normal(0.0, noise_deg, cmd.size)
        for v in (sim.loaded_bend_deg, sim.unloaded_bend_deg, sim.pin_angle_deg)
    ]
    return TrialTable.from_arrays(cmd, noisy[0], noisy[1], measured_pin_deg=noisy[2])


def test_learned_form_spans_the_session():
    form = learned_form(_session())
    # the standard session bends 11 magnitudes from 18.1 to 114.6 deg
    assert form.degree == 5 and form.fit_with_causes
    assert form.span_deg == pytest.approx((18.1, 114.6), abs=0.05)


def test_no_effect_on_another_form_names_nothing_and_says_so():
    result = diagnose(_session())
    assert result.cause == Cause.none() and result.causes == ()
    assert result.misfit is not None and not result.misfit.refused
    assert result.learned is not None and result.learned.degree == 5
    # the curve took up what the simulation's form left beyond the noise: reported as
    # the unnamed discrepancy (held-out RMSE of the simulation's baseline, then the curve's)
    assert result.leftover.unnamed
    assert result.leftover.residual_rmse_deg > 2 * result.leftover.smoothed_rmse_deg
    assert result.to_dict()["learned_curve"]["span_deg"] == pytest.approx([18.1, 114.6], abs=0.05)
    # a machine of the simulation's own form keeps the bounded discrepancy
    assert diagnose(_session(machine={})).learned is None


@pytest.mark.parametrize("effect, tol", [("offset=1.0", 0.05), ("scale=0.03", 0.005)])
def test_a_cause_fitted_beside_the_learned_curve(effect, tol):
    # the baseline's form misses the machine by far more than the noise, the learned
    # curve takes it up and the cause is measured on what the curve cannot absorb (the
    # direction for the offset, the pin for the scale)
    trials = _session((parse_effect(effect),))
    name, value = effect.split("=")
    with discrepancy_form(learned_form(trials)):
        base = fit_model(trials, SimParams(), "none")
        fit = fit_model(trials, SimParams(), name)
    assert fit.values[0] == pytest.approx(float(value), abs=tol)
    lo, hi = fit.intervals[0]
    assert lo <= float(value) <= hi
    assert fit.rmse_deg < 0.08 < base.rmse_deg  # the noise is 0.05 deg
