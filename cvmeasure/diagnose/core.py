"""The diagnosis: find what the simulation gets wrong, name the cause, measure the gain.

Steps, on measured trials:

1. Baseline: the simulation with only the nuisance parameter fitted (material
   strength).
2. Every candidate effect of the catalogue is fitted in turn (strength plus
   the effect's one bounded parameter), with grouped K-fold cross-validation
   for its held-out RMSE.
3. Selection by held-out error with a penalty for the extra parameter: a
   candidate is *accepted* only if its held-out RMSE beats the baseline's by
   ``min_cv_gain`` and its full-data fit improves the BIC by at least
   ``min_delta_bic`` (one extra parameter; about p < 1e-3). The accepted
   candidate with the lowest held-out RMSE is the cause; when none is
   accepted, nothing is named (``cause = "none"``): the residuals are at the
   noise floor.
4. A second cause on top of the first when structure is left (same rule,
   against the one-cause model + discrepancy; the best few first causes each
   get this round and the lowest held-out model wins). The accepted second
   causes are ranked by their held-out RMSE with the discrepancy profiled out
   (a first cause's grid-rounded shape chosen again beside each), and the first
   whose pair has both causes of plausible size is named. A named pair is checked
   for held-out ties with the other pairs: when all that tie share its first
   cause, the second is not settled and the first is named alone.
5. The causes' parameters with 95 % intervals (Gauss-Newton covariance,
   Student t), residual trends before and after, a leftover check, and an
   identifiability check against the other candidates on this design,
   naming the experiment that would separate any confounded pair.

Residuals below ``RESOLUTION_DEG`` are not structure; an extended model
still missing by more than ``GROSS_MISFIT_DEG`` names nothing.

A machine whose form the simulation misses (the steps refused for lack of fit, or
explained only by terms outside the catalogue) is diagnosed again with its no-effect
relation learned from the session (:func:`~cvmeasure.diagnose.fitting.learned_form`: a
smooth curve in the bend magnitude for the loaded and released angles, fitted with every
cause); the causes are then measured on what the curve cannot absorb (the direction, the
order, the pin on the loaded photo).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.discover import (
    DiscoveredTerm,
    Discovery,
    discover,
    library,
    term_words,
)
from cvmeasure.diagnose.fitting import (
    DISCREPANCY_P,
    ModelFit,
    discrepancy_basis,
    discrepancy_form,
    fit_model,
    group_folds,
    grouped_kfold_cv,
    learned_form,
)
from cvmeasure.diagnose.identify import (
    CONFOUNDED_SIMILARITY,
    Identifiability,
    check_identifiability,
)
from cvmeasure.diagnose.misfit import (
    Misfit,
    curve_rms_deg,
    lack_of_fit,
    lack_of_fit_residuals,
    springback_rms_deg,
)
from cvmeasure.diagnose.residuals import (
    LeftoverCheck,
    ResidualTrend,
    leftover_structure,
    residual_trends,
)
from cvmeasure.sim.effects import EFFECT_NAMES, EFFECTS, Effect
from cvmeasure.sim.params import SimParams

if TYPE_CHECKING:
    from cvmeasure.diagnose.follow_up import FollowUp, Rival

__all__ = [
    "MIN_DELTA_BIC",
    "MIN_CV_GAIN",
    "RESOLUTION_DEG",
    "GROSS_MISFIT_DEG",
    "CandidateResult",
    "Diagnosis",
    "cv_groups",
    "diagnose",
]

#: BIC improvement (one extra parameter) a candidate needs ("very strong" evidence).
MIN_DELTA_BIC = 10.0
#: Relative held-out RMSE gain over the baseline a candidate needs.
MIN_CV_GAIN = 0.05
#: A second cause is only tried when a smoother gains this much on the first model's
#: residuals, or a residual trend has a p-value below SECOND_SCREEN_P.
SECOND_SCREEN_GAIN = 0.1
SECOND_SCREEN_P = 1e-4
#: Single causes within this ratio of the best held-out RMSE each get a second round
#: (at most BEAM_WIDTH of them): a greedy first pick can be the wrong one of a pair.
BEAM_RATIO = 1.25
BEAM_WIDTH = 3
#: Angles are never known better than this (deg): residuals below it are not structure,
#: so exact (noise-free) data cannot make a cause out of rounding error.
RESOLUTION_DEG = 1e-3
#: An extended model still missing by more than this (deg rms) names nothing: the
#: simulation does not describe the data (wrong signs, units, columns or params).
GROSS_MISFIT_DEG = 5.0
#: Fewest CV groups (parts); with fewer, every trial is its own group.
MIN_GROUPS = 3
#: Fewest trials the diagnosis accepts.
MIN_TRIALS = 8
#: More trials than this are diagnosed on a random subset of this size (whole CV groups,
#: order kept), said in the notes: the intervals are then those of the subset (wider).
MAX_TRIALS = 5_000


@dataclass(frozen=True)
class CandidateResult:
    """One cause tried (on top of any already named): full-data fit, held-out RMSE, verdict."""

    cause: str  # the effect tried
    cv_rmse_deg: float
    fit: ModelFit
    delta_bic: float  # against the model it extends, both with the model-form discrepancy
    accepted: bool
    cv_discrepancy_rmse_deg: float = math.nan  # held-out, the discrepancy profiled out
    #: held-out residuals (deg, [loaded..., unloaded..., pin...], NaN = not measured) with
    #: the discrepancy profiled out; None when the held-out error was not computed
    cv_residual_deg: NDArray[np.float64] | None = field(default=None, repr=False, compare=False)

    def to_dict(self) -> dict[str, Any]:
        fit = self.fit.to_dict()
        return {
            "cause": self.cause,
            "with": [c for c in self.fit.causes if c != self.cause],
            "cv_rmse_deg": self.cv_rmse_deg,
            "cv_rmse_with_discrepancy_deg": self.cv_discrepancy_rmse_deg,
            "fit_rmse_deg": self.fit.rmse_deg,
            "params": fit["params"],
            "intervals": fit["intervals"],
            "yield_scale": self.fit.strength_scale,
            "delta_bic": self.delta_bic,
            "accepted": self.accepted,
        }


@dataclass(frozen=True)
class Diagnosis:
    """Result of :func:`diagnose` (angles in degrees)."""

    cause: str
    params: dict[str, float]
    intervals: dict[str, tuple[float, float]]
    baseline_rmse_deg: float  # held-out
    extended_rmse_deg: float  # held-out
    candidates: tuple[CandidateResult, ...]
    second_candidates: tuple[CandidateResult, ...]  # tried on top of the cause
    baseline_fit: ModelFit
    extended_fit: ModelFit
    baseline_residual_deg: NDArray[np.float64]  # full-data fit, [loaded..., unloaded...]
    extended_residual_deg: NDArray[np.float64]
    trends_before: tuple[ResidualTrend, ...]
    trends_after: tuple[ResidualTrend, ...]
    identifiability: tuple[Identifiability, ...]
    recommended_experiment: str | None
    leftover: LeftoverCheck
    nominal_params: SimParams
    n_trials: int
    n_folds: int
    notes: tuple[str, ...] = field(default=())
    discovered: tuple[DiscoveredTerm, ...] = field(default=())
    evidence: tuple[tuple[str, float], ...] = field(default=())  # (explanation, weight)
    #: a tie held out: the named cause and the accepted single causes whose held-out error
    #: is within one standard error (over the CV groups) of its own (for a named pair: the
    #: pair and the other pairs the beam could name, each written ``a + b``); then the
    #: library's order-dependent terms (outside the catalogue, e.g. ``warm_up_45``) that
    #: reproduce the named causes' change on this plan; empty when none
    tie: tuple[str, ...] = field(default=())
    #: held-out RMSE (deg, discrepancy profiled out) of the terms discovered in the
    #: baseline's residuals (NaN: none)
    discovered_rmse_deg: float = field(default=math.nan, repr=False)
    #: bends proposed to separate the explanations of a held-out tie (None: no tie, or
    #: fewer than two rivals the catalogue can predict); see :mod:`.follow_up`
    follow_up: FollowUp | None = None
    #: the other pairs the beam could name (the rivals of a named pair's tie)
    other_pairs: tuple[CandidateResult, ...] = field(default=(), repr=False, compare=False)
    #: the best explanation against the scatter of repeated bends (None: no repeats);
    #: ``misfit.refused``: the simulation does not describe this machine, nothing named
    misfit: Misfit | None = None

    @property
    def gain(self) -> float:
        """Relative held-out RMSE reduction, 1 - extended / baseline."""
        if self.baseline_rmse_deg <= 0:
            return 0.0
        return 1.0 - self.extended_rmse_deg / self.baseline_rmse_deg

    @property
    def noise_floor_deg(self) -> float:
        """Residual standard deviation of the chosen model (the noise floor estimate)."""
        return self.extended_fit.sigma_deg

    def extended_params(self) -> SimParams:
        """The nominal params with the fitted material strength of the extended model."""
        return self.extended_fit.params(self.nominal_params)

    @property
    def causes(self) -> tuple[str, ...]:
        """Every cause named, strongest first (empty when nothing is named)."""
        return self.extended_fit.causes

    def extended_effects(self, base_effects: Sequence[Effect] = ()) -> tuple[Effect, ...]:
        """``base_effects`` with the named causes added (or refitted)."""
        fitted = self.extended_fit.effects()
        names = {e.name for e in fitted}
        kept = tuple(e for e in base_effects if e.name not in names and e.name != "none")
        return (*kept, *fitted)

    def to_dict(self) -> dict[str, Any]:
        base_yield = self.nominal_params.yield_mpa
        return {
            "cause": self.cause,
            "causes": list(self.causes),
            "params": dict(self.params),
            "intervals": {k: list(v) for k, v in self.intervals.items()},
            "baseline_rmse_deg": self.baseline_rmse_deg,
            "extended_rmse_deg": self.extended_rmse_deg,
            "gain": self.gain,
            "noise_floor_deg": self.noise_floor_deg,
            "candidates": [c.to_dict() for c in self.candidates],
            "second_candidates": [c.to_dict() for c in self.second_candidates],
            "nuisance": {
                "baseline_yield_mpa": base_yield * self.baseline_fit.strength_scale,
                "extended_yield_mpa": base_yield * self.extended_fit.strength_scale,
                "extended_yield_interval_mpa": [
                    base_yield * v for v in self.extended_fit.strength_interval
                ],
            },
            "fit_rmse_deg": {
                "baseline": self.baseline_fit.rmse_deg,
                "extended": self.extended_fit.rmse_deg,
            },
            "residual_trends": {
                "before": [t.to_dict() for t in self.trends_before],
                "after": [t.to_dict() for t in self.trends_after],
            },
            "identifiability": [i.to_dict() for i in self.identifiability],
            "leftover": self.leftover.to_dict(),
            "recommended_experiment": self.recommended_experiment,
            "n_trials": self.n_trials,
            "n_folds": self.n_folds,
            "selection": {
                "method": "grouped K-fold CV, accept if CV gain >= min_cv_gain and "
                "delta BIC >= min_delta_bic; lowest CV RMSE wins",
                "min_cv_gain": MIN_CV_GAIN,
                "min_delta_bic": MIN_DELTA_BIC,
            },
            "notes": list(self.notes),
            "discovered": [t.to_dict() for t in self.discovered],
            "evidence": [{"explanation": e, "weight": w} for e, w in self.evidence],
            "tie": list(self.tie),
            "follow_up": None if self.follow_up is None else self.follow_up.to_dict(),
            "lack_of_fit": None if self.misfit is None else self.misfit.to_dict(),
        }


def _delta_bic(base: ModelFit, fit: ModelFit) -> float:
    """BIC improvement of ``fit`` over ``base``, both with the bounded model-form
    discrepancy profiled out of their residuals (floored at the resolution)."""
    n = fit.n_obs
    extra = fit.n_params - base.n_params
    floor = n * RESOLUTION_DEG**2
    rss0 = max(base.rss_discrepancy_deg2, floor)
    rss1 = max(fit.rss_discrepancy_deg2, floor)
    return float(n * math.log(rss0 / rss1) - extra * math.log(n))


#: A pair is named only when each of its causes is at most this multiple of its typical
#: size: two causes, one of them far larger than any machine shows, are taking the place
#: of a mechanism the catalogue does not have (the discrepancy hides the rest).
PAIR_PLAUSIBLE_RATIO = 1.5


def _plausible(fit: ModelFit) -> bool:
    """Every cause of ``fit`` within PAIR_PLAUSIBLE_RATIO of its typical size."""
    return all(
        abs(v) <= PAIR_PLAUSIBLE_RATIO * max(abs(x) for x in EFFECTS[c].typical)
        for c, v in zip(fit.causes, fit.values, strict=True)
    )


def _structure_left(
    trials: TrialTable,
    fit: ModelFit,
    params: SimParams,
    base_effects: Sequence[Effect],
    folds: Sequence[NDArray[np.bool_]],
) -> bool:
    """Screen for a second cause: structure left along the angle, or a residual trend."""
    res = fit.residuals(trials, params, base_effects)
    if leftover_structure(trials, res, list(folds)).gain > SECOND_SCREEN_GAIN:
        return True
    p_values = [t.p_value for t in residual_trends(trials, res) if math.isfinite(t.p_value)]
    return bool(p_values) and min(p_values) < SECOND_SCREEN_P


def _design_notes(trials: TrialTable) -> list[str]:
    notes = []
    if not trials.both_directions:
        notes.append(
            "the plan bends in one direction only: per-direction causes (offset, backlash, "
            "axis offset, springback asymmetry) are told apart only by their shape along the "
            "angle, not by their sign; add reverse bends"
        )
    if not trials.has_loaded:
        notes.append(
            "no loaded angles: springback causes and machine causes are only separated by "
            "their shape in the released angle; photograph the loaded angle as well"
        )
    return notes


def diagnose(
    trials: TrialTable,
    params: SimParams | None = None,
    *,
    base_effects: Sequence[Effect] = (),
    candidates: Sequence[str] | None = None,
    folds: int = 5,
    min_cv_gain: float = MIN_CV_GAIN,
    min_delta_bic: float = MIN_DELTA_BIC,
    max_causes: int = 2,
    follow_up: bool = True,
) -> Diagnosis:
    """Diagnose measured trials against the simulation.

    When the data leave a drive compliance and a scale the two best explanations, the
    span's elastic bow decides between them (:func:`_bow_decides`): the two differ by
    the bow's shape, so with the leg straight the bow's over-bend makes a compliance
    look like a scale.

    Parameters
    ----------
    trials : TrialTable
        Measured bends (both directions and loaded angles give the best power).
    params : SimParams, optional
        Nominal simulation parameters (defaults built in).
    base_effects : sequence of Effect
        Effects already part of the model (from a params JSON); kept fixed
        unless a candidate of the same name refits them.
    candidates : sequence of str, optional
        Effect names to try (default: the whole catalogue).
    folds : int
        K of the grouped K-fold cross-validation.
    min_cv_gain, min_delta_bic : float
        Acceptance thresholds (see module notes).
    max_causes : int
        1 names at most one cause; 2 (default) then tries a second cause on
        top of the first, accepted by the same rule against the one-cause model.
    follow_up : bool
        When the result reports a held-out tie of explanations the catalogue predicts,
        propose the bends that would separate them (``Diagnosis.follow_up``).

    Raises
    ------
    ValueError
        With fewer than ``MIN_TRIALS`` trials or an unknown candidate name.
    """
    params = params or SimParams()
    kwargs: dict[str, Any] = dict(
        base_effects=base_effects,
        candidates=candidates,
        folds=folds,
        min_cv_gain=min_cv_gain,
        min_delta_bic=min_delta_bic,
        max_causes=max_causes,
    )
    result = _diagnose_form(trials, params, kwargs, follow_up)
    if not _form_misses(result):
        return result
    # the simulation's form does not describe this machine: its no-effect relation is
    # learned from the session (a smooth curve in the bend, fitted with every cause) and
    # the causes are tested on what such a curve cannot absorb
    with discrepancy_form(learned_form(trials)):
        learned = _diagnose_form(trials, params, kwargs, follow_up)
        fit = learned.extended_fit if learned.causes else learned.baseline_fit
        curve_deg = curve_rms_deg(trials, fit)
    if learned.misfit is not None and learned.misfit.refused:
        return result
    allowed_deg = LEARNED_CURVE_SPRINGBACKS * springback_rms_deg(trials, params)
    if not curve_deg <= allowed_deg:
        note = (
            f"a curve learned from the session would have to move the angles by "
            f"{curve_deg:.2f} deg rms, beyond what the material's response can be off by "
            f"({allowed_deg:.2f} deg, twice the springback the description predicts): the "
            "machine is described wrong (wire, pin or dead zone); no cause is named"
        )
        return dataclasses.replace(result, notes=(*result.notes, note))
    note = (
        "the simulation's form misses this machine beyond the noise: its no-effect relation "
        "was learned from the session (a smooth curve in the bend for loaded and released "
        "angles, both directions alike); the causes were tested on the direction, the order "
        "and the pin, which it cannot absorb"
    )
    return dataclasses.replace(learned, notes=(*learned.notes, note))


#: The learned curve stands for the description's error in the material's response:
#: the springback (the released angle) and the hardening's share of the loaded one, each
#: off by at most about the whole springback. A curve beyond this many times the
#: predicted springback (rms over the session) is a machine described wrong (its wire,
#: pin or dead zone), which the user is told to fix.
LEARNED_CURVE_SPRINGBACKS = 2.0


def _form_misses(result: Diagnosis) -> bool:
    """The simulation's form (bounded discrepancy) leaves the data unexplained: refused
    for lack of fit, or explained only by terms outside the catalogue."""
    refused = result.misfit is not None and result.misfit.refused
    return refused or result.cause == "unexplained"


def _diagnose_form(
    trials: TrialTable, params: SimParams, kwargs: dict[str, Any], follow_up: bool
) -> Diagnosis:
    """One diagnosis in the discrepancy's form in use, the bow decided and the
    follow-up planned."""
    base_effects = kwargs["base_effects"]
    folds, min_cv_gain = kwargs["folds"], kwargs["min_cv_gain"]
    result = _diagnose_once(trials, params, **kwargs)
    bow = _bow_decides(trials, params, result, tuple(base_effects), folds, min_cv_gain)
    if bow is None:
        return _with_follow_up(trials, result, base_effects, follow_up)
    straight = result
    if bow.use_bow:
        result = _diagnose_once(trials, dataclasses.replace(params, span_bow_share=1.0), **kwargs)
    notes = (*result.notes, bow.note)
    other = bow.straight if bow.use_bow else bow.bowed
    if bow.tied and result.causes == (result.cause,) and result.cause in BOW_RIVALS:
        if other != result.cause and other not in result.tie:
            tie = (*(result.tie or (result.cause,)), other)
            result = dataclasses.replace(result, tie=tie, notes=notes)
            # the rival added is fitted in the other model of the machine
            if bow.use_bow:
                other_fit = _single_fit(straight, other)
                other_params = params
            else:
                other_fit = bow.bowed_fits.get(other)
                other_params = dataclasses.replace(params, span_bow_share=1.0)
            overrides = {} if other_fit is None else {other: (other_fit, other_params)}
            return _with_follow_up(trials, result, base_effects, follow_up, overrides)
    result = dataclasses.replace(result, notes=notes)
    return _with_follow_up(trials, result, base_effects, follow_up)


def _single_fit(result: Diagnosis, label: str) -> ModelFit | None:
    """The fit of ``result``'s candidate explaining the data by ``label`` (a cause, or a
    pair ``a + b``), first round or second; None when not tried."""
    causes = set(label.split(" + "))
    for c in (*result.candidates, *result.second_candidates, *result.other_pairs):
        if set(c.fit.causes) == causes:
            return c.fit
    return None


def _with_follow_up(
    trials: TrialTable,
    result: Diagnosis,
    base_effects: Sequence[Effect],
    enabled: bool,
    overrides: dict[str, tuple[ModelFit, SimParams]] | None = None,
) -> Diagnosis:
    """``result`` with the follow-up plan that separates its tie's catalogue rivals (each
    as fitted to the data; ``overrides``: a rival fitted in another model of the machine).
    Only computed when there is a tie of two such rivals."""
    if not enabled or not result.tie or len(trials) != result.n_trials:
        return result
    from cvmeasure.diagnose.follow_up import Rival, propose_follow_up

    rivals: list[Rival] = []
    for label in result.tie:
        if not all(c in EFFECTS for c in label.split(" + ")):
            continue  # a term outside the catalogue: no forward model to plan with
        fit, fitted_on = (overrides or {}).get(label, (None, result.nominal_params))
        fit = fit or _single_fit(result, label)
        if fit is not None:
            rivals.append(Rival(label, fit, fitted_on))
    if len(rivals) < 2:
        return result
    plan = propose_follow_up(trials, rivals, tuple(base_effects))
    if plan is None:
        return result
    note = (
        f"follow-up: {plan.n_trials} bends ({plan.design}) after the data are expected to "
        f"separate {', '.join(plan.rivals)} by {plan.expected_separation_se:.1f} standard "
        "errors (each rival refitted); run them, append and diagnose again"
    )
    return dataclasses.replace(result, follow_up=plan, notes=(*result.notes, note))


#: Causes whose signatures differ by the span's elastic bow: a drive's lag, nearly
#: constant from first contact and rising as the lever shortens, less the bow's
#: over-bend (largest at small bends, falling with the lever) is a scale's shape.
BOW_RIVALS: tuple[str, str] = ("compliance", "scale")


@dataclass(frozen=True)
class _BowDecision:
    """The straight leg against the span's bow, each with its better rival (deg)."""

    straight: str  # the better rival with the leg straight
    bowed: str  # the better rival with the bow
    use_bow: bool
    tied: bool  # within TIE_STANDARD_ERRORS held out: the data do not tell them apart
    note: str
    bowed_fits: dict[str, ModelFit] = field(default_factory=dict)  # each rival with the bow


def _bow_decides(
    trials: TrialTable,
    params: SimParams,
    result: Diagnosis,
    base_effects: tuple[Effect, ...],
    folds: int,
    min_cv_gain: float = MIN_CV_GAIN,
) -> _BowDecision | None:
    """Whether the span's elastic bow (beam theory, share 1) belongs in the model; None
    when not asked.

    Asked only of a straight-leg model (``span_bow_share`` 0) that named one of
    :data:`BOW_RIVALS` (or nothing, terms outside the catalogue preferred), whose best
    accepted single cause is one of them with the other accepted too. Both are refitted
    with the bow, and the better bowed fit is compared with the better straight one
    held out (mean squared error, discrepancy profiled out, per CV group): the bow is
    used when it explains the held-out data better (and, when terms discovered outside
    the catalogue were preferred to the straight rivals, better than those by
    ``min_cv_gain``, the margin by which they replaced the name); within
    :data:`TIE_STANDARD_ERRORS` standard errors the two are a tie."""
    if params.span_bow_share > 0 or len(trials) > MAX_TRIALS:
        return None
    singles = {
        c.cause: c
        for c in result.candidates
        if len(c.fit.causes) == 1 and c.accepted and math.isfinite(c.cv_discrepancy_rmse_deg)
    }
    if not singles or not all(n in singles for n in BOW_RIVALS):
        return None
    best = min(singles.values(), key=lambda c: c.cv_discrepancy_rmse_deg)
    if best.cause not in BOW_RIVALS or result.cause not in (*BOW_RIVALS, "unexplained"):
        return None
    straight = best  # the better straight rival: the best single cause is one of them
    if straight.cv_residual_deg is None:
        return None
    bowed_params = dataclasses.replace(params, span_bow_share=1.0)
    groups, _ = cv_groups(trials)
    masks = group_folds(groups, folds)
    bowed, bowed_res, bowed_fits = {}, {}, {}
    for name in BOW_RIVALS:
        fit = fit_model(trials, bowed_params, name, base_effects=base_effects)
        bowed_fits[name] = fit
        held = grouped_kfold_cv(
            trials, bowed_params, (name,), masks, base_effects=base_effects, full_fit=fit
        )
        bowed_res[name] = held.residual_after_discrepancy_deg(trials)
        bowed[name] = held.rmse_after_discrepancy_deg(trials)
    best_bowed = min(BOW_RIVALS, key=lambda n: bowed[n])
    excess = _held_out_excess(straight.cv_residual_deg, bowed_res[best_bowed], groups)
    if excess is None:
        return None
    # two models of the machine, each with its better rival: the one whose rival explains
    # the held-out data better is used (the bow is beam theory, not a fitted shape, so
    # choosing it adds no parameter); terms outside the catalogue preferred to the straight
    # rivals must be beaten too
    use_bow = excess[0] < 0.0
    if result.cause == "unexplained" and not (
        bowed[best_bowed] <= (1.0 - min_cv_gain) * result.discovered_rmse_deg
    ):
        use_bow = False  # the terms replaced the name by min_cv_gain: so must the name them
    tied = abs(excess[0]) <= TIE_STANDARD_ERRORS * excess[1]
    note = (
        f"the span's elastic bow (beam theory, M l / 6 EI) {'is' if use_bow else 'is not'} "
        "in the model: a compliance and a scale differ by the bow's shape; held out "
        f"(discrepancy profiled out) with the bow {', '.join(f'{n} {bowed[n]:.4f}' for n in BOW_RIVALS)}, "
        f"with the leg straight {', '.join(f'{n} {singles[n].cv_discrepancy_rmse_deg:.4f}' for n in BOW_RIVALS)} deg"
        + (
            f"; {best_bowed} with the bow and {straight.cause} with the leg straight are within "
            f"{TIE_STANDARD_ERRORS:g} standard error over the CV groups: the data do not tell "
            "them apart"
            if tied and best_bowed != straight.cause
            else ""
        )
    )
    return _BowDecision(straight.cause, best_bowed, use_bow, tied, note, bowed_fits)


def _diagnose_once(
    trials: TrialTable,
    params: SimParams | None = None,
    *,
    base_effects: Sequence[Effect] = (),
    candidates: Sequence[str] | None = None,
    folds: int = 5,
    min_cv_gain: float = MIN_CV_GAIN,
    min_delta_bic: float = MIN_DELTA_BIC,
    max_causes: int = 2,
) -> Diagnosis:
    """One diagnosis against ``params`` as given (:func:`diagnose` without the bow's decision).

    Parameters and errors as :func:`diagnose`.
    """
    params = params or SimParams()
    if len(trials) < MIN_TRIALS:
        raise ValueError(f"need at least {MIN_TRIALS} trials to diagnose, got {len(trials)}")
    names = tuple(n for n in (candidates or EFFECT_NAMES) if n != "none")
    for n in names:
        if n not in EFFECTS:
            raise ValueError(f"unknown candidate {n!r}")
    notes: list[str] = []
    if len(trials) > MAX_TRIALS:
        n_all = len(trials)
        trials = _subset_by_group(trials, MAX_TRIALS)
        notes.append(
            f"diagnosed on a random subset of {len(trials)} of the {n_all} trials (whole "
            "parts, order kept) to bound the time; intervals are those of the subset"
        )
    notes.extend(_design_notes(trials))
    groups, note = cv_groups(trials)
    if note:
        notes.append(note)
    ctx = _Context(
        trials=trials,
        params=params,
        base_effects=tuple(base_effects),
        fold_masks=tuple(group_folds(groups, folds)),
        names=names,
        min_cv_gain=min_cv_gain,
        min_delta_bic=min_delta_bic,
    )
    base_fit = fit_model(trials, params, "none", base_effects=ctx.base_effects)
    base_cv_res = grouped_kfold_cv(
        trials, params, "none", ctx.fold_masks, base_effects=ctx.base_effects, full_fit=base_fit
    )
    base_cv = base_cv_res.rmse_deg
    base_cv_disc = base_cv_res.rmse_after_discrepancy_deg(trials)
    results = _try_causes(ctx, base_fit, base_cv_disc, names)
    naming = _name_causes(ctx, results, base_fit, base_cv, max_causes)
    naming, pair_tie = _settle_pair(naming, results, groups)
    notes.extend(naming.notes)
    experiment = naming.experiment
    if experiment is None and not trials.both_directions:
        experiment = "add reverse bends (the same angles in the other direction)"
    elif experiment is None and not trials.has_loaded:
        experiment = "photograph the loaded angle (pin still engaged) as well as the released one"
    ext_fit = naming.fit
    base_res = base_fit.residuals(trials, params, ctx.base_effects)
    ext_res = ext_fit.residuals(trials, params, ctx.base_effects)
    cause, ext_cv = naming.cause, naming.cv_rmse_deg
    basis = discrepancy_basis(trials)
    base_res_d = base_res - basis @ np.asarray(base_fit.discrepancy)
    gain_of = base_fit.head_sensitivity(trials, params, ctx.base_effects)
    found = discover(
        trials,
        base_res_d,
        groups,
        ctx.fold_masks,
        head_gain=gain_of,
        refit=base_fit.nuisance_jacobian(trials, params, ctx.base_effects),
    )
    if base_fit.sigma_deg > GROSS_MISFIT_DEG:  # the simulation does not describe these data
        found = dataclasses.replace(found, terms=())
    mean_terms = [t for t in found.terms if t.term != "scatter"]
    named_cv = naming.cv_discrepancy_rmse_deg if cause != "none" else base_cv_disc
    scores = _scores(results, naming)
    named_bic = max(
        (v for k, v in scores.items() if set(k.split(" + ")) == set(naming.fit.causes)),
        default=0.0,
    )
    # what the library still finds in the named cause's residuals
    beside: tuple[DiscoveredTerm, ...] = ()
    if cause != "none":
        beside = _terms_beside(ctx, ext_fit, ext_res, groups).terms

    # discovered terms replace a catalogue name only when they are better both held out
    # (by min_cv_gain) and in evidence (a larger evidence weight: delta BIC with their
    # coefficients and their choice from the library counted)
    def terms_win() -> bool:
        return found.rmse_after_deg <= (1.0 - min_cv_gain) * named_cv and (
            found.delta_bic > named_bic
        )

    if cause != "none" and mean_terms and terms_win():
        # the terms were fitted together with the discrepancy: so are the named causes
        # before they are compared (fitted without it, a cause's parameter takes up the
        # model-form error and the comparison is unfair to the catalogue); so fitted,
        # they keep their name only at a typical size and leaving nothing the library
        # finds. A pair's first cause alone is tried too (its second may be spurious).
        options = [(naming.fit, named_cv, named_bic)]
        if len(naming.fit.causes) == 2:
            options += [
                (c.fit, c.cv_discrepancy_rmse_deg, c.delta_bic)
                for c in results
                if c.fit.causes == naming.fit.causes[:1]
            ]
        for option, option_cv, option_bic in options:
            kept = _kept_against_terms(ctx, option, base_fit, groups)
            if kept is None:
                continue
            named_cv, named_bic = min(option_cv, kept[0]), max(option_bic, kept[1])
            if terms_win():
                continue
            if option is not naming.fit:
                notes.append(
                    f"{naming.fit.causes[1]} dropped: {option.causes[0]} alone, fitted with "
                    "the model-form discrepancy, explains the data better than the terms "
                    "outside the catalogue"
                )
                cause, ext_fit = option.causes[0], option
                ext_res = ext_fit.residuals(trials, params, ctx.base_effects)
                ext_cv = next(c.cv_rmse_deg for c in results if c.fit is option)
                beside = _terms_beside(ctx, ext_fit, ext_res, groups).terms
            for key in [k for k in scores if set(k.split(" + ")) == set(option.causes)]:
                scores[key] = named_bic
            break
    # a cause (a pair: one of its causes) is named only when its 95 % interval (the
    # discrepancy, the dead zone and the shared errors carried) excludes no effect: its
    # evidence (a delta BIC and a held-out gain against baseline + a *bounded*
    # discrepancy) can be model-form error beyond the bound, which its interval carries
    null_held = _holds_no_effect(ext_fit)
    refused_cv = math.nan  # held-out RMSE of a cause refused for its interval (discrepancy out)
    if cause not in ("none", "unexplained") and len(null_held) == len(ext_fit.causes) > 0:
        alone = _alone_excluding_no_effect(results, ext_fit.causes)
        if alone is not None:
            # two causes sharing one signature hold no effect together (each can take
            # the other's share) while one alone excludes it: that one is named
            notes.append(
                f"{' + '.join(ext_fit.causes)} not named together: each 95 % interval holds "
                f"no effect beside the other; {alone.cause} alone excludes it"
            )
            cause, ext_fit, ext_cv = alone.cause, alone.fit, alone.cv_rmse_deg
            named_cv = alone.cv_discrepancy_rmse_deg
            ext_res = ext_fit.residuals(trials, params, ctx.base_effects)
            beside = _terms_beside(ctx, ext_fit, ext_res, groups).terms
        else:
            notes.append(
                f"{', '.join(null_held)} not named: the 95 % interval with the model-form "
                "error carried holds no effect"
            )
            refused_cv = named_cv
            cause, ext_fit, ext_res, ext_cv, beside = "none", base_fit, base_res, base_cv, ()
    # terms outside the catalogue do not stand in for a catalogue cause refused above that
    # explains the held-out data better than they do: what the data show is that cause's
    # signature at a size the plan cannot tell from none (e.g. a backlash lost on every
    # bend within the dead zone's tolerance), not a new mechanism
    beat_refused = not math.isfinite(refused_cv) or not mean_terms
    beat_refused = beat_refused or found.rmse_after_deg < refused_cv
    if found.terms and cause == "none" and not beat_refused:
        notes.append(
            f"terms outside the catalogue ({', '.join(t.term for t in found.terms)}) explain "
            f"the held-out data worse than the cause refused above ({found.rmse_after_deg:.3f} "
            f"vs {refused_cv:.3f} deg): not reported"
        )
    if found.terms and (
        (cause == "none" and beat_refused) or (cause != "none" and mean_terms and terms_win())
    ):
        if cause != "none":
            notes.append(
                "terms outside the catalogue explain the data better than "
                f"{', '.join(ext_fit.causes)} (held-out "
                f"{found.rmse_after_deg:.3f} vs {named_cv:.3f} deg, model-form discrepancy "
                f"profiled out; delta BIC {found.delta_bic:.0f} vs {named_bic:.0f}): no "
                "catalogue name is given"
            )
        cause, ext_fit = "unexplained", base_fit
        ext_res = base_res - found.correction_deg
        if mean_terms:
            ext_cv = base_cv * found.rmse_after_deg / max(found.rmse_before_deg, 1e-12)
        else:
            ext_cv = base_cv
        discovered = found.terms
    else:
        discovered = beside
    if ext_fit.causes:
        ext_fit = _widened(ctx, ext_fit)
        if cause not in ("none", "unexplained"):
            ext_fit = _averaged(ctx, ext_fit, naming, results, groups)
    if mean_terms and math.isfinite(found.delta_bic):
        scores[_DISCOVERED] = found.delta_bic
    evidence = _evidence(scores)
    tie: tuple[str, ...] = ()
    if cause not in ("none", "unexplained") and len(ext_fit.causes) == 1:
        named_result = next((c for c in results if c.fit.causes == ext_fit.causes), None)
        if named_result is not None:
            tie = _held_out_tie(named_result, results, groups)
    elif cause not in ("none", "unexplained") and set(ext_fit.causes) == set(naming.fit.causes):
        tie = pair_tie
    # an order-dependent term outside the catalogue that reproduces the named causes'
    # change of the predictions on this plan ties them: the name is not a pick
    order_ties: list[tuple[str, str]] = []
    if ext_fit.causes:
        order_ties = _order_confounded(ctx, base_fit, base_res - ext_res, gain_of)
    if tie:
        notes.append(
            f"tie: {', '.join(tie[1:])} explain(s) the held-out data as well as {tie[0]} (held-out "
            f"mean squared error within {TIE_STANDARD_ERRORS:g} standard error over the CV "
            "groups): the data do not tell them apart"
        )
    if order_ties:
        tie = (tie[0] if tie else " + ".join(ext_fit.causes), *tie[1:])
        tie = (*tie, *(name for _, name in order_ties))
    # a name is a pick only when the named causes explain the held-out data at least as
    # well as the discovered terms (both with the discrepancy profiled out); terms better
    # held out, though not by min_cv_gain, tie them
    term_ties = [t.term for t in mean_terms if t.term not in tie]
    if cause not in ("none", "unexplained") and term_ties and found.rmse_after_deg < named_cv:
        tie = (tie[0] if tie else " + ".join(ext_fit.causes), *tie[1:], *term_ties)
        notes.append(
            f"tie: terms outside the catalogue ({', '.join(term_ties)}) explain the held-out "
            f"data at least as well as {', '.join(ext_fit.causes)} ({found.rmse_after_deg:.3f} "
            f"vs {named_cv:.3f} deg, model-form discrepancy profiled out): the name is not "
            "a pick"
        )
    ties = [e for e, w in evidence[1:] if w >= TIE_RATIO * evidence[0][1]]
    if ties:
        notes.append(
            f"tie: {', '.join(ties)} explain the data about as well as {evidence[0][0]} "
            "(evidence weights within a delta BIC of 2)"
        )
    for t in discovered:
        notes.append(
            f"discovered: {t.words} ({t.term}, held-out gain {100 * t.held_out_gain:.0f} %)"
        )
    for words, _ in order_ties:
        notes.append(
            f"{', '.join(ext_fit.causes)} cannot be told from {words} on this plan "
            "(the trial order and the previous bend follow the angle): a tie is reported, "
            f"not a pick; {ORDER_EXPERIMENT}"
        )
        experiment = experiment or ORDER_EXPERIMENT
    if cause == "unexplained":
        n_terms = sum(len(t.coefficients_deg) for t in found.terms)
        misfit = lack_of_fit_residuals(trials, ext_res, base_fit.n_params + n_terms)
    else:
        misfit = lack_of_fit(trials, ext_fit if ext_fit.causes else base_fit)
    if misfit is not None and misfit.refused:
        # the least bad of wrong models is no name: the machine is not what the params say
        # (terms outside the catalogue found stay reported, as what is left unexplained)
        notes.append(misfit.note())
        if cause != "unexplained":
            cause, ext_fit, ext_res, ext_cv, discovered = "none", base_fit, base_res, base_cv, ()
        tie = ()
        experiment = "describe the machine with --params (its geometry and wire) and diagnose again"
    leftover = leftover_structure(trials, ext_res, list(ctx.fold_masks))
    if leftover.unnamed:
        notes.append(
            f"a discrepancy remains that no named cause explains (a smoother along the "
            f"commanded angle lowers the held-out residual RMSE by {100 * leftover.gain:.0f} %): "
            "check the geometry parameters (die radius, pin radius and orbit, head axis) "
            "or look for two causes at once"
        )
    return Diagnosis(
        cause=cause,
        params=ext_fit.param_values(),
        intervals=ext_fit.param_intervals(),
        baseline_rmse_deg=base_cv,
        extended_rmse_deg=ext_cv,
        candidates=tuple(results),
        second_candidates=naming.second_round,
        other_pairs=naming.other_pairs,
        baseline_fit=base_fit,
        extended_fit=ext_fit,
        baseline_residual_deg=base_res,
        extended_residual_deg=ext_res,
        trends_before=tuple(residual_trends(trials, base_res)),
        trends_after=tuple(residual_trends(trials, ext_res)),
        identifiability=naming.identifiability,
        recommended_experiment=experiment,
        leftover=leftover,
        nominal_params=params,
        n_trials=len(trials),
        n_folds=len(ctx.fold_masks),
        notes=tuple(notes),
        discovered=tuple(discovered),
        evidence=evidence,
        tie=tie,
        discovered_rmse_deg=found.rmse_after_deg if mean_terms else math.nan,
        misfit=misfit,
    )


def _alone_excluding_no_effect(
    results: Sequence[CandidateResult], causes: Sequence[str]
) -> CandidateResult | None:
    """Of a refused pair's causes, the accepted single one whose own interval excludes no
    effect, the best held out (discrepancy profiled out); None: none of them."""
    if len(causes) < 2:
        return None
    alone = [
        c
        for c in results
        if c.accepted and len(c.fit.causes) == 1 and c.cause in causes
        if not _holds_no_effect(c.fit)
    ]
    return min(alone, key=lambda c: c.cv_discrepancy_rmse_deg, default=None)


def _holds_no_effect(fit: ModelFit) -> list[str]:
    """The causes of ``fit`` whose 95 % interval holds 0 (every catalogue effect's
    no-effect value).

    On sweeps with nothing hidden, the model-form error beyond the discrepancy's bound
    (its coefficients at +-0.25 deg) passed as a scale of about 0.01: accepted by its
    delta BIC and held-out gain against baseline + the bounded discrepancy, while its
    own interval, which carries the discrepancy, held 0 (e.g. -0.007 .. 0.017). A pair is kept when one of its causes excludes no effect (its
    second cause passed its own test beside the first)."""
    return [c for c, (lo, hi) in zip(fit.causes, fit.intervals, strict=True) if lo <= 0.0 <= hi]


#: A named cause refitted with the discrepancy keeps its name against discovered terms
#: only when it is at least this share of the low end of its typical size: what a
#: smaller cause takes is the model-form error beyond the discrepancy's bound (on data
#: with nothing hidden, where the bound is reached, a scale of 0.003-0.005 against a
#: typical 0.015-0.06), not a cause.
JOINT_MIN_TYPICAL_SHARE = 0.5


def _typical_size(fit: ModelFit) -> bool:
    """Every cause of ``fit`` at least JOINT_MIN_TYPICAL_SHARE of its typical size."""
    return all(
        abs(v) >= JOINT_MIN_TYPICAL_SHARE * min(abs(x) for x in EFFECTS[c].typical)
        for c, v in zip(fit.causes, fit.values, strict=True)
    )


def _kept_against_terms(
    ctx: _Context, fit: ModelFit, base_fit: ModelFit, groups: Sequence[str]
) -> tuple[float, float] | None:
    """Held-out RMSE (deg) and delta BIC of ``fit``'s causes refitted with the
    discrepancy, or None when so fitted a cause is below its typical size
    (:func:`_typical_size`) or the library still finds a term in their residuals."""
    joint, joint_cv, joint_bic = _joint_with_discrepancy(ctx, fit, base_fit)
    if not _typical_size(joint):
        return None
    left = _terms_beside(
        ctx, joint, joint.residuals(ctx.trials, ctx.params, ctx.base_effects), groups
    )
    if any(t.term != "scatter" for t in left.terms):
        return None
    return joint_cv, joint_bic


def _terms_beside(
    ctx: _Context, fit: ModelFit, residual_deg: NDArray[np.float64], groups: Sequence[str]
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
    ctx: _Context, fit: ModelFit, base_fit: ModelFit
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
    return joint, held.rmse_after_discrepancy_deg(ctx.trials), _delta_bic(base_fit, joint)


def cv_groups(trials: TrialTable) -> tuple[tuple[str, ...], str | None]:
    """Cross-validation groups and a note: the parts when there are at least
    ``MIN_GROUPS`` of them, else single trials with repeated identical commands held
    out together (a repeat left in the training folds would leak its own answer)."""
    has_parts = any(t.part for t in trials.trials)
    if has_parts and len(set(trials.group)) >= MIN_GROUPS:
        return trials.group, None
    notes = []
    if has_parts:
        notes.append(
            f"fewer than {MIN_GROUPS} parts: cross-validation groups are single trials, so "
            "effects shared within a part are not held out"
        )
    keys = tuple(f"command {c:.1f}" for c in trials.commanded_pin_deg)
    n_keys = len(set(keys))
    if n_keys < MIN_GROUPS:
        keys = tuple(str(i) for i in range(len(trials)))
    elif n_keys < len(trials):
        notes.append(
            f"repeated commands are held out together in cross-validation ({n_keys} "
            f"distinct commands in {len(trials)} trials)"
        )
    return keys, "; ".join(notes) or None


def _widened(ctx: _Context, fit: ModelFit) -> ModelFit:
    """The fit with its 95 % intervals widened by the model form: the causes are refitted
    with the bounded discrepancy profiled out of every residual, and each interval
    becomes the hull of the two fits' 95 % intervals (within the bounds), so it holds
    the parameter whether the model-form error stays in the residuals or is taken by
    the discrepancy (a move of the estimate and the lost precision both count). Only
    when the data show a model-form error (the discrepancy improves the BIC of the fit,
    its coefficients counted as parameters); otherwise the intervals are kept."""
    if not fit.model_form_p < DISCREPANCY_P:
        return fit
    alt = fit_model(
        ctx.trials,
        ctx.params,
        fit.causes,
        base_effects=ctx.base_effects,
        start=fit,
        discrepancy=True,
    )
    out = []
    for c, (lo, hi), (alo, ahi) in zip(fit.causes, fit.intervals, alt.intervals, strict=True):
        out.append((max(min(lo, alo), EFFECTS[c].lower), min(max(hi, ahi), EFFECTS[c].upper)))
    return dataclasses.replace(fit, intervals=tuple(out))


def _averaged(
    ctx: _Context,
    fit: ModelFit,
    naming: _Naming,
    results: Sequence[CandidateResult],
    groups: Sequence[str],
) -> ModelFit:
    """The widened ``fit`` (:func:`_widened`) with each cause's 95 % interval the hull of
    its intervals (each widened too) in every explanation that explains the held-out data
    as well as the named one (:func:`_held_out_tie`, the one-standard-error rule) and
    holds that cause: the named single cause, the single causes, the pairs the beam
    could name and those it refused for a cause beyond its typical size (rivals all the
    same: :func:`_settle_pair`; on a sweep an offset beside a drift the plan cannot size
    moves with that drift's rate: docs/diagnosis.md, Limits). The interval is then
    conditional on the cause, not on the pair: a cause named beside a second cause the
    held-out data do not settle (a pair against its first cause alone, or against a pair
    with another second cause) keeps the value it would have without that second cause in
    its interval (model averaging over the explanations the data do not tell apart, each
    with the same weight)."""
    key = frozenset(fit.causes)
    pool = [*results, *naming.other_pairs, *naming.unsized_pairs]
    if naming.pair is not None:
        pool.append(naming.pair)
    named = next((c for c in pool if frozenset(c.fit.causes) == key), None)
    if named is None:
        return fit
    others = [c for c in pool if c is not named and key & set(c.fit.causes) and c.fit.intervals]
    by_label = {" + ".join(c.fit.causes): c for c in others}
    tied = _held_out_tie(named, others, groups, lambda c: " + ".join(c.fit.causes))
    out = list(fit.intervals)
    for label in tied[1:]:
        alt = _widened(ctx, by_label[label].fit)
        for i, c in enumerate(fit.causes):
            if c in alt.causes:
                alo, ahi = alt.intervals[alt.causes.index(c)]
                if math.isfinite(alo) and math.isfinite(ahi):
                    out[i] = (min(out[i][0], alo), max(out[i][1], ahi))
    return dataclasses.replace(fit, intervals=tuple(out))


#: Library terms that depend on the order of the bends, not only on each bend.
ORDER_TERMS = ("warm_up", "order_squared", "previous_bend")
ORDER_EXPERIMENT = "bend the same angles in a random order"


def _order_confounded(
    ctx: _Context,
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


#: A single cause ties the named one held out when its held-out mean squared error (the
#: discrepancy profiled out) exceeds the named cause's by at most this many standard
#: errors of the difference over the CV groups (the one-standard-error rule).
TIE_STANDARD_ERRORS = 1.0


def _held_out_excess(
    named_deg: NDArray[np.float64], other_deg: NDArray[np.float64], groups: Sequence[str]
) -> tuple[float, float] | None:
    """(mean, standard error) per observation of ``other``'s squared held-out residuals less
    ``named``'s (deg^2): the differences summed per CV group and the standard error
    cluster-robust over the groups; None with fewer than two groups."""
    labels = np.unique(np.asarray(groups), return_inverse=True)[1]
    rows = np.tile(labels, named_deg.size // labels.size)
    n_groups = int(labels.max()) + 1
    ok = np.isfinite(named_deg) & np.isfinite(other_deg)
    diff = other_deg[ok] ** 2 - named_deg[ok] ** 2
    per_group = np.bincount(rows[ok], weights=diff, minlength=n_groups)
    count = np.bincount(rows[ok], minlength=n_groups).astype(float)
    mean = float(diff.sum() / max(ok.sum(), 1))
    g = int(np.count_nonzero(count))
    if g < 2:
        return None
    dev = per_group - count * mean
    return mean, math.sqrt(g / (g - 1) * float(np.sum(dev**2))) / float(ok.sum())


def _held_out_tie(
    named: CandidateResult,
    others: Sequence[CandidateResult],
    groups: Sequence[str],
    label: Callable[[CandidateResult], str] = lambda c: c.cause,
) -> tuple[str, ...]:
    """The named explanation and the accepted ones (``others``) that explain the held-out
    data as well (:data:`TIE_STANDARD_ERRORS`), each as ``label`` gives it (a single
    cause's name; a pair ``a + b``); empty when none ties.

    The difference of squared held-out errors is summed per CV group (a group's
    observations share their fold and their errors), and its mean per observation is
    compared with its cluster-robust standard error over the groups."""
    if named.cv_residual_deg is None:
        return ()
    tied = []
    for c in others:
        if c is named or not c.accepted or c.cv_residual_deg is None:
            continue
        excess = _held_out_excess(named.cv_residual_deg, c.cv_residual_deg, groups)
        if excess is not None and excess[0] <= TIE_STANDARD_ERRORS * excess[1]:
            tied.append(label(c))
    return (label(named), *tied) if tied else ()


#: Explanations whose evidence weights are within this factor of the best are a tie.
TIE_RATIO = math.exp(-1.0)  # delta BIC of 2


#: The explanation "terms outside the catalogue" in the evidence weights.
_DISCOVERED = "unexplained (discovered terms)"


def _scores(results: Sequence[CandidateResult], naming: _Naming) -> dict[str, float]:
    """Delta BIC against the baseline + discrepancy of nothing, each single cause and
    the named pair."""
    scores = {"none": 0.0}
    for c in results:
        if math.isfinite(c.delta_bic):
            scores[c.cause] = c.delta_bic
    for c in naming.second_round:  # the pair named (a refused pair is not an explanation)
        if set(c.fit.causes) == set(naming.fit.causes) and math.isfinite(c.delta_bic):
            first = [x for x in c.fit.causes if x != c.cause]
            scores[" + ".join([*first, c.cause])] = scores.get(first[0], 0.0) + c.delta_bic
    return scores


def _evidence(scores: dict[str, float]) -> tuple[tuple[str, float], ...]:
    """Evidence weights (BIC approximation of posterior probabilities, equal priors) of
    the explanations scored by :func:`_scores` (and the discovered terms); best first."""
    top = max(scores.values())
    raw = {k: math.exp(0.5 * (v - top)) for k, v in scores.items()}
    total = sum(raw.values())
    return tuple(sorted(((k, v / total) for k, v in raw.items()), key=lambda kv: -kv[1]))


def _subset_by_group(trials: TrialTable, size: int, seed: int = 0) -> TrialTable:
    """About ``size`` trials: whole CV groups drawn at random, in their original order."""
    groups = np.asarray(trials.group)
    unique, counts = np.unique(groups, return_counts=True)
    order = np.random.default_rng(seed).permutation(len(unique))
    keep = unique[order[np.cumsum(counts[order]) <= size]]
    if keep.size == 0:  # one huge group: single trials instead
        mask = np.zeros(len(trials), dtype=bool)
        mask[np.random.default_rng(seed).choice(len(trials), size, replace=False)] = True
        return trials.subset(mask)
    return trials.subset(np.isin(groups, keep))


@dataclass(frozen=True)
class _Context:
    """What every step of one diagnosis works on."""

    trials: TrialTable
    params: SimParams
    base_effects: tuple[Effect, ...]
    fold_masks: tuple[NDArray[np.bool_], ...]
    names: tuple[str, ...]
    min_cv_gain: float
    min_delta_bic: float


@dataclass(frozen=True)
class _Extension:
    """A first cause, extended: the final fit (one or two causes) and what was learnt."""

    fit: ModelFit
    cv_rmse_deg: float
    identifiability: tuple[Identifiability, ...]
    second_round: tuple[CandidateResult, ...]
    notes: tuple[str, ...]
    cv_discrepancy_rmse_deg: float = math.nan
    #: the pairs this first cause could name (accepted, not stuck, of plausible size),
    #: best held out first: the named one (when ``fit`` is a pair), then the others
    pairs: tuple[CandidateResult, ...] = ()
    #: the accepted pairs not named for a cause beyond its typical size (rivals of the
    #: named pair's held-out tie all the same: see :func:`_settle_pair`)
    unsized: tuple[CandidateResult, ...] = ()


@dataclass(frozen=True)
class _Naming:
    """The causes named (or none), the model that names them and the notes on why."""

    cause: str
    fit: ModelFit
    cv_rmse_deg: float
    identifiability: tuple[Identifiability, ...]
    second_round: tuple[CandidateResult, ...]
    experiment: str | None
    notes: tuple[str, ...]
    cv_discrepancy_rmse_deg: float = math.nan
    #: the named pair (None for a single cause) and the other pairs any first cause of
    #: the beam could name, for the held-out tie
    pair: CandidateResult | None = None
    other_pairs: tuple[CandidateResult, ...] = ()
    #: the pairs any first cause of the beam could not name for their size
    #: (:attr:`_Extension.unsized`)
    unsized_pairs: tuple[CandidateResult, ...] = ()


#: First causes whose grid-rounded shape (:data:`~cvmeasure.diagnose.fitting.FORMS`) is
#: chosen again beside each second cause. Only the camera tilt's axis: the drift's form
#: (load exponent, whole steps profiled on a grid) would be profiled again for every
#: candidate, tripling the CPU of a diagnosis with drift first (0.9 -> 2.7 s on 60
#: trials), and a drift is rarely the first of a pair (its signature is the weaker).
REFORMED: tuple[str, ...] = ("camera_tilt",)


def _try_causes(
    ctx: _Context,
    named: ModelFit,
    named_cv: float,
    tried: Sequence[str],
    *,
    cv_all: bool = True,
) -> list[CandidateResult]:
    """Each cause on top of ``named``, best held-out first; ``cv_all=False`` skips the
    held-out error of causes that already fail the BIC test (they cannot be accepted).

    ``named_cv`` is the held-out RMSE of ``named`` with the discrepancy profiled out:
    a cause must beat "model + discrepancy", not the model alone."""
    out = []
    # the tilt's axis is not held at the grid point the tilt's own fit chose: beside a
    # second cause another axis can fit far better (once a scale takes its part), so it
    # is chosen again with the pair (grid and refit; see REFORMED)
    general = [c for c in named.causes if c in REFORMED]
    for name in tried:
        fit = fit_model(
            ctx.trials,
            ctx.params,
            (*named.causes, name),
            base_effects=ctx.base_effects,
            known={**named.param_values_by_cause(), **named.nuisance_values()},
            known_shapes=named.shapes_by_cause(),
        )
        if general:
            reformed = fit_model(
                ctx.trials,
                ctx.params,
                (*named.causes, name),
                base_effects=ctx.base_effects,
                known={
                    **{c: v for c, v in named.param_values_by_cause().items() if c not in general},
                    **named.nuisance_values(),
                },
                known_shapes={c: f for c, f in named.shapes_by_cause().items() if c not in general},
            )
            if reformed.rss_deg2 < fit.rss_deg2:
                fit = reformed
        dbic = _delta_bic(named, fit)
        if not cv_all and dbic < ctx.min_delta_bic:
            out.append(CandidateResult(name, math.nan, fit, dbic, False))
            continue
        held = grouped_kfold_cv(
            ctx.trials,
            ctx.params,
            fit.causes,
            ctx.fold_masks,
            base_effects=ctx.base_effects,
            full_fit=fit,
        )
        held_disc = held.residual_after_discrepancy_deg(ctx.trials)
        cv, cv_disc = held.rmse_deg, held.rmse_after_discrepancy_deg(ctx.trials)
        cv_gain_ok = max(cv_disc, RESOLUTION_DEG) <= (1.0 - ctx.min_cv_gain) * max(
            named_cv, RESOLUTION_DEG
        )
        accepted = bool(cv_gain_ok and dbic >= ctx.min_delta_bic)
        out.append(CandidateResult(name, cv, fit, dbic, accepted, cv_disc, held_disc))
    out.sort(key=lambda c: (math.isnan(c.cv_rmse_deg), c.cv_rmse_deg))
    return out


def _extend(
    ctx: _Context, first: CandidateResult, results: Sequence[CandidateResult], max_causes: int
) -> _Extension:
    """Identifiability of a first cause, and a second cause on top when structure is left."""
    masks = list(ctx.fold_masks)
    ident = tuple(
        check_identifiability(
            ctx.trials,
            ctx.params,
            first.cause,
            [c.cause for c in results if c.cause != first.cause],
            base_effects=ctx.base_effects,
        )
    )
    blocked = {first.cause, *(i.causes[1] for i in ident if not i.separable)}
    fit, cv, round2, notes = first.fit, first.cv_rmse_deg, [], []
    pairs: list[CandidateResult] = []
    unsized: list[CandidateResult] = []
    cv_disc = first.cv_discrepancy_rmse_deg
    if max_causes > 1 and _structure_left(
        ctx.trials, first.fit, ctx.params, ctx.base_effects, masks
    ):
        round2 = _try_causes(
            ctx,
            first.fit,
            first.cv_discrepancy_rmse_deg,
            [n for n in ctx.names if n not in blocked],
            cv_all=False,
        )
        # accepted on the held-out RMSE with the discrepancy profiled out, so ranked on
        # it too (the raw one also carries the model-form wave, the same for every pair)
        more = sorted((c for c in round2 if c.accepted), key=lambda c: c.cv_discrepancy_rmse_deg)
        # a pair that explains less (evidence) than its added cause alone is a fit stuck
        # where the first cause took up the added one's signature: not a pair to name
        alone = {c.cause: c.delta_bic for c in results}
        stuck = [
            c.cause
            for c in more
            if first.delta_bic + c.delta_bic < alone.get(c.cause, -math.inf) - ctx.min_delta_bic
        ]
        if stuck:
            notes.append(
                f"{', '.join(stuck)} on top of {first.cause} explain(s) less than "
                f"{', '.join(stuck)} alone (delta BIC): the pair is not named"
            )
        more = [c for c in more if c.cause not in stuck]
        unsized = [c for c in more if not _plausible(c.fit)]
        # a pair with a cause far beyond its typical size takes the place of a mechanism
        # the catalogue lacks: the next accepted pair is tried, at most BEAM_WIDTH of them.
        # (Structure left beyond the discrepancy no longer refuses a pair: on the
        # independent model the right pair always leaves some, the model-form error beyond
        # the discrepancy's bound, and it refused about half of the missed pairs while
        # refusing no wrong pair on no-effect and outside-catalogue cases; terms outside
        # the catalogue are weighed against the pair after naming, by the held-out and
        # evidence test of step 3b.)
        refused = []
        for c in more[:BEAM_WIDTH]:
            if _plausible(c.fit):
                break
            refused.append(c.cause)
        if refused:
            notes.append(
                f"{', '.join(refused)} on top of {first.cause} lower(s) the held-out RMSE "
                f"but beyond {PAIR_PLAUSIBLE_RATIO:g} times a typical size: a mechanism the "
                "catalogue does not name; not named"
            )
        more = [c for c in more[:BEAM_WIDTH] if c.cause not in refused]
        pairs = [c for c in more if _plausible(c.fit)]
        if more:
            fit, cv = more[0].fit, more[0].cv_rmse_deg
            cv_disc = more[0].cv_discrepancy_rmse_deg
            notes.append(
                f"a second cause, {more[0].cause}, improves the held-out RMSE further "
                f"({first.cv_rmse_deg:.3f} -> {more[0].cv_rmse_deg:.3f} deg)"
            )
    return _Extension(
        fit, cv, ident, tuple(round2), tuple(notes), cv_disc, tuple(pairs), tuple(unsized)
    )


def _settle_pair(
    naming: _Naming, results: Sequence[CandidateResult], groups: Sequence[str]
) -> tuple[_Naming, tuple[str, ...]]:
    """A named pair checked for held-out ties with the other pairs the beam could name
    and those it could not name for a cause beyond its typical size (the
    one-standard-error rule of :func:`_held_out_tie`): the naming and the tie.

    When every pair that ties holds the named pair's first cause, the data settle the
    first cause but not the second: a forward step adds only a cause it can pick, so the
    first cause is named alone (its own ties are checked as any single cause's). When
    the pairs that tie differ in the first cause (play lost on every bend or a drive
    compliance beside the same springback asymmetry: both a nearly constant
    under-bend), the pair is named and the tie reported.

    A pair refused for its size is a rival all the same: it explains the held-out data,
    and a size beyond the typical one can be a size the plan does not determine (on a
    sweep a drift's home shift is undone by the next reverse bend, so its rate runs to
    its bound along offset + constant) or a mechanism the catalogue lacks; either way
    the second cause named beside it is not settled."""
    named = naming.pair
    if named is None or set(named.fit.causes) != set(naming.fit.causes):
        return naming, ()
    order = naming.fit.causes
    rivals = (*naming.other_pairs, *naming.unsized_pairs)
    tie = _held_out_tie(
        named,
        rivals,
        groups,
        lambda c: " + ".join(order if c is named else c.fit.causes),
    )
    if not tie:
        return naming, ()
    first = named.fit.causes[0]
    tied = [c for c in rivals if " + ".join(c.fit.causes) in tie[1:]]
    alone = next((c for c in results if c.fit.causes == (first,)), None)
    if alone is None or not all(first in c.fit.causes for c in tied):
        return naming, tie
    unsized = [c.cause for c in tied if c in naming.unsized_pairs]
    note = (
        f"{', '.join(c.cause for c in (named, *tied))} on top of {first} explain the "
        f"held-out data equally well (within {TIE_STANDARD_ERRORS:g} standard error over "
        f"the CV groups"
        + (
            f"; {', '.join(unsized)} beyond {PAIR_PLAUSIBLE_RATIO:g} times a typical size"
            if unsized
            else ""
        )
        + "): the second cause is not settled and not named"
    )
    single = dataclasses.replace(
        naming,
        cause=first,
        fit=alone.fit,
        cv_rmse_deg=alone.cv_rmse_deg,
        cv_discrepancy_rmse_deg=alone.cv_discrepancy_rmse_deg,
        notes=(*naming.notes, note),
        pair=None,
    )
    return single, ()


def _name_causes(
    ctx: _Context,
    results: Sequence[CandidateResult],
    base_fit: ModelFit,
    base_cv: float,
    max_causes: int,
) -> _Naming:
    """Pick the cause(s) among the accepted candidates, or name none, with the notes why."""
    accepted = [c for c in results if c.accepted]
    notes: list[str] = []
    if not accepted:
        notes.append(
            f"no candidate beats the noise floor (held-out RMSE {base_cv:.3f} deg); "
            "nothing is named"
        )
        return _Naming("none", base_fit, base_cv, (), (), None, tuple(notes))
    # greedy with a small beam: the best few single causes each get their second round
    firsts = [c for c in accepted if c.cv_rmse_deg <= BEAM_RATIO * accepted[0].cv_rmse_deg]
    outcomes = [(first, _extend(ctx, first, results, max_causes)) for first in firsts[:BEAM_WIDTH]]
    # the lowest held-out error wins among the outcomes the evidence does not rule out
    # (a delta BIC within min_delta_bic of the best outcome's): a pair stuck where its
    # first cause took up another's signature can predict held-out data slightly
    # better while explaining far less than that other cause alone
    evidence_of = [_delta_bic(base_fit, o[1].fit) for o in outcomes]
    top = max(evidence_of)
    plausible = [
        o for o, e in zip(outcomes, evidence_of, strict=True) if e >= top - ctx.min_delta_bic
    ]
    best, ext = min(plausible, key=lambda o: o[1].cv_rmse_deg)
    ext_fit = ext.fit
    # a named pair's first cause is the one that alone predicts held-out data best with
    # the discrepancy profiled out (as the pair itself is ranked): the raw held-out RMSE
    # also carries the baseline's model-form wave along the angle, which on a repeats
    # plan (whole commands held out) a cause even in the direction (camera tilt, scale)
    # partly takes and an odd one (springback asymmetry, orthogonal to it there) cannot
    single_cv = {
        c.cause: c.cv_discrepancy_rmse_deg
        if math.isfinite(c.cv_discrepancy_rmse_deg)
        else c.cv_rmse_deg
        for c in results
    }
    if len(ext_fit.causes) == 2 and single_cv[ext_fit.causes[1]] < single_cv[best.cause]:
        ext_fit = ext_fit.reordered(ext_fit.causes[::-1])
    close = [
        c.cause for c in accepted if c is not best and c.cv_rmse_deg <= 1.05 * best.cv_rmse_deg
    ]
    if close and len(ext_fit.causes) == 1:
        notes.append(
            f"{', '.join(close)} explain the data almost as well as {best.cause} "
            "(held-out RMSE within 5 %)"
        )
    confounded = [i for i in ext.identifiability if not i.separable]
    for i in confounded:
        how = i.experiment or "no experiment in the catalogue separates them"
        notes.append(
            f"{i.causes[0]} and {i.causes[1]} cannot be told apart on this data "
            f"(signature similarity {i.similarity:.3f}); {how}"
        )
    experiment = next((i.experiment for i in confounded if i.experiment), None)
    notes.extend(ext.notes)
    at_bound = [
        f"{c} ({EFFECTS[c].param} = {v:.4g} {EFFECTS[c].unit})"
        for c, v in zip(ext_fit.causes, ext_fit.values, strict=True)
        if np.isclose(v, EFFECTS[c].lower) or np.isclose(v, EFFECTS[c].upper)
    ]
    if at_bound:
        notes.append(
            f"{', '.join(at_bound)} at its physical bound: the data want more than the "
            "catalogue allows; treat the name with suspicion"
        )
    if ext_fit.sigma_deg > GROSS_MISFIT_DEG:
        notes.append(
            f"the extended model still misses by {ext_fit.sigma_deg:.1f} deg (rms): the "
            "simulation does not describe these data (check signs, units and columns of the "
            f"trials file, and the params); {', '.join(ext_fit.causes)} not named"
        )
        return _Naming("none", base_fit, base_cv, (), (), None, tuple(notes))
    pair = ext.pairs[0] if len(ext_fit.causes) == 2 and ext.pairs else None
    named_set = set(ext_fit.causes)

    def each_once(kept: Sequence[CandidateResult]) -> tuple[CandidateResult, ...]:
        # each set of causes once (the one best held out), the named set left out
        best: dict[frozenset[str], CandidateResult] = {}
        for c in kept:
            key = frozenset(c.fit.causes)
            if key != named_set and (
                key not in best or c.cv_discrepancy_rmse_deg < best[key].cv_discrepancy_rmse_deg
            ):
                best[key] = c
        return tuple(best.values())

    other_pairs = each_once([c for _, o in outcomes for c in o.pairs])
    unsized = each_once([c for _, o in outcomes for c in o.unsized])
    return _Naming(
        ext_fit.causes[0],
        ext_fit,
        ext.cv_rmse_deg,
        ext.identifiability,
        ext.second_round,
        experiment,
        tuple(notes),
        ext.cv_discrepancy_rmse_deg,
        pair,
        other_pairs,
        unsized,
    )
