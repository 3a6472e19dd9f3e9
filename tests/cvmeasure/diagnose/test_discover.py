"""Discovery beyond the catalogue, CV groups of repeated commands, evidence weights.

Data from the independent physical model (cvmeasure_datasets.physical_bender, not
the simulation the diagnosis fits); seeds below 1000 (the benchmark uses 700,000+).
"""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.diagnose import Cause, diagnose
from cvmeasure.diagnose.core import cv_groups
from cvmeasure.diagnose.discover import (
    _heteroscedastic_loglik,
    _profile_loglik,
    discover,
    library,
)
from cvmeasure.diagnose.fitting import group_folds
from cvmeasure.sim import EFFECTS
from cvmeasure_datasets import physical_bender as pb


def test_a_planted_term_is_found_with_its_amplitude_and_interval():
    case = pb.physical_case(61, "none", plan="random", n_trials=60)
    trials = case.trials
    n = len(trials)
    rng = np.random.default_rng(61)
    s = trials.direction_sign
    mag = np.abs(trials.commanded_pin_deg)
    wave = 0.4 * s * np.sin(2 * np.pi * mag / 90.0)
    residual = np.concatenate([wave, wave, np.full(n, np.nan)])
    residual[: 2 * n] += rng.normal(0.0, 0.05, 2 * n)
    groups = cv_groups(trials)[0]
    found = discover(trials, residual, groups, group_folds(groups))
    terms = {t.term: t for t in found.terms}
    assert set(terms) == {"gear_runout_90"}, list(terms)
    sin_coef, cos_coef = terms["gear_runout_90"].coefficients_deg
    lo, hi = terms["gear_runout_90"].intervals_deg[0]
    assert lo <= 0.4 <= hi and hi - lo < 0.1  # the truth inside a tight 95 % interval
    assert abs(cos_coef) < 0.05
    assert found.gain > 0.8  # the 0.28 deg rms wave falls to the 0.05 deg noise


def test_pure_noise_discovers_nothing():
    case = pb.physical_case(62, "none", plan="sweep", n_trials=60)
    n = len(case.trials)
    rng = np.random.default_rng(62)
    residual = np.concatenate([rng.normal(0.0, 0.05, 2 * n), np.full(n, np.nan)])
    groups = cv_groups(case.trials)[0]
    assert discover(case.trials, residual, groups, group_folds(groups)).terms == ()


def test_gear_runout_outside_the_catalogue_is_unexplained_not_named():
    case = pb.physical_case(43, "gear_runout", plan="random", n_trials=60)
    result = diagnose(case.trials)
    assert result.cause == Cause.unexplained() and result.causes == ()
    assert any(t.term.startswith("gear_runout") for t in result.discovered)
    assert result.gain > 0.6
    d = result.to_dict()
    assert d["cause"] == "unexplained" and d["params"] == {}
    term = next(t for t in d["discovered"] if t["term"].startswith("gear_runout"))
    assert "periodic error of the drive" in term["words"] and term["held_out_gain"] > 0.6


@pytest.mark.parametrize("seed", [51, 52])
def test_repeated_identical_bends_are_held_out_together_and_name_nothing(seed):
    case = pb.physical_case(seed, "none", plan="repeats", n_trials=60)
    groups, note = cv_groups(case.trials)
    assert len(set(groups)) == len(set(np.round(case.trials.commanded_pin_deg, 1))) < 60
    assert note and "repeated commands" in note
    result = diagnose(case.trials)
    assert result.cause == Cause.none() and result.causes == ()


def test_evidence_weights_over_the_explanations():
    case = pb.physical_case(306, "backlash", plan="random", n_trials=60)
    result = diagnose(case.trials)
    assert result.cause.primary == "backlash"
    weights = dict(result.evidence)
    assert sum(weights.values()) == pytest.approx(1.0)
    # the explanation named carries the evidence (a second cause, if any, is listed with it)
    assert result.evidence[0][0] == " + ".join(result.causes) and result.evidence[0][1] > 0.9
    assert {"none", *(c.cause for c in result.candidates)} <= set(weights)
    # the generator lost the play on reversals only: the general form is the one fitted
    assert result.params["same_direction_share"] == 0.0
    truth = case.hidden[0].params["backlash_deg"]
    lo, hi = result.intervals["backlash_deg"]
    assert lo - 0.2 <= truth <= hi + 0.2  # model-form error: a wider margin than 95 %


def test_intervals_widened_by_the_model_form_hold_the_truth():
    # independent model, compliance in the same form as the catalogue's: the fit without
    # the discrepancy is biased by the model-form error (0.31 for 0.55 deg/(N m)); the
    # interval (the hull of the fits with and without it, each widened by its correlation
    # with the discrepancy and the dead zone) holds the truth
    case = pb.physical_case(118, "compliance", plan="sweep", n_trials=60)
    result = diagnose(case.trials)
    assert result.cause.primary == "compliance"
    key = EFFECTS["compliance"].param
    truth = case.hidden[0].params[key]
    lo, hi = result.intervals[key]
    assert lo <= truth <= hi, (truth, (lo, hi))
    assert hi - lo < EFFECTS["compliance"].typical[1]  # widened, not unbounded


def test_previous_bend_term_is_mirror_symmetric():
    # the head is mirror-symmetric: a mirrored run changes every bend's size alike, so
    # every signed regressor of the library flips sign with the run
    case = pb.physical_case(63, "none", plan="random", n_trials=30)
    t = case.trials
    mirrored = type(t).from_arrays(-t.commanded_pin_deg, -t.loaded_bend_deg, -t.unloaded_bend_deg)
    for name, cols in library(t).items():
        np.testing.assert_allclose(library(mirrored)[name], -cols, atol=1e-12, err_msg=name)
    # same sense as the previous bend: the term adds to the bend's size
    n = len(t)
    s = t.direction_sign
    size_change = s * library(t)["previous_bend"][:n, 0]
    same = np.concatenate([[False], s[1:] == s[:-1]])
    assert np.all(size_change[same] > 0) and np.all(size_change[1:][~same[1:]] < 0)


@pytest.mark.parametrize(("seed", "plan"), [(401, "random"), (402, "repeats")])
def test_previous_bend_in_the_span_is_unexplained_with_its_coupling(seed, plan):
    # outside the catalogue: the previous bend lying in the free span (main: named
    # backlash on random orders, nothing discovered); its coupling is recovered
    case = pb.physical_case(seed, "short_segment", plan=plan, n_trials=60)
    result = diagnose(case.trials)
    assert result.cause == Cause.unexplained() and result.causes == ()
    terms = {t.term: t for t in result.discovered}
    assert "previous_bend" in terms, list(terms)
    truth = case.hidden[0].params["coupling_deg"]
    (coef,) = terms["previous_bend"].coefficients_deg
    assert abs(coef - truth) < 0.1 * abs(truth), (coef, truth)  # model error: 10 %
    assert result.gain > 0.8
    assert result.evidence[0][0] == "unexplained (discovered terms)"


@pytest.mark.parametrize(("seed", "plan"), [(403, "random"), (404, "repeats")])
def test_warm_up_is_unexplained_not_named_drift(seed, plan):
    # a loss that builds up and levels off is not the catalogue's drift (main: drift)
    case = pb.physical_case(seed, "warm_up", plan=plan, n_trials=60)
    result = diagnose(case.trials)
    assert result.cause == Cause.unexplained() and result.causes == ()
    assert any(t.term.startswith("warm_up") for t in result.discovered)
    assert result.gain > 0.6


@pytest.mark.parametrize(("seed", "plan"), [(627, "random"), (631, "repeats"), (633, "random")])
def test_a_hidden_scale_is_named_not_displaced_by_a_smooth_discovered_term(seed, plan):
    # fitted without the model-form discrepancy the scale came out at about 0.55 of its
    # value, and a 180 deg periodic term (a smooth curve over the range) beat it: the
    # result was "unexplained". Refitted with the discrepancy, as the terms are, before
    # the two are compared, the scale keeps its name and its interval holds the truth.
    case = pb.physical_case(seed, "scale", plan=plan, n_trials=60)
    result = diagnose(case.trials)
    truth = case.hidden[0].params["scale"]
    assert result.cause.primary == "scale"
    lo, hi = result.intervals["scale"]
    assert lo <= truth <= hi
    assert result.params["scale"] == pytest.approx(truth, rel=0.35)


@pytest.mark.parametrize(("seed", "plan"), [(405, "random"), (406, "sweep")])
def test_springback_scatter_is_found_with_its_size(seed, plan):
    # scatter of the springback growing with the bend (main: found on repeats plans only)
    case = pb.physical_case(seed, "springback_scatter", plan=plan, n_trials=60)
    result = diagnose(case.trials)
    assert result.cause == Cause.unexplained() and result.causes == ()
    (term,) = [t for t in result.discovered if t.term == "scatter"]
    truth = case.hidden[0].params["scatter_deg_per_100deg"]
    lo, hi = term.intervals_deg[0]
    assert lo <= truth <= hi, (truth, (lo, hi))
    assert abs(term.coefficients_deg[0] - truth) < 0.3 * truth


@pytest.mark.parametrize("seed", [407, 408, 409])
def test_no_scatter_is_found_on_homoscedastic_noise(seed):
    case = pb.physical_case(seed, "none", plan=("random", "sweep", "repeats")[seed % 3])
    result = diagnose(case.trials)
    assert all(t.term != "scatter" for t in result.discovered)


def test_an_order_term_indistinguishable_on_a_sweep_is_said_with_the_experiment():
    # on a sweep (rising angles) a warm-up follows the angle: drift fits it, and the
    # result reports drift tied with the warm-up term (not a pick), says that it cannot
    # be told from a warm-up on this plan and how to tell
    case = pb.physical_case(412, "warm_up", plan="sweep", n_trials=60)
    result = diagnose(case.trials)
    assert result.cause.primary == "drift"
    assert result.tie[0] == "drift" and any(t.startswith("warm_up") for t in result.tie)
    assert result.to_dict()["tie"] == list(result.tie)
    notes = [n for n in result.notes if "cannot be told from" in n and "warm-up" in n]
    assert notes, result.notes
    assert result.recommended_experiment == "bend the same angles in a random order"
    # the same mechanism bent in a random order is not given the catalogue name
    shuffled = diagnose(pb.physical_case(403, "warm_up", plan="random", n_trials=60).trials)
    assert shuffled.cause == Cause.unexplained()


def test_two_causes_on_the_independent_model_are_both_named():
    # pairs hidden in the physical model (the tests' own seeds): the second cause is
    # tested, ranked and checked for leftover structure against "baseline + discrepancy
    # + first cause"; on the raw residuals the model-form wave refused every right pair
    # but one of these four (1 of 4 named before)
    cases = [
        (400, ("axis_offset", "compliance"), "repeats"),
        (401, ("backlash", "springback_asymmetry"), "random"),
        (402, ("axis_offset", "compliance"), "random"),
        (403, ("backlash", "springback_asymmetry"), "repeats"),
    ]
    named = []
    for seed, pair, plan in cases:
        result = diagnose(pb.physical_case(seed, pair, plan=plan, n_trials=60).trials)
        if result.cause.primary not in pair:
            # seed 401 (play of 1.2 deg lost on every bend): a drive compliance beside the
            # same asymmetry is the same nearly constant under-bend held out; the pair
            # named is reported as tied with the hidden one, not as a pick
            assert " + ".join(pair) in result.tie, (result.causes, result.tie)
        named.append(set(result.causes) == set(pair))
    assert sum(named) >= 2, named


def test_intervals_on_the_independent_model_hold_the_truth():
    # single causes in the form the fitted parameter means (backlash lost on every bend),
    # the tests' own seeds and every plan: the intervals carry the discrepancy and the
    # dead zone's prior; the 4 named hold the truth (compliance on seed 414 is named
    # scale: no interval to count)
    held = []
    for i, name in enumerate(["offset", "scale", "backlash", "axis_offset", "compliance"]):
        case = pb.physical_case(
            410 + i,
            name,
            plan=pb.PLANS[i % 3],
            n_trials=60,
            params={"backlash": {"same_direction_share": 1.0}},
        )
        result = diagnose(case.trials)
        key = EFFECTS[name].param
        if key in result.intervals:
            lo, hi = result.intervals[key]
            held.append(lo <= case.hidden[0].params[key] <= hi)
            assert hi - lo < EFFECTS[name].typical[1]  # widened, not unbounded
    assert len(held) >= 4 and all(held), held


def test_a_name_that_explains_the_held_out_data_worse_than_the_terms_is_a_tie():
    # a previous-bend coupling on a sweep looks like a scale (the previous bend follows
    # the angle); scale + offset are named, but the discovered previous-bend term
    # predicts the held-out data better (not by min_cv_gain): the name is reported as
    # tied with the term, not as a pick
    case = pb.physical_case(500, "short_segment", plan="sweep", n_trials=60)
    result = diagnose(case.trials)
    assert result.causes and result.tie, (result.causes, result.tie)
    assert "previous_bend" in result.tie
    assert any("the name is not a pick" in n for n in result.notes)


@pytest.mark.parametrize("growth", [0.0, 1.0, 4.0])
def test_scatter_profile_matches_the_scalar_likelihood(growth):
    """The scatter's profile over its slope grid (all slopes at once) is the scalar
    likelihood maximised slope by slope, to 1e-8 in log-likelihood, and never below it."""
    rng = np.random.default_rng(11)
    x = rng.uniform(0.1, 1.5, 80)
    e = rng.normal(0.0, 0.05, 80) * (1.0 + growth * x)
    grid = np.linspace(0.0, 3.0 * np.sqrt(np.mean(e * e)) / np.mean(x), 41)
    scalar = np.array([_heteroscedastic_loglik(e, x, float(c))[0] for c in grid])
    profile = _profile_loglik(e, x, grid)
    assert np.max(np.abs(profile - scalar)) < 1e-8
    assert np.all(profile >= scalar - 1e-9)
