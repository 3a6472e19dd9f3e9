"""Identifiability of named causes on a given design, and the experiment that separates them.

Each effect leaves a *signature* on a design: the change of every predicted
angle (loaded and unloaded, where measured) when the effect is switched on at
a typical size. After projecting out the nuisance direction (material
strength), two causes whose signatures are (anti-)parallel cannot be told
apart on that design, whatever the noise. The check computes the cosine
similarity of signatures, and for each confounded pair tries the catalogue of
experiments (add reverse bends, photograph the loaded angle, measure the pin
angle, widen the range of angles, shuffle the bend order / re-home mid-part) on a modified design,
naming the first that separates the pair.

Reference: /work/shared/reference/springback-discrepancy.md, sections 3.1
and 4.3 (identifiability check before naming).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.contracts import TrialTable
from cvmeasure.sim.effects import Effect, effect_spec_for
from cvmeasure.sim.model import simulate
from cvmeasure.sim.params import SimParams

__all__ = [
    "CONFOUNDED_SIMILARITY",
    "EXPERIMENTS",
    "Identifiability",
    "signature",
    "similarity",
    "check_identifiability",
]

#: |cosine| of nuisance-projected signatures above which two causes are confounded.
CONFOUNDED_SIMILARITY = 0.995


def _mid_value(name: str, params: SimParams) -> float:
    lo, hi = effect_spec_for(name, params).typical
    return 0.5 * (lo + hi)


def _predict(
    design: TrialTable, params: SimParams, effects: Sequence[Effect]
) -> NDArray[np.float64]:
    """Predicted observations at the design's measured entries (stacked by blocks)."""
    res = simulate(design.commanded_pin_deg, params, effects, bend_index=design.bend_index)
    pred = np.concatenate([res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg])
    return pred[np.isfinite(design.observations())]


def signature(
    design: TrialTable,
    params: SimParams,
    name: str,
    *,
    base_effects: Sequence[Effect] = (),
) -> NDArray[np.float64]:
    """Change of the measured angles (deg) when effect ``name`` is on at a typical size."""
    base = tuple(e for e in base_effects if e.name not in (name, "none"))
    ref = _predict(design, params, base)
    on = _predict(design, params, (*base, Effect(name, _mid_value(name, params))))
    return on - ref


def _nuisance(design: TrialTable, params: SimParams, base_effects: Sequence[Effect]) -> np.ndarray:
    soft = params.replace(yield_mpa=params.yield_mpa * 1.1, uts_mpa=params.uts_mpa * 1.1)
    return _predict(design, soft, base_effects) - _predict(design, params, base_effects)


def similarity(a: NDArray[np.float64], b: NDArray[np.float64], nuisance: np.ndarray) -> float:
    """|cosine| of two signatures after projecting out the nuisance direction."""

    def project(v: np.ndarray) -> np.ndarray:
        n2 = float(nuisance @ nuisance)
        return v - (v @ nuisance) / n2 * nuisance if n2 > 0 else v

    pa, pb = project(a), project(b)
    na, nb = np.linalg.norm(pa), np.linalg.norm(pb)
    if na == 0 or nb == 0:
        return 1.0 if na == nb else 0.0
    return float(abs(pa @ pb) / (na * nb))


def _add_reverse(d: TrialTable) -> TrialTable:
    return _concat(d, -d.commanded_pin_deg)


def _add_loaded(d: TrialTable) -> TrialTable:
    return TrialTable.from_arrays(
        d.commanded_pin_deg,
        np.zeros(len(d)),
        d.unloaded_bend_deg,
        bend_index=d.bend_index,
        measured_pin_deg=d.measured_pin_deg,
    )


def _add_pin(d: TrialTable) -> TrialTable:
    return TrialTable.from_arrays(
        d.commanded_pin_deg,
        d.loaded_bend_deg,
        d.unloaded_bend_deg,
        bend_index=d.bend_index,
        measured_pin_deg=np.zeros(len(d)),
    )


def widen(d: TrialTable) -> TrialTable:
    if d.both_directions:
        sign = np.where(np.arange(len(d)) % 2 == 0, 1.0, -1.0)
    else:
        sign = d.direction_sign
    return _concat(d, sign * np.linspace(20.0, 150.0, len(d)))


def _shuffle(d: TrialTable) -> TrialTable:
    rng = np.random.default_rng(0)
    return TrialTable.from_arrays(
        d.commanded_pin_deg,
        d.loaded_bend_deg,
        d.unloaded_bend_deg,
        bend_index=rng.permutation(len(d)).astype(float),
        measured_pin_deg=d.measured_pin_deg,
    )


def _concat(d: TrialTable, extra_cmd: NDArray[np.float64]) -> TrialTable:
    n = len(d)
    loaded_on = 0.0 if d.has_loaded else np.nan
    pin_on = 0.0 if d.has_pin else np.nan
    return TrialTable.from_arrays(
        np.concatenate([d.commanded_pin_deg, extra_cmd]),
        np.concatenate([d.loaded_bend_deg, np.full(extra_cmd.size, loaded_on)]),
        np.concatenate([d.unloaded_bend_deg, np.zeros(extra_cmd.size)]),
        bend_index=np.concatenate([d.bend_index, n + np.arange(extra_cmd.size)]),
        measured_pin_deg=np.concatenate([d.measured_pin_deg, np.full(extra_cmd.size, pin_on)]),
    )


#: The experiments the check may recommend, in the order tried.
EXPERIMENTS: tuple[tuple[str, Callable[[TrialTable], TrialTable]], ...] = (
    ("add reverse bends (the same angles in the other direction)", _add_reverse),
    ("photograph the loaded angle (pin still engaged) as well as the released one", _add_loaded),
    ("measure the pin angle on the loaded photos (measured_pin_deg)", _add_pin),
    ("widen the range of bend angles (about 5-150 deg, both directions)", widen),
    ("shuffle the bend order or re-home mid-part (separates drift from angle)", _shuffle),
)


@dataclass(frozen=True)
class Identifiability:
    """Whether two causes can be told apart on the design, and how to separate them."""

    causes: tuple[str, str]
    similarity: float
    separable: bool
    experiment: str | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "causes": list(self.causes),
            "similarity": self.similarity,
            "separable": self.separable,
            "experiment": self.experiment,
        }


def check_identifiability(
    design: TrialTable,
    params: SimParams,
    cause: str,
    others: Sequence[str],
    *,
    base_effects: Sequence[Effect] = (),
    threshold: float = CONFOUNDED_SIMILARITY,
) -> list[Identifiability]:
    """Compare ``cause`` with each of ``others`` on the design (see module notes)."""
    out = []
    nuis = _nuisance(design, params, base_effects)
    sig = signature(design, params, cause, base_effects=base_effects)
    for other in others:
        if other in (cause, "none"):
            continue
        s = similarity(sig, signature(design, params, other, base_effects=base_effects), nuis)
        separable = s < threshold
        experiment = None
        if not separable:
            for text, modify in EXPERIMENTS:
                d2 = modify(design)
                n2 = _nuisance(d2, params, base_effects)
                a = signature(d2, params, cause, base_effects=base_effects)
                b = signature(d2, params, other, base_effects=base_effects)
                if similarity(a, b, n2) < threshold:
                    experiment = text
                    break
        out.append(Identifiability((cause, other), s, separable, experiment))
    return out
