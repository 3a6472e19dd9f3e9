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
from scipy import stats

from cvmeasure.diagnose.trials import TrialSet

__all__ = ["COVARIATES", "ResidualTrend", "residual_trends"]

#: covariate name -> causes whose signature it carries.
COVARIATES: dict[str, tuple[str, ...]] = {
    "direction": ("offset", "axis_offset", "springback_asymmetry"),
    "bend_index": ("drift",),
    "commanded_angle": ("scale", "camera_tilt", "backlash"),
    "signed_angle": ("offset", "axis_offset", "springback_asymmetry"),
    "unloaded_minus_loaded": ("springback_asymmetry",),
    "direction_x_unloaded": ("springback_asymmetry",),
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


def _features(trials: TrialSet) -> dict[str, NDArray[np.float64]]:
    s = trials.direction
    mag = np.abs(trials.commanded_pin_deg)
    two = lambda v: np.concatenate([v, v])  # noqa: E731  (loaded rows, then unloaded rows)
    unloaded = np.concatenate([np.zeros(len(trials)), np.ones(len(trials))])
    return {
        "direction": two(s),
        "bend_index": two(trials.bend_index),
        "commanded_angle": two(mag),
        "signed_angle": two(s * mag),
        "unloaded_minus_loaded": unloaded,
        "direction_x_unloaded": two(s) * unloaded,
    }


def residual_trends(trials: TrialSet, residual_deg: NDArray[np.float64]) -> list[ResidualTrend]:
    """Correlations of stacked residuals ``[loaded..., unloaded...]`` (NaN = not measured)."""
    r = np.asarray(residual_deg, dtype=np.float64)
    ok = np.isfinite(r)
    out = []
    for name, feature in _features(trials).items():
        x = feature[ok]
        y = r[ok]
        if x.size < 3 or np.ptp(x) == 0 or np.ptp(y) == 0:
            out.append(ResidualTrend(name, math.nan, math.nan, COVARIATES[name]))
            continue
        res = stats.pearsonr(x, y)
        out.append(ResidualTrend(name, float(res.statistic), float(res.pvalue), COVARIATES[name]))
    return out
