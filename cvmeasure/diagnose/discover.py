"""Discovery beyond the catalogue: history-aware regressors searched on the residuals.

When no named cause explains what the model misses, the residuals (measured
minus predicted, deg, stacked loaded / released) are searched with a library of
physically meaningful regressors the catalogue does not name:

=====================  =============================================================
term                   regressor (``s`` = bend direction, ``k`` = trial order)
=====================  =============================================================
``gear_runout_P``      ``s sin(2 pi |cmd| / P)``, ``s cos(...)``: a periodic error of the
                       drive along the head rotation (P = 60, 90, 120, 180 deg); the head's
                       once-per-revolution runout (P = 360, a rival only) zero at home:
                       ``s sin(2 pi |cmd| / P)``, ``s (cos(...) - 1)``
``warm_up_T``          ``s (1 - exp(-k / T))``: a loss that builds up over the first bends
                       of a run and levels off (T = 5, 15, 45 bends)
``previous_bend``      ``s_prev |theta_prev| / 90`` (the bend's size changes by
                       ``s s_prev |theta_prev| / 90``: the previous bend, lying in the free
                       span, adds when it was bent the same way, takes off when not; the
                       same for a mirrored run, as the head is mirror-symmetric)
``order_squared``      ``s (k / N)^2``: a curved trend along the run
``released_angle``     ``s [released] |cmd| / 100``: springback growing with the angle
                       beyond what the model and its discrepancy allow
=====================  =============================================================

Selection is sparse and stable: forward selection (at most three terms, each
adding at least ``MIN_DELTA_BIC``) on bootstrap resamples of the CV groups; a
term is kept when it is selected in at least ``STABILITY`` of the resamples and
its grouped held-out gain is at least ``MIN_GAIN``. Terms come with their
coefficient, a 95 % interval (OLS, Student t) and the held-out gain. A variance
growing with the angle (scatter, no mean) is tested separately and reported as a
term of its own: on the measured springback (loaded minus released residual, which
the photo error shared by a bend's two photos and every machine-side error leave
out; the released residual when no loaded angle was measured), a smooth mean along
the angle removed per direction, a likelihood-ratio test of a standard deviation
``sqrt(sigma0^2 + (c |cmd| / 100)^2)`` against a constant one.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, special

from cvmeasure.contracts import TrialTable

__all__ = [
    "STABILITY",
    "MIN_GAIN",
    "DiscoveredTerm",
    "Discovery",
    "library",
    "term_words",
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
#: Name of the always-fitted nuisance columns (see :func:`discover`).
_REFIT = "_refit"
#: p-value below which a variance growing with the angle is reported.
SCATTER_P = 1e-4

_WORDS = {
    "gear_runout": "a periodic error of the drive along the head rotation, period {p} deg",
    "warm_up": "a loss that builds up over the first bends of the run and levels off "
    "(warm-up), time constant {p} bends",
    "previous_bend": "the previous bend, lying in the free span, changes the next one "
    "(more when bent the same way, less when not)",
    "order_squared": "a curved trend along the run (trial order squared)",
    "released_angle": "springback growing with the angle beyond the model",
    "scatter": "springback scatter growing with the angle (variance, not a mean error): "
    "standard deviation in deg per 100 deg of bend",
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
    #: BIC improvement of the mean terms over the residuals they were found in (each
    #: coefficient counted, and one more per term for its choice from the library)
    delta_bic: float = 0.0

    @property
    def gain(self) -> float:
        if not self.terms or self.rmse_before_deg <= 0:
            return 0.0
        return 1.0 - self.rmse_after_deg / self.rmse_before_deg


#: Periods (deg of head rotation) of the drive's runout terms searched in the residuals.
RUNOUT_PERIODS: tuple[int, ...] = (60, 90, 120, 180)
#: The head's once-per-revolution runout (the pin's orbit off the head's axis): over the
#: 15-120 deg a session bends it is a slow curve that forward selection would take for the
#: model-form error, so it is not searched for; it is a rival a named cause is tested
#: against (:func:`cvmeasure.diagnose.terms.library_confounded`).
HEAD_PERIOD = 360
RIVAL_PERIODS: tuple[int, ...] = (*RUNOUT_PERIODS, HEAD_PERIOD)


def library(
    trials: TrialTable,
    head_gain: NDArray[np.float64] | None = None,
    periods: Sequence[int] = RUNOUT_PERIODS,
) -> dict[str, NDArray[np.float64]]:
    """Regressor groups (name -> columns (3 N, c)) over stacked observations.

    ``head_gain`` (3 N, deg of bend per deg of head rotation, e.g.
    :meth:`ModelFit.head_sensitivity`) carries the drive's terms (runout, warm-up,
    trend along the run: errors of the head rotation) to the bend; None = 1.
    ``periods``: the runout terms' periods (deg of head rotation)."""
    n = len(trials)
    gain = np.ones(3 * n) if head_gain is None else np.asarray(head_gain, dtype=np.float64)
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

    # the drive's terms are errors of the head rotation: they move the pin on the loaded
    # photo as much as the head (gain 1 in the pin block), which the wire's own model-form
    # error does not
    head = (0, 1, 2)
    cols: dict[str, NDArray[np.float64]] = {}
    for p in periods:
        w = 2 * np.pi * mag / p
        if p == HEAD_PERIOD:
            # the head's own runout is zero at home, where the head is referenced: a
            # sin + b (cos - 1) of its rotation. A constant part would be a loss of the
            # same size on every bend, a backlash's signature, which no runout has
            pair = [stack(s * np.sin(w), head), stack(s * (np.cos(w) - 1.0), head)]
        else:
            pair = [stack(s * np.sin(w), head), stack(s * np.cos(w), head)]
        cols[f"gear_runout_{p}"] = gain[:, None] * np.column_stack(pair)
    for t in (5, 15, 45):
        cols[f"warm_up_{t}"] = (gain * stack(s * (1.0 - np.exp(-k / t)), head))[:, None]
    cols["previous_bend"] = stack(prev_s * prev_theta / 90.0)[:, None]
    cols["order_squared"] = (gain * stack(s * (k / max(n - 1, 1)) ** 2, head))[:, None]
    cols["released_angle"] = stack(s * mag / 100.0, blocks=(1,))[:, None]
    return cols


def _family(name: str) -> str:
    """The mechanism of a library term: its name without a trailing period or constant."""
    return name.rpartition("_")[0] if name[-1].isdigit() else name


def term_words(name: str) -> str:
    """A library term in words (e.g. ``warm_up_15``)."""
    return _words(name)


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
    forced: Sequence[str] = (),
) -> list[str]:
    """Forward selection by BIC from the (weighted) normal equations of ``n`` rows:
    ``gram = X^T W X``, ``xty = X^T W y``, ``yty = y^T W y`` over every column of the
    library, ``spans`` each group's columns (the same least squares as on the rows
    repeated by their weights, without building them)."""
    chosen: list[str] = list(forced)
    rss = yty
    if chosen:
        idx = np.concatenate([np.arange(spans[c].start, spans[c].stop) for c in chosen])
        b = xty[idx]
        rss = max(yty - float(b @ np.linalg.lstsq(gram[np.ix_(idx, idx)], b, rcond=None)[0]), 0.0)
    for _ in range(MAX_TERMS):
        best = None
        for name in names:
            if name in chosen or any(_family(c) == _family(name) for c in chosen):
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
    return [c for c in chosen if c not in forced]


def _springback_residual(
    trials: TrialTable, r: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(residual, bend size deg, direction) of the measured springback: loaded minus
    released residual where both were measured, else the released residual."""
    n = len(trials)
    loaded, released = r[:n], r[n : 2 * n]
    both = np.isfinite(loaded) & np.isfinite(released)
    use_both = both.sum() >= 10
    res = loaded - released if use_both else released
    ok = both if use_both else np.isfinite(released)
    size = np.abs(trials.loaded_bend_deg)
    size = np.where(np.isfinite(size), size, np.abs(trials.unloaded_bend_deg))
    size = np.where(np.isfinite(size), size, np.abs(trials.commanded_pin_deg))
    return res[ok], size[ok], trials.direction_sign[ok]


def _heteroscedastic_loglik(
    e: NDArray[np.float64], x: NDArray[np.float64], c: float
) -> tuple[float, float]:
    """Log-likelihood of residuals ``e`` with standard deviation ``sqrt(s0^2 + (c x)^2)``,
    maximised over ``s0``; returns (log-likelihood, s0)."""
    e2 = e * e
    cx2 = (c * x) ** 2

    def nll(log_s0: float) -> float:
        v = math.exp(2.0 * log_s0) + cx2
        return 0.5 * float(np.sum(np.log(v) + e2 / v))

    rms = math.sqrt(float(np.mean(e2))) + 1e-12
    sol = optimize.minimize_scalar(
        nll, bounds=(math.log(rms) - 12.0, math.log(rms) + 1.0), method="bounded"
    )
    return -float(sol.fun) - 0.5 * e.size * math.log(2.0 * math.pi), math.exp(float(sol.x))


#: Golden-section steps of :func:`_profile_loglik`: the search interval (13 in log s0)
#: shrinks to 13 * 0.618^60 ~ 4e-12, finer than the scalar search's 1e-5.
_GOLDEN_STEPS = 60


def _profile_loglik(
    e: NDArray[np.float64], x: NDArray[np.float64], cs: NDArray[np.float64]
) -> NDArray[np.float64]:
    """:func:`_heteroscedastic_loglik`'s log-likelihood at each slope of ``cs``, the
    noise ``s0`` maximised for all of them at once (golden section on ``log s0`` over
    the same bounds, one array operation per step instead of a scalar search per slope)."""
    e2 = e * e
    cx2 = (np.asarray(cs, dtype=np.float64)[:, None] * x[None, :]) ** 2

    def nll(log_s0: NDArray[np.float64]) -> NDArray[np.float64]:
        v = np.exp(2.0 * log_s0)[:, None] + cx2
        return 0.5 * np.sum(np.log(v) + e2 / v, axis=1)

    rms = math.sqrt(float(np.mean(e2))) + 1e-12
    golden = (math.sqrt(5.0) - 1.0) / 2.0
    a = np.full(cx2.shape[0], math.log(rms) - 12.0)
    b = np.full(cx2.shape[0], math.log(rms) + 1.0)
    c, d = b - golden * (b - a), a + golden * (b - a)
    fc, fd = nll(c), nll(d)
    for _ in range(_GOLDEN_STEPS):
        # a < c < d < b; keep [a, d] where f(c) < f(d) (c becomes its upper inner point),
        # else [c, b] (d becomes its lower inner point); one new point per slope
        left = fc < fd
        a, b = np.where(left, a, c), np.where(left, d, b)
        kept, kept_f = np.where(left, c, d), np.where(left, fc, fd)
        new = np.where(left, b - golden * (b - a), a + golden * (b - a))
        f_new = nll(new)
        c, fc = np.where(left, new, kept), np.where(left, f_new, kept_f)
        d, fd = np.where(left, kept, new), np.where(left, kept_f, f_new)
    best = np.minimum(fc, fd)
    return -best - 0.5 * e.size * math.log(2.0 * math.pi)


def _scatter(trials: TrialTable, r: NDArray[np.float64]) -> DiscoveredTerm | None:
    """Springback scatter growing with the bend (see the module notes), or None."""
    res, size, sign = _springback_residual(trials, r)
    if res.size < 10:
        return None
    x = size / 100.0
    e = res.copy()
    for d in (-1.0, 1.0):  # a smooth mean along the bend, per direction, is not scatter
        m = sign == d
        degree = min(3, len(np.unique(np.round(x[m], 3))) - 2)
        if degree >= 0 and m.sum() > degree + 2:
            e[m] = res[m] - np.polyval(np.polyfit(x[m], res[m], degree), x[m])
    ll0, _ = _heteroscedastic_loglik(e, x, 0.0)
    c_max = 3.0 * math.sqrt(float(np.mean(e * e))) / max(float(np.mean(x)), 1e-6)
    grid = np.linspace(0.0, c_max, 121)
    profile = _profile_loglik(e, x, grid)
    best = int(np.argmax(profile))
    lo_c = grid[max(best - 1, 0)]
    hi_c = grid[min(best + 1, grid.size - 1)]
    c_hat = float(
        optimize.minimize_scalar(
            lambda c: -_heteroscedastic_loglik(e, x, c)[0], bounds=(lo_c, hi_c), method="bounded"
        ).x
    )
    ll1 = max(_heteroscedastic_loglik(e, x, c_hat)[0], float(profile[best]))
    lr = max(2.0 * (ll1 - ll0), 0.0)
    p_value = 0.5 * float(special.chdtrc(1, lr))  # c >= 0: half a chi-square on the bound
    if not (p_value < SCATTER_P and c_hat > 0):
        return None
    inside = grid[2.0 * (ll1 - profile) <= float(special.chdtri(1, 0.05))]
    interval = (float(inside.min()), float(inside.max())) if inside.size else (c_hat, c_hat)
    return DiscoveredTerm("scatter", _WORDS["scatter"], (c_hat,), (interval,), 1.0, 0.0)


def discover(
    trials: TrialTable,
    residual_deg: NDArray[np.float64],
    groups: Sequence[str],
    folds: Sequence[NDArray[np.bool_]],
    *,
    seed: int = 0,
    head_gain: NDArray[np.float64] | None = None,
    refit: NDArray[np.float64] | None = None,
) -> Discovery:
    """Search the library on stacked residuals (NaN = not measured); see the module notes
    (``head_gain``: see :func:`library`). ``refit`` (3 N, q): how the model's prediction
    moves with its nuisance parameters (strength, geometry); these columns enter every
    fit beside the terms (a linearised refit of the machine with each term) and are
    not reported as terms."""
    r = np.asarray(residual_deg, dtype=np.float64)
    n = len(trials)
    cols, forced = _columns(trials, head_gain, refit)
    names = list(cols)
    ok = np.isfinite(r)  # the pin too: a drive term must move it, model-form error does not
    y = r[ok]
    sel = {k: v[ok] for k, v in cols.items()}
    trial_of = np.tile(np.arange(n), 3)[ok]
    family_counts, stable = _stable_terms(y, sel, names, forced, groups, trial_of, seed)
    before = float(np.sqrt(np.mean(y**2))) if y.size else math.nan
    empty = Discovery((), before, before, np.zeros(3 * n))
    scatter = _scatter(trials, r)
    if not stable:
        return Discovery((scatter,), before, before, np.zeros(3 * n)) if scatter else empty
    x = np.column_stack([sel[c] for c in (*forced, *stable)])
    after = _held_out_rmse(x, y, folds, trial_of)
    gain = 1.0 - after / before if before > 0 else 0.0
    if gain < MIN_GAIN:
        return Discovery((scatter,), before, before, np.zeros(3 * n)) if scatter else empty
    beta, *_ = np.linalg.lstsq(x, y, rcond=None)
    resid = y - x @ beta
    n_forced = sum(sel[c].shape[1] for c in forced)
    widths = [sel[c].shape[1] for c in stable]
    terms = _found_terms(x, y, beta, resid, n_forced, stable, widths, family_counts, gain)
    if scatter:
        terms.append(scatter)
    full = np.zeros(3 * n)
    full[ok] = x @ beta
    return Discovery(
        tuple(terms), before, after, full, _terms_delta_bic(x, y, resid, n_forced, len(stable))
    )


def _columns(
    trials: TrialTable,
    head_gain: NDArray[np.float64] | None,
    refit: NDArray[np.float64] | None,
) -> tuple[dict[str, NDArray[np.float64]], tuple[str, ...]]:
    """The library's columns (stacked rows) and the names of those every fit carries
    (the machine's linearised refit, :data:`_REFIT`)."""
    cols = library(trials, head_gain)
    forced: tuple[str, ...] = ()
    if refit is not None and np.size(refit):
        cols[_REFIT] = np.asarray(refit, dtype=np.float64).reshape(3 * len(trials), -1)
        forced = (_REFIT,)
    return cols, forced


def _stable_terms(
    y: NDArray[np.float64],
    sel: dict[str, NDArray[np.float64]],
    names: Sequence[str],
    forced: tuple[str, ...],
    groups: Sequence[str],
    trial_of: NDArray[np.int_],
    seed: int,
) -> tuple[dict[str, int], list[str]]:
    """Stability selection over bootstrap resamples of the CV groups: how often each
    family of terms is selected, and the families selected in STABILITY of the
    resamples (each as its most selected member)."""
    unique, group_of = np.unique(np.asarray(groups), return_inverse=True)
    design = np.column_stack([sel[k] for k in names]) if names else np.zeros((y.size, 0))
    widths = np.cumsum([0] + [sel[k].shape[1] for k in names])
    spans = {
        k: slice(int(a), int(b)) for k, a, b in zip(names, widths[:-1], widths[1:], strict=True)
    }
    # per-group sums of the normal equations: a resample's are their weighted sum
    row_group = group_of.reshape(-1)[trial_of]
    gram_g, xty_g, yty_g, rows_g = _group_normal_equations(design, y, row_group, unique.size)
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
            [c for c in names if c not in forced],
            forced,
        )
        for c in chosen:
            counts[c] += 1
    # stability of a mechanism, not of one member of its family (the periods of a runout,
    # the time constants of a warm-up compete for the same resamples): a family selected
    # in STABILITY of them is kept with its most selected member
    family_counts: dict[str, int] = {}
    for k in names:
        if k not in forced:
            family_counts[_family(k)] = family_counts.get(_family(k), 0) + counts[k]
    stable = [
        max((k for k in names if k not in forced and _family(k) == f), key=lambda k: counts[k])
        for f, c in family_counts.items()
        if c >= STABILITY * RESAMPLES
    ]
    return family_counts, stable


def _group_normal_equations(
    design: NDArray[np.float64],
    y: NDArray[np.float64],
    row_group: NDArray[np.int_],
    n_groups: int,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.int_]]:
    """Per CV group: X^T X, X^T y, y^T y and the number of rows."""

    def group_sums(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.bincount(row_group, weights=v, minlength=n_groups)

    n_cols = design.shape[1]
    gram_g = np.zeros((n_groups, n_cols, n_cols))
    for i in range(n_cols):
        for j in range(i, n_cols):
            gram_g[:, i, j] = gram_g[:, j, i] = group_sums(design[:, i] * design[:, j])
    xty_g = np.column_stack([group_sums(design[:, i] * y) for i in range(n_cols)])
    yty_g = group_sums(y**2)
    rows_g = np.bincount(row_group, minlength=n_groups)
    return gram_g, xty_g, yty_g, rows_g


def _held_out_rmse(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    folds: Sequence[NDArray[np.bool_]],
    trial_of: NDArray[np.int_],
) -> float:
    """Grouped held-out RMSE (deg) of the residuals ``y`` less the terms ``x``."""
    held = np.full(y.size, np.nan)
    for mask in folds:
        test = mask[trial_of]
        if test.all() or not test.any():
            continue
        beta = np.linalg.lstsq(x[~test], y[~test], rcond=None)[0]
        held[test] = y[test] - x[test] @ beta
    return float(np.sqrt(np.nanmean(held**2)))


def _found_terms(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    beta: NDArray[np.float64],
    resid: NDArray[np.float64],
    n_forced: int,
    stable: Sequence[str],
    widths: Sequence[int],
    family_counts: dict[str, int],
    gain: float,
) -> list[DiscoveredTerm]:
    """The stable terms with their coefficients and 95 % intervals (deg)."""
    dof = max(y.size - x.shape[1], 1)
    cov = np.linalg.pinv(x.T @ x) * float(np.sum(resid**2)) / dof
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    t = float(special.stdtrit(dof, 0.975))
    terms, i = [], n_forced
    for c, w in zip(stable, widths, strict=True):
        b, e = beta[i : i + w], se[i : i + w]
        terms.append(
            DiscoveredTerm(
                c,
                _words(c),
                tuple(float(v) for v in b),
                tuple((float(v - t * u), float(v + t * u)) for v, u in zip(b, e, strict=True)),
                family_counts[_family(c)] / RESAMPLES,
                gain,
            )
        )
        i += w
    return terms


def _terms_delta_bic(
    x: NDArray[np.float64],
    y: NDArray[np.float64],
    resid: NDArray[np.float64],
    n_forced: int,
    n_terms: int,
) -> float:
    """BIC improvement of the mean terms over the residuals they were found in (each
    coefficient counted, and one more per term for its choice from the library)."""
    rss0 = float(np.sum(y**2))
    if n_forced:
        xf = x[:, :n_forced]
        rss0 = float(np.sum((y - xf @ np.linalg.lstsq(xf, y, rcond=None)[0]) ** 2))
    k = x.shape[1] - n_forced + n_terms
    dbic = y.size * math.log(max(rss0, 1e-12) / max(float(np.sum(resid**2)), 1e-12))
    return dbic - k * math.log(y.size)
