"""The head's once-per-revolution runout is zero at home, where the head is referenced.

``e = a sin(|cmd|) + b (cos(|cmd|) - 1)`` of the head's rotation: without a constant part
it cannot stand in for a loss of the same size on every bend (a backlash), which a runout
``a sin + b cos`` could. A scale, which it looks like over 15-120 deg, is still its rival
and is separated by the follow-up's bends. Cases from
:mod:`cvmeasure_datasets.physical_bender` (no runout of the head in them), the tests' own
seeds.
"""

from __future__ import annotations

import numpy as np

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import Cause, diagnose
from cvmeasure.diagnose.discover import RIVAL_PERIODS, library
from cvmeasure_datasets import physical_bender as pb


def test_the_runout_columns_are_zero_at_home():
    cmd = np.array([30.0, -30.0, 90.0, -90.0, 150.0, -60.0])
    n = cmd.size
    trials = TrialTable.from_arrays(cmd, np.full(n, np.nan), 0.9 * cmd)
    cols = library(trials, None, RIVAL_PERIODS)["gear_runout_360"]
    s, turn = np.sign(cmd), np.radians(np.abs(cmd))
    a, b = 0.4, -0.3  # deg: a runout of the head's rotation, zero at home
    truth = np.tile(s * (a * np.sin(turn) + b * (np.cos(turn) - 1.0)), 3)
    coef, *_ = np.linalg.lstsq(cols, truth, rcond=None)
    assert np.allclose(coef, [a, b], atol=1e-12)
    assert np.allclose(cols @ coef, truth, atol=1e-12)
    # no bend at home: the columns vanish there
    home = TrialTable.from_arrays(np.array([0.0, 1e-9]), np.full(2, np.nan), np.zeros(2))
    assert np.allclose(library(home, None, RIVAL_PERIODS)["gear_runout_360"], 0.0, atol=1e-9)


def test_a_backlash_is_named_without_a_head_runout_tie():
    case = pb.physical_case(501, "backlash", plan="random", n_trials=60)
    truth = case.hidden[0].params["backlash_deg"]  # lost on every bend (share 1)
    result = diagnose(case.trials)
    assert result.cause == Cause.of(["backlash"])
    assert "gear_runout_360" not in result.tie
    lo, hi = result.intervals["backlash_deg"]
    assert lo <= truth <= hi, (truth, lo, hi)


def test_a_scale_tied_with_the_head_runout_is_named_after_its_follow_up():
    case = pb.physical_case(503, "scale", plan="random", n_trials=60)
    truth = case.hidden[0].params["scale"]
    result = diagnose(case.trials)
    assert result.cause == Cause.of(["scale"])
    assert "gear_runout_360" in result.tie
    plan = result.follow_up
    assert plan is not None and "gear_runout_360" in plan.rivals
    assert plan.expected_separation_se >= 2.0
    more = pb.run_follow_up(case, np.asarray(plan.commanded_pin_deg), 503 + 5_000_000)
    again = diagnose(more.trials, follow_up=False)
    assert again.cause == Cause.of(["scale"]) and not again.tie, (again.cause, again.tie)
    lo, hi = again.intervals["scale"]
    assert lo <= truth <= hi, (truth, lo, hi)
