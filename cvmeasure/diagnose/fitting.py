"""Fitting the simulation to measured trials: nuisance parameter plus one candidate effect.

The only nuisance parameter is the material strength (yield and UTS scaled
together: a wire lot is harder or softer than its datasheet), which a user
would fit anyway. A candidate adds one named effect whose parameter is bounded
by its physical range. Fits are bounded nonlinear least squares on every
measured angle (loaded and unloaded), started from the best point of a coarse
grid over the effect parameter so that effects without a gradient at zero
(camera tilt) are found. Held-out error comes from grouped K-fold
cross-validation (a group is a part, or a trial).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats

from cvmeasure.diagnose.trials import TrialSet
from cvmeasure.sim.effects import EFFECTS, Effect
from cvmeasure.sim.model import simulate
from cvmeasure.sim.params import SimParams

__all__ = [
    "ModelFit",
    "CrossValidation",
    "predict",
    "residuals",
    "fit_model",
    "group_folds",
    "cross_validate",
]

_STRENGTH_BOUNDS = (0.2, 5.0)
_GRID_POINTS = 9


@dataclass(frozen=True)
class ModelFit:
    """A fitted model: base simulation, strength scale and (optionally) one effect."""

    cause: str  # effect name, "none" for the baseline
    strength_scale: float  # fitted yield / nominal yield (UTS scaled alike)
    value: float | None  # the effect's parameter (units of EFFECTS[cause].unit)
    interval: tuple[float, float] | None  # 95 % interval of value
    strength_interval: tuple[float, float]
    rss_deg2: float  # residual sum of squares over all measured angles
    n_obs: int
    n_params: int

    @property
    def rmse_deg(self) -> float:
        return math.sqrt(self.rss_deg2 / max(self.n_obs, 1))

    @property
    def sigma_deg(self) -> float:
        """Residual standard deviation (degrees of freedom corrected)."""
        return math.sqrt(self.rss_deg2 / max(self.n_obs - self.n_params, 1))

    def effect(self) -> Effect | None:
        if self.cause == "none" or self.value is None:
            return None
        spec = EFFECTS[self.cause]
        return Effect(self.cause, float(np.clip(self.value, spec.lower, spec.upper)))

    def params(self, base: SimParams) -> SimParams:
        """``base`` with the fitted material strength."""
        return _scaled(base, self.strength_scale)

    def to_dict(self) -> dict[str, Any]:
        spec = EFFECTS[self.cause]
        out: dict[str, Any] = {
            "cause": self.cause,
            "strength_scale": self.strength_scale,
            "strength_interval": list(self.strength_interval),
            "rmse_deg": self.rmse_deg,
            "n_obs": self.n_obs,
            "n_params": self.n_params,
        }
        if self.value is not None:
            out["params"] = {spec.param: self.value}
            out["intervals"] = {spec.param: list(self.interval or (math.nan, math.nan))}
        return out


@dataclass(frozen=True)
class CrossValidation:
    """Held-out residuals of one model (one value per measured angle)."""

    cause: str
    residual_deg: NDArray[np.float64]

    @property
    def rmse_deg(self) -> float:
        r = self.residual_deg[np.isfinite(self.residual_deg)]
        return float(np.sqrt(np.mean(r**2))) if r.size else math.nan

    def to_dict(self) -> dict[str, Any]:
        return {"cause": self.cause, "cv_rmse_deg": self.rmse_deg}


def _scaled(base: SimParams, scale: float) -> SimParams:
    return base.replace(yield_mpa=base.yield_mpa * scale, uts_mpa=base.uts_mpa * scale)


def _effects(base_effects: Sequence[Effect], cause: str, value: float | None) -> tuple[Effect, ...]:
    kept = tuple(e for e in base_effects if e.name not in (cause, "none"))
    if cause == "none" or value is None:
        return kept
    spec = EFFECTS[cause]
    return (*kept, Effect(cause, float(np.clip(value, spec.lower, spec.upper))))


def predict(
    trials: TrialSet,
    params: SimParams,
    base_effects: Sequence[Effect],
    cause: str,
    strength_scale: float,
    value: float | None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Predicted (loaded, unloaded) bend angles (deg) of the trials under a model."""
    res = simulate(
        trials.commanded_pin_deg,
        _scaled(params, strength_scale),
        _effects(base_effects, cause, value),
        bend_index=trials.bend_index,
    )
    return res.loaded_bend_deg, res.unloaded_bend_deg


def residuals(
    trials: TrialSet,
    params: SimParams,
    base_effects: Sequence[Effect],
    cause: str,
    strength_scale: float,
    value: float | None,
) -> NDArray[np.float64]:
    """Measured minus predicted, stacked ``[loaded..., unloaded...]``; NaN where not measured."""
    loaded, unloaded = predict(trials, params, base_effects, cause, strength_scale, value)
    return np.concatenate([trials.loaded_bend_deg - loaded, trials.unloaded_bend_deg - unloaded])


def _interval(center: float, se: float, dof: int, lo: float, hi: float) -> tuple[float, float]:
    if not math.isfinite(se):
        return (lo, hi)
    t = float(stats.t.ppf(0.975, max(dof, 1)))
    return (max(center - t * se, lo), min(center + t * se, hi))


def fit_model(
    trials: TrialSet,
    params: SimParams,
    cause: str = "none",
    *,
    base_effects: Sequence[Effect] = (),
    start: tuple[float, float | None] | None = None,
) -> ModelFit:
    """Fit the strength scale (and the parameter of effect ``cause``) to the trials.

    Parameters
    ----------
    trials : TrialSet
        Measured bends.
    params : SimParams
        The simulation's nominal parameters.
    cause : str
        ``"none"`` (baseline: strength only) or an effect name.
    base_effects : sequence of Effect
        Effects already known (from the params JSON), kept fixed.
    start : (strength_scale, value), optional
        Start point (skips the grid search), e.g. a full-data fit for CV folds.
    """
    spec = EFFECTS[cause]
    with_effect = cause != "none"

    def resid(x: NDArray[np.float64]) -> NDArray[np.float64]:
        value = x[1] if with_effect else None
        r = residuals(trials, params, base_effects, cause, x[0], value)
        return r[np.isfinite(r)]

    if start is not None:
        x0 = [start[0]] + ([start[1] if start[1] is not None else 0.0] if with_effect else [])
    elif with_effect:
        grid = np.linspace(spec.lower, spec.upper, _GRID_POINTS)
        costs = [np.sum(resid(np.array([1.0, v])) ** 2) for v in grid]
        x0 = [1.0, float(grid[int(np.argmin(costs))])]
    else:
        x0 = [1.0]
    lower = [_STRENGTH_BOUNDS[0]] + ([spec.lower] if with_effect else [])
    upper = [_STRENGTH_BOUNDS[1]] + ([spec.upper] if with_effect else [])
    x0 = np.clip(np.asarray(x0, dtype=np.float64), lower, upper)
    # keep the start strictly inside the bounds (least_squares requires it)
    span = np.asarray(upper) - np.asarray(lower)
    x0 = np.clip(x0, np.asarray(lower) + 1e-9 * span, np.asarray(upper) - 1e-9 * span)
    scale = [0.1] + ([max(abs(spec.typical[1]), 1e-3)] if with_effect else [])
    sol = optimize.least_squares(
        resid, x0, bounds=(lower, upper), x_scale=np.asarray(scale), method="trf", xtol=1e-10
    )
    r = sol.fun
    n_obs, n_par = r.size, sol.x.size
    rss = float(np.sum(r**2))
    dof = n_obs - n_par
    jac = sol.jac
    try:
        cov = np.linalg.inv(jac.T @ jac) * rss / max(dof, 1)
        se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    except np.linalg.LinAlgError:
        se = np.full(n_par, math.inf)
    strength_ci = _interval(float(sol.x[0]), float(se[0]), dof, *_STRENGTH_BOUNDS)
    value = float(sol.x[1]) if with_effect else None
    interval = (
        _interval(value, float(se[1]), dof, spec.lower, spec.upper) if value is not None else None
    )
    return ModelFit(
        cause=cause,
        strength_scale=float(sol.x[0]),
        value=value,
        interval=interval,
        strength_interval=strength_ci,
        rss_deg2=rss,
        n_obs=n_obs,
        n_params=n_par,
    )


def group_folds(groups: Sequence[str], k: int = 5, *, seed: int = 0) -> list[NDArray[np.bool_]]:
    """Held-out masks of grouped K-fold CV (leave-one-group-out when there are < 2k groups)."""
    labels = np.asarray(groups)
    unique = np.unique(labels)
    rng = np.random.default_rng(seed)
    order = rng.permutation(unique)
    n_folds = unique.size if unique.size < 2 * k else k
    return [np.isin(labels, order[i::n_folds]) for i in range(n_folds)]


def cross_validate(
    trials: TrialSet,
    params: SimParams,
    cause: str,
    folds: Sequence[NDArray[np.bool_]],
    *,
    base_effects: Sequence[Effect] = (),
    full_fit: ModelFit | None = None,
) -> CrossValidation:
    """Held-out residuals: fit on all folds but one, predict the one, for every fold."""
    n = len(trials)
    out = np.full(2 * n, np.nan)
    start = (full_fit.strength_scale, full_fit.value) if full_fit is not None else None
    for held in folds:
        train = trials.subset(~held)
        fit = fit_model(train, params, cause, base_effects=base_effects, start=start)
        test = trials.subset(held)
        r = residuals(test, params, base_effects, cause, fit.strength_scale, fit.value)
        idx = np.flatnonzero(held)
        out[idx] = r[: idx.size]
        out[n + idx] = r[idx.size :]
    return CrossValidation(cause=cause, residual_deg=out)
