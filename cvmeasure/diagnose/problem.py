"""One fit's least-squares problem over the packed parameter vector
(:class:`~cvmeasure.diagnose.forms.ParamLayout`): its residuals, its start on a grid and
its solution from each start (the steps :func:`~cvmeasure.diagnose.fitting.fit_model`
calls)."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.discrepancy import (
    Factor,
    discrepancy_basis,
    discrepancy_factor,
    profile_discrepancy,
)
from cvmeasure.diagnose.forms import (
    ALONE_FORMS,
    GRID_POINTS,
    LEARNED_SHAPE_KEYS,
    PRIOR_NOISE_DEG,
    STRENGTH_BOUNDS,
    Causes,
    Nuisance,
    ParamLayout,
    Shape,
    forms_of,
)
from cvmeasure.diagnose.model_fit import ModelFit, Solution
from cvmeasure.diagnose.predict import (
    CAMERA,
    PointMemo,
    observed_minus,
    predict,
    residual_rows,
    residuals,
    tilted_curve,
)
from cvmeasure.diagnose.solve import (
    forward_difference_jacobian,
    profile_quantised_drift,
    solve_least_squares,
    whole_steps,
)
from cvmeasure.sim.effects import Effect
from cvmeasure.sim.params import SimParams

#: ``(x, residuals (3 N,), Jacobian (3 N, x.size))`` already known at a point ``x``
Seed = tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]
#: the model's residuals (3 N,) at ``x`` with ``x[index]`` at each of ``rates``
#: (:func:`~cvmeasure.diagnose.predict._drift_rate_residuals`)
DriftRates = Callable[..., NDArray[np.float64]]


class Problem:
    """One fit's least squares over ``x`` (:class:`ParamLayout`): the residuals at a point
    (each point simulated once), with the nuisance priors appended and the discrepancy
    profiled out when fitted with it, and their Jacobian. ``forms`` (each cause's form)
    is changed in place as forms are tried."""

    def __init__(
        self,
        trials: TrialTable,
        params: SimParams,
        base_effects: Sequence[Effect],
        names: Causes,
        specs: Sequence[Any],
        nuis: Sequence[Nuisance],
        forms: list[Shape],
        *,
        rows: NDArray[np.bool_] | None,
        discrepancy: bool,
        seed: Seed | None,
        drift_rates: DriftRates,
    ) -> None:
        self.trials, self.params, self.base_effects = trials, params, base_effects
        self.names, self.specs, self.nuis = names, specs, nuis
        self.layout = ParamLayout(len(nuis))
        self.forms = forms
        self.rows = rows
        self.keep = np.tile(
            np.ones(len(trials), dtype=bool) if rows is None else np.asarray(rows), 3
        )
        self.basis_all = discrepancy_basis(trials)[self.keep] if discrepancy else None
        self.seed, self.seed_forms = seed, tuple(forms)
        self.drift_rates = drift_rates
        # the points evaluated (the grid's best is the solver's start, its final point is
        # evaluated again after the solver)
        self.seen = PointMemo()
        if seed is not None:
            self.seen.put(seed[0], self.seed_forms, seed[1])
        self.resid_seen = PointMemo()
        self.factors: dict[bytes, Factor] = {}
        self.prior_centre = np.array([float(getattr(params, n.key)) for n in nuis])
        self.prior_weight = np.array([PRIOR_NOISE_DEG / n.prior_sd for n in nuis])
        self.lower = np.array(
            [STRENGTH_BOUNDS[0], *(n.lower for n in nuis), *(s.lower for s in specs)]
        )
        self.upper = np.array(
            [STRENGTH_BOUNDS[1], *(n.upper for n in nuis), *(s.upper for s in specs)]
        )
        self.scale = np.array(
            [0.1, *(0.5 * n.prior_sd for n in nuis), *(max(abs(s.typical[1]), 1e-3) for s in specs)]
        )

    def full(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Measured minus predicted over every trial (3 N,) at ``x``."""
        known = self.seen.get(x, self.forms)
        if known is not None:
            return known
        lay = self.layout
        out = residuals(
            self.trials,
            self.params,
            self.base_effects,
            self.names,
            x[lay.strength],
            x[lay.causes],
            nuisance=x[lay.nuisance],
            shapes=self.forms,
        )
        self.seen.put(x, self.forms, out)
        return out

    def raw(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """:meth:`full` on the fitted rows."""
        return self.full(x)[self.keep]

    def with_priors(self, x: NDArray[np.float64], r: NDArray[np.float64]) -> NDArray[np.float64]:
        """The least-squares residuals at ``x`` from its raw residuals ``r``."""
        ok = np.isfinite(r)
        prior = (x[self.layout.nuisance] - self.prior_centre) * self.prior_weight
        if self.basis_all is None:
            return np.concatenate([r[ok], prior])
        basis = self.basis_all[ok]
        key = ok.tobytes()
        if key not in self.factors:  # the measured rows rarely change between points
            self.factors[key] = discrepancy_factor(basis)
        beta = profile_discrepancy(r[ok], basis, self.factors[key])
        return np.concatenate([r[ok] - basis @ beta, prior])

    def resid(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """The least-squares residuals at ``x``."""
        known = self.resid_seen.get(x, self.forms)
        if known is not None:
            return known
        out = self.with_priors(x, self.raw(x))
        self.resid_seen.put(x, self.forms, out)
        return out

    def resid_rates(
        self, x: NDArray[np.float64], index: int, rates: NDArray[np.float64]
    ) -> list[NDArray[np.float64]]:
        """:meth:`resid` at ``x`` with ``x[index]`` (a drift's rate) at each of ``rates``,
        the same numbers from one simulation for them all (a whole-step drift's profile)."""
        full = self.drift_rates(
            self.trials,
            self.params,
            self.base_effects,
            self.names,
            x,
            self.layout.n_nuisance,
            index,
            rates,
            self.forms,
        )
        out = []
        for v, row in zip(rates, full, strict=True):
            point = x.copy()
            point[index] = v
            out.append(self.with_priors(point, row[self.keep]))
        return out

    def fd_jac(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        """Jacobian of :meth:`resid` at ``x`` (the seed's rows when ``x`` is its point)."""
        seed = self.seed
        if (
            seed is not None
            and self.layout.n_nuisance == 0
            and tuple(self.forms) == self.seed_forms
            and x.tobytes() == seed[0].tobytes()
        ):
            known_rows = seed[2][self.keep][np.isfinite(self.raw(x))]
            if known_rows.shape[0] == self.resid(x).size and np.all(np.isfinite(known_rows)):
                return np.ascontiguousarray(known_rows.T).T  # the layout of the differences
        return forward_difference_jacobian(
            self.resid, x, self.lower, self.upper, many=self.resid_many
        )

    def resid_many(self, points: list[NDArray[np.float64]]) -> list[NDArray[np.float64]]:
        """:meth:`resid` at each of ``points``, the same numbers: the points not yet
        known (a forward difference's steps) from one vectorised simulation
        (:func:`residual_rows`)."""
        lay, forms = self.layout, self.forms
        new = [
            p
            for p in points
            if self.resid_seen.get(p, forms) is None and self.seen.get(p, forms) is None
        ]
        if len(new) > 1:  # (one point: the plain simulation)
            try:
                rows = residual_rows(
                    self.trials,
                    self.params,
                    self.base_effects,
                    self.names,
                    [(p[lay.strength], p[lay.causes], p[lay.nuisance]) for p in new],
                    shapes=self.forms,
                )
            except ValueError:
                rows = None  # rows that cannot share a simulation: one by one
            for p, row in zip(new, () if rows is None else rows, strict=False):
                self.seen.put(p, forms, row)
        return [self.resid(p) for p in points]


#: An alternative start: (cause index, its value, its form).
Alternative = tuple[int, float, Shape]


def start_vector(
    problem: Problem,
    start: ModelFit | tuple[float, Sequence[float]] | None,
    known: dict[str, float] | None,
) -> tuple[NDArray[np.float64], list[Alternative]]:
    """The solver's start (see :func:`~cvmeasure.diagnose.fitting.fit_model`): ``start``
    as given, or each cause not ``known`` at the best point of its grid
    (:func:`_grid_start`), and the runner-up forms as alternative starts."""
    lay, names, specs = problem.layout, problem.names, problem.specs
    params = problem.params
    nominal = [float((known or {}).get(n.key, getattr(params, n.key))) for n in problem.nuis]
    alternatives: list[Alternative] = []
    if isinstance(start, ModelFit):
        start_nuis = list(start.nuisance) if len(start.nuisance) == lay.n_nuisance else nominal
        x0 = np.array([start.strength_scale, *start_nuis, *start.values], dtype=np.float64)
    elif start is not None:
        x0 = np.array([start[0], *nominal, *start[1]], dtype=np.float64)
    else:
        known = known or {}
        x0 = np.array([1.0, *nominal] + [known.get(c, 0.0) for c in names], dtype=np.float64)
        x0[lay.causes] = np.clip(x0[lay.causes], [s.lower for s in specs], [s.upper for s in specs])
        for k, c in enumerate(names):
            if c in known:
                continue
            alternatives.extend(_grid_start(problem, x0, k))
    return x0, alternatives


def _grid_start(problem: Problem, x0: NDArray[np.float64], k: int) -> list[Alternative]:
    """Cause ``k``'s value in ``x0`` and its form in ``problem.forms`` set to the best
    point of a grid over its bounds, each form of :func:`~cvmeasure.diagnose.forms.forms_of`
    tried; the other forms' best points to refine too: the runner-up's (none with one
    form), or every one beside the learned curve's forms."""
    lay, names, forms = problem.layout, problem.names, problem.forms
    c, spec, i = names[k], problem.specs[k], lay.cause(k)
    grid = np.linspace(spec.lower, spec.upper, GRID_POINTS)
    per_form = []
    untilted = None
    if c == CAMERA:  # the rest of the model is the same at every grid point
        rest = [j for j in range(len(names)) if j != k]
        untilted = predict(
            problem.trials,
            problem.params,
            [e for e in problem.base_effects if e.name != CAMERA],
            [names[j] for j in rest],
            x0[lay.strength],
            [x0[lay.cause(j)] for j in rest],
            nuisance=x0[lay.nuisance],
            shapes=[forms[j] for j in rest],
        )
    tried = ((),) if c in ALONE_FORMS and len(names) > 1 else forms_of(c)
    for form in tried:
        forms[k] = form
        costs = []
        for v in grid:
            x0[i] = v
            if untilted is None:
                r = problem.resid(x0)
            else:
                full = observed_minus(problem.trials, tilted_curve(untilted, v, form))
                problem.seen.put(x0, forms, full)
                r = problem.with_priors(x0, full[problem.keep])
            costs.append(float(np.sum(r**2)))
        best = int(np.argmin(costs))
        per_form.append((costs[best], float(grid[best]), form))
    per_form.sort(key=lambda t: t[0])
    x0[i], forms[k] = per_form[0][1], per_form[0][2]
    if any(set(dict(f)) & LEARNED_SHAPE_KEYS for f in tried):
        # beside the learned curve's forms every form is refined: on the coarse grid a
        # form with the learned departure can rank before the simulation's own at a value
        # between grid points, and the refined costs decide
        return [(k, v, form) for _, v, form in per_form[1:]]
    # the grid is coarse: the runner-up form is refined too
    out = [(k, v, form) for _, v, form in per_form[1:2]]
    return out


def solve_problem(
    problem: Problem,
    x0: NDArray[np.float64],
    alternatives: Sequence[Alternative],
    learned: bool,
) -> optimize.OptimizeResult:
    """Bounded least squares from ``x0`` and from each alternative start, the lowest cost
    kept and ``problem.forms`` left at its forms (the strength held with the learned
    curve)."""
    lay, forms = problem.layout, problem.forms
    lower, upper = problem.lower, problem.upper
    # keep the start strictly inside the bounds (least_squares requires it)
    span = upper - lower
    x0 = np.clip(x0, lower + 1e-9 * span, upper - 1e-9 * span)
    starts = [(x0, list(forms))]
    for k, v, form in alternatives:
        alt_x, alt_forms = x0.copy(), list(forms)
        alt_x[lay.cause(k)], alt_forms[k] = v, form
        starts.append((np.clip(alt_x, lower + 1e-9 * span, upper - 1e-9 * span), alt_forms))
    sol, best_forms = None, list(forms)
    for x_start, f in starts:
        forms[:] = f
        frozen = [lay.cause(k) for k, c in enumerate(problem.names) if whole_steps(c, f[k])]
        frozen = [lay.strength, *frozen] if learned else frozen
        trial = solve_least_squares(
            problem.resid, x_start, lower, upper, problem.scale, frozen, jac=problem.fd_jac
        )
        if sol is None or trial.cost < sol.cost:
            sol, best_forms = trial, list(f)
    forms[:] = best_forms
    assert sol is not None
    return sol


def profile_drifts(
    problem: Problem, sol: optimize.OptimizeResult, searched: set[str]
) -> optimize.OptimizeResult:
    """``sol`` with a drift's steps lost whole when that fits better
    (:func:`~cvmeasure.diagnose.solve._profile_quantised_drift`). ``searched``: the
    causes whose form was chosen on the grid here (no start given, not known)."""
    names = problem.names
    for k, c in enumerate(names):
        shape = dict(problem.forms[k])
        # a drift alone, its form chosen on the grid here: every home-shifting form on an
        # absolute grid of rates too (beside another cause only the form it fitted, about
        # its rate: the absolute grid cost 0.1-0.3 s of CPU per fit at 100 trials rate by
        # rate; each form's grid in one simulation (resid_rates) it is ~0.03 s, but beside a
        # backlash there its two refits far from the fit cost 0.6 s: docs/diagnosis.md)
        wide = len(names) == 1 and c in searched
        if c == "drift" and not shape.get("step_deg") and (shape.get("home_shift") or wide):
            quantised = profile_quantised_drift(
                problem.resid,
                sol,
                problem.layout.cause(k),
                problem.forms,
                k,
                problem.lower,
                problem.upper,
                problem.scale,
                wide=wide,
                rows=problem.resid_rates,
            )
            if quantised is not None:
                sol = quantised
    return sol


@dataclass(frozen=True)
class Fitted:
    """The fitted point's numbers the intervals need beside its :class:`ModelFit`."""

    sol: optimize.OptimizeResult
    raw_deg: NDArray[np.float64]  # measured minus predicted on the fitted rows
    ok: NDArray[np.bool_]  # the measured ones of those
    basis_ok: NDArray[np.float64]  # the discrepancy's basis on those
    rss_deg2: float  # of the least-squares residuals (priors included)
    rss_discrepancy_deg2: float
    dof: int


def fitted_point(
    problem: Problem, sol: optimize.OptimizeResult, learned: bool
) -> tuple[ModelFit, Fitted]:
    """The fitted point as a :class:`ModelFit` (intervals NaN) and its numbers."""
    lay, forms = problem.layout, problem.forms
    r = sol.fun
    r0 = problem.raw(sol.x)
    ok = np.isfinite(r0)
    basis_all = problem.basis_all
    basis_ok = (
        basis_all if basis_all is not None else discrepancy_basis(problem.trials)[problem.keep]
    )[ok]
    beta = profile_discrepancy(r0[ok], basis_ok)
    rss_disc = float(np.sum((r0[ok] - basis_ok @ beta) ** 2))
    # the prior residuals are not observations; a general form's shape parameters were
    # chosen from the data too, so they count as parameters
    n_obs, n_par = r.size - lay.n_nuisance, sol.x.size + sum(len(f) for f in forms)
    if learned:  # the learned curve's coefficients are fitted parameters too
        n_par += int(np.any(basis_ok != 0, axis=0).sum())
    rss = float(np.sum(r**2))
    solution = None
    if problem.rows is None and basis_all is None:  # the folds of its CV start here
        full = problem.full(sol.x)
        measured = np.isfinite(full)
        jac_full = np.full((full.size, sol.x.size), np.nan)
        jac_full[measured] = sol.jac[: int(measured.sum())]
        solution = Solution(
            problem.trials,
            problem.params,
            tuple(problem.base_effects),
            problem.names,
            tuple(forms),
            sol.x.copy(),
            full,
            jac_full,
        )
    point = ModelFit(
        causes=problem.names,
        strength_scale=float(sol.x[lay.strength]),
        values=tuple(float(v) for v in sol.x[lay.causes]),
        intervals=tuple((math.nan, math.nan) for _ in problem.names),
        strength_interval=(math.nan, math.nan),
        rss_deg2=rss,
        n_obs=n_obs,
        n_params=n_par,
        nuisance=tuple(float(v) for v in sol.x[lay.nuisance]),
        shapes=tuple(forms),
        discrepancy=tuple(float(v) for v in beta),
        rss_discrepancy_deg2=rss_disc,
        solution=solution,
    )
    return point, Fitted(sol, r0, ok, basis_ok, rss, rss_disc, n_obs - n_par)


def whole_step_secants(problem: Problem, sol: optimize.OptimizeResult) -> NDArray[np.float64]:
    """The solution's Jacobian with a whole-step drift's rate column replaced by a secant."""
    jac = sol.jac
    for k, c in enumerate(problem.names):
        if whole_steps(c, problem.forms[k]):
            # whole steps: the residuals are flat between steps; the rate's sensitivity is
            # the secant of the quantised form over half to 1.5 times the rate (the
            # expected change over many steps, the step's phase unknown). It was the
            # continuous form's derivative, which on a plan of alternating directions
            # (a sweep) is nearly nil, the home shifts cancelling, while the steps lost
            # whole do not cancel: sweeps with a drift
            # fitted at a held-out RMSE of 0.03-0.2 deg (baseline 0.5-1.5) had an interval
            # holding 0 and named nothing
            j = problem.layout.cause(k)
            rate = float(sol.x[j])
            lo_x, hi_x = sol.x.copy(), sol.x.copy()
            lo_x[j], hi_x[j] = 0.5 * rate, min(1.5 * rate, float(problem.upper[j]))
            jac = np.array(jac, dtype=np.float64, copy=True)
            if hi_x[j] > lo_x[j]:
                jac[:, j] = (problem.resid(hi_x) - problem.resid(lo_x)) / (hi_x[j] - lo_x[j])
    return jac
