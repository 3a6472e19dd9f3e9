"""The diagnosis: find what the simulation gets wrong, name the cause, measure the gain.

Steps, on measured trials:

1. Baseline: the simulation with only the nuisance parameter fitted (material
   strength).
2. Every candidate effect of the catalogue is fitted in turn (strength plus
   the effect's one bounded parameter), with grouped K-fold cross-validation
   for its held-out RMSE.
3. Selection by held-out error with a penalty for the extra parameter: a
   candidate is *accepted* only if its held-out RMSE beats the baseline's by
   ``min_cv_gain`` and its full-data fit improves the BIC by at least
   ``min_delta_bic`` (one extra parameter; about p < 1e-3). The accepted
   candidate with the lowest held-out RMSE is the cause; when none is
   accepted, nothing is named (``cause = "none"``): the residuals are at the
   noise floor.
4. A second cause on top of the first when structure is left (same rule,
   against the one-cause model + discrepancy; the best few first causes each
   get this round and the lowest held-out model wins). The accepted second
   causes are ranked by their held-out RMSE with the discrepancy profiled out
   (a first cause's grid-rounded shape chosen again beside each), and the first
   whose pair has both causes of plausible size is named. A named pair is checked
   for held-out ties with the other pairs: when all that tie share its first
   cause, the second is not settled and the first is named alone.
5. The causes' parameters with 95 % intervals (Gauss-Newton covariance,
   Student t), residual trends before and after, a leftover check, and an
   identifiability check against the other candidates on this design,
   naming the experiment that would separate any confounded pair.

Residuals below ``RESOLUTION_DEG`` are not structure; an extended model
still missing by more than ``GROSS_MISFIT_DEG`` names nothing.

A machine whose form the simulation misses (the steps refused for lack of fit, or
explained only by terms outside the catalogue) is diagnosed again with its no-effect
relation learned from the session (:func:`~cvmeasure.diagnose.fitting.learned_form`: a
smooth curve in the bend magnitude for the loaded and released angles, fitted with every
cause); the causes are then measured on what the curve cannot absorb (the direction, the
order, the pin on the loaded photo).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.bow import BOW_RIVALS, _bow_decides
from cvmeasure.diagnose.discover import DiscoveredTerm, discover
from cvmeasure.diagnose.evidence import (
    _DISCOVERED,
    TIE_RATIO,
    _alone_excluding_no_effect,
    _evidence,
    _held_out_tie,
    _holds_no_effect,
)
from cvmeasure.diagnose.evidence import TIE_STANDARD_ERRORS as TIE_STANDARD_ERRORS
from cvmeasure.diagnose.evidence import _held_out_excess as _held_out_excess
from cvmeasure.diagnose.fitting import (
    ModelFit,
    current_form,
    discrepancy_basis,
    discrepancy_form,
    fit_model,
    group_folds,
    grouped_kfold_cv,
    learned_form,
)
from cvmeasure.diagnose.intervals import _averaged, _widened
from cvmeasure.diagnose.misfit import (
    curve_rms_deg,
    lack_of_fit,
    lack_of_fit_residuals,
    springback_rms_deg,
)
from cvmeasure.diagnose.naming import _name_causes, _scores, _settle_pair, _try_causes
from cvmeasure.diagnose.residuals import leftover_structure, residual_trends
from cvmeasure.diagnose.result import CandidateResult, Diagnosis
from cvmeasure.diagnose.rules import (
    GROSS_MISFIT_DEG,
    MIN_CV_GAIN,
    MIN_DELTA_BIC,
    MIN_TRIALS,
    RESOLUTION_DEG,
    _Context,
    _subset_by_group,
    cv_groups,
)
from cvmeasure.diagnose.terms import (
    ORDER_EXPERIMENT,
    _kept_against_terms,
    _order_confounded,
    _terms_beside,
)
from cvmeasure.sim.effects import EFFECT_NAMES, EFFECTS, Effect
from cvmeasure.sim.params import SimParams

if TYPE_CHECKING:
    from cvmeasure.diagnose.follow_up import Rival


__all__ = [
    "MIN_DELTA_BIC",
    "MIN_CV_GAIN",
    "RESOLUTION_DEG",
    "GROSS_MISFIT_DEG",
    "CandidateResult",
    "Diagnosis",
    "cv_groups",
    "diagnose",
]


#: More trials than this are diagnosed on a random subset of this size (whole CV groups,
#: order kept), said in the notes: the intervals are then those of the subset (wider).
MAX_TRIALS = 5_000


def _design_notes(trials: TrialTable) -> list[str]:
    notes = []
    if not trials.both_directions:
        notes.append(
            "the plan bends in one direction only: per-direction causes (offset, backlash, "
            "axis offset, springback asymmetry) are told apart only by their shape along the "
            "angle, not by their sign; add reverse bends"
        )
    if not trials.has_loaded:
        notes.append(
            "no loaded angles: springback causes and machine causes are only separated by "
            "their shape in the released angle; photograph the loaded angle as well"
        )
    return notes


def diagnose(
    trials: TrialTable,
    params: SimParams | None = None,
    *,
    base_effects: Sequence[Effect] = (),
    candidates: Sequence[str] | None = None,
    folds: int = 5,
    min_cv_gain: float = MIN_CV_GAIN,
    min_delta_bic: float = MIN_DELTA_BIC,
    max_causes: int = 2,
    follow_up: bool = True,
) -> Diagnosis:
    """Diagnose measured trials against the simulation.

    When the data leave a drive compliance and a scale the two best explanations, the
    span's elastic bow decides between them (:func:`_bow_decides`): the two differ by
    the bow's shape, so with the leg straight the bow's over-bend makes a compliance
    look like a scale.

    Parameters
    ----------
    trials : TrialTable
        Measured bends (both directions and loaded angles give the best power).
    params : SimParams, optional
        Nominal simulation parameters (defaults built in).
    base_effects : sequence of Effect
        Effects already part of the model (from a params JSON); kept fixed
        unless a candidate of the same name refits them.
    candidates : sequence of str, optional
        Effect names to try (default: the whole catalogue).
    folds : int
        K of the grouped K-fold cross-validation.
    min_cv_gain, min_delta_bic : float
        Acceptance thresholds (see module notes).
    max_causes : int
        1 names at most one cause; 2 (default) then tries a second cause on
        top of the first, accepted by the same rule against the one-cause model.
    follow_up : bool
        When the result reports a held-out tie of explanations the catalogue predicts,
        propose the bends that would separate them (``Diagnosis.follow_up``).

    Raises
    ------
    ValueError
        With fewer than ``MIN_TRIALS`` trials or an unknown candidate name.
    """
    params = params or SimParams()
    kwargs: dict[str, Any] = dict(
        base_effects=base_effects,
        candidates=candidates,
        folds=folds,
        min_cv_gain=min_cv_gain,
        min_delta_bic=min_delta_bic,
        max_causes=max_causes,
    )
    result = _diagnose_form(trials, params, kwargs, follow_up)
    if not _form_misses(result):
        return result
    # the simulation's form does not describe this machine: its no-effect relation is
    # learned from the session (a smooth curve in the bend, fitted with every cause) and
    # the causes are tested on what such a curve cannot absorb
    form = learned_form(trials)
    with discrepancy_form(form):
        learned = _diagnose_form(trials, params, kwargs, follow_up)
        fit = learned.extended_fit if learned.causes else learned.baseline_fit
        curve_deg = curve_rms_deg(trials, fit)
    if learned.misfit is not None and learned.misfit.refused:
        return result
    if result.cause == "unexplained" and not _refused(result) and learned.cause != "none":
        # terms outside the catalogue explained the data within the noise: a catalogue
        # name through the learned curve would stand in for them (a warm-up as a drift)
        return result
    allowed_deg = LEARNED_CURVE_SPRINGBACKS * springback_rms_deg(trials, params)
    if not curve_deg <= allowed_deg:
        note = (
            f"a curve learned from the session would have to move the angles by "
            f"{curve_deg:.2f} deg rms, beyond what the material's response can be off by "
            f"({allowed_deg:.2f} deg, twice the springback the description predicts): the "
            "machine is described wrong (wire, pin or dead zone); no cause is named"
        )
        return dataclasses.replace(result, notes=(*result.notes, note))
    note = (
        "the simulation's form misses this machine beyond the noise: its no-effect relation "
        "was learned from the session (a smooth curve in the bend for loaded and released "
        "angles, both directions alike); the causes were tested on the direction, the order "
        "and the pin, which it cannot absorb"
    )
    return dataclasses.replace(learned, notes=(*learned.notes, note), learned=form)


#: The learned curve stands for the description's error in the material's response:
#: the springback (the released angle) and the hardening's share of the loaded one, each
#: off by at most about the whole springback. A curve beyond this many times the
#: predicted springback (rms over the session) is a machine described wrong (its wire,
#: pin or dead zone), which the user is told to fix.
LEARNED_CURVE_SPRINGBACKS = 2.0


def _refused(result: Diagnosis) -> bool:
    return result.misfit is not None and result.misfit.refused


def _form_misses(result: Diagnosis) -> bool:
    """The simulation's form (bounded discrepancy) leaves the data unexplained: refused
    for lack of fit, or explained only by terms outside the catalogue (then the learned
    curve may only say that nothing is there: the no-effect relation was the terms)."""
    return _refused(result) or result.cause == "unexplained"


def _diagnose_form(
    trials: TrialTable, params: SimParams, kwargs: dict[str, Any], follow_up: bool
) -> Diagnosis:
    """One diagnosis in the discrepancy's form in use, the bow decided and the
    follow-up planned."""
    base_effects = kwargs["base_effects"]
    folds, min_cv_gain = kwargs["folds"], kwargs["min_cv_gain"]
    result = _diagnose_once(trials, params, **kwargs)
    # not asked of more trials than MAX_TRIALS (diagnosed on a subset)
    bow = None
    if len(trials) <= MAX_TRIALS:
        bow = _bow_decides(trials, params, result, tuple(base_effects), folds, min_cv_gain)
    if bow is None:
        return _with_follow_up(trials, result, base_effects, follow_up)
    straight = result
    if bow.use_bow:
        result = _diagnose_once(trials, dataclasses.replace(params, span_bow_share=1.0), **kwargs)
    notes = (*result.notes, bow.note)
    other = bow.straight if bow.use_bow else bow.bowed
    if bow.tied and result.causes == (result.cause,) and result.cause in BOW_RIVALS:
        if other != result.cause and other not in result.tie:
            tie = (*(result.tie or (result.cause,)), other)
            result = dataclasses.replace(result, tie=tie, notes=notes)
            # the rival added is fitted in the other model of the machine
            if bow.use_bow:
                other_fit = _single_fit(straight, other)
                other_params = params
            else:
                other_fit = bow.bowed_fits.get(other)
                other_params = dataclasses.replace(params, span_bow_share=1.0)
            overrides = {} if other_fit is None else {other: (other_fit, other_params)}
            return _with_follow_up(trials, result, base_effects, follow_up, overrides)
    result = dataclasses.replace(result, notes=notes)
    return _with_follow_up(trials, result, base_effects, follow_up)


def _single_fit(result: Diagnosis, label: str) -> ModelFit | None:
    """The fit of ``result``'s candidate explaining the data by ``label`` (a cause, or a
    pair ``a + b``), first round or second; None when not tried."""
    causes = set(label.split(" + "))
    for c in (*result.candidates, *result.second_candidates, *result.other_pairs):
        if set(c.fit.causes) == causes:
            return c.fit
    return None


def _with_follow_up(
    trials: TrialTable,
    result: Diagnosis,
    base_effects: Sequence[Effect],
    enabled: bool,
    overrides: dict[str, tuple[ModelFit, SimParams]] | None = None,
) -> Diagnosis:
    """``result`` with the follow-up plan that separates its tie's catalogue rivals (each
    as fitted to the data; ``overrides``: a rival fitted in another model of the machine).
    Only computed when there is a tie of two such rivals."""
    if not enabled or not result.tie or len(trials) != result.n_trials:
        return result
    from cvmeasure.diagnose.follow_up import Rival, propose_follow_up

    rivals: list[Rival] = []
    for label in result.tie:
        if not all(c in EFFECTS for c in label.split(" + ")):
            continue  # a term outside the catalogue: no forward model to plan with
        fit, fitted_on = (overrides or {}).get(label, (None, result.nominal_params))
        fit = fit or _single_fit(result, label)
        if fit is not None:
            rivals.append(Rival(label, fit, fitted_on))
    if len(rivals) < 2:
        return result
    plan = propose_follow_up(trials, rivals, tuple(base_effects))
    if plan is None:
        return result
    note = (
        f"follow-up: {plan.n_trials} bends ({plan.design}) after the data are expected to "
        f"separate {', '.join(plan.rivals)} by {plan.expected_separation_se:.1f} standard "
        "errors (each rival refitted); run them, append and diagnose again"
    )
    return dataclasses.replace(result, follow_up=plan, notes=(*result.notes, note))


#: Causes whose signatures differ by the span's elastic bow: a drive's lag, nearly


def _diagnose_once(
    trials: TrialTable,
    params: SimParams | None = None,
    *,
    base_effects: Sequence[Effect] = (),
    candidates: Sequence[str] | None = None,
    folds: int = 5,
    min_cv_gain: float = MIN_CV_GAIN,
    min_delta_bic: float = MIN_DELTA_BIC,
    max_causes: int = 2,
) -> Diagnosis:
    """One diagnosis against ``params`` as given (:func:`diagnose` without the bow's decision).

    Parameters and errors as :func:`diagnose`.
    """
    params = params or SimParams()
    if len(trials) < MIN_TRIALS:
        raise ValueError(f"need at least {MIN_TRIALS} trials to diagnose, got {len(trials)}")
    names = tuple(n for n in (candidates or EFFECT_NAMES) if n != "none")
    for n in names:
        if n not in EFFECTS:
            raise ValueError(f"unknown candidate {n!r}")
    notes: list[str] = []
    if len(trials) > MAX_TRIALS:
        n_all = len(trials)
        trials = _subset_by_group(trials, MAX_TRIALS)
        notes.append(
            f"diagnosed on a random subset of {len(trials)} of the {n_all} trials (whole "
            "parts, order kept) to bound the time; intervals are those of the subset"
        )
    notes.extend(_design_notes(trials))
    groups, note = cv_groups(trials)
    if note:
        notes.append(note)
    ctx = _Context(
        trials=trials,
        params=params,
        base_effects=tuple(base_effects),
        fold_masks=tuple(group_folds(groups, folds)),
        names=names,
        min_cv_gain=min_cv_gain,
        min_delta_bic=min_delta_bic,
    )
    base_fit = fit_model(trials, params, "none", base_effects=ctx.base_effects)
    base_cv_res = grouped_kfold_cv(
        trials, params, "none", ctx.fold_masks, base_effects=ctx.base_effects, full_fit=base_fit
    )
    base_cv = base_cv_res.rmse_deg
    base_cv_disc = base_cv_res.rmse_after_discrepancy_deg(trials)
    results = _try_causes(ctx, base_fit, base_cv_disc, names)
    naming = _name_causes(ctx, results, base_fit, base_cv, max_causes)
    naming, pair_tie = _settle_pair(naming, results, groups)
    notes.extend(naming.notes)
    experiment = naming.experiment
    if experiment is None and not trials.both_directions:
        experiment = "add reverse bends (the same angles in the other direction)"
    elif experiment is None and not trials.has_loaded:
        experiment = "photograph the loaded angle (pin still engaged) as well as the released one"
    ext_fit = naming.fit
    base_res = base_fit.residuals(trials, params, ctx.base_effects)
    ext_res = ext_fit.residuals(trials, params, ctx.base_effects)
    cause, ext_cv = naming.cause, naming.cv_rmse_deg
    basis = discrepancy_basis(trials)
    base_res_d = base_res - basis @ np.asarray(base_fit.discrepancy)
    gain_of = base_fit.head_sensitivity(trials, params, ctx.base_effects)
    found = discover(
        trials,
        base_res_d,
        groups,
        ctx.fold_masks,
        head_gain=gain_of,
        refit=base_fit.nuisance_jacobian(trials, params, ctx.base_effects),
    )
    if base_fit.sigma_deg > GROSS_MISFIT_DEG:  # the simulation does not describe these data
        found = dataclasses.replace(found, terms=())
    mean_terms = [t for t in found.terms if t.term != "scatter"]
    named_cv = naming.cv_discrepancy_rmse_deg if cause != "none" else base_cv_disc
    scores = _scores(results, naming)
    named_bic = max(
        (v for k, v in scores.items() if set(k.split(" + ")) == set(naming.fit.causes)),
        default=0.0,
    )
    # what the library still finds in the named cause's residuals
    beside: tuple[DiscoveredTerm, ...] = ()
    if cause != "none":
        beside = _terms_beside(ctx, ext_fit, ext_res, groups).terms

    # discovered terms replace a catalogue name only when they are better both held out
    # (by min_cv_gain) and in evidence (a larger evidence weight: delta BIC with their
    # coefficients and their choice from the library counted)
    def terms_win() -> bool:
        return found.rmse_after_deg <= (1.0 - min_cv_gain) * named_cv and (
            found.delta_bic > named_bic
        )

    if cause != "none" and mean_terms and terms_win():
        # the terms were fitted together with the discrepancy: so are the named causes
        # before they are compared (fitted without it, a cause's parameter takes up the
        # model-form error and the comparison is unfair to the catalogue); so fitted,
        # they keep their name only at a typical size and leaving nothing the library
        # finds. A pair's first cause alone is tried too (its second may be spurious).
        options = [(naming.fit, named_cv, named_bic)]
        if len(naming.fit.causes) == 2:
            options += [
                (c.fit, c.cv_discrepancy_rmse_deg, c.delta_bic)
                for c in results
                if c.fit.causes == naming.fit.causes[:1]
            ]
        for option, option_cv, option_bic in options:
            kept = _kept_against_terms(ctx, option, base_fit, groups)
            if kept is None:
                continue
            named_cv, named_bic = min(option_cv, kept[0]), max(option_bic, kept[1])
            if terms_win():
                continue
            if option is not naming.fit:
                notes.append(
                    f"{naming.fit.causes[1]} dropped: {option.causes[0]} alone, fitted with "
                    "the model-form discrepancy, explains the data better than the terms "
                    "outside the catalogue"
                )
                cause, ext_fit = option.causes[0], option
                ext_res = ext_fit.residuals(trials, params, ctx.base_effects)
                ext_cv = next(c.cv_rmse_deg for c in results if c.fit is option)
                beside = _terms_beside(ctx, ext_fit, ext_res, groups).terms
            for key in [k for k in scores if set(k.split(" + ")) == set(option.causes)]:
                scores[key] = named_bic
            break
    # a cause (a pair: one of its causes) is named only when its 95 % interval (the
    # discrepancy, the dead zone and the shared errors carried) excludes no effect: its
    # evidence (a delta BIC and a held-out gain against baseline + a *bounded*
    # discrepancy) can be model-form error beyond the bound, which its interval carries
    null_held = _holds_no_effect(ext_fit)
    refused_cv = math.nan  # held-out RMSE of a cause refused for its interval (discrepancy out)
    if cause not in ("none", "unexplained") and len(null_held) == len(ext_fit.causes) > 0:
        alone = _alone_excluding_no_effect(results, ext_fit.causes)
        if alone is not None:
            # two causes sharing one signature hold no effect together (each can take
            # the other's share) while one alone excludes it: that one is named
            notes.append(
                f"{' + '.join(ext_fit.causes)} not named together: each 95 % interval holds "
                f"no effect beside the other; {alone.cause} alone excludes it"
            )
            cause, ext_fit, ext_cv = alone.cause, alone.fit, alone.cv_rmse_deg
            named_cv = alone.cv_discrepancy_rmse_deg
            ext_res = ext_fit.residuals(trials, params, ctx.base_effects)
            beside = _terms_beside(ctx, ext_fit, ext_res, groups).terms
        else:
            notes.append(
                f"{', '.join(null_held)} not named: the 95 % interval with the model-form "
                "error carried holds no effect"
            )
            refused_cv = named_cv
            cause, ext_fit, ext_res, ext_cv, beside = "none", base_fit, base_res, base_cv, ()
    # terms outside the catalogue do not stand in for a catalogue cause refused above that
    # explains the held-out data better than they do: what the data show is that cause's
    # signature at a size the plan cannot tell from none (e.g. a backlash lost on every
    # bend within the dead zone's tolerance), not a new mechanism
    beat_refused = not math.isfinite(refused_cv) or not mean_terms
    beat_refused = beat_refused or found.rmse_after_deg < refused_cv
    if found.terms and cause == "none" and not beat_refused:
        notes.append(
            f"terms outside the catalogue ({', '.join(t.term for t in found.terms)}) explain "
            f"the held-out data worse than the cause refused above ({found.rmse_after_deg:.3f} "
            f"vs {refused_cv:.3f} deg): not reported"
        )
    if found.terms and (
        (cause == "none" and beat_refused) or (cause != "none" and mean_terms and terms_win())
    ):
        if cause != "none":
            notes.append(
                "terms outside the catalogue explain the data better than "
                f"{', '.join(ext_fit.causes)} (held-out "
                f"{found.rmse_after_deg:.3f} vs {named_cv:.3f} deg, model-form discrepancy "
                f"profiled out; delta BIC {found.delta_bic:.0f} vs {named_bic:.0f}): no "
                "catalogue name is given"
            )
        cause, ext_fit = "unexplained", base_fit
        ext_res = base_res - found.correction_deg
        if mean_terms:
            ext_cv = base_cv * found.rmse_after_deg / max(found.rmse_before_deg, 1e-12)
        else:
            ext_cv = base_cv
        discovered = found.terms
    else:
        discovered = beside
    if ext_fit.causes:
        ext_fit = _widened(ctx, ext_fit)
        if cause not in ("none", "unexplained"):
            ext_fit = _averaged(ctx, ext_fit, naming, results, groups)
    if mean_terms and math.isfinite(found.delta_bic):
        scores[_DISCOVERED] = found.delta_bic
    evidence = _evidence(scores)
    tie: tuple[str, ...] = ()
    if cause not in ("none", "unexplained") and len(ext_fit.causes) == 1:
        named_result = next((c for c in results if c.fit.causes == ext_fit.causes), None)
        if named_result is not None:
            tie = _held_out_tie(named_result, results, groups)
    elif cause not in ("none", "unexplained") and set(ext_fit.causes) == set(naming.fit.causes):
        tie = pair_tie
    # an order-dependent term outside the catalogue that reproduces the named causes'
    # change of the predictions on this plan ties them: the name is not a pick
    order_ties: list[tuple[str, str]] = []
    if ext_fit.causes:
        order_ties = _order_confounded(ctx, base_fit, base_res - ext_res, gain_of)
    if tie:
        notes.append(
            f"tie: {', '.join(tie[1:])} explain(s) the held-out data as well as {tie[0]} (held-out "
            f"mean squared error within {TIE_STANDARD_ERRORS:g} standard error over the CV "
            "groups): the data do not tell them apart"
        )
    if order_ties:
        tie = (tie[0] if tie else " + ".join(ext_fit.causes), *tie[1:])
        tie = (*tie, *(name for _, name in order_ties))
    # a name is a pick only when the named causes explain the held-out data at least as
    # well as the discovered terms (both with the discrepancy profiled out); terms better
    # held out, though not by min_cv_gain, tie them
    term_ties = [t.term for t in mean_terms if t.term not in tie]
    if cause not in ("none", "unexplained") and term_ties and found.rmse_after_deg < named_cv:
        tie = (tie[0] if tie else " + ".join(ext_fit.causes), *tie[1:], *term_ties)
        notes.append(
            f"tie: terms outside the catalogue ({', '.join(term_ties)}) explain the held-out "
            f"data at least as well as {', '.join(ext_fit.causes)} ({found.rmse_after_deg:.3f} "
            f"vs {named_cv:.3f} deg, model-form discrepancy profiled out): the name is not "
            "a pick"
        )
    ties = [e for e, w in evidence[1:] if w >= TIE_RATIO * evidence[0][1]]
    if ties:
        notes.append(
            f"tie: {', '.join(ties)} explain the data about as well as {evidence[0][0]} "
            "(evidence weights within a delta BIC of 2)"
        )
    for t in discovered:
        notes.append(
            f"discovered: {t.words} ({t.term}, held-out gain {100 * t.held_out_gain:.0f} %)"
        )
    for words, _ in order_ties:
        notes.append(
            f"{', '.join(ext_fit.causes)} cannot be told from {words} on this plan "
            "(the trial order and the previous bend follow the angle): a tie is reported, "
            f"not a pick; {ORDER_EXPERIMENT}"
        )
        experiment = experiment or ORDER_EXPERIMENT
    if cause == "unexplained":
        n_terms = sum(len(t.coefficients_deg) for t in found.terms)
        misfit = lack_of_fit_residuals(trials, ext_res, base_fit.n_params + n_terms)
    else:
        misfit = lack_of_fit(trials, ext_fit if ext_fit.causes else base_fit)
    if misfit is not None and misfit.refused:
        # the least bad of wrong models is no name: the machine is not what the params say
        # (terms outside the catalogue found stay reported, as what is left unexplained)
        notes.append(misfit.note())
        if cause != "unexplained":
            cause, ext_fit, ext_res, ext_cv, discovered = "none", base_fit, base_res, base_cv, ()
        tie = ()
        experiment = "describe the machine with --params (its geometry and wire) and diagnose again"
    left_res = ext_res
    if current_form().fit_with_causes and ext_fit.discrepancy:
        # the learned curve is the machine's no-effect relation, not a leftover
        left_res = ext_res - basis @ np.asarray(ext_fit.discrepancy)
    leftover = leftover_structure(trials, left_res, list(ctx.fold_masks))
    if leftover.unnamed:
        notes.append(
            f"a discrepancy remains that no named cause explains (a smoother along the "
            f"commanded angle lowers the held-out residual RMSE by {100 * leftover.gain:.0f} %): "
            "check the geometry parameters (die radius, pin radius and orbit, head axis) "
            "or look for two causes at once"
        )
    return Diagnosis(
        cause=cause,
        params=ext_fit.param_values(),
        intervals=ext_fit.param_intervals(),
        baseline_rmse_deg=base_cv,
        extended_rmse_deg=ext_cv,
        candidates=tuple(results),
        second_candidates=naming.second_round,
        other_pairs=naming.other_pairs,
        baseline_fit=base_fit,
        extended_fit=ext_fit,
        baseline_residual_deg=base_res,
        extended_residual_deg=ext_res,
        trends_before=tuple(residual_trends(trials, base_res)),
        trends_after=tuple(residual_trends(trials, ext_res)),
        identifiability=naming.identifiability,
        recommended_experiment=experiment,
        leftover=leftover,
        nominal_params=params,
        n_trials=len(trials),
        n_folds=len(ctx.fold_masks),
        notes=tuple(notes),
        discovered=tuple(discovered),
        evidence=evidence,
        tie=tie,
        discovered_rmse_deg=found.rmse_after_deg if mean_terms else math.nan,
        misfit=misfit,
    )
