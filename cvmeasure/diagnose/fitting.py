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

import numpy as np
from numpy.typing import NDArray
from scipy import special as special

from cvmeasure.contracts import BLOCKS, TrialTable
from cvmeasure.diagnose.discrepancy import _FORM, Factor, _discrepancy_factor, _profile_discrepancy
from cvmeasure.diagnose.discrepancy import DISCREPANCY_BOUND_DEG as DISCREPANCY_BOUND_DEG
from cvmeasure.diagnose.discrepancy import DISCREPANCY_DEGREE as DISCREPANCY_DEGREE
from cvmeasure.diagnose.discrepancy import DISCREPANCY_P as DISCREPANCY_P
from cvmeasure.diagnose.discrepancy import DiscrepancyForm as DiscrepancyForm
from cvmeasure.diagnose.discrepancy import current_form as current_form
from cvmeasure.diagnose.discrepancy import discrepancy_basis as discrepancy_basis
from cvmeasure.diagnose.discrepancy import discrepancy_form as discrepancy_form
from cvmeasure.diagnose.discrepancy import learned_form as learned_form
from cvmeasure.diagnose.forms import _DRIFT_RATE_GRID as _DRIFT_RATE_GRID
from cvmeasure.diagnose.forms import (
    _GRID_POINTS,
    _STRENGTH_BOUNDS,
    FORM_PRIOR_SD,
    PRIOR_NOISE_DEG,
    Shape,
    _as_causes,
    _shape_bounds,
    nuisance_for,
)
from cvmeasure.diagnose.forms import FORMS as FORMS
from cvmeasure.diagnose.model_fit import CrossValidation, ModelFit, _Solution
from cvmeasure.diagnose.predict import (
    _CAMERA,
    _drift_rate_residuals,
    _observed_minus,
    _PointMemo,
    _scaled,
    _tilted,
    predict,
    residuals,
)
from cvmeasure.diagnose.solve import (
    _forward_difference_jacobian,
    _least_squares,
    _profile_quantised_drift,
    _whole_steps,
)
from cvmeasure.diagnose.solve import _interval as _interval
from cvmeasure.diagnose.solve import _standard_errors as _standard_errors
from cvmeasure.sim.effects import EFFECTS, Effect
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
