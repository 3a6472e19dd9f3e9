"""A cause's continuous shape refined off the grid of forms (the tilt's axis, the loaded
leg an asymmetric wire moves).

The grid of :data:`~cvmeasure.diagnose.forms.FORMS` picks a cause's form in coarse steps
(the tilt's axis every 15 deg, the asymmetric wire's loaded leg every 1 deg per unit of
asymmetry). For a cause of typical size that rounding leaves a misfit far beyond the
noise: a 25 deg tilt about an axis 5 deg off the nearest grid point misses by about
0.4 deg rms, and the lack-of-fit test then refuses the machine although the catalogue's
cause, in its own form, describes it. The shape is a parameter of the cause's physics
(:mod:`cvmeasure.sim.effects`), so it is fitted: profiled within one grid step of the
grid's choice, the causes and the nuisance refitted at the profile's best.
"""

from __future__ import annotations

import numpy as np
from scipy import optimize

from cvmeasure.diagnose.forms import REFINED_SHAPES, shape_bounds
from cvmeasure.diagnose.problem import Problem
from cvmeasure.diagnose.solve import solve_least_squares, whole_steps

#: Profile tolerance, as a share of the grid's step.
_XATOL_SHARE = 0.02


def refine_shapes(
    problem: Problem, sol: optimize.OptimizeResult, searched: set[str], learned: bool
) -> optimize.OptimizeResult:
    """``sol`` with a searched cause's continuous shape (:data:`REFINED_SHAPES`) fitted
    within one grid step of its grid point (a profile: every other parameter refitted
    at each value of the shape), when that lowers the cost; ``problem.forms`` left at
    the forms of the returned solution. ``searched``: the causes whose shape is fitted
    here (a fit started from another keeps that fit's shape: a cross-validation fold is
    not re-shaped; refitting it on each fold's bends moved the held-out RMSE by under
    1 % where it was tried, at half again the CPU of a diagnosis).

    Only a cause fitted alone is refined. Beside a second cause the shape takes up that
    cause's own signature: the tilt's axis turns the tilt's error curve along the bend
    angle, and with an offset or a scale refitted at each axis a small tilt about an
    axis a grid step away describes the model-form error of another machine's bend (on
    an offset-only machine a 4 deg tilt was named beside the offset, its axis at the
    window's edge, the offset pulled off the truth). In a pair the grid's form is kept,
    its rounding carried in the intervals (:func:`~cvmeasure.diagnose.forms.shape_priors`),
    as a narrow form is (:data:`~cvmeasure.diagnose.forms.ALONE_FORMS`)."""
    if len(problem.names) != 1:
        return sol
    if problem.names[0] in REFINED_SHAPES and problem.names[0] in searched:
        sol = _profile_shape(problem, sol, 0, learned)
    return sol


def _profile_shape(
    problem: Problem, sol: optimize.OptimizeResult, k: int, learned: bool
) -> optimize.OptimizeResult:
    """Cause ``k``'s shape profiled within one grid step of its grid value (bounded
    scalar search; at each value every other parameter refitted from the best point so
    far): the profile's best when it is below ``sol``'s cost (``problem.forms`` set to
    it), else ``sol`` (forms unchanged). The shape and the cause's size are strongly
    correlated (an asymmetric wire's loaded leg moves by the product), so refitting at
    each value finds the optimum where alternating the two would crawl along the valley."""
    c = problem.names[k]
    key, step = REFINED_SHAPES[c]
    lo, hi = shape_bounds(c, key)
    before = list(problem.forms)
    shape = dict(before[k])
    value = float(shape.get(key, 0.0))
    lay = problem.layout
    frozen = [lay.cause(j) for j, n in enumerate(problem.names) if whole_steps(n, before[j])]
    frozen = [lay.strength, *frozen] if learned else frozen
    span = problem.upper - problem.lower
    best: dict[str, object] = {"sol": sol, "form": before[k]}

    def cost(v: float) -> float:
        problem.forms[k] = tuple({**shape, key: float(v)}.items())
        start = best["sol"].x  # type: ignore[attr-defined]
        x0 = np.clip(start, problem.lower + 1e-9 * span, problem.upper - 1e-9 * span)
        fit = solve_least_squares(
            problem.resid,
            x0,
            problem.lower,
            problem.upper,
            problem.scale,
            frozen,
            jac=problem.fd_jac,
        )
        if fit.cost < best["sol"].cost:  # type: ignore[attr-defined]
            best["sol"], best["form"] = fit, problem.forms[k]
        return float(fit.cost)

    optimize.minimize_scalar(
        cost,
        bounds=(max(lo, value - step), min(hi, value + step)),
        method="bounded",
        options={"xatol": _XATOL_SHARE * step},
    )
    problem.forms[:] = before
    problem.forms[k] = best["form"]  # type: ignore[assignment]
    return best["sol"]  # type: ignore[return-value]
