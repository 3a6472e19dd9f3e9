"""Residual analysis: what the residuals of a model correlate with.

Residuals (measured minus predicted, every measured angle) are compared with
the covariates a cause could depend on: bend direction, bend index (history),
the commanded angle (unsigned and signed by direction), and loaded versus
unloaded (springback). A significant correlation points at a family of causes
(see the ``suggests`` field).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import special

from cvmeasure.contracts import BLOCKS, TrialTable

__all__ = [
    "COVARIATES",
    "ResidualTrend",
    "residual_trends",
    "UNNAMED_P",
    "LeftoverCheck",
    "leftover_structure",
]

#: A discrepancy is left unnamed when the smoother's held-out gain on the residuals is
#: beyond what it reaches on the noise alone at this p-value: a test against the session's
#: own noise on its own plan and folds, not a fixed share of the residuals (which a
#: smoother of many coefficients fitted to few bends loses to the noise, and a small
#: model-form wave on a long session passes).
UNNAMED_P = 0.01
#: Noise draws of the test's reference distribution (fixed: the diagnosis is repeatable).
NULL_DRAWS = 999
#: ... at most this many values in all (rows x draws)
NULL_ELEMENTS = 5_000_000

#: covariate name -> causes whose signature it carries.
COVARIATES: dict[str, tuple[str, ...]] = {
    "direction": ("offset", "axis_offset", "springback_asymmetry"),
    "bend_index": ("drift",),
    "signed_bend_index": ("drift",),
    "home_walk": ("drift",),
    "commanded_angle": ("scale", "camera_tilt", "backlash"),
    "signed_angle": ("offset", "axis_offset", "springback_asymmetry"),
    "unloaded_minus_loaded": ("springback_asymmetry",),
    "direction_x_unloaded": ("springback_asymmetry",),
    "pin_vs_bend": ("axis_offset", "camera_tilt"),
}


@dataclass(frozen=True)
class ResidualTrend:
    """Pearson correlation of the residuals (deg) with one covariate."""

    covariate: str
    correlation: float
    p_value: float
    suggests: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "covariate": self.covariate,
            "correlation": self.correlation,
            "p_value": self.p_value,
            "suggests": list(self.suggests),
        }


def _features(trials: TrialTable) -> dict[str, NDArray[np.float64]]:
    """Covariates of every stacked observation (blocks: loaded, unloaded, pin)."""
    n = len(trials)
    s = trials.direction_sign
    mag = np.abs(trials.commanded_pin_deg)
    k = len(BLOCKS)
    tile = lambda v: np.tile(v, k)  # noqa: E731
    block = np.repeat(np.arange(k), n)
    unloaded = (block == 1).astype(float)
    return {
        "direction": tile(s),
        "bend_index": tile(trials.bend_index),
        "signed_bend_index": tile(s * trials.bend_index),
        "home_walk": tile(_home_walk(s, trials.bend_index)),
        "commanded_angle": tile(mag),
        "signed_angle": tile(s * mag),
        "unloaded_minus_loaded": np.where(block == 2, np.nan, unloaded),
        "direction_x_unloaded": np.where(block == 2, np.nan, tile(s) * unloaded),
        "pin_vs_bend": (block == 2).astype(float),
    }


def _home_walk(direction: NDArray[np.float64], bend_index: NDArray[np.float64]) -> NDArray:
    """Signed home shift (in losses per bend) of a drift losing the same on every bend
    and shifting home: ``-sum s_j`` over the earlier bends of the run (a re-home,
    ``bend_index`` back to 0 or down, starts a run). Not a trend along the run: on a
    balanced plan it walks about zero (cvmeasure.sim.model's ``home_shift`` form)."""
    k = np.asarray(bend_index, dtype=np.float64)
    start = (k <= np.concatenate([[np.inf], k[:-1]])) | (k == 0)
    before = np.cumsum(direction) - direction
    run = np.cumsum(start) - 1
    first = np.searchsorted(run, run)
    return -(before - before[first])


def _pearson(x: NDArray[np.float64], y: NDArray[np.float64]) -> tuple[float, float]:
    """Pearson correlation and its two-sided p-value (Student t with n - 2 dof)."""
    rho = float(np.clip(np.corrcoef(x, y)[0, 1], -1.0, 1.0))
    dof = x.size - 2
    if abs(rho) >= 1.0:
        return rho, 0.0
    t = abs(rho) * math.sqrt(dof / (1.0 - rho * rho))
    return rho, float(2.0 * special.stdtr(dof, -t))


def residual_trends(trials: TrialTable, residual_deg: NDArray[np.float64]) -> list[ResidualTrend]:
    """Correlations of stacked residuals (blocks of :data:`BLOCKS`; NaN = not measured)."""
    r = np.asarray(residual_deg, dtype=np.float64)
    out = []
    for name, feature in _features(trials).items():
        ok = np.isfinite(r) & np.isfinite(feature)
        x = feature[ok]
        y = r[ok]
        if x.size < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
            out.append(ResidualTrend(name, math.nan, math.nan, COVARIATES[name]))
            continue
        rho, p = _pearson(x, y)
        out.append(ResidualTrend(name, rho, p, COVARIATES[name]))
    return out


@dataclass(frozen=True)
class LeftoverCheck:
    """Is structure left in a model's residuals that no named cause explains?

    The residuals are those of the model's full-data fit, its model-form discrepancy
    (bounded, or the learned no-effect curve) taken out: that curve is part of the model.
    A smoother (a cubic in the commanded angle for each direction and for loaded /
    unloaded / pin angles separately: six cells) is fitted to them with the same grouped
    folds. Its held-out gain in each cell is compared with the gains it reaches there on
    the noise alone (Gaussian draws with the discrepancy taken out as from the residuals,
    same plan and folds); the smallest of the cells' p-values, itself calibrated on the
    draws, below :data:`UNNAMED_P` is a discrepancy that remains: reported, not forced onto
    a name. On the noise the gain is negative (a cubic fitted to few bends predicts worse
    than nothing); the test asks whether the residuals let it do better than that.
    """

    residual_rmse_deg: float  # held-out residuals of the model
    smoothed_rmse_deg: float  # after the smoother (held-out)
    unnamed: bool
    #: p-value of the gain under "the residuals are noise" (NaN: not tested)
    p_value: float = math.nan
    #: the smoother's median held-out gain on the noise alone (NaN: not tested)
    noise_gain: float = math.nan

    @property
    def gain(self) -> float:
        if self.residual_rmse_deg <= 0:
            return 0.0
        return 1.0 - self.smoothed_rmse_deg / self.residual_rmse_deg

    def to_dict(self) -> dict[str, Any]:
        return {
            "residual_rmse_deg": self.residual_rmse_deg,
            "smoothed_rmse_deg": self.smoothed_rmse_deg,
            "smoother_gain": self.gain,
            "noise_gain": self.noise_gain,
            "p_value": self.p_value,
            "unnamed_discrepancy": self.unnamed,
        }


def _cells(trials: TrialTable) -> tuple[NDArray[np.float64], NDArray[np.int_]]:
    """Scaled bend magnitude and smoother cell (direction x block) of every stacked row."""
    n, k = len(trials), len(BLOCKS)
    x = np.tile(np.abs(trials.commanded_pin_deg), k) / 100.0
    cell = np.tile(trials.direction_sign > 0, k).astype(int) + 2 * np.repeat(np.arange(k), n)
    return x, cell


def _held_out_smoothed(
    x: NDArray[np.float64],
    cell: NDArray[np.int_],
    held: NDArray[np.int_],
    values: NDArray[np.float64],
    degree: int,
) -> NDArray[np.float64]:
    """``values`` (rows, columns) less the smoother's held-out prediction: each row
    predicted by the cubic of its cell fitted on the other folds (nothing where too few
    distinct angles remain to fit it). The training fit is the cell's normal equations
    less the held fold's, so the cost grows with the rows, not their square."""
    out = values.copy()
    for c in np.unique(cell):
        in_cell = cell == c
        v = np.vander(x[in_cell], degree + 1)
        y, fold, xs = values[in_cell], held[in_cell], x[in_cell]
        gram, moment = v.T @ v, v.T @ y
        for f in np.unique(fold):
            te = fold == f
            tr = ~te
            # a polynomial of this degree needs more distinct angles than coefficients
            # (a plan of a few repeated commands has not): otherwise nothing is smoothed
            if tr.sum() <= degree + 2 or len(np.unique(xs[tr])) <= degree + 1:
                continue
            coef = np.linalg.lstsq(gram - v[te].T @ v[te], moment - v[te].T @ y[te], rcond=None)[0]
            rows = np.flatnonzero(in_cell)[te]
            out[rows] -= v[te] @ coef
    return out


def _ratio(smoothed: NDArray[np.float64], raw: NDArray[np.float64]) -> NDArray[np.float64]:
    """Held-out sum of squares after the smoother over that before it (per column)."""
    before = np.sum(raw**2, axis=0)
    return np.divide(
        np.sum(smoothed**2, axis=0), before, out=np.ones_like(before), where=before > 0
    )


def leftover_structure(
    trials: TrialTable,
    residual_deg: NDArray[np.float64],
    folds: list[NDArray[np.bool_]],
    *,
    degree: int = 3,
    nuisance: NDArray[np.float64] | None = None,
    null_draws: int = NULL_DRAWS,
) -> LeftoverCheck:
    """Held-out check for structure left in stacked residuals (see :class:`LeftoverCheck`).

    ``nuisance``: the stacked design of a curve already fitted and taken out of the
    residuals (the discrepancy's): the noise draws have it taken out too, so that the
    reference is the noise as the residuals carry it. ``null_draws`` 0: the gain alone,
    not tested (a screen that reads the gain only)."""
    r = np.asarray(residual_deg, dtype=np.float64)
    k = len(BLOCKS)
    x, cell = _cells(trials)
    held = np.full(r.size, -1)
    for f, mask in enumerate(folds):
        held[np.tile(mask, k)] = f
    ok = np.isfinite(r) & (held >= 0)
    if not ok.any():
        return LeftoverCheck(math.nan, math.nan, False)
    y = r[ok]
    xs, cells, folds_ok = x[ok], cell[ok], held[ok]
    smoothed = _held_out_smoothed(xs, cells, folds_ok, y[:, None], degree)[:, 0]
    base = float(np.sqrt(np.mean(y**2)))
    after = float(np.sqrt(np.mean(smoothed**2)))
    if base <= 0 or null_draws <= 0:
        return LeftoverCheck(base, after, False)
    # the reference: the same smoother on Gaussian noise, with the discrepancy's curve
    # taken out as it was from the residuals (least squares; its bound rarely binds on noise)
    # (fewer on a very large session, whose draws would fill the memory; 199 still resolve
    # p = 0.01)
    null_draws = int(min(null_draws, max(199, NULL_ELEMENTS // y.size)))
    z = np.random.default_rng(0).standard_normal((y.size, null_draws))
    if nuisance is not None:
        design = np.asarray(nuisance, dtype=np.float64)[ok]
        design = design[:, np.any(design != 0, axis=0)]
        if design.size:
            z -= design @ np.linalg.lstsq(design, z, rcond=None)[0]
    null_smoothed = _held_out_smoothed(xs, cells, folds_ok, z, degree)
    noise_gain = float(1.0 - np.sqrt(np.median(_ratio(null_smoothed, z))))
    # each cell's held-out ratio (scale-free: a block read with other noise is its own
    # reference) against its noise draws; the smallest of the cells' p-values, calibrated
    # by the smallest in each draw (a structure in one block is not diluted by the rest)
    p_obs, p_null = [], []
    for c in np.unique(cells):
        m = cells == c
        null_ratio = _ratio(null_smoothed[m], z[m])
        null_c = np.sort(null_ratio)
        p_obs.append(
            (1 + np.searchsorted(null_c, _ratio(smoothed[m], y[m]), "right")) / (1 + null_draws)
        )
        p_null.append((1 + np.searchsorted(null_c, null_ratio, "right")) / (1 + null_draws))
    least = min(p_obs)
    p = float((1 + np.sum(np.min(p_null, axis=0) <= least)) / (1 + null_draws))
    return LeftoverCheck(base, after, bool(p < UNNAMED_P), p, noise_gain)
