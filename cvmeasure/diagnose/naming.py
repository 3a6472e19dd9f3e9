"""The naming search: each cause tried, a second cause on top, the pair settled."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cvmeasure.diagnose.evidence import TIE_STANDARD_ERRORS, held_out_tie
from cvmeasure.diagnose.fitting import ModelFit, fit_model, grouped_kfold_cv
from cvmeasure.diagnose.identify import Identifiability, check_identifiability
from cvmeasure.diagnose.result import CandidateResult, Cause
from cvmeasure.diagnose.rules import (
    BEAM_RATIO,
    BEAM_WIDTH,
    GROSS_MISFIT_DEG,
    PAIR_PLAUSIBLE_RATIO,
    RESOLUTION_DEG,
    Context,
    bic_gain,
    is_plausible,
    structure_left,
)
from cvmeasure.sim.effects import effect_spec_for
from cvmeasure.sim.params import SimParams

if TYPE_CHECKING:
    pass


@dataclass(frozen=True)
class _Extension:
    """A first cause, extended: the final fit (one or two causes) and what was learnt."""

    fit: ModelFit
    cv_rmse_deg: float
    identifiability: tuple[Identifiability, ...]
    second_round: tuple[CandidateResult, ...]
    notes: tuple[str, ...]
    cv_discrepancy_rmse_deg: float = math.nan
    #: the pairs this first cause could name (accepted, not stuck, of plausible size),
    #: best held out first: the named one (when ``fit`` is a pair), then the others
    pairs: tuple[CandidateResult, ...] = ()
    #: the accepted pairs not named for a cause beyond its typical size (rivals of the
    #: named pair's held-out tie all the same: see :func:`_settle_pair`)
    unsized: tuple[CandidateResult, ...] = ()


@dataclass(frozen=True)
class Naming:
    """The causes named (or none), the model that names them and the notes on why."""

    cause: Cause
    fit: ModelFit
    cv_rmse_deg: float
    identifiability: tuple[Identifiability, ...]
    second_round: tuple[CandidateResult, ...]
    experiment: str | None
    notes: tuple[str, ...]
    cv_discrepancy_rmse_deg: float = math.nan
    #: the named pair (None for a single cause) and the other pairs any first cause of
    #: the beam could name, for the held-out tie
    pair: CandidateResult | None = None
    other_pairs: tuple[CandidateResult, ...] = ()
    #: the pairs any first cause of the beam could not name for their size
    #: (:attr:`_Extension.unsized`)
    unsized_pairs: tuple[CandidateResult, ...] = ()


#: First causes whose grid-rounded shape (:data:`~cvmeasure.diagnose.fitting.FORMS`) is
#: chosen again beside each second cause. Only the camera tilt's axis: the drift's form
#: (load exponent, whole steps profiled on a grid) would be profiled again for every
#: candidate, tripling the CPU of a diagnosis with drift first (0.9 -> 2.7 s on 60
#: trials), and a drift is rarely the first of a pair (its signature is the weaker).
REFORMED: tuple[str, ...] = ("camera_tilt",)


def try_causes(
    ctx: Context,
    named: ModelFit,
    named_cv: float,
    tried: Sequence[str],
    *,
    cv_all: bool = True,
) -> list[CandidateResult]:
    """Each cause on top of ``named``, best held-out first; ``cv_all=False`` skips the
    held-out error of causes that already fail the BIC test (they cannot be accepted).

    ``named_cv`` is the held-out RMSE of ``named`` with the discrepancy profiled out:
    a cause must beat "model + discrepancy", not the model alone."""
    out = []
    # the tilt's axis is not held at the grid point the tilt's own fit chose: beside a
    # second cause another axis can fit far better (once a scale takes its part), so it
    # is chosen again with the pair (grid and refit; see REFORMED)
    general = [c for c in named.causes if c in REFORMED]
    for name in tried:
        fit = fit_model(
            ctx.trials,
            ctx.params,
            (*named.causes, name),
            base_effects=ctx.base_effects,
            known={**named.param_values_by_cause(), **named.nuisance_values()},
            known_shapes=named.shapes_by_cause(),
        )
        if general:
            reformed = fit_model(
                ctx.trials,
                ctx.params,
                (*named.causes, name),
                base_effects=ctx.base_effects,
                known={
                    **{c: v for c, v in named.param_values_by_cause().items() if c not in general},
                    **named.nuisance_values(),
                },
                known_shapes={c: f for c, f in named.shapes_by_cause().items() if c not in general},
            )
            if reformed.rss_deg2 < fit.rss_deg2:
                fit = reformed
        dbic = bic_gain(named, fit)
        if not cv_all and dbic < ctx.min_delta_bic:
            out.append(CandidateResult(name, math.nan, fit, dbic, False))
            continue
        held = grouped_kfold_cv(
            ctx.trials,
            ctx.params,
            fit.causes,
            ctx.fold_masks,
            base_effects=ctx.base_effects,
            full_fit=fit,
        )
        held_disc = held.residual_after_discrepancy_deg(ctx.trials)
        cv, cv_disc = held.rmse_deg, held.rmse_after_discrepancy_deg(ctx.trials)
        cv_gain_ok = max(cv_disc, RESOLUTION_DEG) <= (1.0 - ctx.min_cv_gain) * max(
            named_cv, RESOLUTION_DEG
        )
        accepted = bool(cv_gain_ok and dbic >= ctx.min_delta_bic)
        out.append(CandidateResult(name, cv, fit, dbic, accepted, cv_disc, held_disc))
    out.sort(key=lambda c: (math.isnan(c.cv_rmse_deg), c.cv_rmse_deg))
    return out


def _extend(
    ctx: Context, first: CandidateResult, results: Sequence[CandidateResult], max_causes: int
) -> _Extension:
    """Identifiability of a first cause, and a second cause on top when structure is left."""
    masks = list(ctx.fold_masks)
    ident = tuple(
        check_identifiability(
            ctx.trials,
            ctx.params,
            first.cause,
            [c.cause for c in results if c.cause != first.cause],
            base_effects=ctx.base_effects,
        )
    )
    blocked = {first.cause, *(i.causes[1] for i in ident if not i.separable)}
    fit, cv, round2, notes = first.fit, first.cv_rmse_deg, [], []
    pairs: list[CandidateResult] = []
    unsized: list[CandidateResult] = []
    cv_disc = first.cv_discrepancy_rmse_deg
    if max_causes > 1 and structure_left(
        ctx.trials, first.fit, ctx.params, ctx.base_effects, masks
    ):
        round2 = try_causes(
            ctx,
            first.fit,
            first.cv_discrepancy_rmse_deg,
            [n for n in ctx.names if n not in blocked],
            cv_all=False,
        )
        # accepted on the held-out RMSE with the discrepancy profiled out, so ranked on
        # it too (the raw one also carries the model-form wave, the same for every pair)
        more = sorted((c for c in round2 if c.accepted), key=lambda c: c.cv_discrepancy_rmse_deg)
        # a pair that explains less (evidence) than its added cause alone is a fit stuck
        # where the first cause took up the added one's signature: not a pair to name
        alone = {c.cause: c.delta_bic for c in results}
        stuck = [
            c.cause
            for c in more
            if first.delta_bic + c.delta_bic < alone.get(c.cause, -math.inf) - ctx.min_delta_bic
        ]
        if stuck:
            notes.append(
                f"{', '.join(stuck)} on top of {first.cause} explain(s) less than "
                f"{', '.join(stuck)} alone (delta BIC): the pair is not named"
            )
        more = [c for c in more if c.cause not in stuck]
        unsized = [c for c in more if not is_plausible(c.fit, ctx.params)]
        # a pair with a cause far beyond its typical size takes the place of a mechanism
        # the catalogue lacks: the next accepted pair is tried, at most BEAM_WIDTH of them.
        # (Structure left beyond the discrepancy no longer refuses a pair: on the
        # independent model the right pair always leaves some, the model-form error beyond
        # the discrepancy's bound, and it refused about half of the missed pairs while
        # refusing no wrong pair on no-effect and outside-catalogue cases; terms outside
        # the catalogue are weighed against the pair after naming, by the held-out and
        # evidence test of step 3b.)
        refused = []
        for c in more[:BEAM_WIDTH]:
            if is_plausible(c.fit, ctx.params):
                break
            refused.append(c.cause)
        if refused:
            notes.append(
                f"{', '.join(refused)} on top of {first.cause} lower(s) the held-out RMSE "
                f"but beyond {PAIR_PLAUSIBLE_RATIO:g} times a typical size: a mechanism the "
                "catalogue does not name; not named"
            )
        more = [c for c in more[:BEAM_WIDTH] if c.cause not in refused]
        pairs = [c for c in more if is_plausible(c.fit, ctx.params)]
        if more:
            fit, cv = more[0].fit, more[0].cv_rmse_deg
            cv_disc = more[0].cv_discrepancy_rmse_deg
            notes.append(
                f"a second cause, {more[0].cause}, improves the held-out RMSE further "
                f"({first.cv_rmse_deg:.3f} -> {more[0].cv_rmse_deg:.3f} deg)"
            )
    return _Extension(
        fit, cv, ident, tuple(round2), tuple(notes), cv_disc, tuple(pairs), tuple(unsized)
    )


def settle_pair(
    naming: Naming, results: Sequence[CandidateResult], groups: Sequence[str]
) -> tuple[Naming, tuple[str, ...]]:
    """A named pair checked for held-out ties with the other pairs the beam could name
    and those it could not name for a cause beyond its typical size (the
    one-standard-error rule of :func:`_held_out_tie`): the naming and the tie.

    When every pair that ties holds the named pair's first cause, the data settle the
    first cause but not the second: a forward step adds only a cause it can pick, so the
    first cause is named alone (its own ties are checked as any single cause's). When
    the pairs that tie differ in the first cause (play lost on every bend or a drive
    compliance beside the same springback asymmetry: both a nearly constant
    under-bend), the pair is named and the tie reported.

    A pair refused for its size is a rival all the same: it explains the held-out data,
    and a size beyond the typical one can be a size the plan does not determine (on a
    sweep a drift's home shift is undone by the next reverse bend, so its rate runs to
    its bound along offset + constant) or a mechanism the catalogue lacks; either way
    the second cause named beside it is not settled."""
    named = naming.pair
    if named is None or set(named.fit.causes) != set(naming.fit.causes):
        return naming, ()
    order = naming.fit.causes
    rivals = (*naming.other_pairs, *naming.unsized_pairs)
    tie = held_out_tie(
        named,
        rivals,
        groups,
        lambda c: Cause.of(order if c is named else c.fit.causes).label,
    )
    if not tie:
        return naming, ()
    first = named.fit.causes[0]
    tied = [c for c in rivals if Cause.of(c.fit.causes).label in tie[1:]]
    alone = next((c for c in results if c.fit.causes == (first,)), None)
    if alone is None or not all(first in c.fit.causes for c in tied):
        return naming, tie
    unsized = [c.cause for c in tied if c in naming.unsized_pairs]
    note = (
        f"{', '.join(c.cause for c in (named, *tied))} on top of {first} explain the "
        f"held-out data equally well (within {TIE_STANDARD_ERRORS:g} standard error over "
        f"the CV groups"
        + (
            f"; {', '.join(unsized)} beyond {PAIR_PLAUSIBLE_RATIO:g} times a typical size"
            if unsized
            else ""
        )
        + "): the second cause is not settled and not named"
    )
    single = dataclasses.replace(
        naming,
        cause=Cause.of(alone.fit.causes),
        fit=alone.fit,
        cv_rmse_deg=alone.cv_rmse_deg,
        cv_discrepancy_rmse_deg=alone.cv_discrepancy_rmse_deg,
        notes=(*naming.notes, note),
        pair=None,
    )
    return single, ()


def name_causes(
    ctx: Context,
    results: Sequence[CandidateResult],
    base_fit: ModelFit,
    base_cv: float,
    max_causes: int,
) -> Naming:
    """Pick the cause(s) among the accepted candidates, or name none, with the notes why."""
    accepted = [c for c in results if c.accepted]
    notes: list[str] = []
    if not accepted:
        notes.append(
            f"no candidate beats the noise floor (held-out RMSE {base_cv:.3f} deg); "
            "nothing is named"
        )
        return Naming(Cause.none(), base_fit, base_cv, (), (), None, tuple(notes))
    outcomes, best, ext = _best_outcome(ctx, accepted, results, base_fit, max_causes)
    ext_fit = _first_cause_first(ext.fit, best, results)
    close = [
        c.cause for c in accepted if c is not best and c.cv_rmse_deg <= 1.05 * best.cv_rmse_deg
    ]
    if close and len(ext_fit.causes) == 1:
        notes.append(
            f"{', '.join(close)} explain the data almost as well as {best.cause} "
            "(held-out RMSE within 5 %)"
        )
    experiment = _confounded_notes(ext, notes)
    notes.extend(ext.notes)
    notes.extend(_at_bound_notes(ext_fit, ctx.params))
    if ext_fit.sigma_deg > GROSS_MISFIT_DEG:
        notes.append(
            f"the extended model still misses by {ext_fit.sigma_deg:.1f} deg (rms): the "
            "simulation does not describe these data (check signs, units and columns of the "
            f"trials file, and the params); {', '.join(ext_fit.causes)} not named"
        )
        return Naming(Cause.none(), base_fit, base_cv, (), (), None, tuple(notes))
    pair = ext.pairs[0] if len(ext_fit.causes) == 2 and ext.pairs else None
    named_set = frozenset(ext_fit.causes)
    return Naming(
        Cause.of(ext_fit.causes),
        ext_fit,
        ext.cv_rmse_deg,
        ext.identifiability,
        ext.second_round,
        experiment,
        tuple(notes),
        ext.cv_discrepancy_rmse_deg,
        pair,
        _each_once([c for _, o in outcomes for c in o.pairs], named_set),
        _each_once([c for _, o in outcomes for c in o.unsized], named_set),
    )


def _best_outcome(
    ctx: Context,
    accepted: Sequence[CandidateResult],
    results: Sequence[CandidateResult],
    base_fit: ModelFit,
    max_causes: int,
) -> tuple[list[tuple[CandidateResult, _Extension]], CandidateResult, _Extension]:
    """Every first cause of the beam extended, and the best: (outcomes, first, extension)."""
    # greedy with a small beam: the best few single causes each get their second round
    firsts = [c for c in accepted if c.cv_rmse_deg <= BEAM_RATIO * accepted[0].cv_rmse_deg]
    outcomes = [(first, _extend(ctx, first, results, max_causes)) for first in firsts[:BEAM_WIDTH]]
    # the lowest held-out error wins among the outcomes the evidence does not rule out
    # (a delta BIC within min_delta_bic of the best outcome's): a pair stuck where its
    # first cause took up another's signature can predict held-out data slightly
    # better while explaining far less than that other cause alone
    evidence_of = [bic_gain(base_fit, o[1].fit) for o in outcomes]
    top = max(evidence_of)
    plausible = [
        o for o, e in zip(outcomes, evidence_of, strict=True) if e >= top - ctx.min_delta_bic
    ]
    # a pair reached from its first cause is a pair only if it also beats its second
    # cause alone by the acceptance rule: the forward step tests the pair against the
    # first cause only, and a weak first cause with the strong one added (an offset, then
    # the drift) is the strong cause alone with a term it does not need
    nested = [o for o in plausible if _beats_each_alone(ctx, o[1], results)]
    best, ext = min(nested or plausible, key=lambda o: o[1].cv_rmse_deg)
    return outcomes, best, ext


def _beats_each_alone(ctx: Context, ext: _Extension, results: Sequence[CandidateResult]) -> bool:
    """The extension's pair (a single cause passes) accepted against each of its causes
    alone: the held-out RMSE with the discrepancy profiled out lowered by
    ``min_cv_gain`` and the evidence raised by ``min_delta_bic``."""
    if len(ext.fit.causes) < 2:
        return True
    pair_cv = ext.cv_discrepancy_rmse_deg
    if not math.isfinite(pair_cv):
        pair_cv = ext.cv_rmse_deg
    for cause in ext.fit.causes:
        alone = next((c for c in results if c.cause == cause), None)
        if alone is None:
            continue
        alone_cv = alone.cv_discrepancy_rmse_deg
        if not math.isfinite(alone_cv):
            alone_cv = alone.cv_rmse_deg
        cv_ok = max(pair_cv, RESOLUTION_DEG) <= (1.0 - ctx.min_cv_gain) * max(
            alone_cv, RESOLUTION_DEG
        )
        if not (cv_ok and bic_gain(alone.fit, ext.fit) >= ctx.min_delta_bic):
            return False
    return True


def _first_cause_first(
    ext_fit: ModelFit, best: CandidateResult, results: Sequence[CandidateResult]
) -> ModelFit:
    """A named pair ordered with the cause that alone predicts held-out data best first."""
    # a named pair's first cause is the one that alone predicts held-out data best with
    # the discrepancy profiled out (as the pair itself is ranked): the raw held-out RMSE
    # also carries the baseline's model-form wave along the angle, which on a repeats
    # plan (whole commands held out) a cause even in the direction (camera tilt, scale)
    # partly takes and an odd one (springback asymmetry, orthogonal to it there) cannot
    single_cv = {
        c.cause: c.cv_discrepancy_rmse_deg
        if math.isfinite(c.cv_discrepancy_rmse_deg)
        else c.cv_rmse_deg
        for c in results
    }
    if len(ext_fit.causes) == 2 and single_cv[ext_fit.causes[1]] < single_cv[best.cause]:
        ext_fit = ext_fit.reordered(ext_fit.causes[::-1])
    return ext_fit


def _confounded_notes(ext: _Extension, notes: list[str]) -> str | None:
    """A note per pair the design cannot tell apart; the first experiment that would."""
    confounded = [i for i in ext.identifiability if not i.separable]
    for i in confounded:
        how = i.experiment or "no experiment in the catalogue separates them"
        notes.append(
            f"{i.causes[0]} and {i.causes[1]} cannot be told apart on this data "
            f"(signature similarity {i.similarity:.3f}); {how}"
        )
    return next((i.experiment for i in confounded if i.experiment), None)


def _at_bound_notes(fit: ModelFit, params: SimParams) -> list[str]:
    """A note when a cause sits at its physical bound (on the machine ``params`` describes)."""
    at_bound = [
        f"{c} ({spec.param} = {v:.4g} {spec.unit})"
        for c, v in zip(fit.causes, fit.values, strict=True)
        for spec in (effect_spec_for(c, params),)
        if np.isclose(v, spec.lower) or np.isclose(v, spec.upper)
    ]
    if not at_bound:
        return []
    return [
        f"{', '.join(at_bound)} at its physical bound: the data want more than the "
        "catalogue allows; treat the name with suspicion"
    ]


def _each_once(
    kept: Sequence[CandidateResult], named_set: frozenset[str]
) -> tuple[CandidateResult, ...]:
    """Each set of causes once (the one best held out), the named set left out."""
    best: dict[frozenset[str], CandidateResult] = {}
    for c in kept:
        key = frozenset(c.fit.causes)
        if key != named_set and (
            key not in best or c.cv_discrepancy_rmse_deg < best[key].cv_discrepancy_rmse_deg
        ):
            best[key] = c
    return tuple(best.values())


def candidate_scores(results: Sequence[CandidateResult], naming: Naming) -> dict[Cause, float]:
    """Delta BIC against the baseline + discrepancy of nothing, each single cause and
    the named pair."""
    scores = {Cause.none(): 0.0}
    for c in results:
        if math.isfinite(c.delta_bic):
            scores[Cause.of((c.cause,))] = c.delta_bic
    for c in naming.second_round:  # the pair named (a refused pair is not an explanation)
        if set(c.fit.causes) == set(naming.fit.causes) and math.isfinite(c.delta_bic):
            first = [x for x in c.fit.causes if x != c.cause]
            pair = Cause.of((*first, c.cause))
            scores[pair] = scores.get(Cause.of(first[:1]), 0.0) + c.delta_bic
    return scores
