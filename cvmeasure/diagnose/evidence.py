"""Held-out ties and evidence weights: whether the data tell explanations apart."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from cvmeasure.diagnose.fitting import ModelFit
from cvmeasure.diagnose.result import CandidateResult

if TYPE_CHECKING:
    pass


#: discrepancy profiled out) exceeds the named cause's by at most this many standard
#: errors of the difference over the CV groups (the one-standard-error rule).
TIE_STANDARD_ERRORS = 1.0


def held_out_excess(
    named_deg: NDArray[np.float64], other_deg: NDArray[np.float64], groups: Sequence[str]
) -> tuple[float, float] | None:
    """(mean, standard error) per observation of ``other``'s squared held-out residuals less
    ``named``'s (deg^2): the differences summed per CV group and the standard error
    cluster-robust over the groups; None with fewer than two groups."""
    labels = np.unique(np.asarray(groups), return_inverse=True)[1]
    rows = np.tile(labels, named_deg.size // labels.size)
    n_groups = int(labels.max()) + 1
    ok = np.isfinite(named_deg) & np.isfinite(other_deg)
    diff = other_deg[ok] ** 2 - named_deg[ok] ** 2
    per_group = np.bincount(rows[ok], weights=diff, minlength=n_groups)
    count = np.bincount(rows[ok], minlength=n_groups).astype(float)
    mean = float(diff.sum() / max(ok.sum(), 1))
    g = int(np.count_nonzero(count))
    if g < 2:
        return None
    dev = per_group - count * mean
    return mean, math.sqrt(g / (g - 1) * float(np.sum(dev**2))) / float(ok.sum())


def held_out_tie(
    named: CandidateResult,
    others: Sequence[CandidateResult],
    groups: Sequence[str],
    label: Callable[[CandidateResult], str] = lambda c: c.cause,
) -> tuple[str, ...]:
    """The named explanation and the accepted ones (``others``) that explain the held-out
    data as well (:data:`TIE_STANDARD_ERRORS`), each as ``label`` gives it (a single
    cause's name; a pair ``a + b``); empty when none ties.

    The difference of squared held-out errors is summed per CV group (a group's
    observations share their fold and their errors), and its mean per observation is
    compared with its cluster-robust standard error over the groups."""
    if named.cv_residual_deg is None:
        return ()
    tied = []
    for c in others:
        if c is named or not c.accepted or c.cv_residual_deg is None:
            continue
        excess = held_out_excess(named.cv_residual_deg, c.cv_residual_deg, groups)
        if excess is not None and excess[0] <= TIE_STANDARD_ERRORS * excess[1]:
            tied.append(label(c))
    return (label(named), *tied) if tied else ()


#: Explanations whose evidence weights are within this factor of the best are a tie.
TIE_RATIO = math.exp(-1.0)  # delta BIC of 2


#: The explanation "terms outside the catalogue" in the evidence weights.
DISCOVERED = "unexplained (discovered terms)"


def evidence_weights(scores: dict[str, float]) -> tuple[tuple[str, float], ...]:
    """Evidence weights (BIC approximation of posterior probabilities, equal priors) of
    the explanations scored by :func:`_scores` (and the discovered terms); best first."""
    top = max(scores.values())
    raw = {k: math.exp(0.5 * (v - top)) for k, v in scores.items()}
    total = sum(raw.values())
    return tuple(sorted(((k, v / total) for k, v in raw.items()), key=lambda kv: -kv[1]))


def alone_excluding_no_effect(
    results: Sequence[CandidateResult], causes: Sequence[str]
) -> CandidateResult | None:
    """Of a refused pair's causes, the accepted single one whose own interval excludes no
    effect, the best held out (discrepancy profiled out); None: none of them."""
    if len(causes) < 2:
        return None
    alone = [
        c
        for c in results
        if c.accepted and len(c.fit.causes) == 1 and c.cause in causes
        if not holds_no_effect(c.fit)
    ]
    return min(alone, key=lambda c: c.cv_discrepancy_rmse_deg, default=None)


def holds_no_effect(fit: ModelFit) -> list[str]:
    """The causes of ``fit`` whose 95 % interval holds 0 (every catalogue effect's
    no-effect value).

    On sweeps with nothing hidden, the model-form error beyond the discrepancy's bound
    (its coefficients at +-0.25 deg) passed as a scale of about 0.01: accepted by its
    delta BIC and held-out gain against baseline + the bounded discrepancy, while its
    own interval, which carries the discrepancy, held 0 (e.g. -0.007 .. 0.017). A pair is kept when one of its causes excludes no effect (its
    second cause passed its own test beside the first)."""
    return [c for c, (lo, hi) in zip(fit.causes, fit.intervals, strict=True) if lo <= 0.0 <= hi]
