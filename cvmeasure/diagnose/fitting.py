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

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, stats

from cvmeasure.contracts import BLOCKS, TrialTable
from cvmeasure.geometry import wrap_deg
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
    "grouped_kfold_cv",
]

_STRENGTH_BOUNDS = (0.2, 5.0)
_GRID_POINTS = 9


Causes = tuple[str, ...]


def _as_causes(causes: str | Sequence[str]) -> Causes:
    if isinstance(causes, str):
        return () if causes == "none" else (causes,)
    return tuple(c for c in causes if c != "none")


@dataclass(frozen=True)
class ModelFit:
    """A fitted model: base simulation, strength scale and zero or more named effects."""

    causes: Causes  # effect names, () for the baseline
    strength_scale: float  # fitted yield / nominal yield (UTS scaled alike)
    values: tuple[float, ...]  # each effect's parameter (units of EFFECTS[name].unit)
    intervals: tuple[tuple[float, float], ...]  # 95 % interval of each value
    strength_interval: tuple[float, float]
    rss_deg2: float  # residual sum of squares over all measured angles
    n_obs: int
    n_params: int

    @property
    def cause(self) -> str:
        """The last effect added ("none" for the baseline)."""
        return self.causes[-1] if self.causes else "none"

    @property
    def value(self) -> float | None:
        return self.values[-1] if self.values else None

    @property
    def interval(self) -> tuple[float, float] | None:
        return self.intervals[-1] if self.intervals else None

    @property
    def rmse_deg(self) -> float:
        return math.sqrt(self.rss_deg2 / max(self.n_obs, 1))

    @property
    def sigma_deg(self) -> float:
        """Residual standard deviation (degrees of freedom corrected)."""
        return math.sqrt(self.rss_deg2 / max(self.n_obs - self.n_params, 1))

    def effects(self) -> tuple[Effect, ...]:
        """The fitted effects (clipped to their physical bounds)."""
        return _effects((), self.causes, self.values)

    def params(self, base: SimParams) -> SimParams:
        """``base`` with the fitted material strength."""
        return _scaled(base, self.strength_scale)

    def param_values(self) -> dict[str, float]:
        return {EFFECTS[c].param: v for c, v in zip(self.causes, self.values, strict=True)}

    def reordered(self, causes: Sequence[str]) -> ModelFit:
        """The same fit with its causes listed in another order."""
        order = [self.causes.index(c) for c in causes]
        return dataclasses.replace(
            self,
            causes=tuple(self.causes[i] for i in order),
            values=tuple(self.values[i] for i in order),
            intervals=tuple(self.intervals[i] for i in order),
        )

    def param_values_by_cause(self) -> dict[str, float]:
        return dict(zip(self.causes, self.values, strict=True))

    def param_intervals(self) -> dict[str, tuple[float, float]]:
        return {EFFECTS[c].param: i for c, i in zip(self.causes, self.intervals, strict=True)}

    def to_dict(self) -> dict[str, Any]:
        return {
            "causes": list(self.causes),
            "strength_scale": self.strength_scale,
            "strength_interval": list(self.strength_interval),
            "params": self.param_values(),
            "intervals": {k: list(v) for k, v in self.param_intervals().items()},
            "rmse_deg": self.rmse_deg,
            "n_obs": self.n_obs,
            "n_params": self.n_params,
        }


@dataclass(frozen=True)
class CrossValidation:
    """Held-out residuals of one model, stacked by blocks (NaN = not measured)."""

    causes: Causes
    residual_deg: NDArray[np.float64]

    @property
    def rmse_deg(self) -> float:
        r = self.residual_deg[np.isfinite(self.residual_deg)]
        return float(np.sqrt(np.mean(r**2))) if r.size else math.nan

    def to_dict(self) -> dict[str, Any]:
        return {"causes": list(self.causes), "cv_rmse_deg": self.rmse_deg}


def _scaled(base: SimParams, scale: float) -> SimParams:
    return base.replace(yield_mpa=base.yield_mpa * scale, uts_mpa=base.uts_mpa * scale)


def _effects(
    base_effects: Sequence[Effect], causes: Causes, values: Sequence[float]
) -> tuple[Effect, ...]:
    kept = tuple(e for e in base_effects if e.name not in (*causes, "none"))
    added = tuple(
        Effect(c, float(np.clip(v, EFFECTS[c].lower, EFFECTS[c].upper)))
        for c, v in zip(causes, values, strict=True)
    )
    return (*kept, *added)


def predict(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: str | Sequence[str],
    strength_scale: float,
    values: Sequence[float] = (),
) -> NDArray[np.float64]:
    """Predicted observations of the trials under a model, stacked like
    :meth:`TrialTable.observations` (loaded, unloaded bend and pin angle, deg)."""
    res = simulate(
        trials.commanded_pin_deg,
        _scaled(params, strength_scale),
        _effects(base_effects, _as_causes(causes), values),
        bend_index=trials.bend_index,
    )
    return np.concatenate([res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg])


def residuals(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: str | Sequence[str],
    strength_scale: float,
    values: Sequence[float] = (),
) -> NDArray[np.float64]:
    """Measured minus predicted, stacked by blocks (loaded, unloaded, pin); NaN = not measured."""
    predicted = predict(trials, params, base_effects, causes, strength_scale, values)
    r = trials.observations() - predicted
    n = len(trials)
    r[2 * n :] = wrap_deg(r[2 * n :])  # pin angles are directions
    return r


def _interval(center: float, se: float, dof: int, lo: float, hi: float) -> tuple[float, float]:
    if not math.isfinite(se):
        return (lo, hi)
    t = float(stats.t.ppf(0.975, max(dof, 1)))
    return (max(center - t * se, lo), min(center + t * se, hi))


def fit_model(
    trials: TrialTable,
    params: SimParams,
    causes: str | Sequence[str] = "none",
    *,
    base_effects: Sequence[Effect] = (),
    start: tuple[float, Sequence[float]] | None = None,
    known: dict[str, float] | None = None,
) -> ModelFit:
    """Fit the strength scale and the parameters of the effects ``causes`` to the trials.

    Parameters
    ----------
    trials : TrialTable
        Measured bends.
    params : SimParams
        The simulation's nominal parameters.
    causes : str or sequence of str
        ``"none"`` (baseline: strength only), an effect name, or several.
    base_effects : sequence of Effect
        Effects already known (from the params JSON), kept fixed.
    start : (strength_scale, values), optional
        Start point (skips the grid search), e.g. a full-data fit for CV folds.
    known : dict, optional
        Start values of some causes (e.g. from a previous round); the others
        start from the best point of a grid over their bounds.
    """
    names = _as_causes(causes)
    specs = [EFFECTS[c] for c in names]

    def resid(x: NDArray[np.float64]) -> NDArray[np.float64]:
        r = residuals(trials, params, base_effects, names, x[0], x[1:])
        return r[np.isfinite(r)]

    if start is not None:
        x0 = np.array([start[0], *start[1]], dtype=np.float64)
    else:
        known = known or {}
        x0 = np.array([1.0] + [known.get(c, 0.0) for c in names], dtype=np.float64)
        x0[1:] = np.clip(x0[1:], [s.lower for s in specs], [s.upper for s in specs])
        for i, (c, spec) in enumerate(zip(names, specs, strict=True), start=1):
            if c in known:
                continue
            grid = np.linspace(spec.lower, spec.upper, _GRID_POINTS)
            costs = []
            for v in grid:
                x0[i] = v
                costs.append(np.sum(resid(x0) ** 2))
            x0[i] = float(grid[int(np.argmin(costs))])
    lower = np.array([_STRENGTH_BOUNDS[0]] + [s.lower for s in specs])
    upper = np.array([_STRENGTH_BOUNDS[1]] + [s.upper for s in specs])
    # keep the start strictly inside the bounds (least_squares requires it)
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    scale = np.array([0.1] + [max(abs(s.typical[1]), 1e-3) for s in specs])
    sol = optimize.least_squares(
        resid, x0, bounds=(lower, upper), x_scale=scale, method="trf", xtol=1e-9
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
    return ModelFit(
        causes=names,
        strength_scale=float(sol.x[0]),
        values=tuple(float(v) for v in sol.x[1:]),
        intervals=tuple(
            _interval(float(sol.x[i]), float(se[i]), dof, spec.lower, spec.upper)
            for i, spec in enumerate(specs, start=1)
        ),
        strength_interval=_interval(float(sol.x[0]), float(se[0]), dof, *_STRENGTH_BOUNDS),
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


def grouped_kfold_cv(
    trials: TrialTable,
    params: SimParams,
    causes: str | Sequence[str],
    folds: Sequence[NDArray[np.bool_]],
    *,
    base_effects: Sequence[Effect] = (),
    full_fit: ModelFit | None = None,
) -> CrossValidation:
    """Held-out residuals: fit on all folds but one, predict the one, for every fold."""
    names = _as_causes(causes)
    n = len(trials)
    n_blocks = len(BLOCKS)
    out = np.full(n_blocks * n, np.nan)
    start = (full_fit.strength_scale, full_fit.values) if full_fit is not None else None
    for held in folds:
        train = trials.subset(~held)
        fit = fit_model(train, params, names, base_effects=base_effects, start=start)
        test = trials.subset(held)
        r = residuals(test, params, base_effects, names, fit.strength_scale, fit.values)
        idx = np.flatnonzero(held)
        for b in range(n_blocks):
            out[b * n + idx] = r[b * idx.size : (b + 1) * idx.size]
    return CrossValidation(causes=names, residual_deg=out)
