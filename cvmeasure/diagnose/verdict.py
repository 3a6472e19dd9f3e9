"""The steps of one diagnosis after the naming search (angles in deg): terms outside the
catalogue found in the baseline's residuals, the name weighed against them and against
its own interval, the intervals widened, the ties, and the lack-of-fit and leftover
checks (:func:`cvmeasure.diagnose.core._diagnose_once` calls them in order)."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from cvmeasure.diagnose.discover import DiscoveredTerm, Discovery, discover, term_words
from cvmeasure.diagnose.evidence import (
    DISCOVERED,
    TIE_RATIO,
    TIE_STANDARD_ERRORS,
    alone_excluding_no_effect,
    evidence_weights,
    held_out_tie,
    holds_no_effect,
)
from cvmeasure.diagnose.fitting import ModelFit, discrepancy_basis
from cvmeasure.diagnose.intervals import averaged, widened
from cvmeasure.diagnose.misfit import Misfit, lack_of_fit, lack_of_fit_residuals
from cvmeasure.diagnose.naming import Naming
from cvmeasure.diagnose.residuals import LeftoverCheck, leftover_structure
from cvmeasure.diagnose.result import CandidateResult, Cause, CauseKind
from cvmeasure.diagnose.rules import GROSS_MISFIT_DEG, Context
from cvmeasure.diagnose.terms import (
    ORDER_EXPERIMENT,
    beside_confounded,
    kept_against_terms,
    library_confounded,
    order_confounded,
    terms_beside,
)


@dataclass(frozen=True)
class _Baseline:
    """The no-effect model and what the library of terms finds in its residuals."""

    fit: ModelFit
    cv_rmse_deg: float
    cv_discrepancy_rmse_deg: float  # held out, the discrepancy profiled out
    residual_deg: NDArray[np.float64]  # (3 N,) measured minus predicted
    basis: NDArray[np.float64]  # the discrepancy's (3 N, columns)
    head_gain: NDArray[np.float64]  # :meth:`ModelFit.head_sensitivity`
    found: Discovery  # the library's terms in the residuals, the discrepancy out
    mean_terms: tuple[DiscoveredTerm, ...]  # the found terms but the scatter


@dataclass
class _Verdict:
    """The explanation as the steps settle it: the cause named (or none, or
    unexplained), its fit, residuals and held-out errors, and what is reported."""

    cause: Cause
    fit: ModelFit
    residual_deg: NDArray[np.float64]
    cv_rmse_deg: float
    named_cv_deg: float  # held-out RMSE with the discrepancy profiled out
    named_bic: float  # delta BIC against the baseline + discrepancy
    beside: tuple[DiscoveredTerm, ...]  # terms the library finds beside the cause
    notes: list[str]
    experiment: str | None
    discovered: tuple[DiscoveredTerm, ...] = ()
    tie: tuple[str, ...] = ()


def baseline(
    ctx: Context,
    base_fit: ModelFit,
    cv_rmse_deg: float,
    cv_discrepancy_rmse_deg: float,
    groups: Sequence[str],
) -> _Baseline:
    """The baseline's residuals and the library's terms in them (none when the simulation
    does not describe the data: beyond GROSS_MISFIT_DEG)."""
    trials, params = ctx.trials, ctx.params
    base_res = base_fit.residuals(trials, params, ctx.base_effects)
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
    mean_terms = tuple(t for t in found.terms if t.term != "scatter")
    return _Baseline(
        base_fit,
        cv_rmse_deg,
        cv_discrepancy_rmse_deg,
        base_res,
        basis,
        gain_of,
        found,
        mean_terms,
    )


def first_verdict(
    ctx: Context,
    base: _Baseline,
    naming: Naming,
    scores: dict[Cause, float],
    groups: Sequence[str],
    notes: list[str],
) -> _Verdict:
    """The naming search's explanation, with the terms the library finds beside it."""
    trials = ctx.trials
    experiment = naming.experiment
    if experiment is None and not trials.both_directions:
        experiment = "add reverse bends (the same angles in the other direction)"
    elif experiment is None and not trials.has_loaded:
        experiment = "photograph the loaded angle (pin still engaged) as well as the released one"
    ext_fit = naming.fit
    ext_res = ext_fit.residuals(trials, ctx.params, ctx.base_effects)
    cause = naming.cause
    named_cv = naming.cv_discrepancy_rmse_deg if cause.named else base.cv_discrepancy_rmse_deg
    named_bic = max(
        (v for k, v in scores.items() if k == Cause.of(naming.fit.causes)),
        default=0.0,
    )
    # what the library still finds in the named cause's residuals
    beside: tuple[DiscoveredTerm, ...] = ()
    if cause.named:
        beside = terms_beside(ctx, ext_fit, ext_res, groups).terms
    return _Verdict(
        cause, ext_fit, ext_res, naming.cv_rmse_deg, named_cv, named_bic, beside, notes, experiment
    )


def _terms_win(base: _Baseline, v: _Verdict, min_cv_gain: float) -> bool:
    """Discovered terms replace a catalogue name only when they are better both held out
    (by min_cv_gain) and in evidence (a larger evidence weight: delta BIC with their
    coefficients and their choice from the library counted)."""
    found = base.found
    return found.rmse_after_deg <= (1.0 - min_cv_gain) * v.named_cv_deg and (
        found.delta_bic > v.named_bic
    )


def weigh_against_terms(
    ctx: Context,
    base: _Baseline,
    v: _Verdict,
    naming: Naming,
    results: Sequence[CandidateResult],
    scores: dict[Cause, float],
    groups: Sequence[str],
) -> None:
    """When the terms win, the named causes refitted with the discrepancy are compared
    again (``v`` and ``scores`` updated)."""
    if not (v.cause.named and base.mean_terms and _terms_win(base, v, ctx.min_cv_gain)):
        return
    # the terms were fitted together with the discrepancy: so are the named causes
    # before they are compared (fitted without it, a cause's parameter takes up the
    # model-form error and the comparison is unfair to the catalogue); so fitted,
    # they keep their name only at a typical size and leaving nothing the library
    # finds. A pair's first cause alone is tried too (its second may be spurious).
    options = [(naming.fit, v.named_cv_deg, v.named_bic)]
    if len(naming.fit.causes) == 2:
        options += [
            (c.fit, c.cv_discrepancy_rmse_deg, c.delta_bic)
            for c in results
            if c.fit.causes == naming.fit.causes[:1]
        ]
    for option, option_cv, option_bic in options:
        kept = kept_against_terms(ctx, option, base.fit, groups)
        if kept is None:
            continue
        v.named_cv_deg, v.named_bic = min(option_cv, kept[0]), max(option_bic, kept[1])
        if _terms_win(base, v, ctx.min_cv_gain):
            continue
        if option is not naming.fit:
            v.notes.append(
                f"{naming.fit.causes[1]} dropped: {option.causes[0]} alone, fitted with "
                "the model-form discrepancy, explains the data better than the terms "
                "outside the catalogue"
            )
            v.cause, v.fit = Cause.of(option.causes[:1]), option
            v.residual_deg = v.fit.residuals(ctx.trials, ctx.params, ctx.base_effects)
            v.cv_rmse_deg = next(c.cv_rmse_deg for c in results if c.fit is option)
            v.beside = terms_beside(ctx, v.fit, v.residual_deg, groups).terms
        for key in [k for k in scores if k == Cause.of(option.causes)]:
            scores[key] = v.named_bic
        break


def check_interval(
    ctx: Context,
    base: _Baseline,
    v: _Verdict,
    results: Sequence[CandidateResult],
    groups: Sequence[str],
) -> float:
    """A cause (a pair: one of its causes) is named only when its 95 % interval (the
    discrepancy, the dead zone and the shared errors carried) excludes no effect: its
    evidence (a delta BIC and a held-out gain against baseline + a *bounded*
    discrepancy) can be model-form error beyond the bound, which its interval carries.
    Returns the held-out RMSE (discrepancy out) of a cause refused for its interval
    (NaN: none)."""
    null_held = holds_no_effect(v.fit)
    refused_cv = math.nan
    if not v.cause.named or not (len(null_held) == len(v.fit.causes) > 0):
        return refused_cv
    alone = alone_excluding_no_effect(results, v.fit.causes)
    if alone is not None:
        # two causes sharing one signature hold no effect together (each can take
        # the other's share) while one alone excludes it: that one is named
        v.notes.append(
            f"{Cause.of(v.fit.causes).label} not named together: each 95 % interval holds "
            f"no effect beside the other; {alone.cause} alone excludes it"
        )
        v.cause, v.fit, v.cv_rmse_deg = Cause.of(alone.fit.causes), alone.fit, alone.cv_rmse_deg
        v.named_cv_deg = alone.cv_discrepancy_rmse_deg
        v.residual_deg = v.fit.residuals(ctx.trials, ctx.params, ctx.base_effects)
        v.beside = terms_beside(ctx, v.fit, v.residual_deg, groups).terms
    else:
        v.notes.append(
            f"{', '.join(null_held)} not named: the 95 % interval with the model-form "
            "error carried holds no effect"
        )
        refused_cv = v.named_cv_deg
        v.cause, v.fit, v.residual_deg = Cause.none(), base.fit, base.residual_deg
        v.cv_rmse_deg, v.beside = base.cv_rmse_deg, ()
    return refused_cv


def terms_or_name(ctx: Context, base: _Baseline, v: _Verdict, refused_cv: float) -> None:
    """The discovered terms reported in place of the name when they win (unexplained),
    else the terms found beside the name."""
    found, mean_terms = base.found, base.mean_terms
    # terms outside the catalogue do not stand in for a catalogue cause refused above that
    # explains the held-out data better than they do: what the data show is that cause's
    # signature at a size the plan cannot tell from none (e.g. a backlash lost on every
    # bend within the dead zone's tolerance), not a new mechanism
    beat_refused = not math.isfinite(refused_cv) or not mean_terms
    beat_refused = beat_refused or found.rmse_after_deg < refused_cv
    if found.terms and v.cause.kind is CauseKind.NONE and not beat_refused:
        v.notes.append(
            f"terms outside the catalogue ({', '.join(t.term for t in found.terms)}) explain "
            f"the held-out data worse than the cause refused above ({found.rmse_after_deg:.3f} "
            f"vs {refused_cv:.3f} deg): not reported"
        )
    if found.terms and (
        (v.cause.kind is CauseKind.NONE and beat_refused)
        or (
            v.cause.kind is not CauseKind.NONE
            and mean_terms
            and _terms_win(base, v, ctx.min_cv_gain)
        )
    ):
        if v.cause.kind is not CauseKind.NONE:
            v.notes.append(
                "terms outside the catalogue explain the data better than "
                f"{', '.join(v.fit.causes)} (held-out "
                f"{found.rmse_after_deg:.3f} vs {v.named_cv_deg:.3f} deg, model-form discrepancy "
                f"profiled out; delta BIC {found.delta_bic:.0f} vs {v.named_bic:.0f}): no "
                "catalogue name is given"
            )
        v.cause, v.fit = Cause.unexplained(), base.fit
        v.residual_deg = base.residual_deg - found.correction_deg
        if mean_terms:
            v.cv_rmse_deg = (
                base.cv_rmse_deg * found.rmse_after_deg / max(found.rmse_before_deg, 1e-12)
            )
        else:
            v.cv_rmse_deg = base.cv_rmse_deg
        v.discovered = found.terms
    else:
        v.discovered = v.beside


def widen(
    ctx: Context,
    v: _Verdict,
    naming: Naming,
    results: Sequence[CandidateResult],
    groups: Sequence[str],
) -> None:
    """The named causes' intervals widened by the model form and averaged over the
    explanations the held-out data do not tell apart."""
    if v.fit.causes:
        v.fit = widened(ctx, v.fit)
        if v.cause.named:
            v.fit = averaged(ctx, v.fit, naming, results, groups)


def _extended_tie(tie: tuple[str, ...], v: _Verdict, names: Sequence[str]) -> tuple[str, ...]:
    """``tie`` with ``names`` appended; an empty tie starts at the named causes' label."""
    return (tie[0] if tie else Cause.of(v.fit.causes).label, *tie[1:], *names)


def tie_report(
    ctx: Context,
    base: _Baseline,
    v: _Verdict,
    naming: Naming,
    results: Sequence[CandidateResult],
    pair_tie: tuple[str, ...],
    groups: Sequence[str],
) -> list[tuple[str, str]]:
    """``v.tie``: the explanations the held-out data do not tell from the named one
    (single causes, pairs, order-dependent terms, discovered terms), with the notes;
    returns the order-dependent terms that tie it ((words, library name))."""
    named = v.cause.named
    tie: tuple[str, ...] = ()
    if named and len(v.fit.causes) == 1:
        named_result = next((c for c in results if c.fit.causes == v.fit.causes), None)
        if named_result is not None:
            tie = held_out_tie(named_result, results, groups)
    elif named and set(v.fit.causes) == set(naming.fit.causes):
        tie = pair_tie
    # an order-dependent term outside the catalogue that reproduces the named causes'
    # change of the predictions on this plan ties them: the name is not a pick
    order_ties: list[tuple[str, str]] = []
    beside_ties: list[str] = []
    rivals: list[tuple[str, float]] = []
    if v.fit.causes:
        change = base.residual_deg - v.residual_deg
        order_ties = order_confounded(ctx, base.fit, change, base.head_gain)
        if named:
            # the terms the library still finds beside the name, when they reproduce
            # what the name explains, tie it
            # (weighed in the residual variance left once the model-form discrepancy is
            # profiled out: a cause's evidence is taken against baseline + discrepancy)
            terms = [t.term for t in v.beside if t.term != "scatter"]
            dof = max(v.fit.n_obs - v.fit.n_params, 1)
            sigma = math.sqrt(v.fit.rss_discrepancy_deg2 / dof)
            beside_ties = beside_confounded(ctx, base.fit, change, base.head_gain, terms, sigma)
            # each term is fitted with the discrepancy's columns, as the name was
            disc = np.asarray(v.fit.discrepancy) if v.fit.discrepancy else 0.0
            rivals = library_confounded(
                ctx,
                base.fit,
                base.residual_deg,
                v.residual_deg - base.basis @ disc,
                v.fit.n_cause_params,
                base.head_gain,
                base.basis,
            )
    if tie:
        v.notes.append(
            f"tie: {', '.join(tie[1:])} explain(s) the held-out data as well as {tie[0]} (held-out "
            f"mean squared error within {TIE_STANDARD_ERRORS:g} standard error over the CV "
            "groups): the data do not tell them apart"
        )
    if order_ties:
        tie = _extended_tie(tie, v, [name for _, name in order_ties])
    rival_ties = [(t, d) for t, d in rivals if t not in tie and t not in beside_ties]
    if rival_ties:
        tie = _extended_tie(tie, v, [t for t, _ in rival_ties])
        v.notes.append(
            f"tie: terms outside the catalogue fit the data, within the noise, as well as "
            f"{', '.join(v.fit.causes)} ("
            + "; ".join(f"{term_words(t)}, {t}, delta BIC {d:.1f}" for t, d in rival_ties)
            + f", below the {ctx.min_delta_bic:g} a cause needs; negative: the term fits better): "
            "the name is not a pick"
        )
    beside_ties = [t for t in beside_ties if t not in tie]
    if beside_ties:
        tie = _extended_tie(tie, v, beside_ties)
        v.notes.append(
            f"tie: terms outside the catalogue found beside {', '.join(v.fit.causes)} "
            f"({', '.join(beside_ties)}) reproduce what it explains on this plan (the part "
            "only it explains is within the evidence a cause needs): the name is not a pick"
        )
    # a name is a pick only when the named causes explain the held-out data at least as
    # well as the discovered terms (both with the discrepancy profiled out); terms better
    # held out, though not by min_cv_gain, tie them
    found = base.found
    term_ties = [t.term for t in base.mean_terms if t.term not in tie]
    if named and term_ties and found.rmse_after_deg < v.named_cv_deg:
        tie = _extended_tie(tie, v, term_ties)
        v.notes.append(
            f"tie: terms outside the catalogue ({', '.join(term_ties)}) explain the held-out "
            f"data at least as well as {', '.join(v.fit.causes)} ({found.rmse_after_deg:.3f} "
            f"vs {v.named_cv_deg:.3f} deg, model-form discrepancy profiled out): the name is "
            "not a pick"
        )
    v.tie = tie
    return order_ties


def verdict_weights(base: _Baseline, scores: dict[Cause, float]) -> tuple[tuple[str, float], ...]:
    """The explanations' evidence weights (:func:`_evidence`), each by its label, the
    discovered terms among them."""
    labelled = {k.label: v for k, v in scores.items()}
    if base.mean_terms and math.isfinite(base.found.delta_bic):
        labelled[DISCOVERED] = base.found.delta_bic
    return evidence_weights(labelled)


def tie_notes(
    v: _Verdict,
    evidence: tuple[tuple[str, float], ...],
    order_ties: Sequence[tuple[str, str]],
) -> None:
    """Notes on evidence ties, on each discovered term and on order-dependent terms (and
    the experiment that separates those)."""
    ties = [e for e, w in evidence[1:] if w >= TIE_RATIO * evidence[0][1]]
    if ties:
        v.notes.append(
            f"tie: {', '.join(ties)} explain the data about as well as {evidence[0][0]} "
            "(evidence weights within a delta BIC of 2)"
        )
    for t in v.discovered:
        v.notes.append(
            f"discovered: {t.words} ({t.term}, held-out gain {100 * t.held_out_gain:.0f} %)"
        )
    for words, _ in order_ties:
        v.notes.append(
            f"{', '.join(v.fit.causes)} cannot be told from {words} on this plan "
            "(the trial order and the previous bend follow the angle): a tie is reported, "
            f"not a pick; {ORDER_EXPERIMENT}"
        )
        v.experiment = v.experiment or ORDER_EXPERIMENT


def check_misfit(ctx: Context, base: _Baseline, v: _Verdict) -> Misfit | None:
    """The lack-of-fit test of the explanation; refused, nothing is named."""
    if v.cause.kind is CauseKind.UNEXPLAINED:
        n_terms = sum(len(t.coefficients_deg) for t in base.found.terms)
        misfit = lack_of_fit_residuals(ctx.trials, v.residual_deg, base.fit.n_params + n_terms)
    else:
        misfit = lack_of_fit(ctx.trials, v.fit if v.fit.causes else base.fit)
    if misfit is not None and misfit.refused:
        # the least bad of wrong models is no name: the machine is not what the params say.
        # Terms outside the catalogue found stay reported (what the library finds in the
        # misfit), but not as the explanation: with them the data are missed beyond the
        # noise too, so "unexplained" (terms that explain the data) would over-claim
        v.notes.append(misfit.note())
        if v.cause.kind is not CauseKind.UNEXPLAINED:
            v.discovered = ()
        v.cause, v.fit, v.residual_deg = Cause.none(), base.fit, base.residual_deg
        v.cv_rmse_deg = base.cv_rmse_deg
        v.tie = ()
        v.experiment = (
            "describe the machine with --params (its geometry and wire) and diagnose again"
        )
    return misfit


def leftover_check(ctx: Context, base: _Baseline, v: _Verdict) -> LeftoverCheck:
    """Structure the explanation leaves along the commanded angle, beyond its model-form
    discrepancy and the noise, with a note."""
    left_res, nuisance = v.residual_deg, None
    if v.fit.discrepancy:
        # the discrepancy (bounded, or the learned curve: the machine's no-effect
        # relation) is part of the model, not a leftover: the smoother is judged beyond it
        left_res = v.residual_deg - base.basis @ np.asarray(v.fit.discrepancy)
        nuisance = base.basis
    leftover = leftover_structure(ctx.trials, left_res, list(ctx.fold_masks), nuisance=nuisance)
    if leftover.unnamed:
        v.notes.append(
            f"a discrepancy remains that no named cause explains (a smoother along the "
            f"commanded angle changes the held-out residual RMSE by {-100 * leftover.gain:+.0f} "
            f"%, {-100 * leftover.noise_gain:+.0f} % on the noise alone: p = "
            f"{leftover.p_value:.1g}): "
            "check the geometry parameters (die radius, pin radius and orbit, head axis) "
            "or look for two causes at once"
        )
    return leftover
