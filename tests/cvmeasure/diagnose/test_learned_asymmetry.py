"""A springback asymmetry beside the learned no-effect curve: it splits the springback
the learned baseline predicts, whatever the wire's mean springback."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.fitting import discrepancy_form, fit_model, learned_baseline_form
from cvmeasure.sim import Effect, SimParams, simulate

#: A machine the default description's form does not reach (as in
#: test_learned_baseline), its springback about 1.6 times the description's: the loaded
#: leg bowed 2.5 times beam theory's share, the springback's span term tripled and a
#: steeper hardening.
OTHER_FORM = {"span_bow_share": 2.5, "span_factor": 1.5, "hardening_exponent": 0.45}


def test_the_machine_springs_back_more_than_described():
    cmd = np.array([20.0, 60.0, 110.0])
    own = simulate(cmd, SimParams().replace(**OTHER_FORM)).springback_deg
    described = simulate(cmd, SimParams()).springback_deg
    assert np.all(own > 1.4 * described)


@pytest.mark.parametrize("asymmetry", [0.3, -0.45])
def test_asymmetry_measured_on_the_learned_springback(bent_session, asymmetry):
    # the machine's own springback split by (1 + dir * alpha): beside the learned curve the
    # fitted alpha is the truth, not the split measured in the description's (smaller)
    # springback, which would read it about 1.6 times too large
    trials = bent_session(
        (Effect("springback_asymmetry", asymmetry),),
        params=SimParams().replace(**OTHER_FORM),
        seed=11,
    )
    form = learned_baseline_form(trials, SimParams())
    assert form.springback_excess  # the learned baseline springs back more
    with discrepancy_form(form):
        fit = fit_model(trials, SimParams(), "springback_asymmetry")
    assert fit.values[0] == pytest.approx(asymmetry, abs=0.05)
    lo, hi = fit.intervals[0]
    assert lo <= asymmetry <= hi
    assert fit.rmse_deg < 0.08  # the noise is 0.05 deg


def test_asymmetric_loaded_departure_beside_the_learned_curve(bent_session):
    # the machine's loaded leg departs from the description's (the bow it has and the
    # description lacks) and a wire stronger one way splits that departure by direction:
    # magnitude times (1 - dir * alpha), the released leg moving with it
    asymmetry = 0.4
    trials = bent_session(
        (Effect("springback_asymmetry", asymmetry),),
        params=SimParams().replace(**OTHER_FORM),
        seed=11,
    )
    cmd = trials.commanded_pin_deg
    own = simulate(cmd, SimParams().replace(**OTHER_FORM)).loaded_bend_deg
    departure = np.abs(own) - np.abs(simulate(cmd, SimParams()).loaded_bend_deg)
    assert np.all(departure > 0.3)  # the bow leads the description's leg
    shift = -asymmetry * departure  # signed: the same both ways
    moved = TrialTable.from_arrays(
        cmd,
        trials.loaded_bend_deg + shift,
        trials.unloaded_bend_deg + shift,
        measured_pin_deg=trials.measured_pin_deg,
    )
    form = learned_baseline_form(moved, SimParams())
    with discrepancy_form(form):
        fit = fit_model(moved, SimParams(), "springback_asymmetry")
        narrow = fit_model(
            moved,
            SimParams(),
            "springback_asymmetry",
            known={"springback_asymmetry": 0.3},
            known_shapes={"springback_asymmetry": ()},
        )
    shape = dict(fit.shapes[0])
    assert shape["learned_loaded_share"] == -1.0
    # a constant loaded shift (the simulation's own general form, refined off the grid
    # when fitted alone) is not what moved the leg
    assert abs(shape.get("loaded_deg", 0.0)) < 0.1
    assert fit.values[0] == pytest.approx(asymmetry, abs=0.05)
    assert fit.rmse_deg < 0.08 < narrow.rmse_deg  # the noise is 0.05 deg
