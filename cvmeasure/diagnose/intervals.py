"""The named causes' 95 % intervals widened by the model form and averaged over the
explanations the held-out data do not tell apart.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from cvmeasure.diagnose.evidence import held_out_tie
from cvmeasure.diagnose.fitting import DISCREPANCY_P, ModelFit, fit_model
from cvmeasure.diagnose.naming import Naming
from cvmeasure.diagnose.result import CandidateResult, Cause
from cvmeasure.diagnose.rules import Context
from cvmeasure.sim.effects import effect_spec_for

if TYPE_CHECKING:
    pass


def widened(ctx: Context, fit: ModelFit) -> ModelFit:
    """The fit with its 95 % intervals widened by the model form: the causes are refitted
    with the bounded discrepancy profiled out of every residual, and each interval
    becomes the hull of the two fits' 95 % intervals (within the bounds), so it holds
    the parameter whether the model-form error stays in the residuals or is taken by
    the discrepancy (a move of the estimate and the lost precision both count). Only
    when the data show a model-form error (the discrepancy improves the BIC of the fit,
    its coefficients counted as parameters); otherwise the intervals are kept.

    The fit's side is its interval with the model-form error counted once
    (``intervals_measured``: by the discrepancy's variance, not also as noise and as an
    error shared by repeated commands), not the one its causes were named with."""
    if not fit.model_form_p < DISCREPANCY_P:
        return fit
    alt = fit_model(
        ctx.trials,
        ctx.params,
        fit.causes,
        base_effects=ctx.base_effects,
        start=fit,
        discrepancy=True,
    )
    own = fit.intervals_measured or fit.intervals
    out = []
    for c, (lo, hi), (alo, ahi) in zip(fit.causes, own, alt.intervals, strict=True):
        spec = effect_spec_for(c, ctx.params)
        out.append((max(min(lo, alo), spec.lower), min(max(hi, ahi), spec.upper)))
    return dataclasses.replace(fit, intervals=tuple(out))


def averaged(
    ctx: Context,
    fit: ModelFit,
    naming: Naming,
    results: Sequence[CandidateResult],
    groups: Sequence[str],
) -> ModelFit:
    """The widened ``fit`` (:func:`_widened`) with each cause's 95 % interval the hull of
    its intervals (each widened too) in every explanation that explains the held-out data
    as well as the named one (:func:`_held_out_tie`, the one-standard-error rule) and
    holds that cause: the named single cause, the single causes, the pairs the beam
    could name and those it refused for a cause beyond its typical size (rivals all the
    same: :func:`_settle_pair`; on a sweep an offset beside a drift the plan cannot size
    moves with that drift's rate: docs/diagnosis.md, Limits). The interval is then
    conditional on the cause, not on the pair: a cause named beside a second cause the
    held-out data do not settle (a pair against its first cause alone, or against a pair
    with another second cause) keeps the value it would have without that second cause in
    its interval (model averaging over the explanations the data do not tell apart, each
    with the same weight)."""
    key = frozenset(fit.causes)
    pool = [*results, *naming.other_pairs, *naming.unsized_pairs]
    if naming.pair is not None:
        pool.append(naming.pair)
    named = next((c for c in pool if frozenset(c.fit.causes) == key), None)
    if named is None:
        return fit
    others = [c for c in pool if c is not named and key & set(c.fit.causes) and c.fit.intervals]
    by_label = {Cause.of(c.fit.causes).label: c for c in others}
    tied = held_out_tie(named, others, groups, lambda c: Cause.of(c.fit.causes).label)
    out = list(fit.intervals)
    for label in tied[1:]:
        alt = widened(ctx, by_label[label].fit)
        for i, c in enumerate(fit.causes):
            if c in alt.causes:
                alo, ahi = alt.intervals[alt.causes.index(c)]
                if math.isfinite(alo) and math.isfinite(ahi):
                    out[i] = (min(out[i][0], alo), max(out[i][1], ahi))
    return dataclasses.replace(fit, intervals=tuple(out))
