"""The fits' typed results: a fitted model and its cross-validation."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.discrepancy import discrepancy_basis, profile_discrepancy
from cvmeasure.diagnose.forms import NUISANCE, Causes, Shape, nuisance_for
from cvmeasure.diagnose.predict import effects_with, predict, residuals, scaled
from cvmeasure.sim.effects import EFFECTS, Effect
from cvmeasure.sim.params import SimParams


@dataclass(frozen=True)
class Solution:
    """Where a fit on every trial ended (without the discrepancy), so that the folds of its
    cross-validation, which start there, need not simulate that point again: the
    residuals and the forward-difference Jacobian of one fold at that point are rows of
    these (the same numbers)."""

    trials: TrialTable  # the very table fitted (compared by identity)
    params: SimParams
    base_effects: tuple[Effect, ...]
    causes: Causes
    shapes: tuple[Shape, ...]
    x: NDArray[np.float64]  # strength scale, NUISANCE values, the causes' values
    residual_deg: NDArray[np.float64]  # (3 N,) measured minus predicted at x
    jacobian: NDArray[np.float64]  # (3 N, x.size) d residual / d x; NaN rows: not measured

    def matches(
        self, trials: TrialTable, params: SimParams, base_effects: Sequence[Effect], causes: Causes
    ) -> bool:
        return (
            trials is self.trials
            and params == self.params
            and tuple(base_effects) == self.base_effects
            and causes == self.causes
        )


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
    nuisance: tuple[float, ...] = ()  # values of NUISANCE (empty: the nominal ones)
    shapes: tuple[Shape, ...] = ()  # each cause's form (empty: the narrow forms)
    discrepancy: tuple[float, ...] = ()  # coefficients (deg) of the discrepancy (empty: none)
    rss_discrepancy_deg2: float = math.nan  # residual sum of squares after the discrepancy
    #: p-value of the discrepancy's share of the residuals under "the model is the machine"
    #: (chi-square; below DISCREPANCY_P the data show a model-form error)
    model_form_p: float = math.nan
    #: the 95 % intervals with the model-form error counted once, where the data show one
    #: (empty: the same as ``intervals``): the noise is what the discrepancy leaves and the
    #: cluster sandwich is taken over the residuals with it profiled out, the discrepancy
    #: itself carried by its own variance; ``intervals`` (used to name the causes) also
    #: count the model-form wave as noise and as an error shared by repeated commands
    intervals_measured: tuple[tuple[float, float], ...] = ()
    #: where the solver ended (a fit on every trial without the discrepancy), for the folds
    solution: Solution | None = field(default=None, repr=False, compare=False)
    #: measured minus predicted over every trial at the fitted point (3 N,), as
    #: :meth:`residuals` gives it with the params fitted on (None: not kept)
    residual_deg: NDArray[np.float64] | None = field(default=None, repr=False, compare=False)

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
    def n_cause_params(self) -> int:
        """Parameters the causes add to the baseline: each cause's value and each shape
        parameter of its form (a grid's choice or a shape refined off it is fitted to the
        data as well), as :attr:`n_params` counts them."""
        return len(self.causes) + sum(len(f) for f in self.shapes)

    @property
    def sigma_deg(self) -> float:
        """Residual standard deviation (degrees of freedom corrected)."""
        return math.sqrt(self.rss_deg2 / max(self.n_obs - self.n_params, 1))

    def effects(self, params: SimParams | None = None) -> tuple[Effect, ...]:
        """The fitted effects (clipped to their physical bounds on the machine ``params``
        describes; None: a DIWire's)."""
        return effects_with((), self.causes, self.values, self.shapes, params=params)

    def params(self, base: SimParams) -> SimParams:
        """``base`` with the fitted material strength and nuisance geometry."""
        return scaled(base, self.strength_scale, self.nuisance)

    def nuisance_values(self) -> dict[str, float]:
        return {n.key: v for n, v in zip(NUISANCE, self.nuisance, strict=False)}

    def residuals(
        self, trials: TrialTable, params: SimParams, base_effects: Sequence[Effect] = ()
    ) -> NDArray[np.float64]:
        """Measured minus predicted by this fit (see :func:`residuals`)."""
        return residuals(
            trials,
            params,
            base_effects,
            self.causes,
            self.strength_scale,
            self.values,
            nuisance=self.nuisance,
            shapes=self.shapes,
        )

    def head_sensitivity(
        self,
        trials: TrialTable,
        params: SimParams,
        base_effects: Sequence[Effect] = (),
        step_deg: float = 0.5,
    ) -> NDArray[np.float64]:
        """How much each measured bend grows per degree more head rotation under this
        fit (deg/deg, stacked like the observations; the pin block is 1): an error of
        the drive in head degrees reaches the bend multiplied by it."""
        s = trials.direction_sign
        kw = dict(nuisance=self.nuisance, shapes=self.shapes)
        args = (trials, params, base_effects, self.causes, self.strength_scale, self.values)
        up = predict(*args, **kw, commanded_pin_deg=trials.commanded_pin_deg + s * step_deg)
        down = predict(*args, **kw, commanded_pin_deg=trials.commanded_pin_deg - s * step_deg)
        out = np.tile(s, 3) * (up - down) / (2.0 * step_deg)
        out[2 * len(trials) :] = 1.0
        return out

    def nuisance_jacobian(
        self, trials: TrialTable, params: SimParams, base_effects: Sequence[Effect] = ()
    ) -> NDArray[np.float64]:
        """(3 N, 1 + len(NUISANCE)): change of every prediction (deg) per unit of the
        strength scale and of each nuisance parameter (central differences), the
        directions in which a refit of the machine moves the model."""
        cols = []
        base = [self.strength_scale, *self.nuisance]
        steps = [0.01, *(0.05 * n.prior_sd for n in nuisance_for(params))]
        for j, step in enumerate(steps[: len(base)]):
            out = []
            for sign in (1.0, -1.0):
                x = list(base)
                x[j] += sign * step
                out.append(
                    predict(
                        trials,
                        params,
                        base_effects,
                        self.causes,
                        x[0],
                        self.values,
                        nuisance=x[1:],
                        shapes=self.shapes,
                    )
                )
            cols.append((out[0] - out[1]) / (2.0 * step))
        return np.column_stack(cols)

    def param_values(self) -> dict[str, float]:
        """Each cause's parameter, and the shape parameters of a general form."""
        out = {EFFECTS[c].param: v for c, v in zip(self.causes, self.values, strict=True)}
        for form in self.shapes:
            out.update(dict(form))
        return out

    def shapes_by_cause(self) -> dict[str, Shape]:
        return dict(zip(self.causes, self.shapes, strict=False))

    def reordered(self, causes: Sequence[str]) -> ModelFit:
        """The same fit with its causes listed in another order."""
        order = [self.causes.index(c) for c in causes]
        return dataclasses.replace(
            self,
            causes=tuple(self.causes[i] for i in order),
            values=tuple(self.values[i] for i in order),
            shapes=tuple(self.shapes[i] for i in order) if self.shapes else (),
            intervals=tuple(self.intervals[i] for i in order),
            intervals_measured=tuple(self.intervals_measured[i] for i in order)
            if self.intervals_measured
            else (),
            solution=None,
            residual_deg=None,
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
            "nuisance": self.nuisance_values(),
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
    #: Held-out residuals less the discrepancy fitted with the model on the other folds
    #: (None: the model was fitted without it).
    residual_discrepancy_deg: NDArray[np.float64] | None = None

    @property
    def rmse_deg(self) -> float:
        r = self.residual_deg[np.isfinite(self.residual_deg)]
        return float(np.sqrt(np.mean(r**2))) if r.size else math.nan

    def residual_after_discrepancy_deg(self, trials: TrialTable) -> NDArray[np.float64]:
        """Held-out residuals with the bounded model-form discrepancy profiled out
        (predicted from the other folds when it was fitted with the model there)."""
        if self.residual_discrepancy_deg is not None:
            return self.residual_discrepancy_deg
        out = np.full(self.residual_deg.shape, np.nan)
        ok = np.isfinite(self.residual_deg)
        if ok.any():
            basis = discrepancy_basis(trials)[ok]
            r = self.residual_deg[ok]
            out[ok] = r - basis @ profile_discrepancy(r, basis)
        return out

    def rmse_after_discrepancy_deg(self, trials: TrialTable) -> float:
        """Held-out RMSE with the bounded model-form discrepancy profiled out (predicted
        from the other folds when it was fitted with the model there)."""
        r = self.residual_after_discrepancy_deg(trials)
        r = r[np.isfinite(r)]
        return float(np.sqrt(np.mean(r**2))) if r.size else math.nan

    def to_dict(self) -> dict[str, Any]:
        return {"causes": list(self.causes), "cv_rmse_deg": self.rmse_deg}
