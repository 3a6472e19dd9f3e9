"""The diagnosis's typed results: each cause tried and the whole diagnosis."""

from __future__ import annotations

import enum
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.diagnose.discover import DiscoveredTerm
from cvmeasure.diagnose.fitting import DiscrepancyForm, ModelFit
from cvmeasure.diagnose.identify import Identifiability
from cvmeasure.diagnose.misfit import Misfit
from cvmeasure.diagnose.residuals import LeftoverCheck, ResidualTrend
from cvmeasure.diagnose.rules import MIN_CV_GAIN, MIN_DELTA_BIC
from cvmeasure.sim.effects import EFFECTS, Effect
from cvmeasure.sim.params import SimParams

if TYPE_CHECKING:
    from cvmeasure.diagnose.follow_up import FollowUp


class CauseKind(enum.Enum):
    """What a diagnosis names: nothing, catalogue effects, or structure no catalogue
    effect explains (terms outside the catalogue reported instead)."""

    NONE = "none"
    NAMED = "named"
    UNEXPLAINED = "unexplained"


#: How a set of named effects is written (``a + b``): the tie, the evidence, the notes.
PAIR_SEPARATOR = " + "


@dataclass(frozen=True, eq=False)
class Cause:
    """The explanation a diagnosis names: a set of catalogue effect names
    (``docs/conventions.md``'s effect table, ``none`` excluded), strongest first, or one
    of the two states without a name (:class:`CauseKind`).

    Two causes are equal when they name the same set, in any order; :attr:`label` writes
    them as the diagnosis JSON and the CLI always have (``"a + b"``, ``"none"``,
    ``"unexplained"``) and :meth:`from_label` reads that text back."""

    kind: CauseKind
    effects: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if (self.kind is CauseKind.NAMED) != bool(self.effects):
            raise ValueError(f"a {self.kind.value} cause names no effects: {self.effects!r}")
        for name in self.effects:
            if name not in EFFECTS or name == "none":
                raise ValueError(f"unknown effect {name!r}")
        if len(set(self.effects)) != len(self.effects):
            raise ValueError(f"an effect named twice: {self.effects!r}")

    @classmethod
    def of(cls, effects: Iterable[str]) -> Cause:
        """The named ``effects`` (strongest first); no effects is :meth:`none`."""
        names = tuple(effects)
        return cls(CauseKind.NAMED, names) if names else cls.none()

    @classmethod
    def none(cls) -> Cause:
        """Nothing named: the nominal machine explains the data."""
        return cls(CauseKind.NONE)

    @classmethod
    def unexplained(cls) -> Cause:
        """Structure that no catalogue effect explains."""
        return cls(CauseKind.UNEXPLAINED)

    @classmethod
    def from_label(cls, label: str) -> Cause:
        """The cause :attr:`label` wrote; ValueError for a name outside the catalogue."""
        for kind in (CauseKind.NONE, CauseKind.UNEXPLAINED):
            if label == kind.value:
                return cls(kind)
        return cls(CauseKind.NAMED, tuple(label.split(PAIR_SEPARATOR)))

    @classmethod
    def parse(cls, label: str) -> Cause | None:
        """:meth:`from_label`, or None for a term outside the catalogue (a tie can hold
        one, e.g. ``warm_up_45``)."""
        try:
            return cls.from_label(label)
        except ValueError:
            return None

    @property
    def named(self) -> bool:
        """Whether catalogue effects are named."""
        return self.kind is CauseKind.NAMED

    @property
    def label(self) -> str:
        """``"a + b"`` (strongest first), ``"none"`` or ``"unexplained"``."""
        return PAIR_SEPARATOR.join(self.effects) if self.named else self.kind.value

    @property
    def primary(self) -> str:
        """The strongest effect named, else ``"none"`` / ``"unexplained"``: the
        diagnosis JSON's ``cause`` key (``causes`` lists every effect)."""
        return self.effects[0] if self.named else self.kind.value

    def __contains__(self, name: object) -> bool:
        return name in self.effects

    def __eq__(self, other: object) -> bool:
        if isinstance(other, str):
            # a silent False would hide a comparison left from when causes were text
            raise TypeError(f"compare a Cause with a Cause, not the text {other!r}")
        if not isinstance(other, Cause):
            return NotImplemented
        return self.kind is other.kind and frozenset(self.effects) == frozenset(other.effects)

    def __hash__(self) -> int:
        return hash((self.kind, frozenset(self.effects)))

    def __str__(self) -> str:
        return self.label


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

    cause: Cause
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
    #: the no-effect relation learned from the session when the simulation's form missed
    #: the machine (None: the simulation's form with its bounded discrepancy)
    learned: DiscrepancyForm | None = None

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
        fitted = self.extended_fit.effects(self.nominal_params)
        names = {e.name for e in fitted}
        kept = tuple(e for e in base_effects if e.name not in names and e.name != "none")
        return (*kept, *fitted)

    def to_dict(self) -> dict[str, Any]:
        base_yield = self.nominal_params.yield_mpa
        return {
            "cause": self.cause.primary,
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
            "learned_curve": None
            if self.learned is None
            else {
                "degree": self.learned.degree,
                "bound_deg": self.learned.bound_deg,
                "span_deg": list(self.learned.span_deg),
            },
        }
