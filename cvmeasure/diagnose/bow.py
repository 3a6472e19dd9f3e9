"""The span's elastic bow: whether it belongs in the model when a compliance and a scale
are the two best explanations.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.evidence import TIE_STANDARD_ERRORS, held_out_excess
from cvmeasure.diagnose.fitting import ModelFit, fit_model, group_folds, grouped_kfold_cv
from cvmeasure.diagnose.result import CauseKind, Diagnosis
from cvmeasure.diagnose.rules import MIN_CV_GAIN, cv_groups
from cvmeasure.sim.effects import Effect
from cvmeasure.sim.params import SimParams

if TYPE_CHECKING:
    pass


#: constant from first contact and rising as the lever shortens, less the bow's
#: over-bend (largest at small bends, falling with the lever) is a scale's shape.
BOW_RIVALS: tuple[str, str] = ("compliance", "scale")


@dataclass(frozen=True)
class _BowDecision:
    """The straight leg against the span's bow, each with its better rival (deg)."""

    straight: str  # the better rival with the leg straight
    bowed: str  # the better rival with the bow
    use_bow: bool
    tied: bool  # within TIE_STANDARD_ERRORS held out: the data do not tell them apart
    note: str
    bowed_fits: dict[str, ModelFit] = field(default_factory=dict)  # each rival with the bow


def bow_decides(
    trials: TrialTable,
    params: SimParams,
    result: Diagnosis,
    base_effects: tuple[Effect, ...],
    folds: int,
    min_cv_gain: float = MIN_CV_GAIN,
) -> _BowDecision | None:
    """Whether the span's elastic bow (beam theory, share 1) belongs in the model; None
    when not asked (the caller does not ask it of more than ``MAX_TRIALS`` trials).

    Asked only of a straight-leg model (``span_bow_share`` 0) that named one of
    :data:`BOW_RIVALS` (or nothing, terms outside the catalogue preferred), whose best
    accepted single cause is one of them with the other accepted too. Both are refitted
    with the bow, and the better bowed fit is compared with the better straight one
    held out (mean squared error, discrepancy profiled out, per CV group): the bow is
    used when it explains the held-out data better (and, when terms discovered outside
    the catalogue were preferred to the straight rivals, better than those by
    ``min_cv_gain``, the margin by which they replaced the name); within
    :data:`TIE_STANDARD_ERRORS` standard errors the two are a tie."""
    if params.span_bow_share > 0:
        return None
    singles = {
        c.cause: c
        for c in result.candidates
        if len(c.fit.causes) == 1 and c.accepted and math.isfinite(c.cv_discrepancy_rmse_deg)
    }
    if not singles or not all(n in singles for n in BOW_RIVALS):
        return None
    best = min(singles.values(), key=lambda c: c.cv_discrepancy_rmse_deg)
    named_rival = result.cause.primary in BOW_RIVALS  # a pair's first cause counts
    if best.cause not in BOW_RIVALS or not (
        named_rival or result.cause.kind is CauseKind.UNEXPLAINED
    ):
        return None
    straight = best  # the better straight rival: the best single cause is one of them
    if straight.cv_residual_deg is None:
        return None
    bowed_params = dataclasses.replace(params, span_bow_share=1.0)
    groups, _ = cv_groups(trials)
    masks = group_folds(groups, folds)
    bowed, bowed_res, bowed_fits = {}, {}, {}
    for name in BOW_RIVALS:
        fit = fit_model(trials, bowed_params, name, base_effects=base_effects)
        bowed_fits[name] = fit
        held = grouped_kfold_cv(
            trials, bowed_params, (name,), masks, base_effects=base_effects, full_fit=fit
        )
        bowed_res[name] = held.residual_after_discrepancy_deg(trials)
        bowed[name] = held.rmse_after_discrepancy_deg(trials)
    best_bowed = min(BOW_RIVALS, key=lambda n: bowed[n])
    excess = held_out_excess(straight.cv_residual_deg, bowed_res[best_bowed], groups)
    if excess is None:
        return None
    # two models of the machine, each with its better rival: the one whose rival explains
    # the held-out data better is used (the bow is beam theory, not a fitted shape, so
    # choosing it adds no parameter); terms outside the catalogue preferred to the straight
    # rivals must be beaten too
    use_bow = excess[0] < 0.0
    if result.cause.kind is CauseKind.UNEXPLAINED and not (
        bowed[best_bowed] <= (1.0 - min_cv_gain) * result.discovered_rmse_deg
    ):
        use_bow = False  # the terms replaced the name by min_cv_gain: so must the name them
    tied = abs(excess[0]) <= TIE_STANDARD_ERRORS * excess[1]
    note = (
        f"the span's elastic bow (beam theory, M l / 6 EI) {'is' if use_bow else 'is not'} "
        "in the model: a compliance and a scale differ by the bow's shape; held out "
        f"(discrepancy profiled out) with the bow {', '.join(f'{n} {bowed[n]:.4f}' for n in BOW_RIVALS)}, "
        f"with the leg straight {', '.join(f'{n} {singles[n].cv_discrepancy_rmse_deg:.4f}' for n in BOW_RIVALS)} deg"
        + (
            f"; {best_bowed} with the bow and {straight.cause} with the leg straight are within "
            f"{TIE_STANDARD_ERRORS:g} standard error over the CV groups: the data do not tell "
            "them apart"
            if tied and best_bowed != straight.cause
            else ""
        )
    )
    return _BowDecision(straight.cause, best_bowed, use_bow, tied, note, bowed_fits)
