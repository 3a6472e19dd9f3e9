"""The head's once-per-revolution runout is an error at its absolute angle.

Both sides bend from one home, so a ccw bend of ``c`` ends at head angle ``+c`` and a cw
bend at ``-c``: the runout ``e(X) = a sin X + b (cos X - 1)`` (zero at home) is the same
in both directions only in its odd part. A backlash (the same loss each way) is then no
rival of it, and a scale, which it looks like over 15-120 deg, is separated by the
follow-up's bends. Cases from :mod:`cvmeasure_datasets.physical_bender` (no runout of the
head in them), the tests' own seeds.
"""

from __future__ import annotations

import numpy as np

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import Cause, diagnose
from cvmeasure.diagnose.discover import RIVAL_PERIODS, library
from cvmeasure_datasets import physical_bender as pb


def test_the_runout_columns_are_the_head_angle_s_sine_and_cosine():
    cmd = np.array([30.0, -30.0, 90.0, -90.0, 150.0, -60.0])
    n = cmd.size
    trials = TrialTable.from_arrays(cmd, np.full(n, np.nan), 0.9 * cmd)
    cols = library(trials, None, RIVAL_PERIODS)["gear_runout_360"]
    x = np.radians(cmd)
    a, b = 0.4, -0.3  # deg: a runout of the head at its absolute angle, zero at home
    truth = np.tile(a * np.sin(x) + b * (np.cos(x) - 1.0), 3)
    coef, *_ = np.linalg.lstsq(cols, truth, rcond=None)
    assert np.allclose(coef, [a, b], atol=1e-12)
    assert np.allclose(cols @ coef, truth, atol=1e-12)
    # a ccw and a cw bend of one size (rows 0 and 1: +-30 deg) sample the head at +-30
    # deg: the signed error's odd part flips with the side, its even part does not
    assert np.isclose(cols[0, 0], -cols[1, 0]) and abs(cols[0, 0]) > 0.4
    assert np.isclose(cols[0, 1], cols[1, 1]) and abs(cols[0, 1]) > 0.1


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
    assert plan.expected_separation_se >= 4.0
    more = pb.run_follow_up(case, np.asarray(plan.commanded_pin_deg), 503 + 5_000_000)
    again = diagnose(more.trials, follow_up=False)
    assert again.cause == Cause.of(["scale"]) and not again.tie, (again.cause, again.tie)
    lo, hi = again.intervals["scale"]
    assert lo <= truth <= hi, (truth, lo, hi)
