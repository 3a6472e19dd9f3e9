"""Springback compensation: which pin command makes the wire end at a wanted angle.

A calibration measures, per bend direction, pairs of a *loaded* bend angle
(the pin holding the wire) and an *unloaded* (final) one. Compensation turns a
wanted final angle into a pin command in two steps::

    target final angle --springback curve--> loaded angle --motion curve--> pin command

Both curves work on magnitudes (degrees, >= 0) per direction: ``"ccw"``
(positive bends, counter-clockwise as seen from above) and ``"cw"`` (negative
bends); the sign is restored at the end.

Springback models (:data:`SPRINGBACK_MODELS`):

``linear``
    piecewise-linear interpolation of the loaded angle over the final angle
    (the seed paper's winner, 0.05 deg on parts against 1.28 deg for the cubic).
``cubic``
    least-squares cubic of springback over the final angle (the seed's and the
    stock software's model). With 5 angles (quick mode) it keeps one residual
    degree of freedom, which the fit notes say.
``pchip``
    monotone piecewise-cubic Hermite interpolation (Fritsch-Carlson) of the
    loaded angle over the final angle: C1, no overshoot, invertible.
``physical``
    the springback law of :mod:`cvmeasure.sim`: ``springback = b * loaded + k *
    lever(loaded)`` (wrapped zone plus free span, whose length ``lever`` follows
    from the nominal head geometry's tangent construction), two parameters per
    direction, fitted by least squares; the one model that may be trusted a
    little beyond its data (it still refuses by default).

Every model is scored by leave-one-angle-out error (the interpolants are exact
at their own knots, so in-sample error says nothing about them): each interior
calibration angle is left out in turn, the model refitted, and the left-out
final angle predicted. End angles are not scored, because leaving them out
would make every model extrapolate.

Motion models (:data:`MOTION_MODELS`) map the loaded angle to the pin command:
``pchip`` (monotone interpolation of the measured pairs, default) or
``linear``.

Nothing extrapolates silently: a target outside the calibrated final-angle
range raises :class:`CompensationRangeError`, or with ``outside="warn"``
extrapolates the end piece and emits :class:`CompensationRangeWarning`, or
with ``outside="clamp"`` clamps and warns.

:mod:`cvmeasure.sim` is imported only by the physical model's lever table: a job
compensated from a curve never loads it (a tenth of a second of start-up).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from cvmeasure.errors import CompensationRangeWarning, CvmeasureError

__all__ = [
    "SPRINGBACK_MODELS",
    "MOTION_MODELS",
    "DIRECTIONS",
    "SpringbackModel",
    "MotionModel",
    "Outside",
    "CompensationRangeError",
    "CompensationRangeWarning",
    "SpringbackCurve",
    "MotionCurve",
    "Compensation",
    "fit_springback",
    "fit_motion",
    "fit_compensation",
    "direction_of",
    "nominal_lever_mm",
]

SpringbackModel = Literal["linear", "cubic", "pchip", "physical"]
MotionModel = Literal["linear", "pchip"]
Outside = Literal["raise", "warn", "clamp"]

#: Springback model names, in the order reports list them.
SPRINGBACK_MODELS: tuple[str, ...] = ("linear", "cubic", "pchip", "physical")
#: Motion-function model names.
MOTION_MODELS: tuple[str, ...] = ("pchip", "linear")
#: Bend directions: ``ccw`` = positive bend angles, ``cw`` = negative.
DIRECTIONS: tuple[str, ...] = ("ccw", "cw")

_MIN_POINTS = {"linear": 2, "pchip": 2, "cubic": 4, "physical": 2}


class CompensationRangeError(CvmeasureError, ValueError):
    """A wanted angle lies outside the calibrated range of a curve."""


def direction_of(angle_deg: float) -> str:
    """``"ccw"`` for a positive (or zero) angle, ``"cw"`` for a negative one."""
    return "cw" if angle_deg < 0 else "ccw"


def _check_model(model: str, valid: Sequence[str], what: str) -> None:
    if model not in valid:
        raise ValueError(f"unknown {what} model {model!r}; valid: {', '.join(valid)}")


def _merge_repeats(
    x: np.ndarray, y: np.ndarray, *, gap_deg: float = 0.5
) -> tuple[np.ndarray, np.ndarray]:
    """Sort by x and average repeats: points closer than ``gap_deg`` in x form one angle."""
    order = np.argsort(x, kind="stable")
    x, y = x[order], y[order]
    if x.size == 0:
        return x, y
    group = np.concatenate([[0], np.cumsum(np.diff(x) > gap_deg)])
    counts = np.bincount(group)
    return np.bincount(group, weights=x) / counts, np.bincount(group, weights=y) / counts


def _interp_eval(model: str, x_knots: np.ndarray, y_knots: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Evaluate a linear or PCHIP interpolant, extending the end pieces linearly."""
    lo, hi = x_knots[0], x_knots[-1]
    xc = np.clip(x, lo, hi)
    if model == "linear" or len(x_knots) < 3:
        inside = np.interp(xc, x_knots, y_knots)
        slope_lo = (y_knots[1] - y_knots[0]) / (x_knots[1] - x_knots[0])
        slope_hi = (y_knots[-1] - y_knots[-2]) / (x_knots[-1] - x_knots[-2])
    else:
        from scipy.interpolate import PchipInterpolator

        pchip = PchipInterpolator(x_knots, y_knots, extrapolate=False)
        inside = pchip(xc)
        deriv = pchip.derivative()
        slope_lo, slope_hi = float(deriv(lo)), float(deriv(hi))
    return np.where(
        x < lo, inside + slope_lo * (x - lo), np.where(x > hi, inside + slope_hi * (x - hi), inside)
    )


def _range_policy(
    x: np.ndarray, domain: tuple[float, float], outside: Outside, what: str
) -> np.ndarray:
    """Apply the out-of-range policy to magnitudes ``x``; return the x to evaluate."""
    lo, hi = domain
    tol = 1e-9 * max(1.0, abs(hi))
    bad = (x < lo - tol) | (x > hi + tol)
    if not np.any(bad):
        return np.clip(x, lo, hi)
    worst = float(x[bad][np.argmax(np.abs(np.clip(x[bad], lo, hi) - x[bad]))])
    message = f"{what} {worst:.3f} deg is outside the calibrated range {lo:.3f}..{hi:.3f} deg"
    if outside == "raise":
        raise CompensationRangeError(message)
    if outside == "clamp":
        warnings.warn(message + "; clamped", CompensationRangeWarning, stacklevel=3)
        return np.clip(x, lo, hi)
    if outside == "warn":
        warnings.warn(message + "; extrapolated", CompensationRangeWarning, stacklevel=3)
        return x
    raise ValueError(f"unknown outside policy {outside!r}; valid: raise, warn, clamp")


@dataclass(frozen=True)
class SpringbackCurve:
    """Springback of one bend direction as a function of the final angle.

    Attributes
    ----------
    model : str
        One of :data:`SPRINGBACK_MODELS`.
    direction : str
        ``"ccw"`` or ``"cw"``.
    final_deg, loaded_deg : tuple of float
        The calibration data as magnitudes (deg): final (unloaded) and loaded
        bend angle, averaged over repeats, sorted by final angle.
    coef : tuple of float
        Model coefficients: cubic ``springback = c0 + c1 f + c2 f^2 + c3 f^3``
        (f = final angle, deg); physical ``(b, k_deg_per_mm)`` of ``springback
        = b * loaded + k * lever_mm(loaded)``; empty for the interpolants.
    domain_deg : (float, float)
        The calibrated final-angle range; compensation outside it is refused.
    rmse_deg : float
        In-sample RMS residual of the final angle (0 for interpolants).
    loao_rmse_deg, loao_max_deg : float or None
        Leave-one-angle-out RMS and largest absolute error of the predicted
        loaded angle (deg) over the interior angles; None with fewer than 3.
    loao_errors_deg : tuple of float
        The individual leave-one-angle-out errors (predicted - measured loaded
        angle), one per interior angle.
    notes : tuple of str
        Warnings about the fit (e.g. a cubic with one residual dof).
    """

    model: str
    direction: str
    final_deg: tuple[float, ...]
    loaded_deg: tuple[float, ...]
    coef: tuple[float, ...] = ()
    domain_deg: tuple[float, float] = (0.0, 0.0)
    rmse_deg: float = 0.0
    loao_rmse_deg: float | None = None
    loao_max_deg: float | None = None
    loao_errors_deg: tuple[float, ...] = ()
    notes: tuple[str, ...] = ()

    def loaded_for_final_deg(self, final_deg: ArrayLike, *, outside: Outside = "raise") -> Any:
        """Loaded angle magnitude (deg) that springs back to ``final_deg`` (magnitude, deg)."""
        f = np.asarray(final_deg, dtype=np.float64)
        x = _range_policy(np.atleast_1d(f), self.domain_deg, outside, "final angle")
        out = _springback_loaded(
            self.model, self.final_deg, self.loaded_deg, self.coef, x, self.direction
        )
        return float(out[0]) if f.ndim == 0 else out

    def springback_deg(self, final_deg: ArrayLike, *, outside: Outside = "raise") -> Any:
        """Springback (deg, positive = opens back) at the final angle magnitude ``final_deg``."""
        loaded = self.loaded_for_final_deg(final_deg, outside=outside)
        return loaded - np.asarray(final_deg, dtype=np.float64)

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "direction": self.direction,
            "x": "final_deg",
            "y": "loaded_deg",
            "final_deg": list(self.final_deg),
            "loaded_deg": list(self.loaded_deg),
            "coef": list(self.coef),
            "domain_deg": list(self.domain_deg),
            "rmse_deg": self.rmse_deg,
            "loao_rmse_deg": self.loao_rmse_deg,
            "loao_max_deg": self.loao_max_deg,
            "loao_errors_deg": list(self.loao_errors_deg),
            "notes": list(self.notes),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SpringbackCurve:
        _check_model(d["model"], SPRINGBACK_MODELS, "springback")
        return cls(
            model=str(d["model"]),
            direction=str(d["direction"]),
            final_deg=tuple(float(v) for v in d["final_deg"]),
            loaded_deg=tuple(float(v) for v in d["loaded_deg"]),
            coef=tuple(float(v) for v in d.get("coef", ())),
            domain_deg=(float(d["domain_deg"][0]), float(d["domain_deg"][1])),
            rmse_deg=float(d.get("rmse_deg", 0.0)),
            loao_rmse_deg=_opt_float(d.get("loao_rmse_deg")),
            loao_max_deg=_opt_float(d.get("loao_max_deg")),
            loao_errors_deg=tuple(float(v) for v in d.get("loao_errors_deg", ())),
            notes=tuple(str(v) for v in d.get("notes", ())),
        )


def _opt_float(value: Any) -> float | None:
    return None if value is None else float(value)


def nominal_lever_mm(loaded_deg: ArrayLike, direction: str = "ccw") -> np.ndarray:
    """Free-span length (mm) at a loaded angle (deg, magnitude) on the nominal head.

    The tangent construction of :mod:`cvmeasure.sim.kinematics` with the
    default :class:`~cvmeasure.sim.SimParams` geometry (tabulated every 0.05
    deg and interpolated); the span between the die tangent point and the pin
    carries the free-span springback term.
    """
    grid, lever = _lever_table(-1.0 if direction == "cw" else 1.0)
    return np.interp(np.asarray(loaded_deg, dtype=np.float64), grid, lever)


@functools.lru_cache(maxsize=2)
def _lever_table(sign: float) -> tuple[np.ndarray, np.ndarray]:
    from cvmeasure.sim import SimParams
    from cvmeasure.sim.kinematics import head_geometry, lever_arm_mm, pin_angle_for_loaded_deg

    geom = head_geometry(SimParams(), sign)
    grid = np.arange(0.0, 178.0, 0.05)
    return grid, lever_arm_mm(geom, pin_angle_for_loaded_deg(geom, grid))


def _springback_coef(
    model: str, final: np.ndarray, loaded: np.ndarray, direction: str
) -> tuple[float, ...]:
    if model == "cubic":
        # numpy.polynomial returns coefficients lowest order first.
        poly = np.polynomial.Polynomial.fit(final, loaded - final, 3).convert()
        coef = np.zeros(4)
        coef[: len(poly.coef)] = poly.coef
        return tuple(float(c) for c in coef)
    if model == "physical":
        # springback = b * loaded + k * lever(loaded): the wrapped zone plus the free
        # span of the affine law of cvmeasure.sim, least squares over (b, k).
        A = np.column_stack([loaded, nominal_lever_mm(loaded, direction)])
        (b, k), *_ = np.linalg.lstsq(A, loaded - final, rcond=None)
        return (float(b), float(k))
    return ()


def _springback_loaded(
    model: str,
    final_knots: Sequence[float],
    loaded_knots: Sequence[float],
    coef: Sequence[float],
    final: np.ndarray,
    direction: str,
) -> np.ndarray:
    if model in ("linear", "pchip"):
        return _interp_eval(
            model, np.asarray(final_knots, float), np.asarray(loaded_knots, float), final
        )
    if model == "cubic":
        return final + np.polynomial.polynomial.polyval(final, coef)
    if model == "physical":
        b, k = coef
        # final = loaded - b loaded - k lever(loaded): increasing in loaded; bisection
        lo = np.maximum(final, 0.0)
        hi = lo + 30.0 + np.abs(final)
        for _ in range(48):
            mid = 0.5 * (lo + hi)
            below = mid * (1.0 - b) - k * nominal_lever_mm(mid, direction) < final
            lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
        return 0.5 * (lo + hi)
    raise ValueError(f"unknown springback model {model!r}")


def fit_springback(
    final_deg: ArrayLike,
    loaded_deg: ArrayLike,
    *,
    model: SpringbackModel = "linear",
    direction: str = "ccw",
) -> SpringbackCurve:
    """Fit one direction's springback curve and score it leave-one-angle-out.

    Parameters
    ----------
    final_deg, loaded_deg : array_like of shape (N,)
        Final (unloaded) and loaded bend-angle magnitudes (deg, >= 0) of the
        calibration bends of one direction; repeats of an angle are averaged.
    model : {"linear", "cubic", "pchip", "physical"}
        See the module docstring.
    direction : {"ccw", "cw"}
        Recorded in the result.

    Returns
    -------
    SpringbackCurve

    Raises
    ------
    ValueError
        Unknown model, mismatched lengths or too few distinct angles.
    """
    _check_model(model, SPRINGBACK_MODELS, "springback")
    f = np.abs(np.asarray(final_deg, dtype=np.float64).ravel())
    l_ = np.abs(np.asarray(loaded_deg, dtype=np.float64).ravel())
    if f.shape != l_.shape:
        raise ValueError("final_deg and loaded_deg must have the same length")
    if not (np.all(np.isfinite(f)) and np.all(np.isfinite(l_))):
        raise ValueError("final_deg and loaded_deg must be finite")
    f, l_ = _merge_repeats(f, l_)
    if len(f) < _MIN_POINTS[model]:
        raise ValueError(
            f"{model} springback needs at least {_MIN_POINTS[model]} distinct angles "
            f"per direction, got {len(f)} ({direction})"
        )
    coef = _springback_coef(model, f, l_, direction)
    fitted = _springback_loaded(model, f, l_, coef, f, direction)
    rmse = float(np.sqrt(np.mean((fitted - l_) ** 2)))
    errors = []
    for i in range(1, len(f) - 1):
        keep = np.arange(len(f)) != i
        if keep.sum() < _MIN_POINTS[model]:
            break
        c = _springback_coef(model, f[keep], l_[keep], direction)
        pred = _springback_loaded(model, f[keep], l_[keep], c, f[i : i + 1], direction)[0]
        errors.append(float(pred - l_[i]))
    notes = []
    dof = len(f) - {"cubic": 4, "physical": 2}.get(model, len(f))
    if model in ("cubic", "physical") and dof <= 1:
        notes.append(f"{model} fit on {len(f)} angles leaves {dof} residual degree(s) of freedom")
    loaded_is_monotone = bool(np.all(np.diff(fitted) > 0))
    if not loaded_is_monotone:
        notes.append("loaded angle is not increasing with the final angle: check the data")
    err = np.asarray(errors)
    return SpringbackCurve(
        model=model,
        direction=direction,
        final_deg=tuple(float(v) for v in f),
        loaded_deg=tuple(float(v) for v in l_),
        coef=coef,
        domain_deg=(float(f[0]), float(f[-1])),
        rmse_deg=rmse,
        loao_rmse_deg=float(np.sqrt(np.mean(err**2))) if err.size else None,
        loao_max_deg=float(np.max(np.abs(err))) if err.size else None,
        loao_errors_deg=tuple(errors),
        notes=tuple(notes),
    )


@dataclass(frozen=True)
class MotionCurve:
    """Motion function of one direction: pin command magnitude for a loaded angle.

    Attributes
    ----------
    model : str
        One of :data:`MOTION_MODELS`.
    direction : str
        ``"ccw"`` or ``"cw"``.
    loaded_deg, pin_deg : tuple of float
        Calibration pairs as magnitudes (deg): loaded bend angle and the pin
        command that produced it, averaged over repeats, sorted.
    domain_deg : (float, float)
        The calibrated loaded-angle range.
    """

    model: str
    direction: str
    loaded_deg: tuple[float, ...]
    pin_deg: tuple[float, ...]
    domain_deg: tuple[float, float]

    def pin_for_loaded_deg(self, loaded_deg: ArrayLike, *, outside: Outside = "raise") -> Any:
        """Pin command magnitude (deg) that bends the wire to ``loaded_deg`` (magnitude)."""
        a = np.asarray(loaded_deg, dtype=np.float64)
        x = _range_policy(np.atleast_1d(a), self.domain_deg, outside, "loaded angle")
        out = _interp_eval(self.model, np.asarray(self.loaded_deg), np.asarray(self.pin_deg), x)
        return float(out[0]) if a.ndim == 0 else out

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "direction": self.direction,
            "x": "loaded_deg",
            "y": "pin_deg",
            "loaded_deg": list(self.loaded_deg),
            "pin_deg": list(self.pin_deg),
            "domain_deg": list(self.domain_deg),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> MotionCurve:
        _check_model(d["model"], MOTION_MODELS, "motion")
        return cls(
            model=str(d["model"]),
            direction=str(d["direction"]),
            loaded_deg=tuple(float(v) for v in d["loaded_deg"]),
            pin_deg=tuple(float(v) for v in d["pin_deg"]),
            domain_deg=(float(d["domain_deg"][0]), float(d["domain_deg"][1])),
        )


def fit_motion(
    loaded_deg: ArrayLike,
    pin_deg: ArrayLike,
    *,
    model: MotionModel = "pchip",
    direction: str = "ccw",
) -> MotionCurve:
    """Fit one direction's motion function (loaded angle -> pin command, magnitudes, deg).

    Raises
    ------
    ValueError
        Unknown model, fewer than 2 distinct angles, or a pin command that does
        not increase with the loaded angle (the map must be invertible).
    """
    _check_model(model, MOTION_MODELS, "motion")
    la = np.abs(np.asarray(loaded_deg, dtype=np.float64).ravel())
    pa = np.abs(np.asarray(pin_deg, dtype=np.float64).ravel())
    if la.shape != pa.shape:
        raise ValueError("loaded_deg and pin_deg must have the same length")
    la, pa = _merge_repeats(la, pa)
    if len(la) < 2:
        raise ValueError(f"motion function needs at least 2 distinct angles ({direction})")
    if np.any(np.diff(pa) <= 0):
        raise ValueError(
            f"pin command does not increase with the loaded angle ({direction}); "
            "the motion function would not be invertible"
        )
    return MotionCurve(
        model=model,
        direction=direction,
        loaded_deg=tuple(float(v) for v in la),
        pin_deg=tuple(float(v) for v in pa),
        domain_deg=(float(la[0]), float(la[-1])),
    )


@dataclass(frozen=True)
class Compensation:
    """Springback compensation for both directions: wanted final angle -> pin command.

    Attributes
    ----------
    springback : dict of str to SpringbackCurve
        Per direction (``"ccw"``, ``"cw"``).
    motion : dict of str to MotionCurve
        Per direction.
    """

    springback: Mapping[str, SpringbackCurve]
    motion: Mapping[str, MotionCurve] = field(default_factory=dict)

    @property
    def model(self) -> str:
        """The springback model name."""
        return next(iter(self.springback.values())).model

    def domain_deg(self, direction: str) -> tuple[float, float]:
        """Calibrated final-angle range (magnitudes, deg) of one direction."""
        return self.springback[direction].domain_deg

    def loaded_for(self, target_final_deg: float, *, outside: Outside = "raise") -> float:
        """Signed loaded bend angle (deg) that springs back to ``target_final_deg`` (signed)."""
        if target_final_deg == 0:
            return 0.0
        direction = direction_of(target_final_deg)
        curve = self._curve(self.springback, direction, "springback")
        loaded = curve.loaded_for_final_deg(abs(target_final_deg), outside=outside)
        return float(np.copysign(loaded, target_final_deg))

    def compensate(self, target_final_deg: float, *, outside: Outside = "raise") -> float:
        """Signed pin command (deg) for the wanted signed final bend angle (deg).

        Zero maps to zero (no bend). Raises :class:`CompensationRangeError`
        outside the calibrated range unless ``outside`` says otherwise.
        """
        if target_final_deg == 0:
            return 0.0
        direction = direction_of(target_final_deg)
        loaded = self.loaded_for(target_final_deg, outside=outside)
        motion = self._curve(self.motion, direction, "motion")
        pin = motion.pin_for_loaded_deg(abs(loaded), outside=outside)
        return float(np.copysign(pin, target_final_deg))

    @staticmethod
    def _curve(curves: Mapping[str, Any], direction: str, what: str) -> Any:
        try:
            return curves[direction]
        except KeyError:
            raise CompensationRangeError(
                f"no {what} calibration for {direction} bends (have: {', '.join(curves) or 'none'})"
            ) from None

    def to_dict(self) -> dict[str, Any]:
        return {
            "springback": {
                "model": self.model,
                **{d: c.to_dict() for d, c in self.springback.items()},
            },
            "motion": {
                "model": next(iter(self.motion.values())).model if self.motion else None,
                **{d: c.to_dict() for d, c in self.motion.items()},
            },
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> Compensation:
        sb = {
            k: SpringbackCurve.from_dict(v) for k, v in d["springback"].items() if k in DIRECTIONS
        }
        mo = {k: MotionCurve.from_dict(v) for k, v in d["motion"].items() if k in DIRECTIONS}
        return cls(springback=sb, motion=mo)


def fit_compensation(
    commanded_pin_deg: ArrayLike,
    loaded_bend_deg: ArrayLike,
    unloaded_bend_deg: ArrayLike,
    *,
    model: SpringbackModel = "linear",
    motion_model: MotionModel = "pchip",
) -> Compensation:
    """Fit springback and motion curves for every direction present in the trials.

    Parameters
    ----------
    commanded_pin_deg, loaded_bend_deg, unloaded_bend_deg : array_like of shape (N,)
        Signed trial data (deg), as in the spec's trials CSV. The direction of
        a trial is the sign of its loaded bend angle.
    model, motion_model : str
        Springback and motion model names.

    Returns
    -------
    Compensation
    """
    pin = np.asarray(commanded_pin_deg, dtype=np.float64).ravel()
    loaded = np.asarray(loaded_bend_deg, dtype=np.float64).ravel()
    unloaded = np.asarray(unloaded_bend_deg, dtype=np.float64).ravel()
    if not (pin.shape == loaded.shape == unloaded.shape):
        raise ValueError("trial columns must have the same length")
    springback: dict[str, SpringbackCurve] = {}
    motion: dict[str, MotionCurve] = {}
    for direction in DIRECTIONS:
        sel = (loaded < 0) if direction == "cw" else (loaded > 0)
        if not np.any(sel):
            continue
        sign = -1.0 if direction == "cw" else 1.0
        springback[direction] = fit_springback(
            sign * unloaded[sel], sign * loaded[sel], model=model, direction=direction
        )
        motion[direction] = fit_motion(
            sign * loaded[sel], sign * pin[sel], model=motion_model, direction=direction
        )
    if not springback:
        raise ValueError("no bends with a non-zero loaded angle")
    return Compensation(springback=springback, motion=motion)
