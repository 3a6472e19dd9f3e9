"""The simulation's predictions and residuals for a fitted point (deg, stacked by blocks)."""

from __future__ import annotations

import functools
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose.discrepancy import (
    discrepancy_basis,
    loaded_excess_deg,
    springback_excess_deg,
)
from cvmeasure.diagnose.forms import LEARNED_SHAPE_KEYS, NUISANCE, Causes, Shape, as_causes
from cvmeasure.geometry import wrap_deg
from cvmeasure.sim.effects import EFFECTS, Effect, effect_spec_for
from cvmeasure.sim.model import (
    apply_camera_tilt_deg,
    simulate,
    simulate_drift_rates,
    simulate_rows,
)
from cvmeasure.sim.params import SimParams

#: The cause whose split follows the learned springback (:func:`learned_split`).
ASYMMETRY = "springback_asymmetry"


def scaled(base: SimParams, scale: float, nuisance: Sequence[float] = ()) -> SimParams:
    """``base`` with its strength scaled and the nuisance geometry set (validated)."""
    return _scaled(base, float(scale), tuple(float(v) for v in nuisance))


@functools.lru_cache(maxsize=64)
def _scaled(base: SimParams, scale: float, nuisance: tuple[float, ...]) -> SimParams:
    # a fit asks again and again for the same point's params (a forward difference
    # steps one cause while the strength and geometry stay), and building and
    # validating a SimParams costs more than the simulation's kinematics: the frozen,
    # hashable params are made once per point
    extra = {n.key: v for n, v in zip(NUISANCE, nuisance, strict=False)}
    return base.replace(yield_mpa=base.yield_mpa * scale, uts_mpa=base.uts_mpa * scale, **extra)


def effects_with(
    base_effects: Sequence[Effect],
    causes: Causes,
    values: Sequence[float],
    shapes: Sequence[Shape] = (),
    *,
    params: SimParams | None = None,
) -> tuple[Effect, ...]:
    """``base_effects`` with ``causes`` at ``values`` (clipped to their bounds on the
    machine ``params`` describes, :func:`~cvmeasure.sim.effects.effect_spec_for`)."""
    kept = tuple(e for e in base_effects if e.name not in (*causes, "none"))
    forms = list(shapes) + [()] * (len(causes) - len(shapes))
    specs = [effect_spec_for(c, params) for c in causes]
    added = tuple(
        Effect(
            c,
            min(max(float(v), spec.lower), spec.upper),
            tuple((k, x) for k, x in f if k not in LEARNED_SHAPE_KEYS),
        )
        for c, v, f, spec in zip(causes, values, forms, specs, strict=True)
    )
    return (*kept, *added)


def _loaded_share(causes: Causes, shapes: Sequence[Shape]) -> float:
    """The asymmetry's ``learned_loaded_share`` (0: not in its form)."""
    for c, f in zip(causes, shapes, strict=False):
        if c == ASYMMETRY:
            return float(dict(f).get("learned_loaded_share", 0.0))
    return 0.0


def predict(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: str | Sequence[str],
    strength_scale: float,
    values: Sequence[float] = (),
    *,
    nuisance: Sequence[float] = (),
    shapes: Sequence[Shape] = (),
    commanded_pin_deg: NDArray[np.float64] | None = None,
) -> NDArray[np.float64]:
    """Predicted observations of the trials under a model, stacked like
    :meth:`TrialTable.observations` (loaded, unloaded bend and pin angle, deg);
    ``commanded_pin_deg`` replaces the trials' commands (same order and history)."""
    cmd = trials.commanded_pin_deg if commanded_pin_deg is None else commanded_pin_deg
    names = as_causes(causes)
    effects = effects_with(base_effects, names, values, shapes, params=params)
    res = simulate(
        cmd, scaled(params, strength_scale, nuisance), effects, bend_index=trials.bend_index
    )
    loaded, unloaded = learned_split(
        cmd,
        effects,
        _loaded_share(names, shapes),
        res.loaded_bend_deg,
        res.unloaded_bend_deg,
        res.springback_deg,
    )
    return np.concatenate([loaded, unloaded, res.pin_angle_deg])


def residual_rows(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: Causes,
    points: Sequence[tuple[float, Sequence[float], Sequence[float]]],
    *,
    shapes: Sequence[Shape] = (),
) -> NDArray[np.float64]:
    """(K, 3 N): :func:`residuals` at each of ``points`` ((strength scale, the causes'
    values, the nuisance geometry)), the same numbers from one vectorised simulation
    (:func:`simulate_rows`) instead of K. ValueError where the rows cannot share one
    simulation (see :func:`simulate_rows`)."""
    cmd = trials.commanded_pin_deg
    effects_rows = [
        effects_with(base_effects, causes, v, shapes, params=params) for _, v, _ in points
    ]
    params_rows = [scaled(params, s, nuisance) for s, _, nuisance in points]
    res = simulate_rows(cmd, params_rows, effects_rows, bend_index=trials.bend_index)
    if not any(e.name == ASYMMETRY and e.value for r in effects_rows for e in r):
        # no row's springback is split (learned_split returns the simulation's angles)
        blocks = [res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg]
        return observed_minus(trials, np.concatenate(blocks, axis=-1))
    share = _loaded_share(causes, shapes)
    predicted = np.empty((len(points), 3 * cmd.size))
    for k, effects in enumerate(effects_rows):
        loaded, unloaded = learned_split(
            cmd,
            effects,
            share,
            res.loaded_bend_deg[k],
            res.unloaded_bend_deg[k],
            res.springback_deg[k],
        )
        predicted[k] = np.concatenate([loaded, unloaded, res.pin_angle_deg[k]])
    return observed_minus(trials, predicted)


def learned_split(
    commanded_pin_deg: NDArray[np.float64],
    effects: Sequence[Effect],
    loaded_share: float,
    loaded_deg: NDArray[np.float64],
    unloaded_deg: NDArray[np.float64],
    springback_deg: NDArray[np.float64],
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The loaded and released angles (deg, signed; leading axes allowed) with a
    springback asymmetry splitting the wire's response as the learned baseline predicts
    it, not only as the simulation does: the learned curve takes up the wire's mean
    springback (the same in both directions), and a wire stronger one way splits the
    springback it has, whatever its mean
    (:func:`~cvmeasure.diagnose.discrepancy.springback_excess_deg`); with a
    ``loaded_share`` its learned loaded departure from the simulation is split too,
    scaled by ``1 + dir * share * alpha`` (the released leg moves with it). Unchanged
    without a learned curve or an asymmetry."""
    alpha = next((float(e.value) for e in effects if e.name == ASYMMETRY), 0.0)
    if not alpha:
        return loaded_deg, unloaded_deg
    excess = springback_excess_deg(commanded_pin_deg)
    if excess is not None:
        direction = np.where(np.asarray(commanded_pin_deg) < 0, -1.0, 1.0)
        # the simulation's springback before its split; the wire's is never below nil
        own = springback_deg / (1.0 + direction * alpha)
        excess = np.maximum(excess, -own)
        # released magnitude less dir * alpha * excess: signed, less alpha * excess
        unloaded_deg = unloaded_deg - alpha * excess
    departure = loaded_excess_deg(commanded_pin_deg) if loaded_share else None
    if departure is not None:
        # magnitude plus dir * share * alpha * departure: signed, plus share * alpha * it
        shift = loaded_share * alpha * departure
        loaded_deg, unloaded_deg = loaded_deg + shift, unloaded_deg + shift
    return loaded_deg, unloaded_deg


def residuals(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: str | Sequence[str],
    strength_scale: float,
    values: Sequence[float] = (),
    *,
    nuisance: Sequence[float] = (),
    discrepancy: Sequence[float] = (),
    shapes: Sequence[Shape] = (),
) -> NDArray[np.float64]:
    """Measured minus predicted, stacked by blocks (loaded, unloaded, pin); NaN = not measured."""
    predicted = predict(
        trials,
        params,
        base_effects,
        causes,
        strength_scale,
        values,
        nuisance=nuisance,
        shapes=shapes,
    )
    r = observed_minus(trials, predicted)
    if len(discrepancy):
        r = r - discrepancy_basis(trials) @ np.asarray(discrepancy, dtype=np.float64)
    return r


#: Points whose residuals one fit keeps (a start grid has at most 12 x 9).
_MEMO_POINTS = 128


class PointMemo:
    """Residual arrays of one fit keyed by the parameter point and the causes' forms,
    the oldest dropped beyond :data:`_MEMO_POINTS`; arrays are copied in and out."""

    def __init__(self) -> None:
        self._kept: dict[tuple[bytes, tuple[Shape, ...]], NDArray[np.float64]] = {}

    @staticmethod
    def _key(x: NDArray[np.float64], forms: Sequence[Shape]) -> tuple[bytes, tuple[Shape, ...]]:
        return np.asarray(x, dtype=np.float64).tobytes(), tuple(forms)

    def get(self, x: NDArray[np.float64], forms: Sequence[Shape]) -> NDArray[np.float64] | None:
        value = self._kept.get(self._key(x, forms))
        return None if value is None else value.copy()

    def put(
        self, x: NDArray[np.float64], forms: Sequence[Shape], value: NDArray[np.float64]
    ) -> None:
        if len(self._kept) >= _MEMO_POINTS:
            self._kept.pop(next(iter(self._kept)))
        self._kept[self._key(x, forms)] = value.copy()


def observed_minus(trials: TrialTable, predicted: NDArray[np.float64]) -> NDArray[np.float64]:
    """Measured minus ``predicted`` (stacked by blocks along the last axis; leading axes:
    several predictions); pin angles wrapped as directions."""
    r = trials.observations() - predicted
    n = len(trials)
    r[..., 2 * n :] = wrap_deg(r[..., 2 * n :])  # pin angles are directions
    return r


def drift_rate_residuals(
    trials: TrialTable,
    params: SimParams,
    base_effects: Sequence[Effect],
    causes: Causes,
    x: NDArray[np.float64],
    m: int,
    index: int,
    rates: NDArray[np.float64],
    shapes: Sequence[Shape],
) -> NDArray[np.float64]:
    """(K, 3 N): :func:`residuals` at the point ``x`` of :func:`fit_model` (strength, ``m``
    nuisance values, the causes' values) with ``x[index]``, a drift's rate, at each of
    ``rates`` (clipped to the drift's bounds as :func:`_effects` clips it): the same
    numbers from one vectorised simulation (:func:`simulate_drift_rates`) instead of K."""
    spec = EFFECTS["drift"]
    effects = effects_with(base_effects, causes, x[1 + m :], shapes, params=params)
    clipped = [min(max(float(v), spec.lower), spec.upper) for v in rates]
    res = simulate_drift_rates(
        trials.commanded_pin_deg,
        scaled(params, x[0], x[1 : 1 + m]),
        effects,
        clipped,
        bend_index=trials.bend_index,
    )
    loaded, unloaded = learned_split(
        trials.commanded_pin_deg,
        effects,
        _loaded_share(causes, shapes),
        res.loaded_bend_deg,
        res.unloaded_bend_deg,
        res.springback_deg,
    )
    predicted = np.concatenate([loaded, unloaded, res.pin_angle_deg], axis=-1)
    return observed_minus(trials, predicted)


#: A measurement-stage cause: it changes only how the camera sees the simulated angles,
#: so the grid over it projects one simulation instead of simulating every grid point.
CAMERA = "camera_tilt"


def tilted_curve(untilted: NDArray[np.float64], value: float, form: Shape) -> NDArray[np.float64]:
    """Predicted observations (stacked by blocks) of a simulation without camera tilt,
    seen by the camera of ``camera_tilt`` = ``value`` in ``form`` (what
    :func:`cvmeasure.sim.simulate` does with the effect on)."""
    spec = EFFECTS[CAMERA]
    effect = Effect(CAMERA, min(max(float(value), spec.lower), spec.upper), form)
    axis = effect.shape_value("tilt_axis_deg")
    tilt = float(effect.value)
    return np.concatenate(
        [apply_camera_tilt_deg(block, tilt, axis) for block in np.split(untilted, 3)]
    )
