"""One bend of a round wire between a die edge and a pin on an orbit.

Geometry (machine frame, a counter-clockwise bend; a clockwise one is its mirror
image in the feed axis): the wire leaves the die at ``x = x_D`` and wraps the die
edge, a circle of centreline radius ``a_d = R_die + r_w`` about ``D = (x_D, a_d)``.
The pin (centre ``P``, contact radius ``rho_p = r_pin + r_w``) pushes the leg from
below. The straight line tangent to both circles (``D`` on its left, ``P`` on its
right) is the rigid leg: its angle ``theta_c = psi + asin((a_d + rho_p) / L)`` with
``L, psi`` the distance and direction from ``D`` to ``P``; its length from the die
tangent point to the pin contact is the lever ``l = sqrt(L^2 - (a_d + rho_p)^2)``.

Mechanics: the free span carries a moment falling linearly from ``M0`` at the die to
zero at the pin; its curvature follows the section's loading curve, its chord must
match the rigid leg. If the die curvature's moment is not reached the span alone
takes the bend (no wrap); otherwise ``M0`` is the die's moment and the rest of the
bend wraps the die at its curvature. The loaded leg beyond the pin is the span's
tangent at the pin; on release every point keeps the residual curvature of its
largest loading (monotonic loading assumed), which gives the unloaded angle.
Small-slope beam theory in the span (its rotations are a few degrees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from benchmarks.heldout.wire_section import SectionTable

_U, _W = np.polynomial.legendre.leggauss(48)
_U = 0.5 * (_U + 1.0)  # on (0, 1)
_W = 0.5 * _W


@dataclass(frozen=True)
class BendGeometry:
    """Geometry of one bend in the counter-clockwise (mirrored) frame, mm."""

    die_centre_x_mm: float
    die_centreline_radius_mm: float  # a_d = R_die + r_w
    pin_contact_radius_mm: float  # rho_p = r_pin + r_w
    orbit_centre_mm: tuple[float, float]
    pin_orbit_radius_mm: float


@dataclass(frozen=True)
class BendResult:
    """A bend's outcome in the counter-clockwise frame (angles in degrees).

    ``loaded_deg``/``unloaded_deg`` are the leg's rotation by bending (the wire's own
    coil set not included); ``torque_nmm`` the torque the drive holds about the head
    axis; ``plastic_work_nmm`` a measure of the plastic work (for warming).
    """

    contact: bool
    chord_deg: float
    loaded_deg: float
    unloaded_deg: float
    wrap_deg: float
    lever_mm: float
    root_moment_nmm: float
    torque_nmm: float
    plastic_work_nmm: float


def pin_centre(geom: BendGeometry, pin_angle_rad: float) -> tuple[float, float]:
    """Pin centre (mm) at this orbit angle (from +x, counter-clockwise)."""
    ox, oy = geom.orbit_centre_mm
    r = geom.pin_orbit_radius_mm
    return ox + r * math.cos(pin_angle_rad), oy + r * math.sin(pin_angle_rad)


def rigid_leg(geom: BendGeometry, pin_angle_rad: float) -> tuple[float, float, bool]:
    """Rigid leg angle (rad), lever (mm) and whether the pin touches the wire."""
    px, py = pin_centre(geom, pin_angle_rad)
    dx = px - geom.die_centre_x_mm
    dy = py - geom.die_centreline_radius_mm
    reach = geom.die_centreline_radius_mm + geom.pin_contact_radius_mm
    dist = math.hypot(dx, dy)
    if dist <= reach * (1.0 + 1e-9):
        return 0.0, 0.0, False
    theta = math.atan2(dy, dx) + math.asin(reach / dist)
    lever = math.sqrt(dist * dist - reach * reach)
    if theta <= 0.0:
        return 0.0, lever, False
    return theta, lever, True


def _span_rotations(
    table: SectionTable, root_moment: float, lever: float
) -> tuple[float, float, float]:
    """Chord rotation, tip rotation and residual tip rotation (rad) of the free span."""
    k0 = table.natural_curvature_per_mm
    curv = table.curvature(root_moment * _U) - k0
    resid = table.residual(curv + k0) - k0
    chord = lever * float(np.sum(_W * _U * curv))
    tip = lever * float(np.sum(_W * curv))
    tip_resid = lever * float(np.sum(_W * resid))
    return chord, tip, tip_resid


def bend(geom: BendGeometry, table: SectionTable, pin_angle_rad: float) -> BendResult:
    """The loaded and released wire for the pin at this orbit angle (mirrored frame)."""
    theta_c, lever, contact = rigid_leg(geom, pin_angle_rad)
    if not contact:
        return BendResult(False, 0.0, 0.0, 0.0, 0.0, lever, 0.0, 0.0, 0.0)
    lever = max(lever, 0.05 * geom.die_centreline_radius_mm)
    k0 = table.natural_curvature_per_mm
    k_die = 1.0 / geom.die_centreline_radius_mm + k0
    m_die = float(table.moment(k_die))
    chord_die, _, _ = _span_rotations(table, m_die, lever)
    if chord_die >= theta_c:
        lo, hi = 0.0, m_die
        for _ in range(50):
            mid = 0.5 * (lo + hi)
            if _span_rotations(table, mid, lever)[0] < theta_c:
                lo = mid
            else:
                hi = mid
        m0, wrap = 0.5 * (lo + hi), 0.0
    else:
        m0, wrap = m_die, theta_c - chord_die
    chord, tip, tip_resid = _span_rotations(table, m0, lever)
    wrap_resid = wrap * geom.die_centreline_radius_mm * (float(table.residual(k_die)) - k0)
    loaded = wrap + tip
    unloaded = wrap_resid + tip_resid
    torque = _torque(geom, pin_angle_rad, theta_c, m0 / lever)
    return BendResult(
        True,
        math.degrees(theta_c),
        math.degrees(loaded),
        math.degrees(unloaded),
        math.degrees(wrap),
        lever,
        m0,
        torque,
        m0 * max(unloaded, 0.0),
    )


def _torque(geom: BendGeometry, pin_angle_rad: float, theta_c: float, force_n: float) -> float:
    """Torque (N mm) of the wire's push on the pin about the head axis (resisting the bend)."""
    px, py = pin_centre(geom, pin_angle_rad)
    ox, oy = geom.orbit_centre_mm
    nx, ny = -math.sin(theta_c), math.cos(theta_c)  # the leg's left normal
    # The wire pushes the pin along -n; the drive holds the opposite torque.
    return abs(force_n * ((px - ox) * ny - (py - oy) * nx))


def residual_zone(
    geom: BendGeometry, table: SectionTable, result: BendResult, points: int = 40
) -> tuple[np.ndarray, np.ndarray]:
    """Released curvature of a bend's zone along the wire (mirrored frame).

    Returns
    -------
    distance_mm : numpy.ndarray
        Distance downstream of the die exit, over the wrap then the free span.
    curvature_per_mm : numpy.ndarray
        Residual curvature there, less the wire's own natural curvature.
    """
    if not result.contact:
        return np.zeros(0), np.zeros(0)
    k0 = table.natural_curvature_per_mm
    a_d = geom.die_centreline_radius_mm
    wrap_len = a_d * math.radians(result.wrap_deg)
    k_die = 1.0 / a_d + k0
    n_wrap = max(2, int(points * wrap_len / max(wrap_len + result.lever_mm, 1e-9)))
    d_wrap = np.linspace(0.0, wrap_len, n_wrap, endpoint=False)
    c_wrap = np.full(n_wrap, float(table.residual(k_die)) - k0)
    if wrap_len == 0.0:
        d_wrap, c_wrap = d_wrap[:0], c_wrap[:0]
    u = np.linspace(1.0, 0.0, points)  # moment share, from the root to the pin
    d_span = wrap_len + (1.0 - u) * result.lever_mm
    c_span = table.residual(table.curvature(result.root_moment_nmm * u)) - k0
    return np.concatenate([d_wrap, d_span]), np.concatenate([c_wrap, c_span])
