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
   accepted, nothing is named (``Cause.none()``): the residuals are at the
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

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.bow import BOW_RIVALS, bow_decides
from cvmeasure.diagnose.evidence import TIE_STANDARD_ERRORS as TIE_STANDARD_ERRORS
from cvmeasure.diagnose.evidence import held_out_excess as held_out_excess
from cvmeasure.diagnose.fitting import (
    ModelFit,
    discrepancy_form,
    fit_model,
    group_folds,
    grouped_kfold_cv,
    learned_baseline_form,
)
from cvmeasure.diagnose.follow_up import Rival, propose_follow_up, term_rival
from cvmeasure.diagnose.misfit import (
    curve_rms_deg,
    springback_rms_deg,
)
from cvmeasure.diagnose.naming import candidate_scores, name_causes, settle_pair, try_causes
from cvmeasure.diagnose.residuals import residual_trends
from cvmeasure.diagnose.result import CandidateResult, Cause, CauseKind, Diagnosis
from cvmeasure.diagnose.rules import (
    GROSS_MISFIT_DEG,
    MIN_CV_GAIN,
    MIN_DELTA_BIC,
    MIN_TRIALS,
    RESOLUTION_DEG,
    Context,
    cv_groups,
    subset_by_group,
)
from cvmeasure.diagnose.terms import ORDER_TERMS
from cvmeasure.diagnose.verdict import (
    baseline,
    check_interval,
    check_misfit,
    first_verdict,
    leftover_check,
    terms_or_name,
    tie_notes,
    tie_report,
    verdict_weights,
    weigh_against_terms,
    widen,
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
    form = learned_baseline_form(trials, params, base_effects)
    with discrepancy_form(form):
        learned = _diagnose_form(trials, params, kwargs, follow_up)
        fit = learned.extended_fit if learned.causes else learned.baseline_fit
        curve_deg = curve_rms_deg(trials, fit)
    if learned.misfit is not None and learned.misfit.refused:
        return result
    if (
        result.cause.kind is CauseKind.UNEXPLAINED
        and not _refused(result)
        and learned.cause.kind is not CauseKind.NONE
        and not learned.extended_rmse_deg < result.extended_rmse_deg
    ):
        # terms outside the catalogue explained the data as well: a catalogue name
        # through the learned curve would stand in for them (a warm-up as a drift). When
        # the name predicts the held-out bends better than the terms do, it is the
        # explanation (a camera tilt about the feed axis, which a session's no-effect
        # curve and a periodic term of the head both half take up, the pin the rest)
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
    learned = dataclasses.replace(learned, notes=(*learned.notes, note), learned=form)
    if learned.cause.kind is CauseKind.NONE:
        return _curve_note(result, learned)
    return learned


def _curve_note(result: Diagnosis, learned: Diagnosis) -> Diagnosis:
    """``learned`` (nothing named) with a note on what the learned curve took up. The
    curve is the machine's no-effect relation, so the unnamed-discrepancy flag stays the
    leftover check's beyond it (a flag raised whenever the curve was needed would be
    raised on every healthy machine the simulation's form misses). A smooth curve in
    the bend also absorbs a head mechanism that depends on the bend alone (a gear's
    runout) wherever the pin does not show it: the note says so, with the held-out RMSE
    of the simulation's baseline, then of the curve."""
    note = (
        f"nothing named: the learned curve takes up the session's departure from the "
        f"simulation along the bend (held-out RMSE {result.baseline_rmse_deg:.3f} -> "
        f"{learned.baseline_rmse_deg:.3f} deg); a mechanism that depends on the bend alone "
        "would be taken up with it (check the geometry parameters and fit the material)"
    )
    return dataclasses.replace(learned, notes=(*learned.notes, note))


#: The learned curve stands for the description's error in the material's response:
#: the springback (the released angle) and the hardening's share of the loaded one, each
#: off by at most about the whole springback. A curve beyond this many times the
#: predicted springback (rms over the session) is a machine described wrong (its wire,
#: pin or dead zone), which the user is told to fix.
LEARNED_CURVE_SPRINGBACKS = 2.0


#: Order terms a follow-up plan varies: the previous bend's coupling follows the plan's
#: sequence of directions and sizes (one direction, alternating), which the planner chooses.
PLANNED_ORDER_TERMS = ("previous_bend",)


def _refused(result: Diagnosis) -> bool:
    return result.misfit is not None and result.misfit.refused


def _form_misses(result: Diagnosis) -> bool:
    """The simulation's form (bounded discrepancy) leaves the data unexplained: refused
    for lack of fit, or explained only by terms outside the catalogue (then the learned
    curve may only say that nothing is there: the no-effect relation was the terms)."""
    return _refused(result) or result.cause.kind is CauseKind.UNEXPLAINED


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
        bow = bow_decides(trials, params, result, tuple(base_effects), folds, min_cv_gain)
    if bow is None:
        return _with_follow_up(trials, result, base_effects, follow_up)
    straight = result
    if bow.use_bow:
        result = _diagnose_once(trials, dataclasses.replace(params, span_bow_share=1.0), **kwargs)
    notes = (*result.notes, bow.note)
    other = bow.straight if bow.use_bow else bow.bowed
    single = result.cause.primary if len(result.cause.effects) == 1 else None
    if bow.tied and result.causes == result.cause.effects and single in BOW_RIVALS:
        if other != single and other not in result.tie:
            tie = (*(result.tie or (single,)), other)
            result = dataclasses.replace(result, tie=tie, notes=notes)
            # the rival added is fitted in the other model of the machine
            if bow.use_bow:
                other_fit = _single_fit(straight, Cause.of((other,)))
                other_params = params
            else:
                other_fit = bow.bowed_fits.get(other)
                other_params = dataclasses.replace(params, span_bow_share=1.0)
            overrides = {} if other_fit is None else {other: (other_fit, other_params)}
            return _with_follow_up(trials, result, base_effects, follow_up, overrides)
    result = dataclasses.replace(result, notes=notes)
    return _with_follow_up(trials, result, base_effects, follow_up)


def _single_fit(result: Diagnosis, cause: Cause) -> ModelFit | None:
    """The fit of ``result``'s candidate explaining the data by ``cause`` (one effect or a
    pair), first round or second; None when not tried."""
    for c in (*result.candidates, *result.second_candidates, *result.other_pairs):
        if Cause.of(c.fit.causes) == cause:
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
    rivals: list[Rival] = []
    base = tuple(base_effects)
    for label in result.tie:
        cause = Cause.parse(label)
        if cause is None:
            if label.startswith(ORDER_TERMS) and not label.startswith(PLANNED_ORDER_TERMS):
                # a trend along the run is separated by the order of the bends
                # (ORDER_EXPERIMENT), which the planner's magnitudes and directions do not
                # vary; the previous bend's coupling they do (the plan's own sequence)
                continue
            # a library term: the baseline with the term's coefficients fitted
            term = term_rival(trials, label, result.baseline_fit, result.nominal_params, base)
            if term is not None:
                rivals.append(term)
            continue
        fit, fitted_on = (overrides or {}).get(label, (None, result.nominal_params))
        fit = fit or _single_fit(result, cause)
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
        + (
            ", with the pin's angle read on each loaded photo (measured_pin_deg)"
            if plan.read_pin and not trials.has_pin
            else ""
        )
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
    trials, names, notes = _admitted(trials, candidates)
    groups, note = cv_groups(trials)
    if note:
        notes.append(note)
    ctx = Context(
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
    results = try_causes(ctx, base_fit, base_cv_disc, names)
    naming = name_causes(ctx, results, base_fit, base_cv, max_causes)
    naming, pair_tie = settle_pair(naming, results, groups)
    notes.extend(naming.notes)
    base = baseline(ctx, base_fit, base_cv, base_cv_disc, groups)
    scores = candidate_scores(results, naming)
    v = first_verdict(ctx, base, naming, scores, groups, notes)
    weigh_against_terms(ctx, base, v, naming, results, scores, groups)
    refused_cv = check_interval(ctx, base, v, results, groups)
    terms_or_name(ctx, base, v, refused_cv)
    widen(ctx, v, naming, results, groups)
    evidence = verdict_weights(base, scores)
    order_ties = tie_report(ctx, base, v, naming, results, pair_tie, groups)
    tie_notes(v, evidence, order_ties)
    misfit = check_misfit(ctx, base, v)
    leftover = leftover_check(ctx, base, v)
    return Diagnosis(
        cause=v.cause,
        params=v.fit.param_values(),
        intervals=v.fit.param_intervals(),
        baseline_rmse_deg=base_cv,
        extended_rmse_deg=v.cv_rmse_deg,
        candidates=tuple(results),
        second_candidates=naming.second_round,
        other_pairs=naming.other_pairs,
        baseline_fit=base_fit,
        extended_fit=v.fit,
        baseline_residual_deg=base.residual_deg,
        extended_residual_deg=v.residual_deg,
        trends_before=tuple(residual_trends(trials, base.residual_deg)),
        trends_after=tuple(residual_trends(trials, v.residual_deg)),
        identifiability=naming.identifiability,
        recommended_experiment=v.experiment,
        leftover=leftover,
        nominal_params=params,
        n_trials=len(trials),
        n_folds=len(ctx.fold_masks),
        notes=tuple(notes),
        discovered=tuple(v.discovered),
        evidence=evidence,
        tie=v.tie,
        discovered_rmse_deg=base.found.rmse_after_deg if base.mean_terms else math.nan,
        misfit=misfit,
    )


def _admitted(
    trials: TrialTable, candidates: Sequence[str] | None
) -> tuple[TrialTable, tuple[str, ...], list[str]]:
    """The trials diagnosed (at most MAX_TRIALS of them), the candidates' names and the
    notes on the design; ValueError with too few trials or an unknown candidate."""
    if len(trials) < MIN_TRIALS:
        raise ValueError(f"need at least {MIN_TRIALS} trials to diagnose, got {len(trials)}")
    names = tuple(n for n in (candidates or EFFECT_NAMES) if n != "none")
    for n in names:
        if n not in EFFECTS:
            raise ValueError(f"unknown candidate {n!r}")
    notes: list[str] = []
    if len(trials) > MAX_TRIALS:
        n_all = len(trials)
        trials = subset_by_group(trials, MAX_TRIALS)
        notes.append(
            f"diagnosed on a random subset of {len(trials)} of the {n_all} trials (whole "
            "parts, order kept) to bound the time; intervals are those of the subset"
        )
    notes.extend(_design_notes(trials))
    return trials, names, notes
