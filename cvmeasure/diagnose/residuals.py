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
    "UNNAMED_GAIN",
    "LeftoverCheck",
    "leftover_structure",
]

#: Held-out gain of a smoother on the residuals above which a discrepancy is left unnamed.
UNNAMED_GAIN = 0.3

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

    The residuals are those of the model's full-data fit. A smoother (a cubic in the commanded angle for each direction and for
    loaded / unloaded angles separately) is fitted to the residuals with the
    same grouped folds; if it lowers their held-out RMSE by more than
    ``UNNAMED_GAIN``, a discrepancy remains: reported, not forced onto a name.
    """

    residual_rmse_deg: float  # held-out residuals of the model
    smoothed_rmse_deg: float  # after the smoother (held-out)
    unnamed: bool

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
            "unnamed_discrepancy": self.unnamed,
        }


def leftover_structure(
    trials: TrialTable,
    residual_deg: NDArray[np.float64],
    folds: list[NDArray[np.bool_]],
    *,
    degree: int = 3,
) -> LeftoverCheck:
    """Held-out check for structure left in stacked residuals (see :class:`LeftoverCheck`)."""
    r = np.asarray(residual_deg, dtype=np.float64)
    n, k = len(trials), len(BLOCKS)
    x = np.tile(np.abs(trials.commanded_pin_deg), k) / 100.0
    cell = np.tile(trials.direction_sign > 0, k).astype(int) + 2 * np.repeat(np.arange(k), n)
    held_trial = np.full(k * n, -1)
    for f, mask in enumerate(folds):
        held_trial[np.tile(mask, k)] = f
    smoothed = np.full(k * n, np.nan)
    ok = np.isfinite(r)
    for f in range(len(folds)):
        test = ok & (held_trial == f)
        train = ok & (held_trial != f)
        for c in range(2 * k):
            tr, te = train & (cell == c), test & (cell == c)
            if not te.any():
                continue
            # a polynomial of this degree needs more distinct angles than coefficients
            # (a plan of a few repeated commands has not): otherwise nothing is smoothed
            if tr.sum() > degree + 2 and len(np.unique(x[tr])) > degree + 1:
                coef = np.polyfit(x[tr], r[tr], degree)
                smoothed[te] = r[te] - np.polyval(coef, x[te])
            else:
                smoothed[te] = r[te]
    base = float(np.sqrt(np.mean(r[ok] ** 2))) if ok.any() else math.nan
    after = float(np.sqrt(np.nanmean(smoothed[ok] ** 2))) if ok.any() else math.nan
    unnamed = bool(base > 0 and 1.0 - after / base > UNNAMED_GAIN)
    return LeftoverCheck(base, after, unnamed)
