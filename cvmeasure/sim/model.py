"""The forward model (pin command -> loaded and unloaded bend angle) and its inverse.

One bend, vectorised over many::

    r       = command effects(commanded_pin_deg)      # backlash, offset, scale, drift
    phi     = phi_contact - approach_deg + |r|         # head angle, die frame of the bend
    phi    -= compliance * (M / l(phi)) * R_p          # drive wind-up under the pin load
    theta_L = tangent construction(phi)                # loaded angle (>= 0), lever l
    sb      = min(theta_L, (b theta_L + a(l)) (1 + s alpha))
    theta_U = theta_L - sb
    measured angles = camera(s * theta_L), camera(s * theta_U)

Signs (spec): a negative command bends the other way (clockwise); angles are
signed like the command; ``springback_deg = sign(loaded) * (loaded - unloaded)``.
``pin_deg`` is the actual signed head rotation from home after the command
effects (what the head really did), in the units of the command;
``pin_angle_deg`` is the same pin position in the machine frame of the spec
(angle of origin -> pin from +x, origin = head axis), as a photo of the loaded
bend measures it: ``dir * (phi_contact - approach_deg + |r|)``.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cvmeasure.geometry import wrap_deg
from cvmeasure.sim.effects import Effect
from cvmeasure.sim.kinematics import contact_angle_deg, head_geometry, loaded_angle_and_lever
from cvmeasure.sim.params import SimParams
from cvmeasure.sim.springback import SpringbackLaw, springback_law

__all__ = [
    "SimResult",
    "simulate",
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


def apply_camera_tilt_deg(angle_deg: ArrayLike, tilt_deg: float) -> NDArray[np.float64]:
    """Angles (deg, from +x) as seen by a camera tilted by ``tilt_deg`` about the feed axis."""
    t = np.radians(np.asarray(angle_deg, dtype=np.float64))
    c = np.cos(np.radians(tilt_deg))
    return np.degrees(np.arctan2(np.sin(t) * c, np.cos(t)))


def _rotation(
    cmd: NDArray[np.float64], values: dict[str, float], bend_index: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(direction, head rotation magnitude >= 0) after the command effects."""
    direction = np.where(cmd < 0, -1.0, 1.0)
    r = np.abs(cmd)
    if "scale" in values:
        r = r * (1.0 + values["scale"])
    if "offset" in values:
        r = r + direction * values["offset"]
    if "backlash" in values:
        r = r - values["backlash"]
    if "drift" in values:
        r = r - values["drift"] * bend_index
    return direction, np.maximum(r, 0.0)


def _forward(
    cmd: NDArray[np.float64],
    params: SimParams,
    values: dict[str, float],
    bend_index: NDArray[np.float64],
    law: SpringbackLaw,
    *,
    measure: bool = True,
) -> SimResult:
    direction, r = _rotation(cmd, values, bend_index)
    nominal = head_geometry(params, direction)
    geom = head_geometry(params, direction, axis_offset_mm=values.get("axis_offset", 0.0))
    phi0 = contact_angle_deg(nominal) - params.approach_deg
    phi = phi0 + r
    theta_l, lever = loaded_angle_and_lever(geom, phi)
    if values.get("compliance", 0.0) > 0.0:
        # the drive winds up under the pin load: torque = (M / l) * R_p; the lag
        # shortens the lever it depends on, so iterate to the fixed point
        for _ in range(_COMPLIANCE_ITERATIONS):
            torque_nm = law.moment_nmm / np.maximum(lever, 1e-3) * params.pin_orbit_mm / 1e3
            lag = np.where(theta_l > 0, values["compliance"] * torque_nm, 0.0)
            phi = phi0 + np.maximum(r - lag, 0.0)
            theta_l, lever = loaded_angle_and_lever(geom, phi)
        r = phi - phi0
    pin_machine = wrap_deg(direction * phi)
    affine = law.wrap_slope * theta_l + law.intercept_deg(lever)
    if "springback_asymmetry" in values:
        affine = affine * (1.0 + direction * values["springback_asymmetry"])
    sb = np.clip(affine, 0.0, theta_l)
    loaded = direction * theta_l
    unloaded = direction * (theta_l - sb)
    if measure and "camera_tilt" in values:
        loaded = apply_camera_tilt_deg(loaded, values["camera_tilt"])
        unloaded = apply_camera_tilt_deg(unloaded, values["camera_tilt"])
        pin_machine = apply_camera_tilt_deg(pin_machine, values["camera_tilt"])
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
    """
    params = params or SimParams()
    cmd = np.atleast_1d(np.asarray(commanded_pin_deg, dtype=np.float64))
    if cmd.ndim != 1 or not np.all(np.isfinite(cmd)):
        raise ValueError("commanded_pin_deg must be a finite 1-D array")
    values = effect_values(effects)
    return _forward(cmd, params, values, _bend_index(bend_index, cmd.size), springback_law(params))


def max_reachable_deg(params: SimParams | None = None, effects: Iterable[Effect] = ()) -> float:
    """Largest final (unloaded) bend angle (deg) the inverse can reach in either direction."""
    params = params or SimParams()
    values = effect_values(effects)
    probe = np.array([_MAX_ROTATION_DEG, -_MAX_ROTATION_DEG])
    res = _forward(probe, params, values, np.zeros(2), springback_law(params), measure=False)
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
    values = effect_values(effects)
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
        res = _forward(direction * mid, params, values, k, law, measure=False)
        below = np.abs(res.unloaded_bend_deg) < goal
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    cmd = direction * 0.5 * (lo + hi)
    cmd = np.where(goal == 0, 0.0, cmd)
    return float(cmd[0]) if target.ndim == 0 else cmd.reshape(target.shape)
