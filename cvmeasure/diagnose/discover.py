"""Discovery beyond the catalogue: history-aware regressors searched on the residuals.

When no named cause explains what the model misses, the residuals (measured
minus predicted, deg, stacked loaded / released) are searched with a library of
physically meaningful regressors the catalogue does not name:

=====================  =============================================================
term                   regressor (``s`` = bend direction, ``k`` = trial order)
=====================  =============================================================
``gear_runout_P``      ``s sin(2 pi |cmd| / P)``, ``s cos(...)``: a periodic error of the
                       drive along the head rotation (P = 60, 90, 120, 180 deg)
``warm_up_T``          ``s exp(-k / T)``: a transient at the start of a run (T = 5, 15 bends)
``previous_bend``      ``s s_prev |theta_prev| / 90``: the previous bend in the free span
``order_squared``      ``s (k / N)^2``: a curved trend along the run
``released_angle``     ``s [released] |cmd| / 100``: springback growing with the angle
                       beyond what the model and its discrepancy allow
=====================  =============================================================

Selection is sparse and stable: forward selection (at most three terms, each
adding at least ``MIN_DELTA_BIC``) on bootstrap resamples of the CV groups; a
term is kept when it is selected in at least ``STABILITY`` of the resamples and
its grouped held-out gain is at least ``MIN_GAIN``. Terms come with their
coefficient, a 95 % interval (OLS, Student t) and the held-out gain. A variance
growing with the angle (scatter, no mean) is tested separately (log squared
residuals against the angle) and reported as a term of its own.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from cvmeasure.contracts import TrialTable

__all__ = [
    "STABILITY",
    "MIN_GAIN",
    "DiscoveredTerm",
    "Discovery",
    "library",
    "discover",
]

#: Share of bootstrap resamples a term must be selected in.
STABILITY = 0.7
#: Held-out RMSE gain (relative) a set of discovered terms must bring.
MIN_GAIN = 0.1
#: BIC improvement each forward step needs.
MIN_DELTA_BIC = 10.0
#: Bootstrap resamples of the stability selection.
RESAMPLES = 30
#: Most terms selected.
MAX_TERMS = 3
#: p-value below which a variance growing with the angle is reported.
SCATTER_P = 1e-4

_WORDS = {
    "gear_runout": "a periodic error of the drive along the head rotation, period {p} deg",
    "warm_up": "a transient at the start of the run, time constant {p} bends",
    "previous_bend": "the previous bend, lying in the free span, changes the next one",
    "order_squared": "a curved trend along the run (trial order squared)",
    "released_angle": "springback growing with the angle beyond the model",
    "scatter": "scatter growing with the angle (variance, not a mean error)",
}


@dataclass(frozen=True)
class DiscoveredTerm:
    """A term the catalogue does not name, found in the residuals."""

    term: str
    words: str
    coefficients_deg: tuple[float, ...]
    intervals_deg: tuple[tuple[float, float], ...]
    stability: float  # share of resamples selecting it
    held_out_gain: float  # of the whole discovered set (relative RMSE reduction)

    def to_dict(self) -> dict[str, Any]:
        return {
            "term": self.term,
            "words": self.words,
            "coefficients_deg": list(self.coefficients_deg),
            "intervals_deg": [list(i) for i in self.intervals_deg],
            "stability": self.stability,
            "held_out_gain": self.held_out_gain,
        }


@dataclass(frozen=True)
class Discovery:
    """Terms found (may be empty), the held-out RMSE before and after them (deg)."""

    terms: tuple[DiscoveredTerm, ...]
    rmse_before_deg: float
    rmse_after_deg: float
    correction_deg: NDArray[np.float64]  # the terms' full-data prediction, stacked

    @property
    def gain(self) -> float:
        if not self.terms or self.rmse_before_deg <= 0:
            return 0.0
        return 1.0 - self.rmse_after_deg / self.rmse_before_deg


def library(trials: TrialTable) -> dict[str, NDArray[np.float64]]:
    """Regressor groups (name -> columns (3 N, c)) over stacked observations."""
    n = len(trials)
    s = trials.direction_sign
    mag = np.abs(trials.commanded_pin_deg)
    k = np.arange(n, dtype=np.float64)
    prev_s = np.concatenate([[0.0], s[:-1]])
    prev_theta = np.concatenate([[0.0], np.abs(trials.loaded_bend_deg[:-1])])
    prev_theta = np.where(np.isfinite(prev_theta), prev_theta, np.concatenate([[0.0], mag[:-1]]))

    def stack(v: NDArray[np.float64], blocks: Sequence[int] = (0, 1)) -> NDArray[np.float64]:
        out = np.zeros(3 * n)
        for b in blocks:
            out[b * n : (b + 1) * n] = v
        return out

    cols: dict[str, NDArray[np.float64]] = {}
    for p in (60, 90, 120, 180):
        w = 2 * np.pi * mag / p
        cols[f"gear_runout_{p}"] = np.column_stack([stack(s * np.sin(w)), stack(s * np.cos(w))])
    for t in (5, 15):
        cols[f"warm_up_{t}"] = stack(s * np.exp(-k / t))[:, None]
    cols["previous_bend"] = stack(s * prev_s * prev_theta / 90.0)[:, None]
    cols["order_squared"] = stack(s * (k / max(n - 1, 1)) ** 2)[:, None]
    cols["released_angle"] = stack(s * mag / 100.0, blocks=(1,))[:, None]
    return cols


def _words(name: str) -> str:
    base, _, p = name.rpartition("_") if name[-1].isdigit() else (name, "", "")
    return _WORDS[base].format(p=p)


def _forward(
    gram: NDArray[np.float64],
    xty: NDArray[np.float64],
    yty: float,
    n: int,
    spans: dict[str, slice],
    names: Sequence[str],
) -> list[str]:
    """Forward selection by BIC from the (weighted) normal equations of ``n`` rows:
    ``gram = X^T W X``, ``xty = X^T W y``, ``yty = y^T W y`` over every column of the
    library, ``spans`` each group's columns (the same least squares as on the rows
    repeated by their weights, without building them)."""
    chosen: list[str] = []
    rss = yty
    for _ in range(MAX_TERMS):
        best = None
        for name in names:
            if name in chosen or any(c.split("_")[0] == name.split("_")[0] for c in chosen):
                continue
            idx = np.concatenate(
                [np.arange(spans[c].start, spans[c].stop) for c in (*chosen, name)]
            )
            g, b = gram[np.ix_(idx, idx)], xty[idx]
            beta = np.linalg.lstsq(g, b, rcond=None)[0]
            r = max(yty - float(b @ beta), 0.0)
            width = spans[name].stop - spans[name].start
            dbic = n * math.log(max(rss, 1e-12) / max(r, 1e-12)) - width * math.log(n)
            if dbic >= MIN_DELTA_BIC and (best is None or dbic > best[0]):
                best = (dbic, name, r)
        if best is None:
            break
        chosen.append(best[1])
        rss = best[2]
    return chosen


def _scatter(trials: TrialTable, r: NDArray[np.float64]) -> DiscoveredTerm | None:
    n = len(trials)
    res = r[n : 2 * n]
    ok = np.isfinite(res)
    if ok.sum() < 10:
        return None
    mag = np.abs(trials.commanded_pin_deg)[ok]
    logsq = np.log(res[ok] ** 2 + 1e-12)
    x = np.column_stack([np.ones(mag.size), mag])
    coef, *_ = np.linalg.lstsq(x, logsq, rcond=None)
    dof = max(mag.size - 2, 1)
    resid = logsq - x @ coef
    stderr = math.sqrt(float(np.sum(resid**2)) / dof / float(np.sum((mag - mag.mean()) ** 2)))
    slope = float(coef[1])
    p_value = float(2.0 * special.stdtr(dof, -abs(slope) / max(stderr, 1e-300)))
    if not (p_value < SCATTER_P and slope > 0):
        return None
    t = float(special.stdtrit(dof, 0.975))
    half = 0.5 * slope  # log sd per deg
    ci = (0.5 * (slope - t * stderr), 0.5 * (slope + t * stderr))
    return DiscoveredTerm(
        "scatter", _WORDS["scatter"], (100 * half,), ((100 * ci[0], 100 * ci[1]),), 1.0, 0.0
    )


def discover(
    trials: TrialTable,
    residual_deg: NDArray[np.float64],
    groups: Sequence[str],
    folds: Sequence[NDArray[np.bool_]],
    *,
    seed: int = 0,
) -> Discovery:
    """Search the library on stacked residuals (NaN = not measured); see the module notes."""
    r = np.asarray(residual_deg, dtype=np.float64)
    n = len(trials)
    cols = library(trials)
    names = list(cols)
    ok = np.isfinite(r) & (np.arange(3 * n) < 2 * n)
    y = r[ok]
    sel = {k: v[ok] for k, v in cols.items()}
    unique, group_of = np.unique(np.asarray(groups), return_inverse=True)
    trial_of = np.tile(np.arange(n), 3)[ok]
    design = np.column_stack([sel[k] for k in names]) if names else np.zeros((y.size, 0))
    widths = np.cumsum([0] + [sel[k].shape[1] for k in names])
    spans = {
        k: slice(int(a), int(b)) for k, a, b in zip(names, widths[:-1], widths[1:], strict=True)
    }
    # per-group sums of the normal equations: a resample's are their weighted sum
    row_group = group_of.reshape(-1)[trial_of]

    def group_sums(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.bincount(row_group, weights=v, minlength=unique.size)

    n_cols = design.shape[1]
    gram_g = np.zeros((unique.size, n_cols, n_cols))
    for i in range(n_cols):
        for j in range(i, n_cols):
            gram_g[:, i, j] = gram_g[:, j, i] = group_sums(design[:, i] * design[:, j])
    xty_g = np.column_stack([group_sums(design[:, i] * y) for i in range(n_cols)])
    yty_g = group_sums(y**2)
    rows_g = np.bincount(row_group, minlength=unique.size)
    rng = np.random.default_rng(seed)
    counts: dict[str, int] = {k: 0 for k in names}
    for _ in range(RESAMPLES):
        w = np.bincount(rng.integers(0, unique.size, unique.size), minlength=unique.size)
        w = w.astype(np.float64)
        chosen = _forward(
            np.tensordot(w, gram_g, axes=1),
            w @ xty_g,
            float(w @ yty_g),
            int(w @ rows_g),
            spans,
            names,
        )
        for c in chosen:
            counts[c] += 1
    stable = [k for k in names if counts[k] >= STABILITY * RESAMPLES]
    before = float(np.sqrt(np.mean(y**2))) if y.size else math.nan
    empty = Discovery((), before, before, np.zeros(3 * n))
    scatter = _scatter(trials, r)
    if not stable:
        return Discovery((scatter,), before, before, np.zeros(3 * n)) if scatter else empty
    x = np.column_stack([sel[c] for c in stable])
    # grouped held-out gain of the stable set
    held = np.full(y.size, np.nan)
    for mask in folds:
        test = mask[trial_of]
        if test.all() or not test.any():
            continue
        beta = np.linalg.lstsq(x[~test], y[~test], rcond=None)[0]
        held[test] = y[test] - x[test] @ beta
    after = float(np.sqrt(np.nanmean(held**2)))
    gain = 1.0 - after / before if before > 0 else 0.0
    if gain < MIN_GAIN:
        return Discovery((scatter,), before, before, np.zeros(3 * n)) if scatter else empty
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ beta
    dof = max(y.size - x.shape[1], 1)
    cov = np.linalg.pinv(x.T @ x) * float(np.sum(resid**2)) / dof
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    t = float(special.stdtrit(dof, 0.975))
    terms, i = [], 0
    for c in stable:
        w = sel[c].shape[1]
        b, e = beta[i : i + w], se[i : i + w]
        terms.append(
            DiscoveredTerm(
                c,
                _words(c),
                tuple(float(v) for v in b),
                tuple((float(v - t * u), float(v + t * u)) for v, u in zip(b, e, strict=True)),
                counts[c] / RESAMPLES,
                gain,
            )
        )
        i += w
    if scatter:
        terms.append(scatter)
    full = np.zeros(3 * n)
    full[ok] = x @ beta
    return Discovery(tuple(terms), before, after, full)
