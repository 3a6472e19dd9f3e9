"""Two causes hidden together in the independent physical model (not ``simulate``).

Seeds are the tests' own (below 1000); the benchmark's start at 700,000.
"""

from __future__ import annotations

import pytest

from cvmeasure.diagnose import diagnose
from cvmeasure_datasets import physical_bender as pb


def test_a_tilt_beside_a_scale_gets_its_axis_chosen_again_with_the_pair():
    # a camera tilted about an axis at 33 deg and a scale of -0.02 (random order): the
    # tilt alone fits best about the 15 deg axis, where it takes up the scale's part; held
    # there, a scale added on top gains nothing (on main only the tilt was named). With
    # the axis chosen again beside the scale both are named, the axis at the grid point
    # next to the truth (grid step 15 deg).
    case = pb.physical_case(640, ("camera_tilt", "scale"), plan="random", n_trials=60)
    tilt, scale = (h.params for h in case.hidden)
    result = diagnose(case.trials)
    assert set(result.causes) == {"camera_tilt", "scale"}, (result.causes, result.notes)
    assert result.params["tilt_deg"] == pytest.approx(tilt["tilt_deg"], abs=1.5)
    assert result.params["tilt_axis_deg"] == pytest.approx(tilt["tilt_axis_deg"], abs=15.0)
    # the scale comes out low (model-form error of the physical model along the scale's
    # own signature), but with its sign and within 0.01 of the truth (typical 0.015-0.06)
    assert result.params["scale"] * scale["scale"] > 0
    assert result.params["scale"] == pytest.approx(scale["scale"], abs=0.01)


def test_a_right_pair_is_not_refused_for_the_model_form_error_it_leaves():
    # axis offset + compliance on a sweep: the pair explains the data (delta BIC in the
    # hundreds) but, as every right pair on the physical model, leaves structure beyond
    # the bounded discrepancy (the generator's bowed span, its Voce hardening); that
    # refused the pair on main (only the axis offset named)
    case = pb.physical_case(640, ("axis_offset", "compliance"), plan="sweep", n_trials=60)
    axis, compliance = (h.params for h in case.hidden)
    result = diagnose(case.trials)
    assert set(result.causes) == {"axis_offset", "compliance"}, (result.causes, result.notes)
    assert result.params["axis_offset_mm"] == pytest.approx(axis["axis_offset_mm"], abs=0.03)
    # the compliance lag comes out 20-45 % low on the physical model (its span bows
    # elastically ahead of the chord; docs/diagnosis.md, Limits)
    true_c = compliance["compliance_deg_per_nm"]
    assert 0.5 * true_c <= result.params["compliance_deg_per_nm"] <= 1.1 * true_c


@pytest.mark.parametrize(("seed", "plan"), [(620, "random"), (607, "repeats")])
def test_a_drift_shifting_home_beside_an_offset_is_named(seed, plan):
    # an offset and a drift whose lost steps shift home (the generator's: whole steps
    # of 0.06 deg, load-dependent): on main only the offset was named, the second round
    # never entered (no residual trend it screened for follows a home shift, which walks
    # about zero on a balanced plan). Screened by the home-shift walk, both are named.
    case = pb.physical_case(seed, ("offset", "drift"), plan=plan, n_trials=60)
    offset, _ = (h.params for h in case.hidden)
    result = diagnose(case.trials)
    assert set(result.causes) == {"offset", "drift"}, (result.causes, result.notes)
    assert not result.tie
    assert result.params["offset_deg"] == pytest.approx(offset["offset_deg"], abs=0.3)
    assert result.params["home_shift"] == 1.0  # the general form, not the spec's helix
    # the rate of whole steps is poorly determined (typical 0.015-0.06 deg per bend)
    assert 0.0075 <= result.params["drift_deg_per_bend"] <= 0.09


def test_play_beside_a_springback_asymmetry_on_a_sweep_is_not_named_a_compliance():
    # play of 0.93 deg lost on every bend (a sweep reverses at every bend) beside a
    # springback asymmetry of -0.35 (the generator's: the wire's strength differs by
    # direction). Play and a drive compliance are both a nearly constant under-bend; with
    # the compliance's torque the same in both directions, compliance + asymmetry was
    # named (tied with backlash + asymmetry). A wire whose springback differs by direction
    # takes a moment, hence a pin torque, that differs in the same ratio: the compliance's
    # lag then differs by direction, which play does not, and the pair is backlash + asymmetry.
    case = pb.physical_case(664, ("backlash", "springback_asymmetry"), plan="sweep", n_trials=60)
    _, asymmetry = (h.params for h in case.hidden)
    result = diagnose(case.trials)
    assert set(result.causes) == {"backlash", "springback_asymmetry"}, (result.causes, result.tie)
    assert "compliance + springback_asymmetry" not in result.tie
    lo, hi = result.intervals["asymmetry"]
    assert lo <= asymmetry["asymmetry"] <= hi
    # the play comes out low (the generator's span bows ahead of the chord), within 0.5 deg
    assert result.params["backlash_deg"] == pytest.approx(
        case.hidden[0].params["backlash_deg"], abs=0.5
    )


@pytest.mark.parametrize("seed", [900, 912])
def test_a_second_cause_is_not_named_where_a_drift_beside_the_offset_ties_it(seed):
    # an offset and a drift on a sweep (each angle bent ccw then cw): the next reverse
    # bend undoes a drift's home shift, so its rate runs far beyond a typical size along
    # offset + constant and the pair is refused; before f8a404c the next pair, an axis offset
    # (900) or a scale (912) beside the offset, was named with no tie. The refused pair
    # explains the held-out data as well (one-standard-error rule), so the second cause
    # is not settled: the offset is named alone, with a note naming the drift, and its
    # interval (the hull over the tied explanations, the drift's pair among them) holds
    # the truth (the estimate is 0.11-0.33 deg off: the offset moves with the drift's
    # rate, which a sweep does not determine)
    case = pb.physical_case(seed, ("offset", "drift"), plan="sweep", n_trials=60)
    offset, _ = (h.params for h in case.hidden)
    result = diagnose(case.trials, follow_up=False)
    assert result.causes == ("offset",), (result.causes, result.tie, result.notes)
    assert any("not settled" in n and "drift" in n for n in result.notes), result.notes
    lo, hi = result.intervals["offset_deg"]
    assert lo <= offset["offset_deg"] <= hi, (lo, hi, offset)
    assert result.params["offset_deg"] == pytest.approx(offset["offset_deg"], abs=0.5)
