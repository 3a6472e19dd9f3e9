"""The bounded model-form discrepancy: its form, its basis and its profile (deg)."""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from contextvars import ContextVar
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

from cvmeasure.contracts import TrialTable

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
    #: Legendre coefficients (deg, this form's degree and span) of the springback the
    #: learned baseline predicts beyond the simulation's (its loaded less its released
    #: curve, in bend magnitude): a springback asymmetry splits the wire's springback,
    #: which is the simulation's plus this (empty: the simulation's own;
    #: :func:`with_learned_springback`)
    springback_excess: tuple[float, ...] = ()
    #: ... and of its loaded curve: how far the loaded leg departs from the simulation's
    #: (empty: none learned)
    loaded_excess: tuple[float, ...] = ()


_DEFAULT_FORM = DiscrepancyForm()
FORM: ContextVar[DiscrepancyForm] = ContextVar("discrepancy_form", default=_DEFAULT_FORM)


@contextmanager
def discrepancy_form(form: DiscrepancyForm) -> Iterator[DiscrepancyForm]:
    """Every fit, profile and interval within the block uses ``form``."""
    token = FORM.set(form)
    try:
        yield form
    finally:
        FORM.reset(token)


def current_form() -> DiscrepancyForm:
    """The discrepancy's form in use (:func:`discrepancy_form`)."""
    return FORM.get()


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


def with_learned_springback(
    form: DiscrepancyForm, coefficients: Sequence[float]
) -> DiscrepancyForm:
    """``form`` with the springback excess of a baseline fitted in it (``coefficients``:
    that fit's discrepancy, loaded then released, deg): the loaded curve less the
    released one is the springback it predicts beyond the simulation's."""
    beta = np.asarray(coefficients, dtype=np.float64)
    m = form.degree + 1
    if beta.size != 2 * m:
        return form
    excess = beta[:m] - beta[m:]
    return replace(
        form,
        springback_excess=tuple(float(v) for v in excess),
        loaded_excess=tuple(float(v) for v in beta[:m]),
    )


def springback_excess_deg(commanded_pin_deg: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The learned baseline's springback beyond the simulation's (deg, > 0 for more) at
    each command, in the form in use; None when it has none."""
    form = FORM.get()
    if not form.springback_excess:
        return None
    return _legendre(commanded_pin_deg, form) @ np.asarray(form.springback_excess)


def loaded_excess_deg(commanded_pin_deg: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The learned baseline's loaded bend beyond the simulation's (deg, bend magnitude, > 0
    for more) at each command, in the form in use; None when it has none."""
    form = FORM.get()
    if not form.loaded_excess:
        return None
    return _legendre(commanded_pin_deg, form) @ np.asarray(form.loaded_excess)


def _legendre(commanded_pin_deg: NDArray[np.float64], form: DiscrepancyForm) -> NDArray[np.float64]:
    """(n, degree + 1) Legendre polynomials of the bend magnitudes mapped from the form's
    span onto [-1, 1]."""
    lo, hi = form.span_deg
    u = np.clip((np.abs(commanded_pin_deg) - lo) / ((hi - lo) / 2.0) - 1.0, -1.0, 1.0)
    return np.polynomial.legendre.legvander(u, form.degree)


def discrepancy_basis(trials: TrialTable) -> NDArray[np.float64]:
    """Design matrix (3 N, 2 (degree + 1)) of the discrepancy over stacked observations
    (the form in use: :func:`current_form`)."""
    form = FORM.get()
    n = len(trials)
    legendre = _legendre(trials.commanded_pin_deg, form)  # (n, d + 1)
    signed = trials.direction_sign[:, None] * legendre
    m = form.degree + 1
    out = np.zeros((3 * n, 2 * m))
    out[:n, :m] = signed
    out[n : 2 * n, m:] = signed
    return out


Factor = tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]]


def discrepancy_factor(basis: NDArray[np.float64]) -> Factor:
    """(columns used, q, R) of the QR factorisation of the discrepancy's used columns."""
    used = np.any(basis != 0, axis=0)
    if not used.any():
        return used, np.zeros((basis.shape[0], 0)), np.zeros((0, 0))
    q, tri = np.linalg.qr(basis[:, used])
    return used, q, tri


def profile_discrepancy(
    r: NDArray[np.float64], basis: NDArray[np.float64], factor: Factor | None = None
) -> NDArray[np.float64]:
    """Bounded least-squares discrepancy coefficients for residuals ``r`` (finite rows):
    the unconstrained solution when it lies within the bounds, else bounded-variable
    least squares. ``factor``: :func:`_discrepancy_factor` of ``basis``, when known."""
    bound = FORM.get().bound_deg
    beta = np.zeros(basis.shape[1])
    used, q, tri = factor if factor is not None else discrepancy_factor(basis)
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
