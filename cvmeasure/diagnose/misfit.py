"""Is the simulation a description of this machine at all? Lack of fit against repeats.

The diagnosis compares causes on top of a baseline fitted to the user's machine. When
the machine is described wrong (another wire diameter, pin or die than the params say),
the best explanation still misses every bend by far more than the photos' noise, and a
catalogue name given then is the least bad of wrong models. Repeated identical bends
(the calibration session bends each one twice) measure the noise without any model:
their pooled scatter is the *pure error*. The best explanation's residual variance
(the bounded model-form discrepancy profiled out) is tested against it (F test, lack of
fit); far beyond it, no cause is named and the user is told to describe the machine.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import fdtrc

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.discrepancy import (
    DISCREPANCY_BOUND_DEG,
    discrepancy_basis,
    profile_discrepancy,
)
from cvmeasure.diagnose.model_fit import ModelFit
from cvmeasure.sim.model import simulate
from cvmeasure.sim.params import SimParams

__all__ = [
    "PureError",
    "Misfit",
    "pure_error",
    "lack_of_fit",
    "lack_of_fit_residuals",
    "springback_rms_deg",
    "curve_rms_deg",
]

#: Lack of fit beyond this p-value ...
MISFIT_P = 1e-6
#: ... and by more than this ratio of standard deviations to the pure error ...
MISFIT_RATIO = 3.0
#: ... and by more than the model-form error the discrepancy allows (deg rms) refuses.
MISFIT_FLOOR_DEG = DISCREPANCY_BOUND_DEG


@dataclass(frozen=True)
class PureError:
    """Scatter of repeated identical commands (deg), pooled over the observations."""

    sigma_deg: float
    dof: int


@dataclass(frozen=True)
class Misfit:
    """The best explanation against the pure error."""

    rms_deg: float  # residual standard deviation, the discrepancy profiled out
    pure: PureError
    p_value: float

    @property
    def refused(self) -> bool:
        return (
            self.p_value < MISFIT_P
            and self.rms_deg > MISFIT_RATIO * self.pure.sigma_deg
            and self.rms_deg > MISFIT_FLOOR_DEG
        )

    def to_dict(self) -> dict[str, float | bool]:
        return {
            "rms_deg": self.rms_deg,
            "pure_error_deg": self.pure.sigma_deg,
            "pure_error_dof": self.pure.dof,
            "p_value": self.p_value,
            "refused": self.refused,
        }

    def note(self) -> str:
        return (
            f"the simulation does not describe this machine: the best explanation misses by "
            f"{self.rms_deg:.2f} deg rms where repeated bends scatter by "
            f"{self.pure.sigma_deg:.3f} deg (lack of fit p = {self.p_value:.1g}); no cause is "
            "named. Describe the machine with --params (wire diameter, die radius, pin "
            "radius and orbit, approach) and diagnose again"
        )


def pure_error(trials: TrialTable) -> PureError | None:
    """Pooled scatter of the bends sharing a command (None: fewer than 3 degrees of
    freedom). A drift or a warm-up between repeats adds to it: the test is then more
    lenient, never less."""
    obs = trials.observations().reshape(3, len(trials))
    groups: dict[float, list[int]] = {}
    for i, c in enumerate(trials.commanded_pin_deg):
        groups.setdefault(round(float(c), 3), []).append(i)
    ss, dof = 0.0, 0
    for rows in groups.values():
        if len(rows) < 2:
            continue
        for block in obs[:, rows]:
            v = block[np.isfinite(block)]
            if v.size >= 2:
                ss += float(np.sum((v - v.mean()) ** 2))
                dof += v.size - 1
    if dof < 3:
        return None
    return PureError(math.sqrt(ss / dof), dof)


def lack_of_fit(trials: TrialTable, fit: ModelFit) -> Misfit | None:
    """``fit`` against the pure error of ``trials`` (None: no repeats to tell)."""
    pure = pure_error(trials)
    if pure is None or not math.isfinite(fit.rss_discrepancy_deg2):
        return None
    dof = max(fit.n_obs - fit.n_params, 1)
    rms = math.sqrt(fit.rss_discrepancy_deg2 / dof)
    if pure.sigma_deg <= 0:
        return Misfit(rms, pure, 0.0 if rms > 0 else 1.0)
    p = float(fdtrc(dof, pure.dof, (rms / pure.sigma_deg) ** 2))
    return Misfit(rms, pure, p)


def lack_of_fit_residuals(
    trials: TrialTable, residual_deg: np.ndarray, n_params: int
) -> Misfit | None:
    """As :func:`lack_of_fit` for residuals (3 N,) of a model with ``n_params``
    parameters (terms outside the catalogue), the discrepancy profiled out here."""
    ok = np.isfinite(residual_deg)
    basis = discrepancy_basis(trials)[ok]
    r = residual_deg[ok]
    r = r - basis @ profile_discrepancy(r, basis)
    fit = ModelFit(
        causes=(),
        strength_scale=1.0,
        values=(),
        intervals=(),
        strength_interval=(math.nan, math.nan),
        rss_deg2=float(r @ r),
        n_obs=int(r.size),
        n_params=n_params,
        rss_discrepancy_deg2=float(r @ r),
    )
    return lack_of_fit(trials, fit)


def springback_rms_deg(trials: TrialTable, params: SimParams) -> float:
    """RMS springback (deg, loaded less released magnitude) the description ``params``
    predicts over the session's bends: the size of the material's part of the bend."""
    sim = simulate(np.asarray(trials.commanded_pin_deg, dtype=np.float64), params, ())
    spring = np.abs(sim.loaded_bend_deg) - np.abs(sim.unloaded_bend_deg)
    ok = np.isfinite(spring)
    return float(np.sqrt(np.mean(spring[ok] ** 2))) if ok.any() else math.nan


def curve_rms_deg(trials: TrialTable, fit: ModelFit) -> float:
    """RMS (deg) of ``fit``'s discrepancy over the loaded and released angles."""
    n = len(trials)
    if not fit.discrepancy:
        return 0.0
    curve = discrepancy_basis(trials)[: 2 * n] @ np.asarray(fit.discrepancy, dtype=np.float64)
    return float(np.sqrt(np.mean(curve**2)))
