"""The next experiment when the data leave a tie: bends chosen to separate the rivals.

When :func:`cvmeasure.diagnose.diagnose` reports explanations tied held out (within
one standard error), the data so far do not tell them apart; another experiment
must. Each rival is taken as fitted to the data so far (strength, die radius, its
causes' values and forms, its model-form discrepancy). Candidate plans of 12, 18, 24
and 30 bends (:func:`_plans`: magnitudes from the smallest the data bent up to the
largest, or up to the head's reach :data:`REACH_DEG`; directions alternating, one
direction, one then the other; the data's first commands again, late) are appended
to the data in the order they would be run, so history-dependent causes (a drift's
home shift, play lost on reversals) see the real sequence.

The plan's bends read the pin's angle on their loaded photos (``measured_pin_deg``)
whenever the data have loaded photos, even when the data did not read it: the pin
shows the head's own rotation, which the wire's model-form discrepancy (a smooth curve
in the bend on the loaded and released angles only) cannot absorb. A head error (a
scale of the rotation, the head's once-per-revolution runout) and the wire's response
(compliance) differ there, and a smooth curve on the bend angles alone takes most of
their difference up: without the pin no plan within the head's reach separates them.

Criterion (linearised T-optimality, Atkinson-Fedorov): for each ordered pair of rivals
(truth, fitted), ``d`` = truth's predictions less the fitted rival's over the data
and the plan; the fitted rival refits its free directions (strength, die radius, its
causes' values: central differences) and its discrepancy, carried as a prior (each
Legendre coefficient uniform within its bound, variance ``b^2 / 3``: the model-form
discrepancy variance). With the noise whitened (the named fit's residual standard
deviation, a bend's loaded and released errors correlated as in its residuals),
``lambda`` = the generalised least-squares misfit of ``d``: the expected excess of
the fitted rival's -2 log likelihood over the truth's. That excess has standard
deviation ``2 sqrt(lambda)``, so the expected separation is ``sqrt(lambda) / 2``
standard errors. A plan's separation is the smallest over the ordered pairs that hold
the named rival (the first), as truth or as fitted (which rival is the truth is
unknown; the plan tests the pick, and two unnamed rivals left alike do not decide it:
planning for them took bends from the pick's own test); the smallest plan reaching
:data:`TARGET_STANDARD_ERRORS` is proposed, else the best of the largest size.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.discover import RIVAL_PERIODS, library
from cvmeasure.diagnose.fitting import ModelFit, current_form, discrepancy_basis, predict
from cvmeasure.sim.effects import Effect, effect_spec_for
from cvmeasure.sim.params import SimParams

__all__ = [
    "FOLLOW_UP_SIZES",
    "REACH_DEG",
    "TARGET_STANDARD_ERRORS",
    "FollowUp",
    "Rival",
    "propose_follow_up",
    "term_rival",
]

#: Sizes (bends) of the plans tried, smallest first.
FOLLOW_UP_SIZES: tuple[int, ...] = (12, 18, 24, 30)
#: The largest head rotation proposed (deg): about 171 deg of released bend on the nominal
#: machine, short of the leg folding back onto the feed (the data's own largest, when
#: larger, is kept). Beyond the angles bent so far a compliance and a scale part (the
#: pin's lever shortens), which the range bent may not show; at 180 deg (about 200 deg of
#: bend) the simulation no longer describes the machine (docs/diagnosis.md, step 3d).
REACH_DEG = 150.0
#: Expected separation (standard errors) at which the smallest plan is taken.
TARGET_STANDARD_ERRORS = 4.0


@dataclass(frozen=True)
class Rival:
    """One explanation of a tie, as fitted to the data so far."""

    label: str  # a cause, or a pair written ``a + b``, or a library term
    fit: ModelFit
    params: SimParams  # the nominal params it was fitted against (span bow share)
    #: a library term's coefficients (deg) on top of ``fit`` (the baseline) when the
    #: rival is a term outside the catalogue (``label`` its library name); empty else
    term_coefficients_deg: tuple[float, ...] = ()


@dataclass(frozen=True)
class FollowUp:
    """Bends proposed to separate tied explanations (run after the data, in this order).

    ``commanded_pin_deg`` are signed head rotations from home (deg), like the trials
    CSV's; ``expected_separation_se`` the smallest expected separation over the ordered
    pairs of rivals that hold the named one (the first), in standard errors, once the
    plan is run and every rival refitted; ``separation_by_pair`` has every pair.
    """

    rivals: tuple[str, ...]
    span_bow: tuple[bool, ...]  # whether each rival's leg bows (the model it was fitted in)
    design: str  # the plan family chosen, in words
    commanded_pin_deg: tuple[float, ...]
    expected_separation_se: float
    separation_by_pair: tuple[tuple[str, str, float], ...]  # (truth, fitted, standard errors)
    first_trial: int  # number of the first proposed bend (the data's count + 1)
    #: the pin's angle is to be read on each proposed bend's loaded photo
    #: (``measured_pin_deg``): the separation counts on it
    read_pin: bool = False

    @property
    def n_trials(self) -> int:
        return len(self.commanded_pin_deg)

    def rows(self) -> list[dict[str, str]]:
        """Plan CSV rows (``trial, commanded_pin_deg``, as ``cvmeasure simulate`` reads)."""
        return [
            {"trial": str(self.first_trial + i), "commanded_pin_deg": f"{c:.1f}"}
            for i, c in enumerate(self.commanded_pin_deg)
        ]

    def to_dict(self) -> dict[str, Any]:
        return {
            "rivals": list(self.rivals),
            "span_bow": list(self.span_bow),
            "design": self.design,
            "n_trials": self.n_trials,
            "first_trial": self.first_trial,
            "read_pin": self.read_pin,
            "commanded_pin_deg": list(self.commanded_pin_deg),
            "expected_separation_se": self.expected_separation_se,
            "separation_by_pair": [
                {"truth": a, "fitted": b, "standard_errors": s}
                for a, b, s in self.separation_by_pair
            ],
        }


def extended_table(trials: TrialTable, commands_deg: Sequence[float]) -> TrialTable:
    """The trials followed by unmeasured bends at ``commands_deg`` (in the order run)."""
    n, m = len(trials), len(commands_deg)
    cmd = np.concatenate([trials.commanded_pin_deg, np.asarray(commands_deg, dtype=np.float64)])
    nan = np.full(m, np.nan)
    index = np.concatenate([trials.bend_index, trials.bend_index[-1] + 1.0 + np.arange(m)])
    return TrialTable.from_arrays(
        cmd,
        np.concatenate([trials.loaded_bend_deg, nan]),
        np.concatenate([trials.unloaded_bend_deg, nan]),
        bend_index=[int(i) for i in index],
        trial=[str(i + 1) for i in range(n + m)],
    )


def _prediction_and_columns(
    rival: Rival, table: TrialTable, base_effects: Sequence[Effect]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(predictions (3 N,), columns (3 N, k)): the rival's predictions with its discrepancy,
    and the directions a refit moves them freely (strength, nuisance, causes' values by
    central differences; the discrepancy is carried in the covariance instead)."""
    fit = rival.fit
    basis = discrepancy_basis(table)
    kw = dict(nuisance=fit.nuisance, shapes=fit.shapes)
    args = (table, rival.params, base_effects, fit.causes, fit.strength_scale)
    pred = predict(*args, fit.values, **kw)
    if len(fit.discrepancy) == basis.shape[1]:
        pred = pred + basis @ np.asarray(fit.discrepancy, dtype=np.float64)
    cols = [fit.nuisance_jacobian(table, rival.params, base_effects)]
    if rival.term_coefficients_deg:
        # a term outside the catalogue: the baseline with the term's columns, which a
        # refit moves freely as it does the machine's
        gain = fit.head_sensitivity(table, rival.params, base_effects)
        term = library(table, gain, RIVAL_PERIODS)[rival.label]
        pred = pred + term @ np.asarray(rival.term_coefficients_deg, dtype=np.float64)
        cols.append(term)
    for j, cause in enumerate(fit.causes):
        step = 0.05 * max(abs(x) for x in effect_spec_for(cause, rival.params).typical)
        up, down = list(fit.values), list(fit.values)
        up[j] += step
        down[j] -= step
        cols.append(((predict(*args, up, **kw) - predict(*args, down, **kw)) / (2 * step))[:, None])
    return pred, np.column_stack(cols)


def _whiten(
    x: NDArray[np.float64], n: int, rows: NDArray[np.bool_], sigma_deg: float, rho: float
) -> NDArray[np.float64]:
    """Rows (observations stacked loaded, released, pin) whitened for noise of ``sigma_deg``
    with a bend's loaded and released error correlated by ``rho``: their sum and
    difference scaled to unit variance; unobserved rows dropped."""
    x = np.where(rows.reshape(-1, *([1] * (x.ndim - 1))), x, 0.0)
    load, rel, pin = x[:n], x[n : 2 * n], x[2 * n :]
    both = (rows[:n] & rows[n : 2 * n]).reshape(-1, *([1] * (x.ndim - 1)))
    r = min(rho, 0.95)
    plus = np.where(both, (load + rel) / math.sqrt(2.0 * (1.0 + r)), load + rel)
    minus = np.where(both, (load - rel) / math.sqrt(2.0 * (1.0 - r)), 0.0)
    return np.concatenate([plus, minus, pin]) / sigma_deg


def _separation(
    truth: NDArray[np.float64],
    fitted: NDArray[np.float64],
    columns: NDArray[np.float64],
    basis: NDArray[np.float64],
    rows: NDArray[np.bool_],
    sigma_deg: float,
    rho: float,
) -> float:
    """Expected excess of the refitted rival's -2 log likelihood over the truth's, in
    its standard deviations: sqrt(lambda) / 2, lambda the misfit of the truth's
    predictions by the fitted rival refitted (its free directions ``columns``; the
    discrepancy ``basis`` with each coefficient's prior variance b^2 / 3, the bounded
    discrepancy as uniform), the noise whitened."""
    n = rows.size // 3
    d = _whiten(truth - fitted, n, rows, sigma_deg, rho)
    a = _whiten(np.column_stack([columns, basis]), n, rows, sigma_deg, rho)
    k = basis.shape[1]
    prior = np.zeros((k, a.shape[1]))
    prior[:, columns.shape[1] :] = np.eye(k) / (current_form().bound_deg / math.sqrt(3.0))
    a = np.vstack([a, prior])
    d = np.concatenate([d, np.zeros(k)])
    coef = np.linalg.lstsq(a, d, rcond=None)[0]
    r = d - a @ coef
    return 0.5 * math.sqrt(float(r @ r))


def _plans(trials: TrialTable, size: int) -> list[tuple[str, NDArray[np.float64]]]:
    """Candidate plans of ``size`` bends: magnitudes from the smallest the data bent up to
    the largest, or up to :data:`REACH_DEG`; both directions when the data have both."""
    mag = np.abs(trials.commanded_pin_deg)
    mag = mag[mag > 0]
    lo, hi = float(np.min(mag)), float(np.max(mag))
    alt = np.where(np.arange(size) % 2 == 0, 1.0, -1.0)
    ones = np.ones(size)
    sign = 1.0 if np.mean(trials.direction_sign) >= 0 else -1.0
    plans: list[tuple[str, NDArray[np.float64]]] = [
        (f"{lo:.1f} deg, one direction", sign * lo * ones),
        ("the data's first commands again, in order", np.resize(trials.commanded_pin_deg, size)),
    ]
    for top in sorted({hi, max(hi, REACH_DEG)}):
        spread = np.linspace(lo, top, size)
        mid = 0.5 * (lo + top)
        plans += [
            (f"{top:.1f} deg, directions alternating", top * alt),
            (
                f"{lo:.1f} and {top:.1f} deg in turn, directions alternating",
                np.where(np.arange(size) % 4 < 2, lo, top) * alt,
            ),
            (f"{lo:.1f}-{top:.1f} deg rising, directions alternating", spread * alt),
            (f"{lo:.1f}-{top:.1f} deg rising, one direction", sign * spread),
            (f"{top:.1f} deg, one direction", sign * top * ones),
            (f"{mid:.1f} deg, one direction", sign * mid * ones),
        ]
        if trials.both_directions:
            half = size // 2
            plans += [
                (
                    f"{top:.1f} deg, one direction then the other",
                    np.concatenate([np.full(half, top), np.full(size - half, -top)]),
                ),
                (f"{lo:.1f}-{top:.1f} deg rising, the other direction", -sign * spread),
            ]
    if not trials.both_directions:  # keep the user's single direction
        plans = [(w.replace(", directions alternating", ""), sign * np.abs(c)) for w, c in plans]
    return [(w, np.round(c, 1)) for w, c in plans]


def _loaded_released_correlation(fit: ModelFit, n: int) -> float:
    """Correlation of a bend's loaded and released residual under ``fit`` (0..1)."""
    if fit.residual_deg is None:
        return 0.5
    rl, ru = fit.residual_deg[:n], fit.residual_deg[n : 2 * n]
    ok = np.isfinite(rl) & np.isfinite(ru)
    if ok.sum() < 5:
        return 0.5
    c = np.corrcoef(rl[ok], ru[ok])[0, 1]
    return float(np.clip(c, 0.0, 1.0)) if math.isfinite(c) else 0.5


def propose_follow_up(
    trials: TrialTable,
    rivals: Sequence[Rival],
    base_effects: Sequence[Effect] = (),
    *,
    sizes: Sequence[int] = FOLLOW_UP_SIZES,
    target_se: float = TARGET_STANDARD_ERRORS,
) -> FollowUp | None:
    """The follow-up plan that best separates ``rivals`` (at least two), or None.

    The first rival is the named one: its residual standard deviation (the noise and the
    model-form error it leaves) and loaded/released error correlation set the standard
    errors."""
    if len(rivals) < 2 or len(trials) < 2:
        return None
    n0 = len(trials)
    sigma = max(rivals[0].fit.sigma_deg, 1e-3)
    rho = _loaded_released_correlation(rivals[0].fit, n0)
    # the pin is on the loaded photo: read it on the plan's bends (see the module's note)
    read_pin = trials.has_pin or trials.has_loaded
    measured = (trials.has_loaded, True, read_pin)
    obs_old = trials.observations()
    best: tuple[float, str, NDArray[np.float64], list[tuple[str, str, float]]] | None = None
    for size in sorted(sizes):
        for words, cmd in _plans(trials, size):
            table = extended_table(trials, cmd)
            # rows observed: the data's measured angles and the plan's, as the data measure
            rows = np.concatenate(
                [
                    np.concatenate([np.isfinite(obs_old[k * n0 : (k + 1) * n0]), np.full(size, m)])
                    for k, m in enumerate(measured)
                ]
            )
            basis = discrepancy_basis(table)
            pc = [_prediction_and_columns(r, table, base_effects) for r in rivals]
            pairs = []
            for i, a in enumerate(rivals):
                for j, b in enumerate(rivals):
                    if i != j:
                        s = _separation(pc[i][0], pc[j][0], pc[j][1], basis, rows, sigma, rho)
                        pairs.append((a.label, b.label, s))
            # the plan tests the pick: the named rival against each other one, either the
            # truth; two unnamed rivals left alike do not make the named one right or wrong
            worst = min(s for a, b, s in pairs if rivals[0].label in (a, b))
            if best is None or worst > best[0] + 1e-9:
                best = (worst, words, cmd, pairs)
        if best is not None and best[0] >= target_se:
            break
    if best is None:
        return None
    worst, words, cmd, pairs = best
    return FollowUp(
        rivals=tuple(r.label for r in rivals),
        span_bow=tuple(r.params.span_bow_share > 0 for r in rivals),
        design=words,
        commanded_pin_deg=tuple(float(c) for c in cmd),
        expected_separation_se=float(worst),
        separation_by_pair=tuple((a, b, float(s)) for a, b, s in pairs),
        first_trial=n0 + 1,
        read_pin=read_pin,
    )


def term_rival(
    trials: TrialTable,
    term: str,
    base_fit: ModelFit,
    params: SimParams,
    base_effects: Sequence[Effect] = (),
) -> Rival | None:
    """A library term (:func:`~cvmeasure.diagnose.discover.library`, the once-per-revolution
    runout included) as a rival: the baseline ``base_fit`` with the term's coefficients
    fitted by least squares to its residuals (the machine's nuisance directions refitted
    with them, the discrepancy as fitted); None for a name outside the library."""
    gain = base_fit.head_sensitivity(trials, params, base_effects)
    cols = library(trials, gain, RIVAL_PERIODS).get(term)
    if cols is None:
        return None
    res = base_fit.residuals(trials, params, base_effects)
    basis = discrepancy_basis(trials)
    if len(base_fit.discrepancy) == basis.shape[1]:
        res = res - basis @ np.asarray(base_fit.discrepancy, dtype=np.float64)
    nuisance = base_fit.nuisance_jacobian(trials, params, base_effects)
    x = np.column_stack([cols, nuisance])
    rows = np.isfinite(res) & np.all(np.isfinite(x), axis=1)
    if rows.sum() <= x.shape[1]:
        return None
    coef = np.linalg.lstsq(x[rows], res[rows], rcond=None)[0][: cols.shape[1]]
    return Rival(term, base_fit, params, tuple(float(c) for c in coef))
