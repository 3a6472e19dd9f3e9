"""What a fit varies: the material strength, the machine's nuisance geometry, and each
cause's parameter and grid of shapes.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from cvmeasure.sim.effects import EFFECTS
from cvmeasure.sim.params import SimParams

STRENGTH_BOUNDS = (0.2, 5.0)
GRID_POINTS = 9


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
    "springback_asymmetry": ((), (("loaded_deg", -1.0),), (("loaded_deg", 1.0),)),
    "camera_tilt": tuple((("tilt_axis_deg", float(a)),) if a else () for a in range(-75, 91, 15)),
}


#: Causes whose general form is tried only alone: the loaded leg an asymmetric wire moves
#: by direction would also take up a second cause's own difference by direction (a
#: compliance's lag under a pin torque that differs by direction), so in a pair the
#: narrow form is kept and the two stay told apart by that difference.
ALONE_FORMS: frozenset[str] = frozenset({"springback_asymmetry"})

#: Head steps (deg) a drift shifting home may lose whole (``step_deg``): after the fit with
#: a continuous home shift, its rate is profiled on a fine grid for each step size and the
#: quantised form is kept when it fits better (see :func:`_profile_quantised_drift`).
DRIFT_STEPS_DEG: tuple[float, ...] = (0.03, 0.06, 0.12)
#: Rates profiled for a quantised drift, as multiples of the continuous form's rate.
DRIFT_RATE_FACTORS = np.linspace(0.4, 1.6, 25)
#: Rates (head deg per bend at the reference torque) profiled for a quantised drift
#: whatever the continuous form's rate: with whole steps the home shift of alternating
#: directions need not cancel (a loss of about half a step per bend loses a step on every
#: other bend, all one way on a sweep: a steady walk of home), so the continuous form's
#: rate (near 0, or several times the truth, on such plans) is no guide to it. 12 % apart;
#: the best point is profiled again on a fine grid about it (+-6 %).
DRIFT_RATE_GRID = np.geomspace(0.01, 0.5, 35)

#: Continuous shape parameters of a form chosen from the grid of :data:`FORMS`, with the
#: standard deviation of the grid's rounding (uniform within half a step: step / sqrt(12)):
#: marginalised in every interval like the unfitted machine parameters.
FORM_PRIOR_SD: dict[str, tuple[tuple[str, float], ...]] = {
    "drift": (("load_exponent", 1.0 / math.sqrt(12.0)),),
}

#: Continuous shapes fitted off the grid (:mod:`cvmeasure.diagnose.shapes`), each with its
#: grid's step: in a cause fitted alone the shape is profiled within one step of the
#: grid's choice (in a pair it stays on the grid, see :func:`refine_shapes`). In the
#: intervals such a shape counts as a fitted parameter: it is marginalised with a prior sd
#: of one step (weak: the data decide it), so the cause's interval carries the shape's
#: own uncertainty (the two are correlated: an asymmetric wire's loaded leg moves by the
#: product of the shape and the asymmetry).
REFINED_SHAPES: dict[str, tuple[str, float]] = {
    "camera_tilt": ("tilt_axis_deg", 15.0),
    "springback_asymmetry": ("loaded_deg", 1.0),
}
#: Finite-difference step of a refined shape's column, as a share of its prior sd.
SHAPE_DIFF_SHARE = 0.1


def shape_priors(cause: str, n_causes: int) -> tuple[tuple[str, float, float], ...]:
    """(shape key, prior sd, finite-difference step) of each of ``cause``'s continuous
    shapes carried in the intervals, in a fit of ``n_causes`` causes: a shape refined off
    the grid in a cause fitted alone (:data:`REFINED_SHAPES`), or the grid's rounding
    (uniform within half a step, differenced over one sd: :data:`FORM_PRIOR_SD`, and a
    refined shape's grid in a pair, where it is not refined); none for a form held
    narrow in a pair (:data:`ALONE_FORMS`)."""
    if cause in REFINED_SHAPES:
        key, step = REFINED_SHAPES[cause]
        if n_causes == 1:
            return ((key, step, SHAPE_DIFF_SHARE * step),)
        if cause in ALONE_FORMS:
            return ()
        return ((key, step / math.sqrt(12.0), step / math.sqrt(12.0)),)
    return tuple((key, sd, sd) for key, sd in FORM_PRIOR_SD.get(cause, ()))


def on_grid(cause: str, shape: Shape) -> Shape:
    """``shape`` with a shape refined off the grid (:data:`REFINED_SHAPES`) put back on
    the nearest form of :data:`FORMS` (the form used in a pair, where shapes are not
    refined); any other shape unchanged."""
    if cause not in REFINED_SHAPES:
        return shape
    key, _ = REFINED_SHAPES[cause]
    value = dict(shape).get(key, 0.0)
    return min(FORMS[cause], key=lambda form: abs(dict(form).get(key, 0.0) - value))


def shape_bounds(cause: str, key: str) -> tuple[float, float]:
    """Bounds of a shape parameter of a cause (see cvmeasure.sim.effects)."""
    spec = EFFECTS[cause].shape_spec(key)
    return (spec.lower, spec.upper)


def as_causes(causes: str | Sequence[str]) -> Causes:
    if isinstance(causes, str):
        return () if causes == "none" else (causes,)
    return tuple(c for c in causes if c != "none")


@dataclass(frozen=True)
class ParamLayout:
    """Where each parameter sits in a fit's packed vector ``x`` (the solver's): the
    strength scale, then the nuisance geometry (:data:`NUISANCE`, ``n_nuisance`` of
    them), then each cause's value (units of its effect)."""

    n_nuisance: int
    #: index of the strength scale (fitted yield / nominal yield)
    strength: int = 0

    @property
    def nuisance(self) -> slice:
        """The nuisance geometry's values."""
        return slice(1, 1 + self.n_nuisance)

    @property
    def causes(self) -> slice:
        """The causes' values, in the order of the causes."""
        return slice(1 + self.n_nuisance, None)

    def cause(self, k: int) -> int:
        """Index of the ``k``-th cause's value."""
        return 1 + self.n_nuisance + k
