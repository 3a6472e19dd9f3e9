"""A held-out tie gets a follow-up plan; run on the independent model, it names the truth."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from benchmarks.diagnosis_independent import with_pin_read
from benchmarks.diagnosis_session import follow_up_trials, make_case
from cvmeasure.cli import main
from cvmeasure.diagnose import diagnose
from cvmeasure.diagnose.follow_up import FOLLOW_UP_SIZES, REACH_DEG
from cvmeasure_datasets import physical_bender as pb


def _feasible(case: pb.PhysicalCase, commands: tuple[float, ...]) -> None:
    data = np.abs(case.trials.commanded_pin_deg)
    mag = np.abs(np.asarray(commands))
    assert FOLLOW_UP_SIZES[0] <= len(commands) <= FOLLOW_UP_SIZES[-1]
    assert np.all(mag >= data.min() - 0.05)
    assert np.all(mag <= max(REACH_DEG, data.max()) + 0.05)
    assert np.allclose(np.round(mag, 1), mag)  # 0.1 deg commands


@pytest.mark.parametrize(
    ("seed", "hidden", "rival", "order"),
    [
        (943, "drift", "axis_offset", "sweep"),  # a home shift, tied with an axis offset
        (946, "compliance", "scale", "sweep"),  # the bowed compliance and the straight scale
        # the wire's compliance and the head's once-per-revolution runout, on runs of
        # repeated commands: told apart by the pin the follow-up reads (below)
        (960, "compliance", "gear_runout_360", "repeats"),
    ],
)
def test_a_tie_on_the_independent_model_is_separated_by_its_follow_up(seed, hidden, rival, order):
    case = pb.physical_case(seed, hidden, plan=order, n_trials=60)
    result = diagnose(case.trials)
    # the data leave it open (library terms that fit as well within the noise tie too:
    # drift with a curved trend, a compliance or scale with the head's runout; a trend
    # along the run is left to a random order, not planned for)
    assert {hidden, rival} <= set(result.tie)
    plan = result.follow_up
    assert plan is not None and {hidden, rival} <= set(plan.rivals)
    assert not any(r.startswith(("warm_up", "order_squared")) for r in plan.rivals)
    _feasible(case, plan.commanded_pin_deg)
    assert plan.first_trial == len(case.trials) + 1
    assert plan.expected_separation_se >= 1.0
    d = result.to_dict()["follow_up"]
    assert d["n_trials"] == plan.n_trials == len(d["commanded_pin_deg"])
    # run on the same machine after the data (its state continued), append, diagnose again
    # the data have loaded photos but no pin readings: the plan asks for the pin on its own
    assert not case.trials.has_pin and plan.read_pin and d["read_pin"]
    more = pb.run_follow_up(case, plan.commanded_pin_deg, seed + 1)
    assert np.array_equal(more.trials.unloaded_bend_deg[:60], case.trials.unloaded_bend_deg)
    again = diagnose(with_pin_read(case, more.trials, plan.read_pin), follow_up=False)
    assert again.cause.primary == hidden and again.tie == ()
    assert again.follow_up is None
    if rival == "gear_runout_360":
        # the same bends without the pin leave the head's runout tied: the bend angles'
        # smooth model-form curve takes up what tells it from the wire's compliance
        assert rival in diagnose(more.trials, follow_up=False).tie


def test_the_follow_up_continues_the_machines_state():
    """Bent after the data, a drift's home shift carries on from where the data left it:
    the same commands bent on a fresh machine differ."""
    case = pb.physical_case(943, "drift", plan="sweep", n_trials=60)
    cmd = np.full(12, 60.0)
    after = pb.run_follow_up(case, cmd, 1)
    fresh = pb.bend(cmd, case.machine, case.hidden)
    cont = pb.bend(after.trials.commanded_pin_deg, case.machine, case.hidden)
    assert len(after.trials) == 72
    assert np.allclose(cont.unloaded_deg[60:], after.trials.unloaded_bend_deg[60:], atol=0.5)
    assert np.max(np.abs(cont.unloaded_deg[60:] - fresh.unloaded_deg)) > 0.05


def test_cli_writes_the_follow_up_plan(tmp_path, capsys):
    case = pb.physical_case(943, "drift", plan="sweep", n_trials=60)
    trials = case.trials.write_csv(tmp_path / "t.csv")
    plan_csv = tmp_path / "next.csv"
    assert main(["diagnose", str(trials), "--json", "--follow-up-csv", str(plan_csv)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["follow_up_csv"] == str(plan_csv)
    with plan_csv.open() as f:
        rows = list(csv.DictReader(f))
    assert list(rows[0]) == ["trial", "commanded_pin_deg"]
    assert [float(r["commanded_pin_deg"]) for r in rows] == out["follow_up"]["commanded_pin_deg"]
    assert rows[0]["trial"] == "61"
    # the plan is what `cvmeasure simulate` reads
    sim_out = tmp_path / "sim.csv"
    assert main(["simulate", str(plan_csv), "-o", str(sim_out)]) == 0


def test_a_tie_with_the_previous_bend_is_planned_for_and_separated():
    # a quick calibration session on the independent model with a drift hidden: the
    # previous bend's coupling (an order term) ties with it; the follow-up plan varies the
    # sequence of directions the coupling follows, and run on the same machine it names
    # the drift alone
    case = make_case("physical", 103, "drift", "quick")
    result = diagnose(case.trials)
    assert result.cause.primary == "drift" and "previous_bend" in result.tie
    plan = result.follow_up
    assert plan is not None and {"drift", "previous_bend"} <= set(plan.rivals)
    assert not any(r.startswith(("warm_up", "order_squared")) for r in plan.rivals)
    again = diagnose(follow_up_trials(case, np.asarray(plan.commanded_pin_deg)), follow_up=False)
    assert again.causes == ("drift",) and again.tie == ()
