"""The diagnosis's thresholds and the small rules every step applies (angles in deg).

The module notes of :mod:`cvmeasure.diagnose.core` say how they are used.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.fitting import ModelFit
from cvmeasure.diagnose.residuals import leftover_structure, residual_trends
from cvmeasure.sim.effects import Effect, effect_spec_for
from cvmeasure.sim.params import SimParams

if TYPE_CHECKING:
    pass


#: BIC improvement (one extra parameter) a candidate needs ("very strong" evidence).
MIN_DELTA_BIC = 10.0
#: Relative held-out RMSE gain over the baseline a candidate needs.
MIN_CV_GAIN = 0.05
#: A second cause is only tried when a smoother gains this much on the first model's
#: residuals, or a residual trend has a p-value below SECOND_SCREEN_P.
SECOND_SCREEN_GAIN = 0.1
SECOND_SCREEN_P = 1e-4
#: Single causes within this ratio of the best held-out RMSE each get a second round
#: (at most BEAM_WIDTH of them): a greedy first pick can be the wrong one of a pair.
BEAM_RATIO = 1.25
BEAM_WIDTH = 3
#: Angles are never known better than this (deg): residuals below it are not structure,
#: so exact (noise-free) data cannot make a cause out of rounding error.
RESOLUTION_DEG = 1e-3
#: An extended model still missing by more than this (deg rms) names nothing: the
#: simulation does not describe the data (wrong signs, units, columns or params).
GROSS_MISFIT_DEG = 5.0
#: Fewest CV groups (parts); with fewer, every trial is its own group.
MIN_GROUPS = 3
#: Fewest trials the diagnosis accepts.
MIN_TRIALS = 8


#: size: two causes, one of them far larger than any machine shows, are taking the place
#: of a mechanism the catalogue does not have (the discrepancy hides the rest).
PAIR_PLAUSIBLE_RATIO = 1.5


def is_plausible(fit: ModelFit, params: SimParams) -> bool:
    """Every cause of ``fit`` within PAIR_PLAUSIBLE_RATIO of its typical size (on the
    machine ``params`` describes)."""
    return all(
        abs(v) <= PAIR_PLAUSIBLE_RATIO * max(abs(x) for x in effect_spec_for(c, params).typical)
        for c, v in zip(fit.causes, fit.values, strict=True)
    )


#: A named cause refitted with the discrepancy keeps its name against discovered terms
#: only when it is at least this share of the low end of its typical size: what a
#: smaller cause takes is the model-form error beyond the discrepancy's bound (on data
#: with nothing hidden, where the bound is reached, a scale of 0.003-0.005 against a
#: typical 0.015-0.06), not a cause.
JOINT_MIN_TYPICAL_SHARE = 0.5


def typical_size(fit: ModelFit, params: SimParams) -> bool:
    """Every cause of ``fit`` at least JOINT_MIN_TYPICAL_SHARE of its typical size (on
    the machine ``params`` describes)."""
    return all(
        abs(v) >= JOINT_MIN_TYPICAL_SHARE * min(abs(x) for x in effect_spec_for(c, params).typical)
        for c, v in zip(fit.causes, fit.values, strict=True)
    )


def bic_gain(base: ModelFit, fit: ModelFit) -> float:
    """BIC improvement of ``fit`` over ``base``, both with the bounded model-form
    discrepancy profiled out of their residuals (floored at the resolution)."""
    n = fit.n_obs
    extra = fit.n_params - base.n_params
    floor = n * RESOLUTION_DEG**2
    rss0 = max(base.rss_discrepancy_deg2, floor)
    rss1 = max(fit.rss_discrepancy_deg2, floor)
    return float(n * math.log(rss0 / rss1) - extra * math.log(n))


def structure_left(
    trials: TrialTable,
    fit: ModelFit,
    params: SimParams,
    base_effects: Sequence[Effect],
    folds: Sequence[NDArray[np.bool_]],
) -> bool:
    """Screen for a second cause: structure left along the angle, or a residual trend."""
    res = fit.residuals(trials, params, base_effects)
    if leftover_structure(trials, res, list(folds), null_draws=0).gain > SECOND_SCREEN_GAIN:
        return True
    p_values = [t.p_value for t in residual_trends(trials, res) if math.isfinite(t.p_value)]
    return bool(p_values) and min(p_values) < SECOND_SCREEN_P


def cv_groups(trials: TrialTable) -> tuple[tuple[str, ...], str | None]:
    """Cross-validation groups and a note: the parts when there are at least
    ``MIN_GROUPS`` of them, else single trials with repeated identical commands held
    out together (a repeat left in the training folds would leak its own answer)."""
    has_parts = any(t.part for t in trials.trials)
    if has_parts and len(set(trials.group)) >= MIN_GROUPS:
        return trials.group, None
    notes = []
    if has_parts:
        notes.append(
            f"fewer than {MIN_GROUPS} parts: cross-validation groups are single trials, so "
            "effects shared within a part are not held out"
        )
    keys = tuple(f"command {c:.1f}" for c in trials.commanded_pin_deg)
    n_keys = len(set(keys))
    if n_keys < MIN_GROUPS:
        keys = tuple(str(i) for i in range(len(trials)))
    elif n_keys < len(trials):
        notes.append(
            f"repeated commands are held out together in cross-validation ({n_keys} "
            f"distinct commands in {len(trials)} trials)"
        )
    return keys, "; ".join(notes) or None


def subset_by_group(trials: TrialTable, size: int, seed: int = 0) -> TrialTable:
    """About ``size`` trials: whole CV groups drawn at random, in their original order."""
    groups = np.asarray(trials.group)
    unique, counts = np.unique(groups, return_counts=True)
    order = np.random.default_rng(seed).permutation(len(unique))
    keep = unique[order[np.cumsum(counts[order]) <= size]]
    if keep.size == 0:  # one huge group: single trials instead
        mask = np.zeros(len(trials), dtype=bool)
        mask[np.random.default_rng(seed).choice(len(trials), size, replace=False)] = True
        return trials.subset(mask)
    return trials.subset(np.isin(groups, keep))


@dataclass(frozen=True)
class Context:
    """What every step of one diagnosis works on."""

    trials: TrialTable
    params: SimParams
    base_effects: tuple[Effect, ...]
    fold_masks: tuple[NDArray[np.bool_], ...]
    names: tuple[str, ...]
    min_cv_gain: float
    min_delta_bic: float
