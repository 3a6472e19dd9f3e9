"""A machine whose form the simulation misses: its no-effect relation learned from the
session, the causes tested on what that curve cannot absorb."""

from __future__ import annotations

import pytest

from cvmeasure.diagnose import Cause, diagnose
from cvmeasure.diagnose.fitting import discrepancy_form, fit_model, learned_form
from cvmeasure.sim import SimParams, parse_effect

#: A machine the default description's form does not reach: the loaded leg bowed 2.5
#: times beam theory's share, the springback's span term tripled and a steeper hardening
#: (the bounded discrepancy leaves the no-effect session beyond the noise).
OTHER_FORM = {"span_bow_share": 2.5, "span_factor": 1.5, "hardening_exponent": 0.45}


def test_learned_form_spans_the_session(bent_session):
    form = learned_form(bent_session(params=SimParams().replace(**OTHER_FORM), seed=8))
    # the standard session bends 11 magnitudes from 18.1 to 114.6 deg
    assert form.degree == 5 and form.fit_with_causes
    assert form.span_deg == pytest.approx((18.1, 114.6), abs=0.05)


def test_no_effect_on_another_form_names_nothing_and_says_so(bent_session):
    result = diagnose(bent_session(params=SimParams().replace(**OTHER_FORM), seed=8))
    assert result.cause == Cause.none() and result.causes == ()
    assert result.misfit is not None and not result.misfit.refused
    assert result.learned is not None and result.learned.degree == 5
    # the curve took up what the simulation's form left beyond the noise: it is the
    # machine's no-effect relation, so no unnamed discrepancy is raised; what it leaves is
    # the noise (0.05 deg, within 20 %), and the note gives the departure it took up
    assert not result.leftover.unnamed
    assert result.leftover.residual_rmse_deg == pytest.approx(0.05, rel=0.2)
    assert any("learned curve takes up" in n for n in result.notes)
    assert result.to_dict()["learned_curve"]["span_deg"] == pytest.approx([18.1, 114.6], abs=0.05)
    # a machine of the simulation's own form keeps the bounded discrepancy
    assert diagnose(bent_session(seed=8)).learned is None


@pytest.mark.parametrize("effect, tol", [("offset=1.0", 0.05), ("scale=0.03", 0.005)])
def test_a_cause_fitted_beside_the_learned_curve(bent_session, effect, tol):
    # the baseline's form misses the machine by far more than the noise, the learned
    # curve takes it up and the cause is measured on what the curve cannot absorb (the
    # direction for the offset, the pin for the scale)
    trials = bent_session((parse_effect(effect),), params=SimParams().replace(**OTHER_FORM), seed=8)
    name, value = effect.split("=")
    with discrepancy_form(learned_form(trials)):
        base = fit_model(trials, SimParams(), "none")
        fit = fit_model(trials, SimParams(), name)
    assert fit.values[0] == pytest.approx(float(value), abs=tol)
    lo, hi = fit.intervals[0]
    assert lo <= float(value) <= hi
    assert fit.rmse_deg < 0.08 < base.rmse_deg  # the noise is 0.05 deg
