"""The forward model (pin command -> loaded and unloaded bend angle) and its inverse.

One bend, vectorised over many::

    r       = command effects(commanded_pin_deg)      # backlash, offset, scale, drift
                                                       # (history: reversals, home shift)
    phi     = phi_contact - approach_deg + |r|         # head angle, die frame of the bend
    phi    -= compliance * (M / l(phi)) * R_p cos(phi - theta_L)  # drive wind-up under the pin load
    theta_L = tangent construction(phi)                # loaded angle (>= 0), lever l
    sb      = min(theta_L, (b theta_L + a(l)) (1 + s alpha))
    theta_U = theta_L - sb
    measured angles = camera(s * theta_L), camera(s * theta_U)

Signs (spec): a negative command bends the other way (clockwise); angles are
signed like the command; ``springback_deg = sign(loaded) * (loaded - unloaded)``.
``pin_deg`` is the actual signed head rotation from home after the command
effects (what the head really did), in the units of the command;
``pin_angle_deg`` is the same pin position in the machine frame of the spec
(angle of origin -> pin from +x), as a photo of the loaded bend measures it:
from the origin marker, which sits on the die at the nominal head axis, so
``dir * (phi_contact - approach_deg + |r|)`` on a nominal machine and, with the
axis ``e`` off the marker, about ``(e / R_p) cos(phi)`` (rad) more.
"""

from __future__ import annotations

import dataclasses
import operator
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cvmeasure.geometry import mod_positive, wrap_deg
from cvmeasure.sim.effects import Effect, check_effect_bounds
from cvmeasure.sim.kinematics import (
    HeadGeometry,
    contact_angle_deg,
    head_geometry,
    loaded_angle_and_lever,
)
from cvmeasure.sim.params import SimParams
from cvmeasure.sim.springback import SpringbackLaw, springback_law

__all__ = [
    "SimResult",
    "simulate",
    "simulate_drift_rates",
    "simulate_rows",
    "pin_command_for_angle",
    "effect_values",
    "apply_camera_tilt_deg",
    "max_reachable_deg",
    "add_noise",
]

#: Largest head rotation from home the inverse searches (deg).
_MAX_ROTATION_DEG = 200.0
#: Fixed-point iterations of the compliance lag (converges to < 1e-4 deg in 4).
_COMPLIANCE_ITERATIONS = 6
#: Fixed-point iterations of a load-dependent drift (the load changes little with the shift).
_DRIFT_ITERATIONS = 3
#: Largest final bend the inverse accepts (deg): the tangent construction ends at 180.
_MAX_BEND_DEG = 179.0


@dataclass(frozen=True)
class SimResult:
    """Simulated bends (arrays of shape (N,), degrees; lever in mm)."""

    commanded_pin_deg: NDArray[np.float64]
    pin_deg: NDArray[np.float64]
    loaded_bend_deg: NDArray[np.float64]
    unloaded_bend_deg: NDArray[np.float64]
    springback_deg: NDArray[np.float64]
    lever_mm: NDArray[np.float64]
    pin_angle_deg: NDArray[np.float64]  # machine frame, as a photo of the loaded bend shows it

    def to_dict(self) -> dict[str, Any]:
        return {k: np.asarray(v).tolist() for k, v in self.__dict__.items()}

    def rows(self, trial: Iterable[Any] | None = None) -> list[dict[str, Any]]:
        """One dict per bend with the simulate CSV columns."""
        n = self.pin_deg.shape[0]
        trials = list(trial) if trial is not None else list(range(1, n + 1))
        return [
            {
                "trial": trials[i],
                "commanded_pin_deg": float(self.commanded_pin_deg[i]),
                "pin_deg": float(self.pin_deg[i]),
                "loaded_bend_deg": float(self.loaded_bend_deg[i]),
                "unloaded_bend_deg": float(self.unloaded_bend_deg[i]),
                "springback_deg": float(self.springback_deg[i]),
            }
            for i in range(n)
        ]


def add_noise(result: SimResult, noise_deg: float, rng: np.random.Generator) -> SimResult:
    """``result`` with Gaussian noise (deg) on the loaded, unloaded and pin angles, as measured.

    Springback is recomputed from the noisy angles; the commands and the true
    head rotation ``pin_deg`` are kept.
    """
    n = result.loaded_bend_deg.shape[0]
    loaded = result.loaded_bend_deg + rng.normal(0.0, noise_deg, n)
    unloaded = result.unloaded_bend_deg + rng.normal(0.0, noise_deg, n)
    pin = wrap_deg(result.pin_angle_deg + rng.normal(0.0, noise_deg, n))
    return SimResult(
        commanded_pin_deg=result.commanded_pin_deg,
        pin_deg=result.pin_deg,
        loaded_bend_deg=loaded,
        unloaded_bend_deg=unloaded,
        springback_deg=np.sign(loaded) * (loaded - unloaded),
        lever_mm=result.lever_mm,
        pin_angle_deg=np.asarray(pin, dtype=np.float64),
    )


def effect_values(effects: Iterable[Effect]) -> dict[str, float]:
    """``{name: value}`` of the effects (``none`` dropped); a repeated name raises."""
    out: dict[str, float] = {}
    for e in effects:
        if e.name == "none":
            continue
        if e.name in out:
            raise ValueError(f"effect {e.name} given twice")
        out[e.name] = float(e.value)
    return out


def _shapes(effects: Iterable[Effect]) -> dict[str, float]:
    """Every shape parameter of the effects switched on (defaults filled in)."""
    return {s.key: e.shape_value(s.key) for e in effects if e.name != "none" for s in e.spec.shape}


def apply_camera_tilt_deg(
    angle_deg: ArrayLike, tilt_deg: float, axis_deg: float = 0.0
) -> NDArray[np.float64]:
    """Angles (deg, from the feed leg +x) as seen by a camera tilted by ``tilt_deg``.

    The tilt is about an axis in the bending plane at ``axis_deg`` from +x (0: the
    feed axis, ``tan t' = tan t cos(tau)``); orthographic view, so a direction ``v``
    is seen as ``R(psi) diag(1, cos tau) R(-psi) v`` and the angle is measured from
    the image of the feed leg.
    """
    t = np.radians(np.asarray(angle_deg, dtype=np.float64))
    c = np.cos(np.radians(tilt_deg))
    psi = np.radians(axis_deg)

    def seen(a: NDArray[np.float64] | float) -> NDArray[np.float64]:
        u = np.cos(np.asarray(a) - psi)  # along the axis: kept
        v = np.sin(np.asarray(a) - psi) * c  # across it: foreshortened
        return np.arctan2(v, u) + psi

    return np.degrees(wrap_rad(seen(t) - seen(0.0)))


def wrap_rad(a: NDArray[np.float64]) -> NDArray[np.float64]:
    """Angles (rad) wrapped to [-pi, pi)."""
    return mod_positive(np.asarray(a) + np.pi, 2 * np.pi) - np.pi


@dataclass(frozen=True)
class _History:
    """What each bend inherits from the bends before it (rows in the order executed)."""

    direction: NDArray[np.float64]
    reversal: NDArray[np.bool_]  # first bend of a run, or direction changed
    run: NDArray[np.int64]  # run id: a re-home (bend_index back to 0 or down) starts one
    bend_index: NDArray[np.float64]  # as given

    @classmethod
    def of(cls, cmd: NDArray[np.float64], bend_index: NDArray[np.float64]) -> _History:
        key = (cmd.tobytes(), bend_index.tobytes())  # a fit simulates one plan many times
        known = _HISTORIES.get(key)
        if known is not None:
            return known
        bend_index = bend_index.copy()
        direction = np.where(cmd < 0, -1.0, 1.0)
        prev_index = np.concatenate([[np.inf], bend_index[:-1]])
        start = (bend_index <= prev_index) | (bend_index == 0)
        prev_dir = np.concatenate([[0.0], direction[:-1]])
        reversal = start | (direction != prev_dir)
        out = cls(direction, reversal, np.cumsum(start) - 1, bend_index)
        for a in (out.direction, out.reversal, out.run, out.bend_index):
            a.setflags(write=False)  # shared by every simulation of the same plan
        if len(_HISTORIES) >= 8:
            _HISTORIES.clear()  # (single dict operations: safe beside a simulating thread)
        _HISTORIES[key] = out
        return out

    def accumulated(self, step: NDArray[np.float64]) -> NDArray[np.float64]:
        """``sum step_j`` over the earlier bends of each bend's run (along the last axis:
        leading axes, if any, are independent simulations of the same plan)."""
        before = np.cumsum(step, axis=-1) - step
        first = np.searchsorted(self.run, self.run)  # index of each run's first bend
        return before - before[..., first]

    def home_shift(self, loss_deg: NDArray[np.float64]) -> NDArray[np.float64]:
        """Signed home shift of each bend: ``-sum s_j loss_j`` over earlier bends of its run."""
        return -self.accumulated(self.direction * loss_deg)


#: The histories of the last plans simulated (keyed by commands and bend indices).
_HISTORIES: dict[tuple[bytes, bytes], _History] = {}

#: The nominal head geometries of the last plans simulated and their contact angles
#: (keyed by the machine's circles and the bends' directions).
_GEOMETRIES: dict[tuple[Any, ...], tuple[HeadGeometry, NDArray[np.float64]]] = {}


def _nominal_geometry(
    params: SimParams, direction: NDArray[np.float64]
) -> tuple[HeadGeometry, NDArray[np.float64]]:
    """``head_geometry(params, direction)`` and its contact angle (deg), made once per
    machine geometry and plan: a fit simulates the same circles at every point (only the
    material, or the die radius among the nuisance, changes between its points)."""
    key = (
        params.die_radius_mm,
        params.wire_diameter_mm,
        params.pin_radius_mm,
        params.pin_orbit_mm,
        params.head_axis_x_mm,
        params.head_axis_y_mm,
        direction.tobytes(),
    )
    known = _GEOMETRIES.get(key)
    if known is not None:
        return known
    geom = head_geometry(params, direction)
    contact = np.asarray(contact_angle_deg(geom), dtype=np.float64)
    for a in (geom.axis_y_mm, contact):
        if isinstance(a, np.ndarray):
            a.setflags(write=False)  # shared by every simulation of the same geometry
    if len(_GEOMETRIES) >= 16:
        _GEOMETRIES.clear()  # (single dict operations: safe beside a simulating thread)
    _GEOMETRIES[key] = (geom, contact)
    return geom, contact


#: Reference pin torque of the drift's load law (N m) for a wire of
#: :data:`DRIFT_REFERENCE_WIRE_MM`: d is the loss per bend at this load.
DRIFT_REFERENCE_TORQUE_NM = 3.0
#: Wire diameter (mm) the reference torque is given for (a DIWire's).
DRIFT_REFERENCE_WIRE_MM = 3.0


def drift_reference_torque_nm(params: SimParams) -> float:
    """The drift load law's reference torque (N m) on the machine ``params`` describes.

    In proportion to the wire's diameter cubed (the pin torque of a machine bending the
    same wire material at the same strains grows as ``d^3``: the moment as ``d^3``, the
    lever and the arm alike), so that a similar machine described at another size has the
    same load ratio ``T / T_ref``, hence the same drift at the same ``d`` and ``p``: with a
    fixed DIWire torque, the load exponent's change carried ``p ln(k^3)`` of a machine
    described ``k`` times larger, which the drift's rate alone could not tell from it (a
    drift named on a session was not named when its machine was described at twice or
    half its size).
    """
    return DRIFT_REFERENCE_TORQUE_NM * (params.wire_diameter_mm / DRIFT_REFERENCE_WIRE_MM) ** 3


def _rotation(
    cmd: NDArray[np.float64],
    values: dict[str, float],
    shapes: dict[str, float],
    history: _History,
    load_ratio: NDArray[np.float64] | None,
) -> NDArray[np.float64]:
    """Head rotation magnitude (>= 0) after the command effects; ``load_ratio``: the pin
    torque over the drift's reference torque (:func:`drift_reference_torque_nm`)."""
    direction = history.direction
    r = np.abs(cmd)
    if "scale" in values:
        r = r * (1.0 + values["scale"])
    if "offset" in values:
        r = r + direction * values["offset"]
    if "backlash" in values:
        share = shapes.get("same_direction_share", 1.0)
        r = r - values["backlash"] * np.where(history.reversal, 1.0, share)
    if "drift" in values:
        p = shapes.get("load_exponent", 0.0)
        share = shapes.get("home_shift", 0.0)
        if p == 0.0 and share == 0.0 and shapes.get("step_deg", 0.0) == 0.0:
            # the spec's helix: bend k loses d k whatever the order (bend_index as given)
            r = r - values["drift"] * history.bend_index
        else:
            if p == 0.0 or load_ratio is None:
                loss = values["drift"] + np.zeros(r.shape)  # (a batch of rates: (K, N))
            else:
                loss = values["drift"] * np.maximum(load_ratio, 0.0) ** p
            step = shapes.get("step_deg", 0.0)
            if step > 0.0:  # steps lost whole: the run's accumulated loss, rounded
                before = history.accumulated(loss)
                loss = step * (
                    np.floor((before + loss) / step + 0.5) - np.floor(before / step + 0.5)
                )
            r = r - (1.0 - share) * history.accumulated(loss)
            r = r + share * direction * history.home_shift(loss)
    return np.maximum(r, 0.0)


def _torque_nm(
    law: SpringbackLaw,
    params: SimParams,
    phi_deg: NDArray[np.float64],
    theta_l: NDArray[np.float64],
    lever: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Pin torque about the head axis (N m) while the pin loads the wire: the pin force
    ``M / l`` is normal to the free leg (direction ``theta_l``, die frame), so its arm
    about the head axis is the orbit radius' component along the leg,
    ``R_p |cos(phi - theta_l)|`` (``phi``: the pin's angle about the axis, deg)."""
    arm_mm = params.pin_orbit_mm * np.abs(np.cos(np.radians(phi_deg - theta_l)))
    torque = law.moment_nmm / np.maximum(lever, 1e-3) * arm_mm / 1e3
    return np.where(theta_l > 0, torque, 0.0)


def _pin_seen_deg(
    geom: HeadGeometry, nominal: HeadGeometry, phi_deg: NDArray[np.float64]
) -> NDArray[np.float64]:
    """The pin's angle (deg, mirrored die frame of the bend) seen from the origin marker.

    The marker sits on the die at the head axis the machine was built with (``nominal``);
    a photo reads the pin from it. An axis offset moves the pin's orbit, not the marker:
    with the axis ``e`` off it, the reading is ``phi + (e / R_p) cos(phi)`` (rad) to first
    order, not the head's own angle ``phi``.
    """
    if geom is nominal:
        return phi_deg
    phi = np.radians(phi_deg)
    dx = np.asarray(geom.axis_x_mm) - np.asarray(nominal.axis_x_mm)
    dy = np.asarray(geom.axis_y_mm) - np.asarray(nominal.axis_y_mm)
    seen = np.arctan2(dy + geom.pin_orbit_mm * np.sin(phi), dx + geom.pin_orbit_mm * np.cos(phi))
    # the same turn as phi (continuous past 180 deg): only the small difference is wrapped
    return phi_deg + np.degrees(wrap_rad(seen - phi))


def _forward(
    cmd: NDArray[np.float64],
    params: SimParams,
    values: dict[str, float],
    bend_index: NDArray[np.float64],
    law: SpringbackLaw,
    *,
    measure: bool = True,
    shapes: dict[str, float] | None = None,
    die_wrap_mm: NDArray[np.float64] | None = None,
) -> SimResult:
    """The simulation (see :func:`simulate`); ``die_wrap_mm``: the die's centreline
    radius (mm) in place of the params' one, e.g. one per row of :func:`simulate_rows`
    (the contact angle does not depend on it)."""
    shapes = shapes or {}
    history = _History.of(cmd, bend_index)
    direction = history.direction
    r = _rotation(cmd, values, shapes, history, None)
    nominal, nominal_contact = _nominal_geometry(params, direction)
    if die_wrap_mm is not None:
        nominal = dataclasses.replace(nominal, die_wrap_mm=die_wrap_mm)  # type: ignore[arg-type]
    if "axis_offset" in values:
        geom = head_geometry(params, direction, axis_offset_mm=values["axis_offset"])
        if die_wrap_mm is not None:
            geom = dataclasses.replace(geom, die_wrap_mm=die_wrap_mm)  # type: ignore[arg-type]
        contact = contact_angle_deg(geom)
    else:
        geom, contact = nominal, nominal_contact  # the same circles (an offset of 0 adds nothing)
    phi0 = nominal_contact - params.approach_deg
    phi = phi0 + r
    theta_l, lever = loaded_angle_and_lever(geom, phi, contact_deg=contact)
    # a springback that differs by direction is a wire whose strength differs by direction
    # (coil set): the moment it takes, hence the pin's torque, differs in the same ratio
    load = (
        1.0 + direction * values["springback_asymmetry"]
        if "springback_asymmetry" in values
        else 1.0
    )
    if "drift" in values and shapes.get("load_exponent", 0.0) > 0.0:
        # the steps a bend loses depend on its own load: iterate to the fixed point
        reference = drift_reference_torque_nm(params)
        for _ in range(_DRIFT_ITERATIONS):
            torque = load * _torque_nm(law, params, phi, theta_l, lever)
            r = _rotation(cmd, values, shapes, history, torque / reference)
            phi = phi0 + r
            theta_l, lever = loaded_angle_and_lever(geom, phi, contact_deg=contact)
    if np.any(values.get("compliance", 0.0) > 0.0):  # (a batch of rows: all > 0)
        # the drive winds up under the pin load: torque = (M / l) * R_p cos(phi - theta); the lag
        # shortens the lever it depends on, so iterate to the fixed point
        for _ in range(_COMPLIANCE_ITERATIONS):
            lag = values["compliance"] * load * _torque_nm(law, params, phi, theta_l, lever)
            phi = phi0 + np.maximum(r - lag, 0.0)
            theta_l, lever = loaded_angle_and_lever(geom, phi, contact_deg=contact)
        r = phi - phi0
    pin_machine = wrap_deg(direction * _pin_seen_deg(geom, nominal, phi))
    affine = law.wrap_slope * theta_l + law.intercept_deg(lever)
    if "springback_asymmetry" in values:
        affine = affine * (1.0 + direction * values["springback_asymmetry"])
    if "springback_asymmetry" in values and shapes.get("loaded_deg", 0.0):
        # the span's curvature follows the wire's strength by direction: the loaded leg
        # (and the released one with it) moves by loaded_deg per unit of asymmetry
        shift = shapes["loaded_deg"] * direction * values["springback_asymmetry"]
        theta_l = np.where(theta_l > 0, np.maximum(theta_l + shift, 0.0), theta_l)
    if params.span_bow_share:
        # the leg beyond the pin leads the chord by (a share of) the span's elastic bow;
        # released, that elastic curvature is part of the span term, so the bow moves
        # the loaded and the released angle alike
        theta_l = theta_l + params.span_bow_share * law.span_bow_deg(theta_l, lever)
    sb = np.minimum(np.maximum(affine, 0.0), theta_l)  # np.clip's values, less overhead
    loaded = direction * theta_l
    unloaded = direction * (theta_l - sb)
    if measure and "camera_tilt" in values:
        axis = shapes.get("tilt_axis_deg", 0.0)
        loaded = apply_camera_tilt_deg(loaded, values["camera_tilt"], axis)
        unloaded = apply_camera_tilt_deg(unloaded, values["camera_tilt"], axis)
        pin_machine = apply_camera_tilt_deg(pin_machine, values["camera_tilt"], axis)
    springback = np.sign(loaded) * (loaded - unloaded)
    return SimResult(
        commanded_pin_deg=cmd,
        pin_deg=direction * r,
        loaded_bend_deg=loaded,
        unloaded_bend_deg=unloaded,
        springback_deg=springback,
        lever_mm=lever,
        pin_angle_deg=np.asarray(pin_machine, dtype=np.float64),
    )


def _bend_index(bend_index: ArrayLike | None, n: int) -> NDArray[np.float64]:
    if bend_index is None:
        return np.arange(n, dtype=np.float64)
    k = np.asarray(bend_index, dtype=np.float64)
    if k.shape != (n,):
        raise ValueError(f"bend_index must have shape ({n},), got {k.shape}")
    return k


def _commands(commanded_pin_deg: ArrayLike) -> NDArray[np.float64]:
    """The signed pin commands (deg) as a finite 1-D float array; ValueError otherwise."""
    cmd = np.atleast_1d(np.asarray(commanded_pin_deg, dtype=np.float64))
    if cmd.ndim != 1 or not np.isfinite(cmd).all():
        raise ValueError("commanded_pin_deg must be a finite 1-D array")
    return cmd


def simulate(
    commanded_pin_deg: ArrayLike,
    params: SimParams | None = None,
    effects: Iterable[Effect] = (),
    *,
    bend_index: ArrayLike | None = None,
) -> SimResult:
    """Simulate bends for signed pin commands (deg of head rotation from home).

    Parameters
    ----------
    commanded_pin_deg : array_like of shape (N,)
        Signed head rotation commands, in the order executed; negative bends
        clockwise.
    params : SimParams, optional
        Machine and wire (defaults: 3 mm low-carbon steel, DIWire-like head).
    effects : iterable of Effect
        Effects switched on (see :mod:`cvmeasure.sim.effects`).
    bend_index : array_like of shape (N,), optional
        Number of bends executed before each one (drift); default 0..N-1.

    Returns
    -------
    SimResult
        Angles in degrees, signed like the command, as a camera would measure
        them (measurement effects included).

    Raises
    ------
    ValueError
        An effect outside its physical bounds on this machine (a sized effect's bounds
        scale with the machine: :func:`cvmeasure.sim.effects.effect_spec_for`), or
        commands that are not a finite 1-D array.
    """
    params = params or SimParams()
    cmd = _commands(commanded_pin_deg)
    effects = tuple(effects)
    check_effect_bounds(effects, params)
    values = effect_values(effects)
    k = _bend_index(bend_index, cmd.size)
    return _forward(cmd, params, values, k, springback_law(params), shapes=_shapes(effects))


def simulate_drift_rates(
    commanded_pin_deg: ArrayLike,
    params: SimParams,
    effects: Iterable[Effect],
    rates: ArrayLike,
    *,
    bend_index: ArrayLike | None = None,
) -> SimResult:
    """:func:`simulate` at many values of the drift at once, in one vectorised run.

    ``effects`` must include ``drift`` (its form is kept, its value replaced): row ``k``
    of every angle array, of shape (K, N), is what :func:`simulate` gives with the drift
    at ``rates[k]`` (deg per bend, within the drift's bounds), the same numbers (every
    operation is elementwise along the rates, the run sums along the bends). For a fit
    that profiles a drift losing whole steps over a grid of rates: one simulation instead
    of K.
    """
    cmd = _commands(commanded_pin_deg)
    effects = tuple(effects)
    values: dict[str, Any] = dict(effect_values(effects))
    if "drift" not in values:
        raise ValueError("simulate_drift_rates needs the drift among the effects")
    values["drift"] = np.asarray(rates, dtype=np.float64).reshape(-1, 1)
    k = _bend_index(bend_index, cmd.size)
    shapes = _shapes(effects)
    res = _forward(cmd, params, values, k, springback_law(params), shapes=shapes)
    rows = values["drift"].shape[0]
    return dataclasses.replace(
        res,
        **{
            f.name: np.broadcast_to(getattr(res, f.name), (rows, cmd.size))
            for f in dataclasses.fields(res)
            if f.name != "commanded_pin_deg"
        },
    )


#: The params fields that may differ between the rows of :func:`simulate_rows`: the
#: material's strength (it changes the springback law only) and the die's radius (the
#: law and the die's circle: not the contact angle).
_ROW_FIELDS = ("yield_mpa", "uts_mpa", "die_radius_mm")
#: The params fields every row of :func:`simulate_rows` shares.
_SHARED = operator.attrgetter(
    *(f.name for f in dataclasses.fields(SimParams) if f.name not in _ROW_FIELDS)
)


def _column(values: Sequence[float]) -> float | NDArray[np.float64]:
    """The rows' common value, or a (K, 1) column of them where they differ."""
    first = values[0]
    if all(v == first for v in values):
        return first
    return np.array(values, dtype=np.float64)[:, None]


def _stacked(laws: Sequence[SpringbackLaw], fields: tuple[str, ...]) -> SpringbackLaw:
    """The rows' springback laws as one law whose ``fields`` are (K, 1) columns where they
    differ; ValueError when another field differs."""
    law = laws[0]
    if any(other != law for other in laws):
        rest = [f.name for f in dataclasses.fields(law) if f.name not in fields]
        if any(getattr(o, n) != getattr(law, n) for o in laws for n in rest):
            raise ValueError("simulate_rows: the rows' wires differ beyond the strength")
        columns = {n: _column([getattr(o, n) for o in laws]) for n in fields}
        law = dataclasses.replace(law, **columns)  # type: ignore[arg-type]
    return law


def simulate_rows(
    commanded_pin_deg: ArrayLike,
    params_rows: Sequence[SimParams],
    effects_rows: Sequence[Sequence[Effect]],
    *,
    bend_index: ArrayLike | None = None,
) -> SimResult:
    """:func:`simulate` of K models of the same plan in one vectorised run.

    Row ``k`` of every angle array, of shape (K, N), is what :func:`simulate` gives with
    ``params_rows[k]`` and ``effects_rows[k]``, the same numbers (every operation is
    elementwise along the rows). The rows may differ in the effects' values, the
    material's strength (yield and UTS) and the die's radius only: the same effects with
    the same forms in the same order, the rest of the machine the same; ValueError
    otherwise (and for a compliance on in some rows only). For the forward differences of a fit: one simulation per Jacobian
    instead of one per column.
    """
    cmd = _commands(commanded_pin_deg)
    rows = [tuple(e) for e in effects_rows]
    if not rows or len(rows) != len(params_rows):
        raise ValueError("simulate_rows needs one params and one effects per row")
    base = params_rows[0]
    shared = _SHARED(base)
    if any(p is not base and _SHARED(p) != shared for p in params_rows):
        raise ValueError("simulate_rows: the rows' params differ beyond the strength")
    forms = [(e.name, e.shape) for e in rows[0]]
    if any([(e.name, e.shape) for e in r] != forms for r in rows[1:]):
        raise ValueError("simulate_rows: the rows' effects differ beyond their values")
    per_row = [effect_values(r) for r in rows]
    values: dict[str, Any] = {name: _column([v[name] for v in per_row]) for name in per_row[0]}
    if isinstance(values.get("compliance"), np.ndarray) and not np.all(values["compliance"] > 0):
        raise ValueError("simulate_rows: the compliance is on in some rows only")
    laws = [springback_law(p) for p in params_rows]
    law = _stacked(laws, ("moment_nmm", "bend_radius_mm"))
    # head_geometry's die circle, row by row
    wrap = _column([p.die_radius_mm + p.wire_radius_mm for p in params_rows])
    res = _forward(
        cmd,
        base,
        values,
        _bend_index(bend_index, cmd.size),
        law,
        shapes=_shapes(rows[0]),
        die_wrap_mm=wrap if isinstance(wrap, np.ndarray) else None,
    )
    shape = (len(rows), cmd.size)

    def full(a: NDArray[np.float64]) -> NDArray[np.float64]:
        return a if a.shape == shape else np.broadcast_to(a, shape)

    return SimResult(
        commanded_pin_deg=cmd,
        pin_deg=full(res.pin_deg),
        loaded_bend_deg=full(res.loaded_bend_deg),
        unloaded_bend_deg=full(res.unloaded_bend_deg),
        springback_deg=full(res.springback_deg),
        lever_mm=full(res.lever_mm),
        pin_angle_deg=full(res.pin_angle_deg),
    )


def max_reachable_deg(params: SimParams | None = None, effects: Iterable[Effect] = ()) -> float:
    """Largest final (unloaded) bend angle (deg) the inverse can reach in either direction."""
    params = params or SimParams()
    effects = tuple(effects)
    values = effect_values(effects)
    probe = np.array([_MAX_ROTATION_DEG, -_MAX_ROTATION_DEG])
    res = _forward(
        probe,
        params,
        values,
        np.zeros(2),
        springback_law(params),
        measure=False,
        shapes=_shapes(effects),
    )
    return min(float(np.min(np.abs(res.unloaded_bend_deg))), _MAX_BEND_DEG)


def pin_command_for_angle(
    target_bend_deg: ArrayLike,
    params: SimParams | None = None,
    effects: Iterable[Effect] = (),
    *,
    bend_index: ArrayLike | None = None,
    iterations: int = 56,
) -> float | NDArray[np.float64]:
    """The signed pin command (deg of head rotation from home) giving a wanted final angle.

    Inverts :func:`simulate` for the *unloaded* (final) bend angle, with the
    machine and springback effects given; measurement effects (camera tilt)
    do not change the part and are ignored. Used by the G-code generator.

    Parameters
    ----------
    target_bend_deg : float or array_like of shape (N,)
        Wanted final bend angle(s), signed (negative = clockwise), degrees.
    params, effects, bend_index
        As for :func:`simulate`.

    Returns
    -------
    float or ndarray
        Command(s) in degrees, same shape as the target. A target of 0 gives 0.

    Raises
    ------
    ValueError
        If a target is beyond :func:`max_reachable_deg`.

    Examples
    --------
    >>> cmd = pin_command_for_angle(90.0)
    >>> round(float(simulate([cmd]).unloaded_bend_deg[0]), 6)
    90.0
    """
    params = params or SimParams()
    target = np.asarray(target_bend_deg, dtype=np.float64)
    flat = np.atleast_1d(target).ravel()
    if not np.all(np.isfinite(flat)):
        raise ValueError("target_bend_deg must be finite")
    effects = tuple(effects)
    values = effect_values(effects)
    shapes = _shapes(effects)
    k = _bend_index(bend_index, flat.size)
    law = springback_law(params)
    direction = np.where(flat < 0, -1.0, 1.0)
    goal = np.abs(flat)
    reach = max_reachable_deg(params, effects)
    if np.any(goal > reach):
        raise ValueError(
            f"target bend {flat[np.argmax(goal)]:.2f} deg is beyond the reachable {reach:.2f} deg"
        )
    hi = np.full(flat.shape, _MAX_ROTATION_DEG)
    lo = np.zeros(flat.shape)
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        res = _forward(direction * mid, params, values, k, law, measure=False, shapes=shapes)
        below = np.abs(res.unloaded_bend_deg) < goal
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    cmd = direction * 0.5 * (lo + hi)
    cmd = np.where(goal == 0, 0.0, cmd)
    return float(cmd[0]) if target.ndim == 0 else cmd.reshape(target.shape)
