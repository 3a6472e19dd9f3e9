"""Hide an effect in simulated trials and require the diagnosis to find it."""

from __future__ import annotations

import pytest

from cvmeasure.diagnose import Cause, core, diagnose, fitting
from cvmeasure.diagnose.fitting import UNFITTED_PRIOR_SD
from cvmeasure.sim import EFFECT_NAMES, EFFECTS, SimParams
from cvmeasure_datasets import physical_bender as pb
from cvmeasure_datasets.trials import hidden_case

HIDDEN = [name for name in EFFECT_NAMES if name != "none"]


@pytest.mark.parametrize("seed", [11, 12])
@pytest.mark.parametrize("name", HIDDEN)
def test_hidden_effect_is_named_and_recovered(name, seed):
    case = hidden_case(seed, effect=name, n_trials=40)
    result = diagnose(case.trials)
    assert result.cause.primary == name
    key = EFFECTS[name].param
    lo, hi = result.intervals[key]
    # A 95 % interval misses 1 case in 20 by design (its coverage over many seeds is
    # measured in benchmarks/diagnosis.py); here the truth must lie within 1.7 half-widths
    # (about 3.3 standard errors), which a correct interval misses 1 time in 1000.
    half = 0.5 * (hi - lo)
    assert abs(result.params[key] - case.effect.value) <= 1.7 * half, (case.effect.value, (lo, hi))
    # the interval is informative: narrower than a quarter of the effect's typical size
    # (it includes the dead zone's prior, which a nearly constant under-bend such as the
    # compliance lag is correlated with), and for play lost on every bend, which is a
    # constant under-bend like the dead zone itself, than that plus the prior's 95 % width
    # (0.3: the interval is the hull of those about the estimate and about the joint fit
    # with the dead zone, whose pull is the compliance's own shape). The compliance lag takes
    # part of the dead zone's prior (0.25 deg): 0.155 / 0.235 wide at seeds 11 / 12 (0.118 /
    # 0.160 with a 0.1 deg prior, 0.025 / 0.103 with the dead zone known), so its allowance
    # is 0.2 of its typical 0.6 on top
    dead_zone = 2 * 1.96 * dict(UNFITTED_PRIOR_SD)["approach_deg"] if name == "backlash" else 0
    if name == "compliance":
        dead_zone = 0.2 * EFFECTS[name].typical[1]
    assert hi - lo < 0.3 * EFFECTS[name].typical[1] + dead_zone
    # held-out error improves, and the extended model sits near the noise floor
    assert result.extended_rmse_deg < 0.6 * result.baseline_rmse_deg
    assert result.extended_rmse_deg < 1.5 * case.noise_deg
    assert result.noise_floor_deg == pytest.approx(case.noise_deg, rel=0.3)
    assert not result.leftover.unnamed


@pytest.mark.parametrize("seed", [21, 22, 23, 24])
def test_null_data_names_nothing(seed):
    case = hidden_case(seed, effect="none", n_trials=40)
    result = diagnose(case.trials)
    assert result.cause == Cause.none()
    assert result.params == {} and result.intervals == {}
    assert result.extended_rmse_deg == result.baseline_rmse_deg
    assert result.baseline_rmse_deg < 1.3 * case.noise_deg
    assert any("noise floor" in note for note in result.notes)
    assert all(not c.accepted for c in result.candidates)
    assert not result.leftover.unnamed


def test_every_candidate_reported_with_held_out_error():
    case = hidden_case(5, effect="drift", n_trials=30)
    result = diagnose(case.trials)
    names = sorted(c.cause for c in result.candidates)
    assert names == sorted(HIDDEN)
    best = min(result.candidates, key=lambda c: c.cv_rmse_deg)
    assert best.cause == "drift" and best.accepted
    d = result.to_dict()
    for key in ("cause", "params", "baseline_rmse_deg", "extended_rmse_deg", "candidates"):
        assert key in d
    assert d["candidates"][0]["cv_rmse_deg"] == pytest.approx(result.extended_rmse_deg)


def test_yield_nuisance_is_not_an_effect():
    # a softer wire lot (yield and UTS -15 %) is absorbed by the nuisance fit, not named
    from cvmeasure.sim import SimParams

    soft = SimParams().replace(yield_mpa=238.0, uts_mpa=340.0)
    case = hidden_case(31, effect="none", n_trials=40, params=soft)
    result = diagnose(case.trials, SimParams())
    assert result.cause == Cause.none()
    assert result.baseline_fit.strength_scale == pytest.approx(0.85, abs=0.05)


def test_die_radius_is_fitted_as_the_users_machine_not_named_as_a_cause():
    # the real die edge is 2.0 mm, the model says 1.5 mm: a nuisance of the baseline
    # (normal prior 1.5 +- 0.2 mm), recovered from the data; nothing is named
    from cvmeasure.sim import SimParams

    case = hidden_case(32, effect="none", n_trials=60, params=SimParams(die_radius_mm=2.0))
    result = diagnose(case.trials, SimParams())
    assert result.cause == Cause.none() and not result.leftover.unnamed
    assert result.baseline_fit.nuisance_values()["die_radius_mm"] == pytest.approx(2.0, abs=0.03)
    assert result.baseline_rmse_deg < 1.3 * case.noise_deg


def test_discrepancy_outside_the_catalogue_is_reported_unnamed():
    # the head axis sits 1 mm off where the model puts it: the kinematics differ in shape
    # (no effect of the catalogue nor the nuisance geometry reproduces it); the best
    # candidate leaves far more than the noise; terms outside the catalogue (fitted with a
    # linearised refit of the machine) explain more, held out and in evidence, so no
    # catalogue name is given (it was: one name and the leftover check's flag)
    from cvmeasure.sim import SimParams

    case = hidden_case(32, effect="none", n_trials=60, params=SimParams(head_axis_x_mm=1.0))
    result = diagnose(case.trials, SimParams())
    assert result.extended_rmse_deg > 5 * case.noise_deg
    assert result.cause == Cause.unexplained() and result.causes == ()
    assert result.discovered and result.gain > 0.5
    assert result.evidence[0][0] == "unexplained (discovered terms)"
    assert any("terms outside the catalogue explain the data better" in n for n in result.notes)


@pytest.mark.parametrize(
    "hidden",
    [
        (("backlash", 1.5), ("springback_asymmetry", 0.4)),
        (("offset", 1.0), ("drift", 0.03)),
    ],
)
def test_two_causes_at_once_are_both_named(hidden):
    import numpy as np

    from cvmeasure.sim import Effect
    from cvmeasure_datasets.trials import measure_trials, random_plan

    rng = np.random.default_rng(71)
    effects = tuple(Effect(n, v) for n, v in hidden)
    trials = measure_trials(random_plan(rng, 60), effects, 0.07, rng)
    result = diagnose(trials)
    assert set(result.causes) == {n for n, _ in hidden}
    for name, value in hidden:
        key = EFFECTS[name].param
        lo, hi = result.intervals[key]
        assert abs(result.params[key] - value) <= 1.7 * 0.5 * (hi - lo)
    assert result.extended_rmse_deg < 1.5 * 0.07
    assert any("second cause" in note for note in result.notes)


def test_single_cause_is_not_split_in_two():
    case = hidden_case(13, effect="axis_offset", n_trials=60)
    result = diagnose(case.trials)
    assert result.causes == ("axis_offset",)
    assert diagnose(case.trials, max_causes=1).causes == ("axis_offset",)


def test_measured_pin_angles_are_used():
    # released angles only: offset and springback asymmetry look alike (similarity 0.998);
    # the pin angle on the loaded photo separates them (offset moves the pin, asymmetric
    # springback does not)
    without = diagnose(
        hidden_case(17, effect="springback_asymmetry", n_trials=40, loaded=False).trials
    )
    assert any(not i.separable for i in without.identifiability)
    case = hidden_case(17, effect="springback_asymmetry", n_trials=40, loaded=False, pin=True)
    assert case.trials.has_pin
    result = diagnose(case.trials)
    assert result.cause.primary == "springback_asymmetry"
    assert all(i.separable for i in result.identifiability)
    key = "asymmetry"
    lo, hi = result.intervals[key]
    assert abs(result.params[key] - case.effect.value) <= 1.7 * 0.5 * (hi - lo)


def test_grouped_cv_by_part_and_single_part_fallback():
    case = hidden_case(19, effect="backlash", n_trials=40)
    parts = tuple(f"part{i // 5}" for i in range(40))  # 8 parts of 5 bends
    grouped = diagnose(case.trials.with_groups(parts))
    assert grouped.cause.primary == "backlash" and grouped.n_folds == 8  # leave one part out
    one_part = diagnose(case.trials.with_groups(("p",) * 40))
    assert one_part.cause.primary == "backlash" and one_part.n_folds == 5
    assert any("fewer than 3 parts" in note for note in one_part.notes)


def test_garbage_data_name_nothing():
    import numpy as np

    from cvmeasure.contracts import TrialTable

    rng = np.random.default_rng(5)
    cmd = np.linspace(20.0, 120.0, 12) * np.where(np.arange(12) % 2, 1.0, -1.0)
    # angles in the wrong units (radians) and with a flipped sign: nothing fits
    truth = diagnose(hidden_case(5, effect="none", n_trials=12).trials)
    assert truth.cause == Cause.none()
    garbage = TrialTable.from_arrays(cmd, -np.radians(cmd), rng.normal(0.0, 30.0, 12))
    result = diagnose(garbage)
    assert result.cause == Cause.none() and result.causes == ()
    assert any("does not describe these data" in note for note in result.notes)


def test_very_many_trials_are_diagnosed_on_a_stated_subset(monkeypatch):
    import cvmeasure.diagnose.core as core

    monkeypatch.setattr(core, "MAX_TRIALS", 150)  # the real bound is 5,000 (benchmarked)
    case = hidden_case(23, effect="backlash", n_trials=400)
    result = diagnose(case.trials)
    assert result.n_trials <= 150 and result.cause.primary == "backlash"
    assert any("random subset of" in note and "400 trials" in note for note in result.notes)


def test_a_cause_whose_interval_holds_no_effect_is_not_named_on_a_no_effect_sweep():
    # independent physical model, nothing hidden, a sweep (development seed 310064, not
    # the benchmark's): the model-form error beyond the discrepancy's bound passed as a
    # scale of 0.010 (delta BIC 34, held-out gain) whose own interval, with the
    # discrepancy carried, held 0 (-0.007 .. 0.017); it was named
    case = pb.physical_case(310064, "none", plan="sweep", n_trials=60)
    result = diagnose(case.trials)
    assert not set(result.causes) & set(HIDDEN), (result.cause, result.causes)
    assert any("holds no effect" in n for n in result.notes)


@pytest.mark.parametrize(
    ("seed", "plan", "held"),
    [
        (910003, "random", True),
        (1500003, "random", False),
        (1501000, "sweep", True),
        (1502002, "repeats", True),
    ],
)
def test_a_compliance_on_the_independent_model_is_named_compliance(seed, plan, held):
    # development seeds (not the benchmark's): a drive compliance of 0.34-0.51 deg/(N m).
    # The physical model's span bows elastically under the load (an over-bend of
    # M l / (6 EI), 0.16-0.32 deg, largest at small bends); with the leg straight the
    # compliance's parameter takes it (about half its value) and what is left is a scale's
    # shape: the straight-leg diagnosis names scale (910003, 1500003, 1502002) or ties
    # compliance with scale (1501000). Refitted with the bow (beam theory, share 1) both
    # rivals, the bowed compliance explains the held-out data better than either straight
    # fit, so the diagnosis is made with the bow: compliance, no tie (fitted 0.28 / 0.36 /
    # 0.36 / 0.40 for 0.34 / 0.51 / 0.43 / 0.49); the interval holds the truth but at
    # 1500003 (0.264 .. 0.5105 for 0.5113: the lag still comes out low, Limits)
    case = pb.physical_case(seed, "compliance", plan=plan, n_trials=60)
    straight = core._diagnose_once(case.trials, SimParams())
    assert straight.cause.primary != "compliance" or straight.tie, (straight.cause, straight.tie)
    result = diagnose(case.trials)
    assert result.cause.primary == "compliance" and not result.tie, (result.cause, result.tie)
    assert result.causes == ("compliance",)
    assert any("elastic bow" in n and "is in the model" in n for n in result.notes)
    truth = case.hidden[0].params["compliance_deg_per_nm"]
    lo, hi = result.intervals["compliance_deg_per_nm"]
    assert lo <= truth <= hi or not held, (lo, hi, truth)
    assert result.params["compliance_deg_per_nm"] == pytest.approx(truth, rel=0.35)


def _catalogue(tie: tuple[str, ...]) -> tuple[str, ...]:
    """The catalogue explanations of a tie (library terms left out)."""
    return tuple(t for t in tie if Cause.parse(t) is not None)


def test_a_compliance_and_a_scale_within_one_standard_error_are_reported_as_a_tie():
    # development seed 1560000 of the independent generator (a compliance of 0.36 alone,
    # random plan; the benchmark's seeds start at 700,000): with the span's bow in the
    # model the compliance and the scale explain the held-out data equally well (0.0638 vs
    # 0.0643 deg, discrepancy profiled out; 0.3 standard error), so the result names the
    # compliance but reports the tie: a pick the data do not make is not made (Limits)
    case = pb.physical_case(1560000, "compliance", plan="random", n_trials=60)
    result = diagnose(case.trials)
    assert result.cause.primary == "compliance" and result.causes == ("compliance",)
    # (the head's once-per-revolution runout, a library rival, may tie them as well)
    assert _catalogue(result.tie) == ("compliance", "scale"), result.tie
    assert any("elastic bow" in n and "is in the model" in n for n in result.notes)
    groups, _ = core.cv_groups(case.trials)
    single = {c.cause: c for c in result.candidates if len(c.fit.causes) == 1 and c.accepted}
    excess = core.held_out_excess(
        single["compliance"].cv_residual_deg, single["scale"].cv_residual_deg, groups
    )
    assert excess is not None and abs(excess[0]) <= core.TIE_STANDARD_ERRORS * excess[1]
    truth = case.hidden[0].params["compliance_deg_per_nm"]
    lo, hi = result.intervals["compliance_deg_per_nm"]
    assert lo <= truth <= hi, (lo, hi, truth)


@pytest.mark.parametrize(("seed", "tied"), [(11, True), (31, False)])
def test_a_scale_on_the_models_own_data_keeps_the_straight_leg(seed, tied):
    # `simulate`'s own data (straight leg): a hidden scale is refitted with the bow too
    # (compliance is accepted beside it), and the straight scale explains the held-out data
    # better, so the bow is not used and scale is named. Seed 11: the bowed compliance is
    # within one standard error of the straight scale held out (0.0762 vs 0.0753 deg, 0.7
    # standard error): the result reports the tie; seed 31: 2.2 standard errors, no tie
    case = hidden_case(seed, effect="scale", n_trials=40)
    result = diagnose(case.trials)
    assert result.cause.primary == "scale" and result.causes == ("scale",)
    assert any("elastic bow" in n and "is not in the model" in n for n in result.notes)
    assert (_catalogue(result.tie) == ("scale", "compliance")) is tied, result.tie
    lo, hi = result.intervals["scale"]
    assert lo <= case.effect.value <= hi


def test_a_compliance_is_named_with_the_span_bow_known_and_its_tolerance_carried(monkeypatch):
    # the same development seed as above, the user's machine given with the span's bow
    # (share 1, beam theory: opt-in, SimParams.span_bow_share): compliance is named without
    # a tie (0.28 for the truth 0.34; scale is named without the bow); the bow's share and
    # the chord modulus are held at their values and marginalised with their physical
    # tolerances (0.2 of the share, 0.1 of E), which widens the compliance's interval to
    # hold the truth (0.21..0.36; held exactly it is 0.25..0.33 and misses)
    case = pb.physical_case(910003, "compliance", plan="random", n_trials=60)
    bowed = SimParams(span_bow_share=1.0)
    truth = case.hidden[0].params["compliance_deg_per_nm"]
    result = diagnose(case.trials, bowed)
    assert result.cause.primary == "compliance" and not result.tie, (result.cause, result.tie)
    assert result.params["compliance_deg_per_nm"] == pytest.approx(truth, rel=0.2)
    lo, hi = result.intervals["compliance_deg_per_nm"]
    assert lo <= truth <= hi, (lo, hi, truth)
    carried = fitting.fit_model(case.trials, bowed, ("compliance",)).intervals[0]
    monkeypatch.setattr(fitting, "unfitted_priors", lambda params: fitting.UNFITTED_PRIOR_SD)
    exact = fitting.fit_model(case.trials, bowed, ("compliance",)).intervals[0]
    assert carried[0] < exact[0] and carried[1] > exact[1], (carried, exact)
    assert carried[0] <= truth <= carried[1] and not exact[0] <= truth <= exact[1]
    assert fitting.unfitted_priors(SimParams()) == fitting.UNFITTED_PRIOR_SD  # default: as before


def test_a_springback_asymmetry_on_repeats_is_named_before_an_even_cause_beside_it():
    # a springback asymmetry of -0.26 (the generator's: the wire's strength differs by
    # direction) on a repeats plan (10 angles, each bent 3 times each way; whole commands
    # held out together). Alone it is far the best held out with the discrepancy profiled
    # out (0.12 deg against the tilt's 0.25) and in evidence (delta BIC 209 against 28),
    # but not on the raw held-out RMSE (0.35 against 0.31): that also carries the
    # baseline's model-form wave along the angle, which a cause even in the direction (a
    # camera tilt, a scale) partly takes and the asymmetry, odd in it, cannot. The pair's
    # order followed the raw RMSE and named the tilt first. Development seed (not the
    # benchmark's), the asymmetry set to the low end of its drawn range.
    case = pb.physical_case(
        2001012,
        "springback_asymmetry",
        plan="repeats",
        n_trials=60,
        params={"springback_asymmetry": {"asymmetry": -0.26}},
    )
    result = diagnose(case.trials)
    if result.cause.primary != "springback_asymmetry":
        # with the tilt's axis fitted off the grid (-84 deg) a tilt, odd in the direction
        # about such an axis, ties the asymmetry on the raw held-out RMSE (0.28 against
        # 0.35): a tie reported with the bends that separate it, the asymmetry far ahead
        # in evidence
        assert "springback_asymmetry" in result.tie, (result.causes, result.notes)
        assert result.follow_up is not None
        assert result.evidence[0][0] == "springback_asymmetry"
        return
    lo, hi = result.intervals["asymmetry"]
    # the generator's asymmetry is of strength, the catalogue's of springback: same sign,
    # size within a few tenths (fitted -0.24 here)
    assert lo < 0 and hi < 0
    assert result.params["asymmetry"] == pytest.approx(-0.26, abs=0.1)
