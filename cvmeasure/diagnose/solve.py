"""The numerical steps of a fit: bounded least squares, forward differences, the
quantised drift's profile, standard errors and intervals.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize, special

from cvmeasure.diagnose.discrepancy import DISCREPANCY_BOUND_DEG, DISCREPANCY_P
from cvmeasure.diagnose.forms import (
    DRIFT_RATE_FACTORS,
    DRIFT_RATE_GRID,
    DRIFT_STEPS_DEG,
    FORMS,
    Shape,
)


def profile_interval(
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


#: Relative step of the forward differences (the square root of the float64 epsilon).
FD_REL_STEP = float(np.finfo(np.float64).eps ** 0.5)


def forward_difference_jacobian(
    fun: Any,
    x: NDArray[np.float64],
    lower: NDArray[np.float64],
    upper: NDArray[np.float64],
    *,
    many: Callable[[list[NDArray[np.float64]]], list[NDArray[np.float64]]] | None = None,
) -> NDArray[np.float64]:
    """Forward-difference Jacobian of ``fun`` at ``x`` within ``[lower, upper]``: the
    steps and arithmetic of scipy's ``least_squares(jac="2-point")`` (so the same
    numbers), without its per-call overhead, and ``fun(x)`` taken from the caller's
    cache of the point just evaluated. ``many(points)``: ``[fun(p) for p in points]``,
    the same numbers (e.g. from one vectorised simulation of every stepped point)."""
    x = np.asarray(x, dtype=np.float64)
    f0 = fun(x)
    sign = (x >= 0).astype(float) * 2 - 1
    h = FD_REL_STEP * sign * np.maximum(1.0, np.abs(x))
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
    points = []
    for i in range(x.size):
        x1 = np.copy(x)
        x1[i] = x[i] + h[i]
        points.append(x1)
    values = [fun(p) for p in points] if many is None else many(points)
    jac_t = np.empty((x.size, f0.size))
    for i in range(x.size):
        jac_t[i] = (values[i] - f0) / ((x[i] + h[i]) - x[i])
    return jac_t.T  # the layout scipy's own differences have


def whole_steps(cause: str, form: Shape) -> bool:
    """Whether a cause's form loses whole steps (residuals flat in its parameter)."""
    return cause == "drift" and bool(dict(form).get("step_deg"))


def solve_least_squares(
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


def profile_quantised_drift(
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
        [rate * DRIFT_RATE_FACTORS if rate > 0 else [], DRIFT_RATE_GRID if wide else []]
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
    fit = solve_least_squares(resid, x, lower, upper, scale, [index])
    x = fit.x.copy()
    fine = best[1] * (1.0 + np.linspace(-0.06, 0.06, 13))
    costs = [float(np.sum(r**2)) for r in rows(x, index, np.minimum(fine, upper[index]))]
    x[index] = min(float(fine[int(np.argmin(costs))]), upper[index])
    x = np.clip(x, lower + 1e-9 * span, upper - 1e-9 * span)
    fit = solve_least_squares(resid, x, lower, upper, scale, [index])
    if fit.cost < sol.cost:
        return fit
    forms[cause] = continuous
    return None


def standard_errors(
    jac: NDArray[np.float64],
    noise_var_deg2: float,
    basis: NDArray[np.float64],
    unfitted: NDArray[np.float64],
    residual_deg: NDArray[np.float64],
    noise_disc_deg2: float,
    *,
    clusters: NDArray[np.int_] | None = None,
    shared_deg: NDArray[np.float64] | None = None,
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

    ``shared_deg`` (observation rows; default the residuals): the residuals the sandwich
    is taken over (with the discrepancy profiled out of them, it sees only the errors
    shared beyond the model-form wave, which is counted by ``tau^2`` already).

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
            e = r[:n_obs] if shared_deg is None else shared_deg
            np.add.at(per.T, where, (a * e).T)
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
