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
from cvmeasure.diagnose.discrepancy import DISCREPANCY_BOUND_DEG as DISCREPANCY_BOUND_DEG
from cvmeasure.diagnose.discrepancy import DISCREPANCY_DEGREE as DISCREPANCY_DEGREE
from cvmeasure.diagnose.discrepancy import DISCREPANCY_P as DISCREPANCY_P
from cvmeasure.diagnose.discrepancy import FORM, profile_discrepancy
from cvmeasure.diagnose.discrepancy import DiscrepancyForm as DiscrepancyForm
from cvmeasure.diagnose.discrepancy import current_form as current_form
from cvmeasure.diagnose.discrepancy import discrepancy_basis as discrepancy_basis
from cvmeasure.diagnose.discrepancy import discrepancy_form as discrepancy_form
from cvmeasure.diagnose.discrepancy import learned_form as learned_form
from cvmeasure.diagnose.discrepancy import with_learned_springback as with_learned_springback
from cvmeasure.diagnose.forms import (
    ALONE_FORMS,
    STRENGTH_BOUNDS,
    Shape,
    as_causes,
    nuisance_for,
    on_grid,
    shape_bounds,
    shape_priors,
)
from cvmeasure.diagnose.forms import DRIFT_RATE_GRID as DRIFT_RATE_GRID
from cvmeasure.diagnose.forms import FORMS as FORMS
from cvmeasure.diagnose.model_fit import CrossValidation, ModelFit
from cvmeasure.diagnose.predict import (
    drift_rate_residuals,
    predict,
    residuals,
    scaled,
)
from cvmeasure.diagnose.problem import (
    Fitted,
    Problem,
    fitted_point,
    profile_drifts,
    solve_problem,
    start_vector,
    whole_step_secants,
)
from cvmeasure.diagnose.shapes import refine_shapes
from cvmeasure.diagnose.solve import FD_REL_STEP
from cvmeasure.diagnose.solve import profile_interval as profile_interval
from cvmeasure.diagnose.solve import standard_errors as standard_errors
from cvmeasure.sim.effects import Effect, effect_spec_for
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
#: prior standard deviations. The estimate holds them at nominal; the intervals fit them
#: with this prior (a Gaussian prior row in the Gauss-Newton system:
#: :func:`~cvmeasure.diagnose.solve.standard_errors`), so each interval widens by what
#: the data leave of them, its posterior: on a calibration session (pin readings, noise
#: 0.02-0.1 deg) the dead zone is left 0.02-0.05 of its prior sd beside a scale, 0.2-0.35
#: beside a compliance, and those intervals are still 2 and 3-4 times the ones with it
#: known (their signatures are in part a constant under-bend's).
#: Beside play lost on every bend it keeps its whole prior: a dead zone longer by ``b``
#: and that play are the same data, the pin readings too (the photo reads the head's
#: angle, which both move alike: the session's readings agree to 1e-14 deg). The
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
    learned = FORM.get().fit_with_causes
    discrepancy = discrepancy or learned
    # the learned curve takes the material's and the geometry's shape: the strength and
    # the die radius are held at the user's values (fitted beside it they are not
    # separable from it and wander to their bounds)
    nuisance = nuisance and not learned
    names = as_causes(causes)
    forms: list[Shape] = [dict(known_shapes or {}).get(c, ()) for c in names]
    if isinstance(start, ModelFit) and len(start.shapes) == len(names):
        forms = list(start.shapes)
    if len(names) > 1:
        # in a pair these keep their narrow form (see ALONE_FORMS), and a shape refined
        # alone goes back on the grid (see cvmeasure.diagnose.shapes.refine_shapes)
        forms = [
            () if c in ALONE_FORMS else on_grid(c, f) for c, f in zip(names, forms, strict=True)
        ]
    problem = Problem(
        trials,
        params,
        base_effects,
        names,
        [effect_spec_for(c, params) for c in names],
        nuisance_for(params) if nuisance else (),
        forms,
        rows=rows,
        discrepancy=discrepancy,
        seed=_seed,
        drift_rates=drift_rate_residuals,
    )
    x0, alternatives = start_vector(problem, start, known)
    sol = solve_problem(problem, x0, alternatives, learned)
    searched = {c for c in names if start is None and c not in (known or {})}
    sol = profile_drifts(problem, sol, searched)
    sol = refine_shapes(problem, sol, searched, learned)
    point, fitted = fitted_point(problem, sol, learned)
    if not intervals:
        return dataclasses.replace(point, residual_deg=problem.full(sol.x))
    return _with_intervals(problem, point, fitted, learned)


def learned_baseline_form(
    trials: TrialTable, params: SimParams, base_effects: Sequence[Effect] = ()
) -> DiscrepancyForm:
    """The learned no-effect curve's form (:func:`learned_form`) with the springback its
    baseline (no cause, fitted in that form) predicts beyond the simulation's: a
    springback asymmetry then splits the wire's springback as learned, whatever its mean
    (a wire stronger one way whose mean springback is off the description's is still an
    asymmetry; see :func:`~cvmeasure.diagnose.predict.learned_split`)."""
    form = learned_form(trials)
    with discrepancy_form(form):
        base = fit_model(trials, params, "none", base_effects=base_effects, intervals=False)
    return with_learned_springback(form, base.discrepancy)


def _unfitted_columns(problem: Problem, fitted: Fitted) -> NDArray[np.float64]:
    """(observation rows, one column per prior): the change of the residuals per prior
    standard deviation of each machine parameter held at its value
    (:func:`unfitted_priors`) and of each form's continuous shape chosen from a grid
    (:func:`~cvmeasure.diagnose.forms.shape_priors`)."""
    trials, params, names, forms = problem.trials, problem.params, problem.names, problem.forms
    lay, x, keep, ok, r0 = problem.layout, fitted.sol.x, problem.keep, fitted.ok, fitted.raw_deg
    unfitted = []
    for key, sd in unfitted_priors(params):
        # the predictions' derivative per prior sd, by the forward step the fit's own
        # Jacobian takes: a parameter that moves the predictions as a fitted one does
        # (the dead zone and play lost on every bend) then has that one's column, and its
        # prior is carried whole. A secant over a whole sd is another column where the
        # model bends within it (a contact starting, a yield): play of 1.4 deg then read
        # the dead zone as pinned by the data and gave an interval 10 times too narrow.
        value = float(getattr(params, key))
        h = FD_REL_STEP * max(1.0, abs(value))
        moved = params.replace(**{key: value + h})
        shifted = residuals(
            trials,
            moved,
            problem.base_effects,
            names,
            x[lay.strength],
            x[lay.causes],
            nuisance=x[lay.nuisance],
            shapes=forms,
        )[keep]
        unfitted.append((r0 - shifted)[ok] * (sd / h))
    for i, c in enumerate(names):  # a form's continuous shape (grid or refined)
        for key, sd, diff in shape_priors(c, len(names)):
            shape = dict(forms[i])
            if c == "drift" and not shape.get("home_shift"):
                continue  # the load exponent is only tried with the home shift
            value = shape.get(key, 0.0)
            lo, hi = shape_bounds(c, key)
            step = diff if value + diff <= hi or value - diff < lo else -diff  # inside bounds
            shape[key] = value + step
            moved_forms = [*forms[:i], tuple(shape.items()), *forms[i + 1 :]]
            shifted = residuals(
                trials,
                params,
                problem.base_effects,
                names,
                x[lay.strength],
                x[lay.causes],
                nuisance=x[lay.nuisance],
                shapes=moved_forms,
            )[keep]
            unfitted.append((r0 - shifted)[ok] * (sd / step))
    return np.column_stack(unfitted) if unfitted else np.zeros((int(ok.sum()), 0))


def _with_intervals(problem: Problem, point: ModelFit, fitted: Fitted, learned: bool) -> ModelFit:
    """``point`` with its 95 % intervals and model-form p-value, what is not fitted carried
    (:func:`~cvmeasure.diagnose.solve._standard_errors`)."""
    sol, basis_ok, dof, lay = fitted.sol, fitted.basis_ok, fitted.dof, problem.layout
    cols = _unfitted_columns(problem, fitted)
    # the noise left once the discrepancy is taken too (the residual variance of the
    # fit, rss / dof, also carries the model-form wave)
    k_disc = int(np.any(basis_ok != 0, axis=0).sum())
    noise_disc = fitted.rss_discrepancy_deg2 / max(dof - k_disc, 1)
    # clusters of observation rows (of r0[ok]) whose errors may be shared: the loaded and
    # released photo of one bend, and every bend of one repeated command (the model-form
    # error of an angle is the same for all its repeats)
    rows, trials = problem.rows, problem.trials
    command = trials.commanded_pin_deg if rows is None else trials.commanded_pin_deg[rows]
    cluster = np.unique(np.round(command, 1), return_inverse=True)[1]
    jac = whole_step_secants(problem, sol)
    if learned:
        # the curve was fitted with the causes (``jac`` is of the profiled residuals): the
        # unfitted priors count only off it, and it has no prior of its own to add
        q_disc = np.linalg.qr(basis_ok[:, np.any(basis_ok != 0, axis=0)])[0]
        cols = cols - q_disc @ (q_disc.T @ cols)
        basis_ok = np.zeros((basis_ok.shape[0], 0))
        jac = np.array(jac, dtype=np.float64, copy=True)
        jac[:, lay.strength] = 0.0
    held = 1 if learned else 0  # the strength held: no column of its own
    args = (jac[:, held:], fitted.rss_deg2 / max(dof, 1), basis_ok, cols, sol.fun, noise_disc)
    clusters = np.tile(cluster, 3)[fitted.ok]
    se, shift, model_form_p = standard_errors(*args, clusters=clusters)
    measured = se
    if model_form_p < DISCREPANCY_P and not learned:
        # the model-form wave counted once: by the discrepancy's variance (tau^2), not
        # also as noise (rss / dof holds it) and as an error shared by repeated commands
        r_ok = fitted.raw_deg[fitted.ok]
        profiled = r_ok - basis_ok @ profile_discrepancy(r_ok, basis_ok)
        measured = standard_errors(
            jac[:, held:], noise_disc, *args[2:], clusters=clusters, shared_deg=profiled
        )[0]
    if held:
        se, shift = np.concatenate([[math.inf], se]), np.concatenate([[0.0], shift])
        measured = np.concatenate([[math.inf], measured])
    center = sol.x + shift
    s = lay.strength

    def cause_intervals(errors: NDArray[np.float64]) -> tuple[tuple[float, float], ...]:
        return tuple(
            profile_interval(
                float(center[i]),
                float(errors[i]),
                dof,
                spec.lower,
                spec.upper,
                keep=float(sol.x[i]),
            )
            for i, spec in ((lay.cause(k), spec) for k, spec in enumerate(problem.specs))
        )

    return dataclasses.replace(
        point,
        intervals=cause_intervals(se),
        intervals_measured=cause_intervals(measured),
        strength_interval=profile_interval(
            float(center[s]), float(se[s]), dof, *STRENGTH_BOUNDS, keep=float(sol.x[s])
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
    discrepancy = discrepancy or FORM.get().fit_with_causes
    names = as_causes(causes)
    n = len(trials)
    n_blocks = len(BLOCKS)
    out = np.full(n_blocks * n, np.nan)
    out_d = np.full(n_blocks * n, np.nan)
    basis = discrepancy_basis(trials)
    # the nuisance geometry stays at its full-data fit within the folds (the same for
    # every model compared: the machine is measured once); strength and causes are refitted
    fold_params = scaled(params, 1.0, full_fit.nuisance) if full_fit is not None else params
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
    if FORM.get().fit_with_causes:
        # the learned curve is the machine's no-effect relation, a nuisance like its
        # geometry: held at its fit on every trial (profiled from the held-out residuals
        # together), the causes are what is held out
        ok = np.isfinite(out)
        out_d = np.full_like(out, np.nan)
        out_d[ok] = out[ok] - basis[ok] @ profile_discrepancy(out[ok], basis[ok])
        out = out_d
    return CrossValidation(
        causes=names, residual_deg=out, residual_discrepancy_deg=out_d if discrepancy else None
    )
