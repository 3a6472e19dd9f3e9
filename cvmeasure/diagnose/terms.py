"""Terms outside the catalogue against the named causes: the causes refitted with the
discrepancy, the terms left beside them, and order-dependent terms that tie them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray
from scipy import optimize

from cvmeasure.diagnose.discover import RIVAL_PERIODS, Discovery, discover, library, term_words
from cvmeasure.diagnose.fitting import (
    ModelFit,
    current_form,
    discrepancy_basis,
    fit_model,
    grouped_kfold_cv,
)
from cvmeasure.diagnose.identify import CONFOUNDED_SIMILARITY
from cvmeasure.diagnose.rules import Context, bic_gain, typical_size

if TYPE_CHECKING:
    pass


def kept_against_terms(
    ctx: Context, fit: ModelFit, base_fit: ModelFit, groups: Sequence[str]
) -> tuple[float, float] | None:
    """Held-out RMSE (deg) and delta BIC of ``fit``'s causes refitted with the
    discrepancy, or None when so fitted a cause is below its typical size
    (:func:`_typical_size`) or the library still finds a term in their residuals."""
    joint, joint_cv, joint_bic = _joint_with_discrepancy(ctx, fit, base_fit)
    if not typical_size(joint, ctx.params):
        return None
    left = terms_beside(
        ctx, joint, joint.residuals(ctx.trials, ctx.params, ctx.base_effects), groups
    )
    if any(t.term != "scatter" for t in left.terms):
        return None
    return joint_cv, joint_bic


def terms_beside(
    ctx: Context, fit: ModelFit, residual_deg: NDArray[np.float64], groups: Sequence[str]
) -> Discovery:
    """What the library of :mod:`~cvmeasure.diagnose.discover` finds in ``fit``'s
    residuals (deg, (3N,)) once its model-form discrepancy is taken out."""
    trials, params = ctx.trials, ctx.params
    return discover(
        trials,
        residual_deg - discrepancy_basis(trials) @ np.asarray(fit.discrepancy),
        groups,
        ctx.fold_masks,
        head_gain=fit.head_sensitivity(trials, params, ctx.base_effects),
        refit=fit.nuisance_jacobian(trials, params, ctx.base_effects),
    )


def _joint_with_discrepancy(
    ctx: Context, fit: ModelFit, base_fit: ModelFit
) -> tuple[ModelFit, float, float]:
    """``fit``'s causes refitted together with the bounded model-form discrepancy, its
    held-out RMSE (deg; the discrepancy fitted with the model on the other folds) and
    its delta BIC against ``base_fit``."""
    joint = fit_model(
        ctx.trials,
        ctx.params,
        fit.causes,
        base_effects=ctx.base_effects,
        start=fit,
        discrepancy=True,
    )
    held = grouped_kfold_cv(
        ctx.trials,
        ctx.params,
        fit.causes,
        ctx.fold_masks,
        base_effects=ctx.base_effects,
        full_fit=joint,
        discrepancy=True,
    )
    return joint, held.rmse_after_discrepancy_deg(ctx.trials), bic_gain(base_fit, joint)


#: Library terms that depend on the order of the bends, not only on each bend.
ORDER_TERMS = ("warm_up", "order_squared", "previous_bend")
ORDER_EXPERIMENT = "bend the same angles in a random order"


def order_confounded(
    ctx: Context,
    base_fit: ModelFit,
    change_deg: NDArray[np.float64],
    head_gain: NDArray[np.float64],
) -> list[tuple[str, str]]:
    """Order-dependent library terms (:data:`ORDER_TERMS`) whose columns reproduce the
    named causes' change of the predictions on this plan (|cosine| above
    CONFOUNDED_SIMILARITY after projecting out the machine's nuisance directions): on
    an ordered plan a warm-up or the previous bend can look like a catalogue cause.
    Each as (its words with the similarity, its library name)."""
    n = len(ctx.trials)
    rows = np.isfinite(change_deg) & (np.arange(3 * n) < 2 * n)
    jac = base_fit.nuisance_jacobian(ctx.trials, ctx.params, ctx.base_effects)[rows]
    q = np.linalg.qr(jac)[0]

    def project(v: NDArray[np.float64]) -> NDArray[np.float64]:
        return v - q @ (q.T @ v)

    sig = project(change_deg[rows])
    norm = float(np.sum(sig**2))
    if norm <= 0:
        return []
    best: dict[str, tuple[float, str]] = {}  # family -> (similarity, member)
    for name, cols in library(ctx.trials, head_gain).items():
        family = next((f for f in ORDER_TERMS if name.startswith(f)), None)
        if family is None:
            continue
        x = np.column_stack([project(c[rows]) for c in cols.T])
        fit = x @ np.linalg.lstsq(x, sig, rcond=None)[0]
        similarity = math.sqrt(max(float(sig @ fit) / norm, 0.0))
        if similarity > max(CONFOUNDED_SIMILARITY, best.get(family, (0.0, ""))[0]):
            best[family] = (similarity, name)
    return [(f"{term_words(name)} (similarity {sim:.4f})", name) for sim, name in best.values()]


def beside_confounded(
    ctx: Context,
    base_fit: ModelFit,
    change_deg: NDArray[np.float64],
    head_gain: NDArray[np.float64],
    beside: Sequence[str],
    sigma_deg: float,
) -> list[str]:
    """The library terms found beside the named causes (``beside``, library names) when
    they, with the machine's nuisance directions, reproduce the causes' change of the
    predictions on this plan (``change_deg``, (3 N,)): the part of it only the causes
    explain, in the named fit's residual variance (``sigma_deg``: with the model-form
    discrepancy profiled out, as a cause's evidence is weighed), carries less evidence
    than a cause needs to be named (a chi-square less the log of the observations, the BIC
    of one parameter, below ``ctx.min_delta_bic``). The causes then stand in for a
    mechanism outside the catalogue as well as for themselves: the name is not a pick.
    Empty otherwise (or with no term beside)."""
    if not beside or not (sigma_deg > 0):  # NaN: no discrepancy profiled
        return []
    n = len(ctx.trials)
    rows = np.isfinite(change_deg) & (np.arange(3 * n) < 2 * n)
    lib = library(ctx.trials, head_gain)
    cols = [base_fit.nuisance_jacobian(ctx.trials, ctx.params, ctx.base_effects)]
    cols += [lib[t] for t in beside if t in lib]
    x = np.column_stack(cols)[rows]
    y = change_deg[rows]
    unique = y - x @ np.linalg.lstsq(x, y, rcond=None)[0]
    evidence = float(unique @ unique) / sigma_deg**2 - math.log(max(int(rows.sum()), 2))
    return list(beside) if evidence < ctx.min_delta_bic else []


def library_confounded(
    ctx: Context,
    base_fit: ModelFit,
    base_residual_deg: NDArray[np.float64],
    named_residual_deg: NDArray[np.float64],
    n_named: int,
    head_gain: NDArray[np.float64],
    basis: NDArray[np.float64],
) -> list[tuple[str, float]]:
    """Library terms (the runouts :data:`~cvmeasure.diagnose.discover.RIVAL_PERIODS`
    included) that explain the data within the noise as well as the named causes: each
    term, with the machine's nuisance directions refitted, fitted to the baseline's
    residuals (``base_residual_deg``, (3 N,), its model-form discrepancy out) leaves a
    residual sum of squares whose excess over the named fit's (``named_residual_deg``,
    its discrepancy out; ``n_named`` parameters: the causes' values and their forms'
    shapes) carries less evidence than a cause needs (in the named fit's residual
    variance, each extra coefficient charged the log of the observations: a delta BIC below ``ctx.min_delta_bic``): the data cannot prefer the
    name to the term. The best member of each family, as (library name, that delta BIC).
    Every observed angle counts, the pin's too (the drive's terms move the pin).
    ``basis``: the model-form discrepancy's columns, fitted with each term within their
    bound as with the name; ``base_residual_deg`` is the baseline's without its
    discrepancy."""
    nuisance = base_fit.nuisance_jacobian(ctx.trials, ctx.params, ctx.base_effects)
    rows = np.isfinite(base_residual_deg) & np.isfinite(named_residual_deg)
    rows &= np.all(np.isfinite(nuisance), axis=1)
    n_obs = int(rows.sum())
    rss_named = float(np.sum(named_residual_deg[rows] ** 2))
    # the named fit's discrepancy has only the columns the observed rows use (no loaded
    # block without loaded angles): those are its degrees of freedom
    used = np.any(basis[rows] != 0.0, axis=0)
    dof = n_obs - nuisance.shape[1] - n_named - int(used.sum())
    if dof <= 0 or not rss_named > 0:
        return []
    variance = rss_named / dof
    y = base_residual_deg[rows]
    best: dict[str, tuple[float, str]] = {}  # family -> (delta BIC, member)
    bound = current_form().bound_deg
    for name, cols in library(ctx.trials, head_gain, RIVAL_PERIODS).items():
        x = np.column_stack([basis[:, used], nuisance, cols])[rows]
        coef = np.linalg.lstsq(x, y, rcond=None)[0]
        k = int(used.sum())
        if np.any(np.abs(coef[:k]) > bound):  # the discrepancy within its bound, as the name's
            lower = np.r_[np.full(k, -bound), np.full(x.shape[1] - k, -np.inf)]
            coef = optimize.lsq_linear(x, y, bounds=(lower, -lower), method="bvls").x
        left = y - x @ coef
        excess = (float(left @ left) - rss_named) / variance
        dbic = excess + (cols.shape[1] - n_named) * math.log(max(n_obs, 2))
        family = name.rpartition("_")[0] if name[-1].isdigit() else name
        if dbic < min(ctx.min_delta_bic, best.get(family, (math.inf, ""))[0]):
            best[family] = (dbic, name)
    return [(name, dbic) for dbic, name in best.values()]
