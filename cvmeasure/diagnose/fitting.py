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
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, special

from cvmeasure.contracts import BLOCKS, TrialTable
from cvmeasure.geometry import wrap_deg
from cvmeasure.sim.effects import EFFECTS, Effect
from cvmeasure.sim.model import apply_camera_tilt_deg, simulate, simulate_drift_rates
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


@dataclass(frozen=True)
class Nuisance:
    """A machine parameter fitted with every model (the user's own machine).

    Physical prior: normal about the nominal value with standard deviation
    ``prior_sd`` (a workshop tolerance), truncated to ``[lower, upper]``; it
    enters the least squares as one residual ``(v - nominal) / prior_sd *
    PRIOR_NOISE_DEG``.
    """

    key: str  # SimParams field
    lower: float
    upper: float
    prior_sd: float
    #: the value the bounds and the tolerance are given for (a DIWire's); a machine
    #: described with another value has them in proportion (:func:`nuisance_for`)
    reference: float = 1.0

    def scaled_to(self, value: float) -> Nuisance:
        """Bounds and tolerance of a machine whose nominal value is ``value``."""
        f = value / self.reference
        return dataclasses.replace(
            self, lower=self.lower * f, upper=self.upper * f, prior_sd=self.prior_sd * f
        )


#: Geometry fitted beside the strength: the die edge radius decides where the pin meets
#: the wire and the shape of the loaded angle along the bend. (The hardening law's
#: shape is left to the discrepancy: its exponent and the strength are not separable.)
#: Given for a DIWire's 1.5 mm die: 0.8-2.6 mm, tolerance 0.2 mm; another machine's
#: (the user's params) has them in proportion to its own radius.
NUISANCE: tuple[Nuisance, ...] = (Nuisance("die_radius_mm", 0.8, 2.6, 0.2, reference=1.5),)


def nuisance_for(params: SimParams) -> tuple[Nuisance, ...]:
    """:data:`NUISANCE` about the user's machine: bounds and prior in proportion to its
    nominal values, so that the diagnosis does not depend on the machine's size (a die
    of 4 mm is not pulled into a DIWire's 0.8-2.6 mm)."""
    return tuple(n.scaled_to(float(getattr(params, n.key))) for n in NUISANCE)


#: Angle noise (deg) that scales the priors' residuals (mid of the 0.02-0.1 deg range).
PRIOR_NOISE_DEG = 0.05
#: Machine parameters kept at their nominal values but not known exactly, with their
#: prior standard deviations: they are not fitted (a constant under-bend from the dead
#: zone and one from play lost on every bend are the same data unless the pin angle is
#: measured), but every interval widens by its parameter's correlation with them. The
#: dead zone (head rotation from home to first contact) is known to about 0.25 deg, the
#: root sum of squares of: the home switch's repeatability (0.1 deg); where it trips on
#: the user's machine (the firmware's 13.2 deg approach is a design constant, not a
#: calibration: a switch or flag placed within about 0.1 mm at the head's ~25 mm rim is
#: 0.2 deg); the contact angle's tolerances (a ground pin's radius within 0.01 mm,
#: 0.05 deg; the orbit radius within 0.05 mm, 0.09 deg; the wire's diameter within
#: 0.04 mm, drawn wire of 3 mm, 0.10 deg). It was 0.1 deg (the repeatability and the pin
#: alone): on the independent physical model (play lost on every bend) 24 of 32 backlash
#: intervals held the truth, 32 of 32 with 0.25 deg.
UNFITTED_PRIOR_SD: tuple[tuple[str, float], ...] = (("approach_deg", 0.25),)
#: The span's elastic bow is known, not fitted: beam theory gives the loaded leg's lead
#: over the tangent construction's chord, ``M l / (6 EI)`` (share 1: the moment falls
#: linearly from the die to the pin, the wire is clamped at the die), from the user's
#: geometry and material. Its share is known to about 0.2, the root sum of squares of:
#: the modulus (below), the wire's diameter (EI ~ d^4: 0.04 mm of 3 mm, 5 %), the span's
#: length (where the wire leaves the die's and the pin's rounded edges, +-0.5 mm of
#: 6-11 mm: 5-8 %), the partially plastic root at the die (the moment there is near the
#: plastic moment, and the curvature beyond the yield moment (0.59 M_p) is not elastic:
#: up to about 10 %) and the die's clamp (the wire's clearance in the die lets the span's
#: root turn: a few %). It is held at its value, not fitted (a fitted share ran to its
#: bounds and took up the causes' shapes), and marginalised in every interval like the
#: dead zone (only when the model has the bow: ``SimParams.span_bow_share`` > 0).
SPAN_BOW_SHARE_SD = 0.2
#: The wire's unloading (chord) modulus relative to the nominal Young's modulus: the
#: chord modulus of steel falls with plastic prestrain, by 5-20 % at the strains of a
#: bend (Morestin & Boivin, Nucl. Eng. Des. 162, 1996; Yoshida, Uemori & Fujiwara, Int.
#: J. Plast. 18, 2002), and a mill's wire is within a few % of the handbook's E: 0.1 of E.
#: Held at nominal, marginalised like the above (only with the bow: the idealised model
#: without it, which ``simulate`` makes by default, has its modulus exact). A lower
#: chord modulus is more springback for the same moment, which the fitted strength
#: meets with a larger moment, hence a larger predicted drive lag: the compliance's own
#: direction.
CHORD_MODULUS_SD = 0.1


def unfitted_priors(params: SimParams) -> tuple[tuple[str, float], ...]:
    """Machine parameters held at their values but marginalised, with their prior
    standard deviations (units of the field): :data:`UNFITTED_PRIOR_SD`, plus the bow's
    share and the chord modulus when the model has the span's bow."""
    if params.span_bow_share > 0:
        return (
            *UNFITTED_PRIOR_SD,
            ("span_bow_share", SPAN_BOW_SHARE_SD),
            ("youngs_modulus_mpa", CHORD_MODULUS_SD * params.youngs_modulus_mpa),
        )
    return UNFITTED_PRIOR_SD


#: Model-form discrepancy (Kennedy-O'Hagan style, bounded): the baseline of a simulation
#: that is not the machine leaves a smooth wave along the bend, the same in both
#: directions (the head is mirror-symmetric), its own for loaded and released angles.
#: It is ``s * sum_j beta_bj P_j(|cmd| / 90 - 1)`` (Legendre P_0..P_3, b = loaded,
#: released), each coefficient within +- DISCREPANCY_BOUND_DEG: large enough for the
#: model-form error of a fitted baseline (0.1-0.5 deg), too small for a catalogue cause
#: of typical size, which must therefore explain the excess. Causes are compared on
#: their residuals with the discrepancy profiled out (bounded least squares); their
#: parameters are fitted without it (inside its bounds it would absorb them).
DISCREPANCY_DEGREE = 3
DISCREPANCY_BOUND_DEG = 0.25
#: The data show a model-form error when the discrepancy's share of the residuals is
#: beyond the noise at this p-value (chi-square): the intervals then carry the
#: discrepancy's prior variance (see :func:`_standard_errors`).
DISCREPANCY_P = 0.01


@dataclass(frozen=True)
class DiscrepancyForm:
    """The model-form discrepancy's form: Legendre degree, coefficient bound (deg), the
    bend magnitudes (deg) mapped onto [-1, 1], and whether the causes are fitted with it
    profiled out (True) or without it (False: inside a small bound it would absorb them).

    The default is the bounded discrepancy of a baseline that is the machine's form
    (:data:`DISCREPANCY_DEGREE`, :data:`DISCREPANCY_BOUND_DEG` over 0-180 deg). A machine
    the simulation's form does not describe has its no-effect relation learned from the
    session instead (:func:`learned_form`)."""

    degree: int = DISCREPANCY_DEGREE
    bound_deg: float = DISCREPANCY_BOUND_DEG
    span_deg: tuple[float, float] = (0.0, 180.0)
    fit_with_causes: bool = False


_DEFAULT_FORM = DiscrepancyForm()
_FORM: ContextVar[DiscrepancyForm] = ContextVar("discrepancy_form", default=_DEFAULT_FORM)


@contextmanager
def discrepancy_form(form: DiscrepancyForm) -> Iterator[DiscrepancyForm]:
    """Every fit, profile and interval within the block uses ``form``."""
    token = _FORM.set(form)
    try:
        yield form
    finally:
        _FORM.reset(token)


def current_form() -> DiscrepancyForm:
    """The discrepancy's form in use (:func:`discrepancy_form`)."""
    return _FORM.get()


#: The learned no-effect curve: Legendre up to this degree in the bend magnitude (one
#: fewer than the session's distinct magnitudes) ...
LEARNED_DEGREE_MAX = 5
#: ... each coefficient within this share of the largest bend: a simulation whose form
#: misses the machine by more than a tenth of the bend is not a description of it.
LEARNED_BOUND_SHARE = 0.1


def learned_form(trials: TrialTable) -> DiscrepancyForm:
    """The no-effect relation learned from the session itself: a smooth curve in the
    bend magnitude, the same in both directions, for loaded and released angles (never
    the pin: the head's kinematics are the machine's whatever its material and dies),
    fitted as nuisance together with every cause. What it cannot absorb is what the
    catalogue's causes are tested on: the direction's sign (offset, backlash,
    asymmetry, axis offset, tilt), the order (drift) and the pin (the head's causes)."""
    mags = np.abs(np.asarray(trials.commanded_pin_deg, dtype=np.float64))
    distinct = np.unique(np.round(mags, 1))
    degree = int(min(LEARNED_DEGREE_MAX, max(distinct.size - 1, 1)))
    lo, hi = float(distinct.min()), float(distinct.max())
    if hi - lo < 1.0:
        lo, hi = 0.0, max(hi, 1.0)
    return DiscrepancyForm(
        degree=degree,
        bound_deg=LEARNED_BOUND_SHARE * hi,
        span_deg=(lo, hi),
        fit_with_causes=True,
    )


def discrepancy_basis(trials: TrialTable) -> NDArray[np.float64]:
    """Design matrix (3 N, 2 (degree + 1)) of the discrepancy over stacked observations
    (the form in use: :func:`current_form`)."""
    form = _FORM.get()
    n = len(trials)
    lo, hi = form.span_deg
    u = np.clip((np.abs(trials.commanded_pin_deg) - lo) / ((hi - lo) / 2.0) - 1.0, -1.0, 1.0)
    legendre = np.polynomial.legendre.legvander(u, form.degree)  # (n, d + 1)
    signed = trials.direction_sign[:, None] * legendre
    m = form.degree + 1
    out = np.zeros((3 * n, 2 * m))
    out[:n, :m] = signed
    out[n : 2 * n, m:] = signed
    return out


Factor = tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]


def _discrepancy_factor(basis: NDArray[np.float64]) -> Factor:
    """(columns used, q, R) of the QR factorisation of the discrepancy's used columns."""
    used = np.any(basis != 0, axis=0)
    if not used.any():
        return used, np.zeros((basis.shape[0], 0)), np.zeros((0, 0))
    q, tri = np.linalg.qr(basis[:, used])
    return used, q, tri


def _profile_discrepancy(
    r: NDArray[np.float64], basis: NDArray[np.float64], factor: Factor | None = None
) -> NDArray[np.float64]:
    """Bounded least-squares discrepancy coefficients for residuals ``r`` (finite rows):
    the unconstrained solution when it lies within the bounds, else bounded-variable
    least squares. ``factor``: :func:`_discrepancy_factor` of ``basis``, when known."""
    bound = _FORM.get().bound_deg
    beta = np.zeros(basis.shape[1])
    used, q, tri = factor if factor is not None else _discrepancy_factor(basis)
    if not used.any():
        return beta
    # ||r - a b||^2 = ||q^T r - R b||^2 + const (a = q R): the same minimisers on the
    # small triangular problem, whatever the number of rows
    qtr = q.T @ r
    sol = np.linalg.lstsq(tri, qtr, rcond=None)[0]
    if np.any(np.abs(sol) > bound):
        sol = optimize.lsq_linear(tri, qtr, bounds=(-bound, bound), method="bvls").x
    beta[used] = sol
    return beta


Causes = tuple[str, ...]
Shape = tuple[tuple[str, float], ...]

#: The forms of a cause that are tried (shape parameters, see cvmeasure.sim.effects); the
#: first is the spec's narrow form. The form whose grid point fits best is refined.
FORMS: dict[str, tuple[Shape, ...]] = {
    "backlash": ((), (("same_direction_share", 0.0),)),
    "drift": (
        (),
        (("home_shift", 1.0),),
        (("home_shift", 1.0), ("load_exponent", 1.0)),
    ),
    "camera_tilt": tuple((("tilt_axis_deg", float(a)),) if a else () for a in range(-75, 91, 15)),
}


#: Head steps (deg) a drift shifting home may lose whole (``step_deg``): after the fit with
#: a continuous home shift, its rate is profiled on a fine grid for each step size and the
#: quantised form is kept when it fits better (see :func:`_profile_quantised_drift`).
DRIFT_STEPS_DEG: tuple[float, ...] = (0.03, 0.06, 0.12)
#: Rates profiled for a quantised drift, as multiples of the continuous form's rate.
_DRIFT_RATE_FACTORS = np.linspace(0.4, 1.6, 25)
#: Rates (head deg per bend at the reference torque) profiled for a quantised drift
#: whatever the continuous form's rate: with whole steps the home shift of alternating
#: directions need not cancel (a loss of about half a step per bend loses a step on every
#: other bend, all one way on a sweep: a steady walk of home), so the continuous form's
#: rate (near 0, or several times the truth, on such plans) is no guide to it. 12 % apart;
#: the best point is profiled again on a fine grid about it (+-6 %).
_DRIFT_RATE_GRID = np.geomspace(0.01, 0.5, 35)

#: Continuous shape parameters of a form chosen from the grid of :data:`FORMS`, with the
#: standard deviation of the grid's rounding (uniform within half a step: step / sqrt(12)):
#: marginalised in every interval like the unfitted machine parameters.
FORM_PRIOR_SD: dict[str, tuple[tuple[str, float], ...]] = {
    "camera_tilt": (("tilt_axis_deg", 15.0 / math.sqrt(12.0)),),
    "drift": (("load_exponent", 1.0 / math.sqrt(12.0)),),
}


def _shape_bounds(cause: str, key: str) -> tuple[float, float]:
    """Bounds of a shape parameter of a cause (see cvmeasure.sim.effects)."""
    spec = EFFECTS[cause].shape_spec(key)
    return (spec.lower, spec.upper)


def _as_causes(causes: str | Sequence[str]) -> Causes:
    if isinstance(causes, str):
        return () if causes == "none" else (causes,)
    return tuple(c for c in causes if c != "none")


@dataclass(frozen=True)
class _Solution:
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
    #: where the solver ended (a fit on every trial without the discrepancy), for the folds
    solution: _Solution | None = field(default=None, repr=False, compare=False)
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
    def sigma_deg(self) -> float:
        """Residual standard deviation (degrees of freedom corrected)."""
        return math.sqrt(self.rss_deg2 / max(self.n_obs - self.n_params, 1))

    def effects(self) -> tuple[Effect, ...]:
        """The fitted effects (clipped to their physical bounds)."""
        return _effects((), self.causes, self.values, self.shapes)

    def params(self, base: SimParams) -> SimParams:
        """``base`` with the fitted material strength and nuisance geometry."""
        return _scaled(base, self.strength_scale, self.nuisance)

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
            out[ok] = r - basis @ _profile_discrepancy(r, basis)
        return out

    def rmse_after_discrepancy_deg(self, trials: TrialTable) -> float:
        """Held-out RMSE with the bounded model-form discrepancy profiled out (predicted
        from the other folds when it was fitted with the model there)."""
        r = self.residual_after_discrepancy_deg(trials)
        r = r[np.isfinite(r)]
        return float(np.sqrt(np.mean(r**2))) if r.size else math.nan

    def to_dict(self) -> dict[str, Any]:
        return {"causes": list(self.causes), "cv_rmse_deg": self.rmse_deg}


def _scaled(base: SimParams, scale: float, nuisance: Sequence[float] = ()) -> SimParams:
    extra = {n.key: float(v) for n, v in zip(NUISANCE, nuisance, strict=False)}
    return base.replace(yield_mpa=base.yield_mpa * scale, uts_mpa=base.uts_mpa * scale, **extra)


def _effects(
    base_effects: Sequence[Effect],
    causes: Causes,
    values: Sequence[float],
    shapes: Sequence[Shape] = (),
) -> tuple[Effect, ...]:
    kept = tuple(e for e in base_effects if e.name not in (*causes, "none"))
    forms = list(shapes) + [()] * (len(causes) - len(shapes))
    added = tuple(
        Effect(c, min(max(float(v), EFFECTS[c].lower), EFFECTS[c].upper), f)
        for c, v, f in zip(causes, values, forms, strict=True)
    )
    return (*kept, *added)


def predict(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: str | Sequence[str],
    strength_scale: float,
    values: Sequence[float] = (),
    *,
    nuisance: Sequence[float] = (),
    shapes: Sequence[Shape] = (),
    commanded_pin_deg: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Predicted observations of the trials under a model, stacked like
    :meth:`TrialTable.observations` (loaded, unloaded bend and pin angle, deg);
    ``commanded_pin_deg`` replaces the trials' commands (same order and history)."""
    res = simulate(
        trials.commanded_pin_deg if commanded_pin_deg is None else commanded_pin_deg,
        _scaled(params, strength_scale, nuisance),
        _effects(base_effects, _as_causes(causes), values, shapes),
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
    *,
    nuisance: Sequence[float] = (),
    discrepancy: Sequence[float] = (),
    shapes: Sequence[Shape] = (),
) -> NDArray[np.float64]:
    """Measured minus predicted, stacked by blocks (loaded, unloaded, pin); NaN = not measured."""
    predicted = predict(
        trials,
        params,
        base_effects,
        causes,
        strength_scale,
        values,
        nuisance=nuisance,
        shapes=shapes,
    )
    r = _observed_minus(trials, predicted)
    if len(discrepancy):
        r = r - discrepancy_basis(trials) @ np.asarray(discrepancy, dtype=np.float64)
    return r


#: Points whose residuals one fit keeps (a start grid has at most 12 x 9).
_MEMO_POINTS = 128


class _PointMemo:
    """Residual arrays of one fit keyed by the parameter point and the causes' forms,
    the oldest dropped beyond :data:`_MEMO_POINTS`; arrays are copied in and out."""

    def __init__(self) -> None:
        self._kept: dict[tuple[bytes, tuple[Shape, ...]], NDArray[np.float64]] = {}

    @staticmethod
    def _key(x: NDArray[np.float64], forms: Sequence[Shape]) -> tuple[bytes, tuple[Shape, ...]]:
        return np.asarray(x, dtype=np.float64).tobytes(), tuple(forms)

    def get(self, x: NDArray[np.float64], forms: Sequence[Shape]) -> NDArray[np.float64] | None:
        value = self._kept.get(self._key(x, forms))
        return None if value is None else value.copy()

    def put(
        self, x: NDArray[np.float64], forms: Sequence[Shape], value: NDArray[np.float64]
    ) -> None:
        if len(self._kept) >= _MEMO_POINTS:
            self._kept.pop(next(iter(self._kept)))
        self._kept[self._key(x, forms)] = value.copy()


def _observed_minus(trials: TrialTable, predicted: NDArray[np.float64]) -> NDArray[np.float64]:
    """Measured minus ``predicted`` (stacked by blocks along the last axis; leading axes:
    several predictions); pin angles wrapped as directions."""
    r = trials.observations() - predicted
    n = len(trials)
    r[..., 2 * n :] = wrap_deg(r[..., 2 * n :])  # pin angles are directions
    return r


def _drift_rate_residuals(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: Causes,
    x: NDArray[np.float64],
    m: int,
    index: int,
    rates: NDArray[np.float64],
    shapes: Sequence[Shape],
) -> NDArray[np.float64]:
    """(K, 3 N): :func:`residuals` at the point ``x`` of :func:`fit_model` (strength, ``m``
    nuisance values, the causes' values) with ``x[index]``, a drift's rate, at each of
    ``rates`` (clipped to the drift's bounds as :func:`_effects` clips it): the same
    numbers from one vectorised simulation (:func:`simulate_drift_rates`) instead of K."""
    spec = EFFECTS["drift"]
    effects = _effects(base_effects, causes, x[1 + m :], shapes)
    clipped = [min(max(float(v), spec.lower), spec.upper) for v in rates]
    res = simulate_drift_rates(
        trials.commanded_pin_deg,
        _scaled(params, x[0], x[1 : 1 + m]),
        effects,
        clipped,
        bend_index=trials.bend_index,
    )
    predicted = np.concatenate(
        [res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg], axis=-1
    )
    return _observed_minus(trials, predicted)


#: A measurement-stage cause: it changes only how the camera sees the simulated angles,
#: so the grid over it projects one simulation instead of simulating every grid point.
_CAMERA = "camera_tilt"


def _tilted(untilted: NDArray[np.float64], value: float, form: Shape) -> NDArray[np.float64]:
    """Predicted observations (stacked by blocks) of a simulation without camera tilt,
    seen by the camera of ``camera_tilt`` = ``value`` in ``form`` (what
    :func:`cvmeasure.sim.simulate` does with the effect on)."""
    spec = EFFECTS[_CAMERA]
    effect = Effect(_CAMERA, min(max(float(value), spec.lower), spec.upper), form)
    axis = effect.shape_value("tilt_axis_deg")
    tilt = float(effect.value)
    return np.concatenate(
        [apply_camera_tilt_deg(block, tilt, axis) for block in np.split(untilted, 3)]
    )


def _interval(
    center: float, se: float, dof: int, lo: float, hi: float, *, keep: float | None = None
) -> tuple[float, float]:
    """Student-t 95 % interval about ``center`` within ``[lo, hi]``; with ``keep`` (the
    reported estimate, when the interval's centre was moved by the pull of the unfitted
    parameters) the hull of the intervals about both.

    The centre's move is the joint fit's answer only if the model is right: the dead
    zone held at nominal also takes up model-form error along its own shape, and its
    pull then moves the centre the wrong way (a scale's centre moved 2.3 standard
    errors away from the truth on the independent model, the estimate held it). Neither
    fit is known to be the right one, so the interval holds both."""
    if not math.isfinite(se):
        return (lo, hi)
    t = float(special.stdtrit(max(dof, 1), 0.975))  # Student t quantile (no scipy.stats)
    a, b = center - t * se, center + t * se
    if keep is not None:
        a, b = min(a, keep - t * se), max(b, keep + t * se)
    return (max(a, lo), min(b, hi))


def fit_model(
    trials: TrialTable,
    params: SimParams,
    causes: str | Sequence[str] = "none",
    *,
    base_effects: Sequence[Effect] = (),
    start: ModelFit | tuple[float, Sequence[float]] | None = None,
    known: dict[str, float] | None = None,
    known_shapes: dict[str, Shape] | None = None,
    nuisance: bool = True,
    discrepancy: bool = False,
    rows: NDArray[np.bool_] | None = None,
    intervals: bool = True,
    _seed: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None,
) -> ModelFit:
    """Fit the strength scale, the nuisance geometry and the causes' parameters.

    Parameters
    ----------
    trials : TrialTable
        Measured bends.
    params : SimParams
        The simulation's nominal parameters (the nuisance start there).
    causes : str or sequence of str
        ``"none"`` (baseline: strength and nuisance only), an effect name, or several.
    base_effects : sequence of Effect
        Effects already known (from the params JSON), kept fixed.
    start : ModelFit or (strength_scale, values), optional
        Start point (skips the grid search), e.g. a full-data fit for CV folds.
    known : dict, optional
        Start values of some causes or nuisance parameters (e.g. from a previous
        round); the other causes start from the best point of a grid over their bounds.
    nuisance : bool
        Fit :data:`NUISANCE` (die radius, hardening exponent) within their
        physical bounds (True, default) or keep the nominal values.
    known_shapes : dict, optional
        The forms of causes given in ``known`` (the others: every form of
        :data:`FORMS` is tried on the grid, the best one refined).
    discrepancy : bool
        Fit with the bounded model-form discrepancy profiled out of every residual
        (False, default: the parameters are fitted without it, and the discrepancy
        is profiled from the final residuals for ``rss_discrepancy_deg2``).
    rows : bool array of shape (N,), optional
        Fit only these trials; the model still runs over every trial in order, so
        a bend's history (reversals, home shift) is that of the real sequence.
    intervals : bool
        Compute the intervals and the model-form p-value (True, default); False
        leaves them NaN (a cross-validation fold uses only the fitted values and
        the discrepancy, and the point estimate is the same).
    _seed : (x, residuals (3 N,), Jacobian (3 N, x.size)), optional
        The residuals and Jacobian already known at the point ``x`` (a fold started
        where the fit on every trial ended; see :class:`_Solution`).
    """
    learned = _FORM.get().fit_with_causes
    discrepancy = discrepancy or learned
    # the learned curve takes the material's and the geometry's shape: the strength and
    # the die radius are held at the user's values (fitted beside it they are not
    # separable from it and wander to their bounds)
    nuisance = nuisance and not learned
    names = _as_causes(causes)
    specs = [EFFECTS[c] for c in names]
    nuis = nuisance_for(params) if nuisance else ()
    m = len(nuis)

    keep = np.tile(np.ones(len(trials), dtype=bool) if rows is None else np.asarray(rows), 3)
    basis_all = discrepancy_basis(trials)[keep] if discrepancy else None

    forms: list[Shape] = [dict(known_shapes or {}).get(c, ()) for c in names]
    if isinstance(start, ModelFit) and len(start.shapes) == len(names):
        forms = list(start.shapes)

    def raw(x: NDArray[np.float64]) -> NDArray[np.float64]:
        return _residuals_full(x)[keep]

    # the points evaluated (the grid's best is the solver's start, its final point is
    # evaluated again below)
    seen = _PointMemo()
    seed_forms = tuple(forms)
    if _seed is not None:
        seen.put(_seed[0], seed_forms, _seed[1])

    def _residuals_full(x: NDArray[np.float64]) -> NDArray[np.float64]:
        known = seen.get(x, forms)
        if known is not None:
            return known
        out = residuals(
            trials,
            params,
            base_effects,
            names,
            x[0],
            x[1 + m :],
            nuisance=x[1 : 1 + m],
            shapes=forms,
        )
        seen.put(x, forms, out)
        return out

    prior_centre = np.array([float(getattr(params, n.key)) for n in nuis])
    prior_weight = np.array([PRIOR_NOISE_DEG / n.prior_sd for n in nuis])

    resid_seen = _PointMemo()
    factors: dict[bytes, Factor] = {}

    def with_priors(x: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
        """The least-squares residuals at ``x`` from its raw residuals ``r``."""
        ok = np.isfinite(r)
        prior = (x[1 : 1 + m] - prior_centre) * prior_weight
        if basis_all is None:
            return np.concatenate([r[ok], prior])
        basis = basis_all[ok]
        key = ok.tobytes()
        if key not in factors:  # the measured rows rarely change between points
            factors[key] = _discrepancy_factor(basis)
        beta = _profile_discrepancy(r[ok], basis, factors[key])
        return np.concatenate([r[ok] - basis @ beta, prior])

    def resid(x: NDArray[np.float64]) -> NDArray[np.float64]:
        known = resid_seen.get(x, forms)
        if known is not None:
            return known
        out = with_priors(x, raw(x))
        resid_seen.put(x, forms, out)
        return out

    def resid_rates(
        x: NDArray[np.float64], index: int, rates: NDArray[np.float64]
    ) -> list[NDArray[np.float64]]:
        """``resid`` at ``x`` with ``x[index]`` (a drift's rate) at each of ``rates``, the
        same numbers from one simulation for them all (a whole-step drift's profile)."""
        full = _drift_rate_residuals(trials, params, base_effects, names, x, m, index, rates, forms)
        out = []
        for v, row in zip(rates, full, strict=True):
            point = x.copy()
            point[index] = v
            out.append(with_priors(point, row[keep]))
        return out

    def fd_jac(x: NDArray[np.float64]) -> NDArray[np.float64]:
        if (
            _seed is not None
            and m == 0
            and tuple(forms) == seed_forms
            and x.tobytes() == _seed[0].tobytes()
        ):
            known_rows = _seed[2][keep][np.isfinite(raw(x))]
            if known_rows.shape[0] == resid(x).size and np.all(np.isfinite(known_rows)):
                return np.ascontiguousarray(known_rows.T).T  # the layout of the differences
        return _forward_difference_jacobian(resid, x, lower, upper)

    nominal = [float((known or {}).get(n.key, getattr(params, n.key))) for n in nuis]
    alternatives: list[tuple[int, float, Shape]] = []  # (index, start value, form)
    if isinstance(start, ModelFit):
        start_nuis = list(start.nuisance) if len(start.nuisance) == m else nominal
        x0 = np.array([start.strength_scale, *start_nuis, *start.values], dtype=np.float64)
    elif start is not None:
        x0 = np.array([start[0], *nominal, *start[1]], dtype=np.float64)
    else:
        known = known or {}
        x0 = np.array([1.0, *nominal] + [known.get(c, 0.0) for c in names], dtype=np.float64)
        x0[1 + m :] = np.clip(x0[1 + m :], [s.lower for s in specs], [s.upper for s in specs])
        for i, (c, spec) in enumerate(zip(names, specs, strict=True), start=1 + m):
            if c in known:
                continue
            grid = np.linspace(spec.lower, spec.upper, _GRID_POINTS)
            per_form = []
            untilted = None
            if c == _CAMERA:  # the rest of the model is the same at every grid point
                rest = [k for k in range(len(names)) if k != i - 1 - m]
                untilted = predict(
                    trials,
                    params,
                    [e for e in base_effects if e.name != _CAMERA],
                    [names[k] for k in rest],
                    x0[0],
                    [x0[1 + m + k] for k in rest],
                    nuisance=x0[1 : 1 + m],
                    shapes=[forms[k] for k in rest],
                )
            for form in FORMS.get(c, ((),)):
                forms[i - 1 - m] = form
                costs = []
                for v in grid:
                    x0[i] = v
                    if untilted is None:
                        r = resid(x0)
                    else:
                        full = _observed_minus(trials, _tilted(untilted, v, form))
                        seen.put(x0, forms, full)
                        r = with_priors(x0, full[keep])
                    costs.append(float(np.sum(r**2)))
                j = int(np.argmin(costs))
                per_form.append((costs[j], float(grid[j]), form))
            per_form.sort(key=lambda t: t[0])
            x0[i], forms[i - 1 - m] = per_form[0][1], per_form[0][2]
            if len(per_form) > 1:  # the grid is coarse: the runner-up form is refined too
                alternatives.append((i, per_form[1][1], per_form[1][2]))
    lower = np.array([_STRENGTH_BOUNDS[0], *(n.lower for n in nuis), *(s.lower for s in specs)])
    upper = np.array([_STRENGTH_BOUNDS[1], *(n.upper for n in nuis), *(s.upper for s in specs)])
    # keep the start strictly inside the bounds (least_squares requires it)
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    scale = np.array(
        [0.1, *(0.5 * n.prior_sd for n in nuis), *(max(abs(s.typical[1]), 1e-3) for s in specs)]
    )
    starts = [(x0, list(forms))]
    for i, v, form in alternatives:
        alt_x, alt_forms = x0.copy(), list(forms)
        alt_x[i], alt_forms[i - 1 - m] = v, form
        starts.append((np.clip(alt_x, lower + 1e-9 * span, upper - 1e-9 * span), alt_forms))
    sol, best_forms = None, list(forms)
    for x_start, f in starts:
        forms[:] = f
        frozen = [1 + m + i for i, c in enumerate(names) if _whole_steps(c, f[i])]
        frozen = [0, *frozen] if learned else frozen
        trial = _least_squares(resid, x_start, lower, upper, scale, frozen, jac=fd_jac)
        if sol is None or trial.cost < sol.cost:
            sol, best_forms = trial, list(f)
    forms[:] = best_forms
    assert sol is not None
    for i, c in enumerate(names):
        shape = dict(forms[i])
        # a drift alone, its form chosen on the grid here: every home-shifting form on an
        # absolute grid of rates too (beside another cause only the form it fitted, about
        # its rate: the absolute grid cost 0.1-0.3 s of CPU per fit at 100 trials rate by
        # rate; each form's grid in one simulation (resid_rates) it is ~0.03 s, but beside a
        # backlash there its two refits far from the fit cost 0.6 s: docs/diagnosis.md)
        wide = len(names) == 1 and start is None and c not in (known or {})
        if c == "drift" and not shape.get("step_deg") and (shape.get("home_shift") or wide):
            quantised = _profile_quantised_drift(
                resid, sol, 1 + m + i, forms, i, lower, upper, scale, wide=wide, rows=resid_rates
            )
            if quantised is not None:
                sol = quantised
    r = sol.fun
    r0 = raw(sol.x)
    ok = np.isfinite(r0)
    basis_ok = (basis_all if basis_all is not None else discrepancy_basis(trials)[keep])[ok]
    beta = _profile_discrepancy(r0[ok], basis_ok)
    rss_disc = float(np.sum((r0[ok] - basis_ok @ beta) ** 2))
    # the prior residuals are not observations; a general form's shape parameters were
    # chosen from the data too, so they count as parameters
    n_obs, n_par = r.size - m, sol.x.size + sum(len(f) for f in forms)
    if learned:  # the learned curve's coefficients are fitted parameters too
        n_par += int(np.any(basis_ok != 0, axis=0).sum())
    rss = float(np.sum(r**2))
    dof = n_obs - n_par
    solution = None
    if rows is None and basis_all is None:  # the folds of its cross-validation start here
        full = _residuals_full(sol.x)
        measured = np.isfinite(full)
        jac_full = np.full((full.size, sol.x.size), np.nan)
        jac_full[measured] = sol.jac[: int(measured.sum())]
        solution = _Solution(
            trials, params, tuple(base_effects), names, tuple(forms), sol.x.copy(), full, jac_full
        )
    point = ModelFit(  # the fitted point; its intervals follow unless not wanted
        causes=names,
        strength_scale=float(sol.x[0]),
        values=tuple(float(v) for v in sol.x[1 + m :]),
        intervals=tuple((math.nan, math.nan) for _ in names),
        strength_interval=(math.nan, math.nan),
        rss_deg2=rss,
        n_obs=n_obs,
        n_params=n_par,
        nuisance=tuple(float(v) for v in sol.x[1 : 1 + m]),
        shapes=tuple(forms),
        discrepancy=tuple(float(v) for v in beta),
        rss_discrepancy_deg2=rss_disc,
        solution=solution,
    )
    if not intervals:
        return dataclasses.replace(point, residual_deg=_residuals_full(sol.x))
    unfitted = []
    for key, sd in unfitted_priors(params):  # prediction change per prior sd
        moved = params.replace(**{key: float(getattr(params, key)) + sd})
        shifted = residuals(
            trials,
            moved,
            base_effects,
            names,
            sol.x[0],
            sol.x[1 + m :],
            nuisance=sol.x[1 : 1 + m],
            shapes=forms,
        )[keep]
        unfitted.append((r0 - shifted)[ok])
    for i, c in enumerate(names):  # a form's continuous shape, chosen from a grid
        for key, sd in FORM_PRIOR_SD.get(c, ()):
            shape = dict(forms[i])
            if c == "drift" and not shape.get("home_shift"):
                continue  # the load exponent is only tried with the home shift
            value = shape.get(key, 0.0)
            lo, hi = _shape_bounds(c, key)
            step = sd if value + sd <= hi or value - sd < lo else -sd  # inside the bounds
            shape[key] = value + step
            moved_forms = [*forms[:i], tuple(shape.items()), *forms[i + 1 :]]
            shifted = residuals(
                trials,
                params,
                base_effects,
                names,
                sol.x[0],
                sol.x[1 + m :],
                nuisance=sol.x[1 : 1 + m],
                shapes=moved_forms,
            )[keep]
            unfitted.append((r0 - shifted)[ok] * (sd / step))
    cols = np.column_stack(unfitted) if unfitted else np.zeros((int(ok.sum()), 0))
    # the noise left once the discrepancy is taken too (the residual variance of the
    # fit, rss / dof, also carries the model-form wave)
    k_disc = int(np.any(basis_ok != 0, axis=0).sum())
    noise_disc = rss_disc / max(dof - k_disc, 1)
    # clusters of observation rows (of r0[ok]) whose errors may be shared: the loaded and
    # released photo of one bend, and every bend of one repeated command (the model-form
    # error of an angle is the same for all its repeats)
    command = trials.commanded_pin_deg if rows is None else trials.commanded_pin_deg[rows]
    cluster = np.unique(np.round(command, 1), return_inverse=True)[1]
    jac = sol.jac
    for i, c in enumerate(names):
        if _whole_steps(c, forms[i]):
            # whole steps: the residuals are flat between steps; the rate's sensitivity is
            # the secant of the quantised form over half to 1.5 times the rate (the
            # expected change over many steps, the step's phase unknown). It was the
            # continuous form's derivative, which on a plan of alternating directions
            # (a sweep) is nearly nil, the home shifts cancelling, while the steps lost
            # whole do not cancel: sweeps with a drift
            # fitted at a held-out RMSE of 0.03-0.2 deg (baseline 0.5-1.5) had an interval
            # holding 0 and named nothing
            j = 1 + m + i
            rate = float(sol.x[j])
            lo_x, hi_x = sol.x.copy(), sol.x.copy()
            lo_x[j], hi_x[j] = 0.5 * rate, min(1.5 * rate, float(upper[j]))
            jac = np.array(jac, dtype=np.float64, copy=True)
            if hi_x[j] > lo_x[j]:
                jac[:, j] = (resid(hi_x) - resid(lo_x)) / (hi_x[j] - lo_x[j])
    if learned:
        # the curve was fitted with the causes (``jac`` is of the profiled residuals): the
        # unfitted priors count only off it, and it has no prior of its own to add
        q_disc = np.linalg.qr(basis_ok[:, np.any(basis_ok != 0, axis=0)])[0]
        cols = cols - q_disc @ (q_disc.T @ cols)
        basis_ok = np.zeros((basis_ok.shape[0], 0))
        jac = np.array(jac, dtype=np.float64, copy=True)
        jac[:, 0] = 0.0
    held = 1 if learned else 0  # the strength held: no column of its own
    se, shift, model_form_p = _standard_errors(
        jac[:, held:],
        rss / max(dof, 1),
        basis_ok,
        cols,
        r,
        noise_disc,
        clusters=np.tile(cluster, 3)[ok],
    )
    if held:
        se, shift = np.concatenate([[math.inf], se]), np.concatenate([[0.0], shift])
    center = sol.x + shift
    return dataclasses.replace(
        point,
        intervals=tuple(
            _interval(
                float(center[i]),
                float(se[i]),
                dof,
                spec.lower,
                spec.upper,
                keep=float(sol.x[i]),
            )
            for i, spec in enumerate(specs, start=1 + m)
        ),
        strength_interval=_interval(
            float(center[0]), float(se[0]), dof, *_STRENGTH_BOUNDS, keep=float(sol.x[0])
        ),
        model_form_p=model_form_p,
    )


#: Relative step of the forward differences (the square root of the float64 epsilon).
_FD_REL_STEP = float(np.finfo(np.float64).eps ** 0.5)


def _forward_difference_jacobian(
    fun: Any,
    x: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Forward-difference Jacobian of ``fun`` at ``x`` within ``[lower, upper]``: the
    steps and arithmetic of scipy's ``least_squares(jac="2-point")`` (so the same
    numbers), without its per-call overhead, and ``fun(x)`` taken from the caller's
    cache of the point just evaluated."""
    x = np.asarray(x, dtype=np.float64)
    f0 = fun(x)
    sign = (x >= 0).astype(float) * 2 - 1
    h = _FD_REL_STEP * sign * np.maximum(1.0, np.abs(x))
    # a step that would leave the bounds goes the other way (or to the far bound)
    lower_dist, upper_dist = x - lower, upper - x
    stepped = x + h
    violated = (stepped < lower) | (stepped > upper)
    fits = np.abs(h) <= np.maximum(lower_dist, upper_dist)
    h[violated & fits] *= -1
    forward = (upper_dist >= lower_dist) & ~fits
    h[forward] = upper_dist[forward]
    backward = (upper_dist < lower_dist) & ~fits
    h[backward] = -lower_dist[backward]
    jac_t = np.empty((x.size, f0.size))
    for i in range(x.size):
        x1 = np.copy(x)
        x1[i] = x[i] + h[i]
        jac_t[i] = (fun(x1) - f0) / ((x[i] + h[i]) - x[i])
    return jac_t.T  # the layout scipy's own differences have


def _whole_steps(cause: str, form: Shape) -> bool:
    """Whether a cause's form loses whole steps (residuals flat in its parameter)."""
    return cause == "drift" and bool(dict(form).get("step_deg"))


def _least_squares(
    resid: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    x0: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    scale: NDArray[np.float64],
    frozen: Sequence[int] = (),
    *,
    jac: Callable[[NDArray[np.float64]], NDArray[np.float64]] | None = None,
) -> optimize.OptimizeResult:
    """Bounded least squares (trf) with the parameters ``frozen`` held at ``x0`` (a
    drift losing whole steps: profiled on a grid, its residuals are flat between steps
    and a finite difference across a step would throw the solver); the result's ``x``
    and ``jac`` are full-width (zero columns for the frozen ones). ``jac``: the
    Jacobian of ``resid`` (default scipy's forward differences), used when nothing is
    frozen."""
    if not frozen:
        return optimize.least_squares(
            resid,
            x0,
            jac="2-point" if jac is None else jac,
            bounds=(lower, upper),
            x_scale=scale,
            method="trf",
            xtol=1e-9,
        )
    free = np.setdiff1d(np.arange(x0.size), frozen)
    full = x0.copy()

    def reduced(z: NDArray[np.float64]) -> NDArray[np.float64]:
        full[free] = z
        return resid(full)

    fit = optimize.least_squares(
        reduced,
        x0[free],
        bounds=(lower[free], upper[free]),
        x_scale=scale[free],
        method="trf",
        xtol=1e-9,
    )
    x = x0.copy()
    x[free] = fit.x
    jac = np.zeros((fit.jac.shape[0], x0.size))
    jac[:, free] = fit.jac
    fit.x, fit.jac = x, jac
    return fit


#: ``rows(x, index, rates)``: the least-squares residuals at ``x`` with ``x[index]`` at each
#: of ``rates`` (one array per rate).
RateResiduals = Callable[
    [NDArray[np.float64], int, NDArray[np.float64]], Sequence[NDArray[np.float64]]
]


def _per_rate(resid: Callable[[NDArray[np.float64]], NDArray[np.float64]]) -> RateResiduals:
    """:data:`RateResiduals` by one ``resid`` call per rate (the reference form)."""

    def rows(
        x: NDArray[np.float64], index: int, rates: NDArray[np.float64]
    ) -> list[NDArray[np.float64]]:
        out = []
        for v in rates:
            point = x.copy()
            point[index] = v
            out.append(resid(point))
        return out

    return rows


def _profile_quantised_drift(
    resid: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    sol: optimize.OptimizeResult,
    index: int,
    forms: list[Shape],
    cause: int,
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    scale: NDArray[np.float64],
    *,
    wide: bool = True,
    rows: RateResiduals | None = None,
) -> optimize.OptimizeResult | None:
    """The fit with the drift's steps lost whole, if it is better than ``sol`` (its
    continuous fit), else None; ``forms[cause]`` is set to the form kept. ``wide``:
    every home-shifting form and the absolute grid too (else the form fitted, about its
    rate, as before).

    Whole steps make the residuals flat in the rate between steps, so the rate is
    profiled on a grid for each step of :data:`DRIFT_STEPS_DEG` and each home-shifting
    form of :data:`FORMS` with
    the other parameters at the continuous fit: :data:`_DRIFT_RATE_FACTORS` times the
    continuous rate and the absolute :data:`_DRIFT_RATE_GRID`. The best point is
    refitted (the other parameters) and its rate profiled again on a finer grid about
    it. ``rows(x, index, rates)``: ``resid`` at ``x`` with ``x[index]`` at each rate (the
    grid's evaluations; default one ``resid`` call per rate)."""
    if rows is None:
        rows = _per_rate(resid)
    rate = float(sol.x[index])
    continuous = forms[cause]
    # every home-shifting form: the continuous forms cannot choose among them on a plan
    # where their home shifts cancel (on a sweep each is an offset, |cosine| > 0.99)
    bases = [f for f in FORMS["drift"] if dict(f).get("home_shift")] if wide else [continuous]
    if not wide and rate <= 0.0:
        return None
    rates = np.concatenate(
        [rate * _DRIFT_RATE_FACTORS if rate > 0 else [], _DRIFT_RATE_GRID if wide else []]
    )
    rates = np.minimum(rates, upper[index])
    best: tuple[float, float, Shape] | None = None
    for base in bases:
        for step in DRIFT_STEPS_DEG:
            forms[cause] = (*base, ("step_deg", step))
            for v, r in zip(rates, rows(sol.x, index, rates), strict=True):
                cost = float(np.sum(r**2))
                if best is None or cost < best[0]:
                    best = (cost, float(v), forms[cause])
    assert best is not None
    forms[cause] = best[2]
    span = upper - lower
    x = sol.x.copy()
    x[index] = best[1]
    x = np.clip(x, lower + 1e-9 * span, upper - 1e-9 * span)
    fit = _least_squares(resid, x, lower, upper, scale, [index])
    x = fit.x.copy()
    fine = best[1] * (1.0 + np.linspace(-0.06, 0.06, 13))
    costs = [float(np.sum(r**2)) for r in rows(x, index, np.minimum(fine, upper[index]))]
    x[index] = min(float(fine[int(np.argmin(costs))]), upper[index])
    x = np.clip(x, lower + 1e-9 * span, upper - 1e-9 * span)
    fit = _least_squares(resid, x, lower, upper, scale, [index])
    if fit.cost < sol.cost:
        return fit
    forms[cause] = continuous
    return None


def _standard_errors(
    jac: NDArray[np.float64],
    noise_var_deg2: float,
    basis: NDArray[np.float64],
    unfitted: NDArray[np.float64],
    residual_deg: NDArray[np.float64],
    noise_disc_deg2: float,
    *,
    clusters: NDArray[np.int_] | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64], float]:
    """Standard errors of the fitted parameters and the move of their centre, with what
    is not fitted carried (Kennedy-O'Hagan).

    ``jac`` (residual rows then prior rows) is the fit's Jacobian; ``residual_deg`` are the fit's
    residuals (the rows of ``jac``); ``unfitted`` (one
    column per parameter of :data:`UNFITTED_PRIOR_SD`, observation rows) the change of
    the predictions by one prior standard deviation of a machine parameter held at its
    nominal value. That parameter is *marginalised*: it joins the Gauss-Newton system
    as a column with its prior (unit precision per prior sd), so the parameters widen
    only by the part of it the data cannot tell from them (all of it for play lost on
    every bend, little for a scale), and the centre moves by the one Gauss-Newton step
    of the joint fit (the data's pull on it: the fit held it at nominal).

    The model-form discrepancy ``D beta`` (``basis`` over the observation rows) is a
    random bias with ``beta ~ N(0, tau^2 I)``: ``cov += tau^2 (A D)(A D)'``, ``A`` the
    estimator's sensitivity to the observations. ``tau^2`` by the method of moments on
    the fit's residuals ``r`` (which are ``P (D beta + e)``, ``P`` the projector off the
    fitted directions): ``E |Q'r|^2 = tau^2 tr(D'PD) + s^2 rank(Q)``, ``Q`` an orthonormal
    basis of ``PD`` and ``s^2 = noise_disc_deg2`` the noise left after the discrepancy;
    so the part of the discrepancy that the parameters absorbed is counted (it was the
    mean square of the profiled coefficients, which misses that part).

    ``clusters`` (one label per observation row) group rows whose errors may be shared
    (the two photos of a bend, the repeats of one command): the noise part of the
    variance is the larger of the model's (independent errors, ``s^2 A A'``) and the
    cluster-robust sandwich ``G / (G - 1) sum_g (A r_g)(A r_g)'`` (consistent whatever
    the errors' correlation within a cluster), so a shared photo error or the model-form
    error common to the repeats of an angle is carried.

    Returns (standard errors, centre moves), both of shape (n_par,), and the p-value of
    the discrepancy's energy under "no model-form error" (1 without a discrepancy).
    """
    n_par = jac.shape[1]
    n_obs = basis.shape[0]
    n_unf = unfitted.shape[1] if unfitted.size else 0
    # prediction sensitivities (the residual Jacobian is minus them), the unfitted
    # parameters in prior sd units with their prior rows scaled to the noise
    sens = np.zeros((jac.shape[0] + n_unf, n_par + n_unf))
    sens[: jac.shape[0], :n_par] = -jac
    if n_unf:
        sens[:n_obs, n_par:] = unfitted
        sens[jac.shape[0] :, n_par:] = math.sqrt(noise_var_deg2) * np.eye(n_unf)
    try:
        inv = np.linalg.inv(sens.T @ sens)
    except np.linalg.LinAlgError:
        return np.full(n_par, math.inf), np.zeros(n_par), 1.0
    var = np.diag(inv)[:n_par] * noise_var_deg2
    r = np.zeros(sens.shape[0])
    r[: jac.shape[0]] = residual_deg  # at the fit: only the unfitted columns pull
    shift = (inv @ (sens.T @ r))[:n_par]
    if clusters is not None and clusters.size == n_obs:
        a = (inv[:n_par] @ sens.T)[:, :n_obs]  # parameter change per unit observation
        model = noise_var_deg2 * np.sum(a**2, axis=1)
        labels, where = np.unique(clusters, return_inverse=True)
        if labels.size > 1:
            per = np.zeros((n_par, labels.size))
            np.add.at(per.T, where, (a * r[:n_obs]).T)
            robust = labels.size / (labels.size - 1.0) * np.sum(per**2, axis=1)
            var = var + np.maximum(robust - model, 0.0)
    used = np.any(basis != 0, axis=0)
    p_value = 1.0
    if used.any():
        d = np.zeros((sens.shape[0], int(used.sum())))
        d[:n_obs] = basis[:, used]
        q_fit = np.linalg.qr(sens)[0]
        pd = d - q_fit @ (q_fit.T @ d)  # the discrepancy off the fitted directions
        q, tri, *_ = np.linalg.svd(pd, full_matrices=False)
        keep = tri > 1e-9 * max(float(tri[0]), 1e-300)
        q = q[:, keep]
        trace = float(np.sum(pd**2))
        if trace > 0:
            energy = float(np.sum((q.T @ r) ** 2))
            rank = int(keep.sum())
            tau2 = max((energy - noise_disc_deg2 * rank) / trace, 0.0)
            # the data show a model-form error (the discrepancy's energy beyond the noise
            # at p < DISCREPANCY_P): the part of it along the parameters is absorbed and
            # cannot be measured, so the coefficients' variance is at least that of the
            # discrepancy's own prior (uniform within its bounds)
            p_value = float(special.chdtrc(rank, energy / max(noise_disc_deg2, 1e-300)))
            if p_value < DISCREPANCY_P:
                tau2 = max(tau2, DISCREPANCY_BOUND_DEG**2 / 3.0)
            a_d = inv @ (sens.T @ d)  # parameter shift per unit coefficient
            var = var + tau2 * np.sum(a_d[:n_par] ** 2, axis=1)
    return np.sqrt(np.maximum(var, 0.0)), shift, p_value


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
    discrepancy: bool = False,
) -> CrossValidation:
    """Held-out residuals: fit on all folds but one, predict the one, for every fold
    (with ``discrepancy``, the model and the bounded discrepancy are fitted together on
    the other folds and both predict the held-out one)."""
    discrepancy = discrepancy or _FORM.get().fit_with_causes
    names = _as_causes(causes)
    n = len(trials)
    n_blocks = len(BLOCKS)
    out = np.full(n_blocks * n, np.nan)
    out_d = np.full(n_blocks * n, np.nan)
    basis = discrepancy_basis(trials)
    # the nuisance geometry stays at its full-data fit within the folds (the same for
    # every model compared: the machine is measured once); strength and causes are refitted
    fold_params = _scaled(params, 1.0, full_fit.nuisance) if full_fit is not None else params
    seed = None
    state = full_fit.solution if full_fit is not None else None
    if (
        state is not None
        and not discrepancy
        and state.matches(trials, params, base_effects, names)
        and state.shapes == full_fit.shapes
    ):
        # the folds start where the fit on every trial ended (strength and causes; the
        # nuisance is held there): its residuals and Jacobian columns at that point
        cols = [0, *range(state.x.size - len(names), state.x.size)]
        seed = (state.x[cols], state.residual_deg, state.jacobian[:, cols])
    for held in folds:
        # fitted on the other folds and predicted on this one, the model running over
        # the whole sequence (history-dependent causes see the real order)
        fit = fit_model(
            trials,
            fold_params,
            names,
            base_effects=base_effects,
            start=full_fit,
            nuisance=False,
            discrepancy=discrepancy,
            rows=~held,
            intervals=False,  # only the fitted values and discrepancy are used
            _seed=seed,
        )
        r = (
            fit.residual_deg
            if fit.residual_deg is not None
            else fit.residuals(trials, fold_params, base_effects)
        )
        mask = np.tile(held, n_blocks)
        out[mask] = r[mask]
        out_d[mask] = (r - basis @ np.asarray(fit.discrepancy))[mask]
    if _FORM.get().fit_with_causes:
        # the learned curve is the machine's no-effect relation, a nuisance like its
        # geometry: held at its fit on every trial (profiled from the held-out residuals
        # together), the causes are what is held out
        ok = np.isfinite(out)
        out_d = np.full_like(out, np.nan)
        out_d[ok] = out[ok] - basis[ok] @ _profile_discrepancy(out[ok], basis[ok])
        out = out_d
    return CrossValidation(
        causes=names, residual_deg=out, residual_discrepancy_deg=out_d if discrepancy else None
    )
