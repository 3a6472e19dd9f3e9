"""Pin -> loaded bend angle by the tangent construction (pin orbiting an off-centre axis).

Frame (die frame, mm): the straight wire's centreline is the x-axis and leaves
the die at x = 0. A counter-clockwise bend wraps the wire on the die-edge
circle centred at ``D = (0, a_d)``, ``a_d = die_radius_mm + r_wire``. The pin
centre orbits the head axis ``O`` at radius ``R_p``:
``P(phi) = O + R_p (cos phi, sin phi)``. The straight free leg is the common
internal tangent of circle(D, a_d) (on its left) and circle(P, rho_p) (on its
right), ``rho_p = pin_radius_mm + r_wire``::

    L     = |P - D|,   psi = atan2(P_y - D_y, P_x - D_x)
    theta = max(0, psi + asin((a_d + rho_p) / L))       loaded bend angle
    l     = sqrt(L^2 - (a_d + rho_p)^2)                  lever arm (die tangent -> pin)
    phi_c = -asin((rho_p + O_y) / R_p)                   first contact

A clockwise bend is the mirror image (y -> -y), so a lateral head-axis offset
``e`` enters as ``O_y = +e`` for counter-clockwise and ``-e`` for clockwise
bends. The head starts ``approach_deg`` before first contact (the dead zone):
a head rotation ``r`` from home puts the pin at ``phi = phi_c - approach + r``.

Reference: /work/shared/reference/springback-discrepancy.md, section 2.1
(R_p = 12 mm, rho_p = 4 mm, R_die = 1.5 mm: 40.5 / 73.8 / 105.0 deg of head
rotation after contact for 45 / 90 / 135 deg of wire).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from cvmeasure.sim.params import SimParams

__all__ = [
    "HeadGeometry",
    "head_geometry",
    "contact_angle_deg",
    "loaded_angle_deg",
    "lever_arm_mm",
    "loaded_angle_and_lever",
    "pin_angle_for_loaded_deg",
]


@dataclass(frozen=True)
class HeadGeometry:
    """The circles of the tangent construction for one bend direction (die frame, mm).

    ``axis_y_mm`` is the head-axis y in the *mirrored* frame of the bend, i.e.
    ``+e`` for counter-clockwise and ``-e`` for clockwise bends.
    """

    die_wrap_mm: float  # a_d: centreline radius on the die edge
    pin_contact_mm: float  # rho_p: pin centre to wire centreline at contact
    pin_orbit_mm: float  # R_p
    axis_x_mm: float | NDArray[np.float64]
    axis_y_mm: float | NDArray[np.float64]

    def to_dict(self) -> dict[str, Any]:
        return {
            "die_wrap_mm": self.die_wrap_mm,
            "pin_contact_mm": self.pin_contact_mm,
            "pin_orbit_mm": self.pin_orbit_mm,
            "axis_x_mm": np.asarray(self.axis_x_mm).tolist(),
            "axis_y_mm": np.asarray(self.axis_y_mm).tolist(),
        }


def head_geometry(
    params: SimParams, direction: ArrayLike = 1.0, *, axis_offset_mm: ArrayLike = 0.0
) -> HeadGeometry:
    """Geometry for bends of the given direction(s) (+1 ccw, -1 cw).

    ``axis_offset_mm`` is an extra lateral head-axis offset towards +y (machine
    frame), added to ``params.head_axis_y_mm`` before mirroring.
    """
    s = np.where(np.asarray(direction, dtype=np.float64) < 0, -1.0, 1.0)
    e = params.head_axis_y_mm + np.asarray(axis_offset_mm, dtype=np.float64)
    return HeadGeometry(
        die_wrap_mm=params.die_radius_mm + params.wire_radius_mm,
        pin_contact_mm=params.pin_radius_mm + params.wire_radius_mm,
        pin_orbit_mm=params.pin_orbit_mm,
        axis_x_mm=params.head_axis_x_mm,
        axis_y_mm=s * e,
    )


def contact_angle_deg(geom: HeadGeometry) -> NDArray[np.float64] | float:
    """Pin angle phi_c (deg, die frame of the bend) at first contact with the straight wire."""
    ratio = (geom.pin_contact_mm + np.asarray(geom.axis_y_mm)) / geom.pin_orbit_mm
    out = -np.degrees(np.arcsin(np.minimum(np.maximum(ratio, -1.0), 1.0)))
    return float(out) if np.ndim(out) == 0 else out


def _tangent(geom: HeadGeometry, pin_angle_deg: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    phi = np.radians(np.asarray(pin_angle_deg, dtype=np.float64))
    px = geom.axis_x_mm + geom.pin_orbit_mm * np.cos(phi)
    py = geom.axis_y_mm + geom.pin_orbit_mm * np.sin(phi)
    dx = px
    dy = py - geom.die_wrap_mm
    span = np.hypot(dx, dy)
    psi = np.arctan2(dy, dx)
    psi = np.where(psi < -np.pi / 2, psi + 2 * np.pi, psi)  # continuous past 180 deg
    sep = geom.die_wrap_mm + geom.pin_contact_mm
    # np.minimum(np.maximum(.)) is np.clip's arithmetic without its call overhead
    theta = psi + np.arcsin(np.minimum(np.maximum(sep / np.maximum(span, sep), -1.0), 1.0))
    lever = np.sqrt(np.maximum(span**2 - sep**2, 0.0))
    return theta, lever


def loaded_angle_deg(geom: HeadGeometry, pin_angle_deg: ArrayLike) -> NDArray[np.float64]:
    """Loaded bend angle theta (deg, >= 0) for pin angle(s) phi (deg, die frame of the bend).

    Zero before contact (the pin has not reached the wire).
    """
    theta, _ = _tangent(geom, pin_angle_deg)
    phi = np.asarray(pin_angle_deg, dtype=np.float64)
    before = phi <= contact_angle_deg(geom)
    return np.where(before, 0.0, np.maximum(np.degrees(theta), 0.0))


def lever_arm_mm(geom: HeadGeometry, pin_angle_deg: ArrayLike) -> NDArray[np.float64]:
    """Free-span length l (mm) from the die tangent point to the pin contact.

    Before contact it is the lever at contact (the span the pin will load).
    """
    phi = np.maximum(np.asarray(pin_angle_deg, dtype=np.float64), contact_angle_deg(geom))
    _, lever = _tangent(geom, phi)
    return lever


def loaded_angle_and_lever(
    geom: HeadGeometry,
    pin_angle_deg: ArrayLike,
    *,
    contact_deg: NDArray[np.float64] | float | None = None,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Both :func:`loaded_angle_deg` and :func:`lever_arm_mm` from one tangent construction.

    ``contact_deg``: ``contact_angle_deg(geom)`` when the caller has it already (a
    simulation evaluates the same geometry many times).
    """
    if contact_deg is None:
        contact_deg = contact_angle_deg(geom)
    phi = np.maximum(np.asarray(pin_angle_deg, dtype=np.float64), contact_deg)
    theta, lever = _tangent(geom, phi)
    return np.maximum(np.degrees(theta), 0.0), lever


def pin_angle_for_loaded_deg(
    geom: HeadGeometry, loaded_deg: ArrayLike, *, iterations: int = 60
) -> NDArray[np.float64]:
    """Inverse kinematics: pin angle phi (deg) giving the loaded angle(s) theta (deg, >= 0).

    Bisection on the monotone branch from first contact to 179 deg of pin travel.
    """
    target = np.asarray(loaded_deg, dtype=np.float64)
    lo = np.broadcast_to(np.asarray(contact_angle_deg(geom), dtype=np.float64), target.shape)
    lo = lo.copy()
    hi = lo + 179.0
    for _ in range(iterations):
        mid = 0.5 * (lo + hi)
        below = loaded_angle_deg(geom, mid) < target
        lo = np.where(below, mid, lo)
        hi = np.where(below, hi, mid)
    return 0.5 * (lo + hi)
