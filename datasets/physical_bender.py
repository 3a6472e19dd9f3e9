"""An independent physical model of the bender, to judge the diagnosis on (not ``simulate``).

``cvmeasure.sim.simulate`` is what the diagnosis fits; judging it on data from the
same code hides every model-form error. This generator is written separately
(it imports nothing from :mod:`cvmeasure.sim`) and differs in its physics:

- **wire**: Voce hardening ``sigma = sigma_y + Q (1 - exp(-b eps_p)) + H eps_p``
  (the fitted model uses Swift's power law), integrated over the round section
  by strips; elastic unloading with a chord modulus that falls with plastic
  strain (Yoshida-Uemori style: ``E_u = E (1 - D (1 - exp(-xi eps_p))``);
- **bend**: the wire wraps tangentially on the die edge (curvature ``1 / a_d``);
  the free span carries a moment falling linearly to the pin, its curvature
  from the inverted moment-curvature law; the leg beyond the pin leaves at the
  chord angle plus the span's elastic bow ``int (s / l) kappa_el ds`` (the
  fitted model has a straight leg); springback integrates ``M / (E_u I)`` over
  the wrap and the span;
- **drive**: effects act on a motor -> head chain with history: gear play taken
  up on direction reversals, steps lost under load in whole quanta (carried),
  shifting home; compliance from the pin force times its arm about the head axis;
- **measurement**: each bend's loaded and released photo share one error (the
  feed-leg reference line of that bend) plus independent photo noise; a camera
  tilt about any axis of the plane.

Hidden effects carry the catalogue's names in their general forms, and four
mechanisms the catalogue does not name (:data:`OUTSIDE`). Plans: random order,
sweeps, and runs of repeated identical commands.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.contracts import TrialTable

__all__ = [
    "CATALOGUE",
    "OUTSIDE",
    "PLANS",
    "Machine",
    "Hidden",
    "PhysicalCase",
    "bend",
    "draw_hidden",
    "draw_machine",
    "loaded_pin_deg",
    "plan_commands",
    "physical_case",
    "run_follow_up",
]

#: Catalogue causes the generator can hide (general forms).
CATALOGUE: tuple[str, ...] = (
    "backlash",
    "offset",
    "scale",
    "drift",
    "springback_asymmetry",
    "camera_tilt",
    "axis_offset",
    "compliance",
)
#: Mechanisms outside the catalogue.
OUTSIDE: tuple[str, ...] = ("gear_runout", "warm_up", "short_segment", "springback_scatter")
#: Plan types.
PLANS: tuple[str, ...] = ("random", "sweep", "repeats")


@dataclass(frozen=True)
class Machine:
    """The true wire and head of one machine (mm, MPa, deg)."""

    wire_diameter_mm: float = 3.0
    youngs_modulus_mpa: float = 200_000.0
    yield_mpa: float = 280.0
    voce_q_mpa: float = 170.0  # saturating hardening
    voce_b: float = 14.0
    hardening_slope_mpa: float = 300.0  # linear hardening beyond the saturation
    modulus_drop: float = 0.12  # D: chord modulus falls by up to this share
    modulus_rate: float = 40.0  # xi
    die_radius_mm: float = 1.5
    pin_radius_mm: float = 2.5
    pin_orbit_mm: float = 12.0
    head_axis_x_mm: float = 0.0
    head_axis_y_mm: float = 0.0
    home_pin_deg: float = -32.67  # pin angle at home (die frame): contact - 13.2 deg approach

    @property
    def wire_radius_mm(self) -> float:
        return 0.5 * self.wire_diameter_mm

    @property
    def inertia_mm4(self) -> float:
        return math.pi * self.wire_radius_mm**4 / 4.0


@dataclass(frozen=True)
class Hidden:
    """A hidden mechanism and its parameters (keys as the catalogue's JSON where named)."""

    name: str = "none"
    params: dict[str, float] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {"name": self.name, **self.params}


# ----------------------------------------------------------------------------- the wire


def _flow_mpa(m: Machine, eps: NDArray[np.float64], strength: float) -> NDArray[np.float64]:
    e = m.youngs_modulus_mpa
    sy = m.yield_mpa * strength
    eps_y = sy / e
    ep = np.maximum(np.abs(eps) - eps_y, 0.0)
    flow = sy + strength * (
        m.voce_q_mpa * (1.0 - np.exp(-m.voce_b * ep)) + m.hardening_slope_mpa * ep
    )
    return np.where(np.abs(eps) <= eps_y, e * np.abs(eps), flow)


_STRIPS = 200


def _moment_nmm(m: Machine, kappa: NDArray[np.float64], strength: float) -> NDArray[np.float64]:
    """Moment (N mm) at curvature(s) kappa (1/mm): strips across the round section."""
    a = m.wire_radius_mm
    y = (np.arange(_STRIPS) + 0.5) / _STRIPS * a  # strip centres, one half
    width = 2.0 * np.sqrt(a * a - y * y)
    dy = a / _STRIPS
    k = np.atleast_1d(np.asarray(kappa, dtype=np.float64))[:, None]
    sigma = _flow_mpa(m, k * y[None, :], strength)
    return 2.0 * np.sum(sigma * y * width * dy, axis=1)


@functools.lru_cache(maxsize=64)
def _law(m: Machine, strength: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(kappa, M) table of the loading moment-curvature law (monotone)."""
    kappa = np.geomspace(1e-6, 2.0, 400)
    return kappa, _moment_nmm(m, kappa, strength)


def _kappa_of_moment(m: Machine, moment: NDArray[np.float64], strength: float) -> NDArray:
    kappa, table = _law(m, strength)
    return np.interp(moment, table, kappa, left=0.0)


def _chord_modulus(m: Machine, kappa: NDArray[np.float64], strength: float) -> NDArray:
    eps_y = m.yield_mpa * strength / m.youngs_modulus_mpa
    ep = np.maximum(kappa * m.wire_radius_mm - eps_y, 0.0)
    return m.youngs_modulus_mpa * (1.0 - m.modulus_drop * (1.0 - np.exp(-m.modulus_rate * ep)))


_SPAN_POINTS = 48


def _span(
    m: Machine, lever_mm: NDArray[np.float64], strength: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(tip slope over the chord, springback, die moment) of each bend's span (rad, rad, N mm)."""
    a_d = m.die_radius_mm + m.wire_radius_mm
    t = (np.arange(_SPAN_POINTS) + 0.5) / _SPAN_POINTS  # s / l
    tip = np.empty(lever_mm.shape)
    back = np.empty(lever_mm.shape)
    m0 = np.empty(lever_mm.shape)
    for st in np.unique(strength):
        sel = strength == st
        moment_die = float(_moment_nmm(m, np.array([1.0 / a_d]), float(st))[0])
        moment = moment_die * (1.0 - t)
        kappa = _kappa_of_moment(m, moment, float(st))
        e_u = _chord_modulus(m, kappa, float(st))
        lev = lever_mm[sel][:, None]
        # the leg beyond the pin runs ahead of the chord by the span's elastic bow; the
        # plastic curvature next to the die is part of the bend at the die edge
        bow = np.minimum(kappa, moment / (m.youngs_modulus_mpa * m.inertia_mm4))
        tip[sel] = np.sum(t * bow) / _SPAN_POINTS * lev[:, 0]
        back[sel] = np.sum(moment / (e_u * m.inertia_mm4)) / _SPAN_POINTS * lev[:, 0]
        m0[sel] = moment_die
    return tip, back, m0


def _wrap_springback(
    m: Machine, theta_rad: NDArray, moment_die: NDArray, strength: NDArray
) -> NDArray:
    a_d = m.die_radius_mm + m.wire_radius_mm
    e_u = np.array([_chord_modulus(m, np.array([1.0 / a_d]), float(s))[0] for s in strength])
    return moment_die / (e_u * m.inertia_mm4) * a_d * theta_rad


# ----------------------------------------------------------------------------- the head


def _tangent(
    m: Machine, pin_deg: NDArray[np.float64], axis_y_mm: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """(chord angle rad, lever mm, pin force arm about the head axis mm); chord 0 before contact."""
    a_d = m.die_radius_mm + m.wire_radius_mm
    rho_p = m.pin_radius_mm + m.wire_radius_mm
    phi = np.radians(pin_deg)
    px = m.head_axis_x_mm + m.pin_orbit_mm * np.cos(phi)
    py = axis_y_mm + m.pin_orbit_mm * np.sin(phi)
    dx, dy = px, py - a_d
    dist = np.hypot(dx, dy)
    psi = np.arctan2(dy, dx)
    psi = np.where(psi < -np.pi / 2, psi + 2 * np.pi, psi)
    sep = a_d + rho_p
    theta = psi + np.arcsin(np.clip(sep / np.maximum(dist, sep), -1.0, 1.0))
    lever = np.sqrt(np.maximum(dist**2 - sep**2, 1e-6))
    contact = py + rho_p >= 0.0
    theta = np.where(contact, np.maximum(theta, 0.0), 0.0)
    # the pin force is normal to the leg; its arm about the head axis
    nx, ny = -np.sin(theta), np.cos(theta)
    arm = np.abs((px - m.head_axis_x_mm) * ny - (py - axis_y_mm) * nx)
    return theta, lever, arm


# ----------------------------------------------------------------------------- one run of bends


@dataclass(frozen=True)
class Bends:
    """True and measured angles of a run (deg, signed like the command)."""

    loaded_deg: NDArray[np.float64]
    unloaded_deg: NDArray[np.float64]
    head_deg: NDArray[np.float64]  # true head rotation from home, signed
    torque_nm: NDArray[np.float64]


def bend(
    commands_deg: NDArray[np.float64],
    machine: Machine,
    hidden: tuple[Hidden, ...] = (),
    rng: np.random.Generator | None = None,
) -> Bends:
    """True loaded and released angles (camera effects applied, no noise) of a run of bends.

    Commands are signed head rotations from home in the order executed. ``rng``
    drives the stochastic mechanisms (springback scatter); None = their mean.
    """
    cmd = np.asarray(commands_deg, dtype=np.float64)
    n = cmd.size
    s = np.where(cmd < 0, -1.0, 1.0)
    h = {x.name: x.params for x in hidden}
    k = np.arange(n, dtype=np.float64)
    prev_s = np.concatenate([[0.0], s[:-1]])
    reversal = s != prev_s
    # -- the material of each bend (asymmetric yield by direction: coil set / Bauschinger)
    strength = np.ones(n)
    if "springback_asymmetry" in h:
        strength = 1.0 + s * h["springback_asymmetry"]["asymmetry"]
    # -- motor command -> head rotation magnitude (before load-dependent terms)
    r = np.abs(cmd)
    if "scale" in h:
        r = r * (1.0 + h["scale"]["scale"])
    if "offset" in h:
        r = r + s * h["offset"]["offset_deg"]
    if "backlash" in h:
        b = h["backlash"]["backlash_deg"]
        share = h["backlash"].get("same_direction_share", 1.0)
        r = r - b * np.where(reversal, 1.0, share)
    if "gear_runout" in h:
        g = h["gear_runout"]
        r = r + g["amplitude_deg"] * np.sin(2 * np.pi * r / g["period_deg"] + g["phase_rad"])
    if "warm_up" in h:
        w = h["warm_up"]
        r = r - w["amplitude_deg"] * (1.0 - np.exp(-k / (w["time_constant_bends"])))
    axis_y = s * (machine.head_axis_y_mm + h.get("axis_offset", {}).get("axis_offset_mm", 0.0))
    r_cmd = r.copy()
    torque = np.zeros(n)
    for _ in range(4):  # load-dependent terms: step loss and compliance need the load
        r = r_cmd.copy()
        if "drift" in h:
            d = h["drift"]
            quantum = d.get("quantum_deg", 0.06)
            rate = d["drift_deg_per_bend"] * (torque / 3.0) ** d.get("load_exponent", 0.0)
            rate = np.where(torque > 0, rate, 0.0 if d.get("load_exponent", 0.0) > 0 else rate)
            lost = np.diff(np.floor(np.cumsum(rate) / quantum + 0.5), prepend=0.0) * quantum
            home = -np.cumsum(s * lost) + s * lost  # shift left by earlier bends
            r = r + s * home
        if "compliance" in h:
            r = r - h["compliance"]["compliance_deg_per_nm"] * torque
        r = np.maximum(r, 0.0)
        chord, lever, arm = _tangent(machine, machine.home_pin_deg + r, axis_y)
        tip, back, m0 = _span(machine, lever, strength)
        force_n = m0 / np.maximum(lever, 1e-3)
        torque = np.where(chord > 0, force_n * arm / 1e3, 0.0)
    theta_l = np.where(chord > 0, chord + tip, 0.0)
    springback = back + _wrap_springback(machine, chord, m0, strength)
    if "springback_scatter" in h and rng is not None:
        c = h["springback_scatter"]["scatter_deg_per_100deg"]
        springback = springback + np.radians(c * np.degrees(theta_l) / 100.0) * rng.normal(size=n)
    theta_u = theta_l - np.clip(springback, 0.0, theta_l)
    loaded, unloaded = np.degrees(theta_l), np.degrees(theta_u)
    if "short_segment" in h:
        # the previous bend lies in the free span: the pin pushes a bent segment
        prev = np.concatenate([[0.0], s[:-1] * loaded[:-1]])
        extra = h["short_segment"]["coupling_deg"] * (prev * s) / 90.0
        loaded, unloaded = loaded + extra, unloaded + extra
    loaded, unloaded = s * loaded, s * unloaded
    if "camera_tilt" in h:
        c = h["camera_tilt"]
        loaded = _tilted(loaded, c["tilt_deg"], c.get("tilt_axis_deg", 0.0))
        unloaded = _tilted(unloaded, c["tilt_deg"], c.get("tilt_axis_deg", 0.0))
    return Bends(loaded, unloaded, s * r, torque)


def _tilted(angle_deg: NDArray[np.float64], tilt_deg: float, axis_deg: float) -> NDArray:
    """A camera tilted by tilt_deg about the in-plane axis at axis_deg: angle of the leg's
    image from the feed leg's image (orthographic projection of the plane)."""
    tau, psi = math.radians(tilt_deg), math.radians(axis_deg)
    rot = np.array([[math.cos(psi), -math.sin(psi)], [math.sin(psi), math.cos(psi)]])
    proj = rot @ np.diag([1.0, math.cos(tau)]) @ rot.T
    t = np.radians(angle_deg)
    leg = proj @ np.vstack([np.cos(t), np.sin(t)])
    feed = proj @ np.array([1.0, 0.0])
    ang = np.arctan2(leg[1], leg[0]) - math.atan2(feed[1], feed[0])
    return np.degrees((ang + np.pi) % (2 * np.pi) - np.pi)


def loaded_pin_deg(
    machine: Machine, head_deg: NDArray[np.float64], hidden: tuple[Hidden, ...] = ()
) -> NDArray[np.float64]:
    """The pin's angle on the loaded photo (machine frame, deg) for the true head rotation
    ``head_deg`` (:attr:`Bends.head_deg`), seen through the camera's tilt like the bends.
    The photo reads it from the origin marker, which sits on the die at the nominal head
    axis: a hidden axis offset moves the pin's orbit, not the marker."""
    s = np.where(head_deg < 0, -1.0, 1.0)
    phi = np.radians(machine.home_pin_deg + np.abs(head_deg))  # about the true axis
    e = sum(h.params["axis_offset_mm"] for h in hidden if h.name == "axis_offset")
    seen = np.arctan2(
        e * s + machine.pin_orbit_mm * np.sin(phi), machine.pin_orbit_mm * np.cos(phi)
    )
    pin = s * np.degrees(phi + np.angle(np.exp(1j * (seen - phi))))
    for h in hidden:
        if h.name == "camera_tilt":
            pin = _tilted(pin, h.params["tilt_deg"], h.params.get("tilt_axis_deg", 0.0))
    return pin


# ----------------------------------------------------------------------------- draws


def draw_machine(rng: np.random.Generator) -> Machine:
    """A machine off the datasheet: material and geometry within workshop tolerances."""
    return Machine(
        youngs_modulus_mpa=float(rng.uniform(195_000.0, 210_000.0)),
        yield_mpa=float(rng.uniform(250.0, 320.0)),
        voce_q_mpa=float(rng.uniform(120.0, 220.0)),
        voce_b=float(rng.uniform(8.0, 20.0)),
        hardening_slope_mpa=float(rng.uniform(100.0, 500.0)),
        modulus_drop=float(rng.uniform(0.05, 0.18)),
        die_radius_mm=float(rng.uniform(1.3, 1.8)),
        pin_radius_mm=float(rng.uniform(2.46, 2.54)),
        pin_orbit_mm=float(rng.uniform(11.9, 12.1)),
    )


def draw_hidden(rng: np.random.Generator, name: str) -> Hidden:
    """A hidden mechanism of typical size, general form drawn at random."""
    u = lambda lo, hi: float(rng.uniform(lo, hi))  # noqa: E731
    sign = lambda: float(rng.choice([-1.0, 1.0]))  # noqa: E731
    params: dict[str, float]
    if name == "none":
        params = {}
    elif name == "backlash":
        params = {
            "backlash_deg": u(0.6, 3.0),
            "same_direction_share": float(rng.choice([0.0, 1.0])),
        }
    elif name == "offset":
        params = {"offset_deg": sign() * u(0.6, 3.0)}
    elif name == "scale":
        params = {"scale": sign() * u(0.015, 0.06)}
    elif name == "drift":
        params = {
            "drift_deg_per_bend": u(0.02, 0.06),
            "load_exponent": float(rng.choice([0.0, 1.0, 2.0])),
        }
    elif name == "springback_asymmetry":
        params = {"asymmetry": sign() * u(0.25, 0.6)}
    elif name == "camera_tilt":
        params = {"tilt_deg": u(12.0, 25.0), "tilt_axis_deg": u(-90.0, 90.0)}
    elif name == "axis_offset":
        params = {"axis_offset_mm": sign() * u(0.15, 0.5)}
    elif name == "compliance":
        params = {"compliance_deg_per_nm": u(0.2, 0.6)}
    elif name == "gear_runout":
        params = {
            "amplitude_deg": u(0.6, 1.5),
            "period_deg": float(rng.choice([90.0, 120.0])),
            "phase_rad": u(0.0, 2 * np.pi),
        }
    elif name == "warm_up":
        params = {"amplitude_deg": u(1.0, 2.5), "time_constant_bends": u(10.0, 30.0)}
    elif name == "short_segment":
        params = {"coupling_deg": sign() * u(0.8, 2.0)}
    elif name == "springback_scatter":
        params = {"scatter_deg_per_100deg": u(0.3, 0.6)}
    else:
        raise ValueError(f"unknown mechanism {name!r}")
    return Hidden(name, params)


@functools.lru_cache(maxsize=4)
def _inverse_table(machine: Machine) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(released angle, head rotation) of the machine without effects, rotation 0-200 deg."""
    rotation = np.linspace(0.0, 200.0, 2001)
    return np.abs(bend(rotation, machine).unloaded_deg), rotation


def _nominal_command(machine: Machine, target_deg: NDArray[np.float64]) -> NDArray[np.float64]:
    """Head rotation (signed) giving the target released angle on this model without effects."""
    released, rotation = _inverse_table(machine)
    first = int(np.flatnonzero(released > 0)[0]) - 1  # the monotone branch from contact
    cmd = np.interp(np.abs(target_deg), released[first:], rotation[first:])
    return np.sign(target_deg) * cmd


def plan_commands(
    rng: np.random.Generator, plan: str, n_trials: int, *, both_directions: bool = True
) -> NDArray[np.float64]:
    """Signed commands (deg, 0.1 deg steps) of a plan, from the nominal machine's inverse.

    ``random``: targets 5-130 deg in random order; ``sweep``: rising targets, each
    angle bent ccw then cw; ``repeats``: a few targets each bent several times
    (identical commands), shuffled.
    """
    if plan == "random":
        targets = rng.uniform(5.0, 130.0, n_trials)
        signs = rng.permutation(np.where(np.arange(n_trials) % 2 == 0, 1.0, -1.0))
    elif plan == "sweep":
        targets = np.repeat(np.linspace(5.0, 130.0, (n_trials + 1) // 2), 2)[:n_trials]
        signs = np.where(np.arange(n_trials) % 2 == 0, 1.0, -1.0)
    elif plan == "repeats":
        n_angles = max(n_trials // 6, 2)
        angles = np.linspace(10.0, 125.0, n_angles)
        base = np.concatenate([angles, -angles])
        reps = int(np.ceil(n_trials / base.size))
        signed = rng.permutation(np.tile(base, reps))[:n_trials]
        targets, signs = np.abs(signed), np.sign(signed)
    else:
        raise ValueError(f"unknown plan {plan!r}; known: {', '.join(PLANS)}")
    if not both_directions:
        signs = np.ones(n_trials)
    return np.round(_nominal_command(Machine(), signs * targets), 1)


@dataclass(frozen=True)
class PhysicalCase:
    """Measured trials from the physical model and the truth hidden in them."""

    trials: TrialTable
    hidden: tuple[Hidden, ...]
    machine: Machine
    noise_deg: float
    shared_share: float
    plan: str
    seed: int

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(h.name for h in self.hidden if h.name != "none")

    def to_dict(self) -> dict[str, Any]:
        return {
            "hidden": [h.to_dict() for h in self.hidden],
            "noise_deg": self.noise_deg,
            "shared_share": self.shared_share,
            "plan": self.plan,
            "seed": self.seed,
            "n_trials": len(self.trials),
        }


def physical_case(
    seed: int,
    hidden: str | tuple[str, ...] = "none",
    *,
    plan: str = "random",
    n_trials: int = 60,
    noise_range_deg: tuple[float, float] = (0.02, 0.1),
    both_directions: bool = True,
    loaded: bool = True,
    machine: Machine | None = None,
    params: dict[str, dict[str, float]] | None = None,
) -> PhysicalCase:
    """One case from ``seed``: a machine, the hidden mechanism(s), a plan and noise.

    Noise: per angle a standard deviation drawn in ``noise_range_deg``, of which a
    drawn share (30-70 % of the variance) is common to the loaded and released
    photo of the same bend. ``params`` overrides drawn parameters per mechanism.
    """
    rng = np.random.default_rng(seed)
    names = (hidden,) if isinstance(hidden, str) else tuple(hidden)
    mach = machine or draw_machine(rng)
    drawn = []
    for name in names:
        h = draw_hidden(rng, name)
        if params and name in params:
            h = replace(h, params={**h.params, **params[name]})
        drawn.append(h)
    noise = float(rng.uniform(*noise_range_deg))
    shared = float(rng.uniform(0.3, 0.7))
    cmd = plan_commands(rng, plan, n_trials, both_directions=both_directions)
    true = bend(cmd, mach, tuple(drawn), rng)
    common = rng.normal(0.0, noise * math.sqrt(shared), cmd.size)
    own = noise * math.sqrt(1.0 - shared)
    measured_l = true.loaded_deg + common + rng.normal(0.0, own, cmd.size)
    measured_u = true.unloaded_deg + common + rng.normal(0.0, own, cmd.size)
    if not loaded:
        measured_l = np.full(cmd.size, np.nan)
    trials = TrialTable.from_arrays(cmd, measured_l, measured_u, source="physical")
    return PhysicalCase(trials, tuple(drawn), mach, noise, shared, plan, seed)


def run_follow_up(case: PhysicalCase, commands_deg: NDArray[np.float64], seed: int) -> PhysicalCase:
    """``case`` with bends at ``commands_deg`` run after its own on the same machine.

    The machine's state continues: the whole sequence is bent in order (trial count,
    direction history, steps lost shifting home, warm-up), so the case's own trials keep
    their true angles and the new ones follow them; the new bends' noise (the case's
    size and loaded/released share) is drawn from ``seed``. Stochastic mechanisms
    (springback scatter) are drawn afresh for the new bends.
    """
    rng = np.random.default_rng(seed)
    old = case.trials
    new = np.round(np.asarray(commands_deg, dtype=np.float64), 1)
    cmd = np.concatenate([old.commanded_pin_deg, new])
    true = bend(cmd, case.machine, case.hidden, rng)
    n, m = len(old), new.size
    common = rng.normal(0.0, case.noise_deg * math.sqrt(case.shared_share), m)
    own = case.noise_deg * math.sqrt(1.0 - case.shared_share)
    measured_l = true.loaded_deg[n:] + common + rng.normal(0.0, own, m)
    measured_u = true.unloaded_deg[n:] + common + rng.normal(0.0, own, m)
    if not old.has_loaded:
        measured_l = np.full(m, np.nan)
    trials = TrialTable.from_arrays(
        cmd,
        np.concatenate([old.loaded_bend_deg, measured_l]),
        np.concatenate([old.unloaded_bend_deg, measured_u]),
        source="physical",
    )
    return replace(case, trials=trials)
