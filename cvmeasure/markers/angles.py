"""The machine frame and the signed pin, bend and springback angles.

Machine frame (spec ``Frames``): origin at the ``origin`` marker's centre, +x
the unit vector from the ``axis`` marker to the ``origin`` marker, +y is +x
turned 90 degrees counter-clockwise *as seen in the photo*, angles
counter-clockwise positive, wrapped to (-180, 180].

Marker centres come in a planar measurement frame: image pixels (y down), or a
rectified plane frame. ``y_down`` says whether that frame has the image's
handedness (x right, y down as seen); then y is negated before ``arctan2`` so
that counter-clockwise as seen in the photo is positive.

Uncertainties are first-order propagations of the centres' covariances
(Jacobian of each angle with respect to the five centres).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cvmeasure.geometry import wrap_deg
from cvmeasure.kit import ROLES

__all__ = [
    "MachineAngles",
    "machine_angles",
    "to_machine_frame",
    "springback_deg",
    "springback_sigma_deg",
]


@dataclass(frozen=True)
class MachineAngles:
    """Signed angles in the machine frame (degrees) and their standard uncertainties."""

    pin_angle_deg: float
    bend_angle_deg: float
    pin_sigma_deg: float
    bend_sigma_deg: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "pin_angle_deg": self.pin_angle_deg,
            "bend_angle_deg": self.bend_angle_deg,
            "uncertainty_deg": {
                "pin_angle_deg": self.pin_sigma_deg,
                "bend_angle_deg": self.bend_sigma_deg,
            },
        }


def _grad_dir(d: np.ndarray, flip: float) -> np.ndarray:
    """d(angle)/d(tip) of the direction of vector d (the tail gets the negative)."""
    n2 = float(d @ d)
    return np.array([-flip * d[1], flip * d[0]]) / n2


def pin_bend_deg(centres: Mapping[str, ArrayLike], *, y_down: bool = True) -> np.ndarray:
    """(pin, bend) angles in deg, (..., 2), wrapped to (-180, 180]: the definition
    :func:`machine_angles` reports, for centres given per role as (..., 2) arrays (one set
    of five or many at once). No checks: degenerate geometry gives a meaningless angle.
    """
    flip = -1.0 if y_down else 1.0
    c = {r: np.asarray(centres[r], dtype=np.float64) for r in ROLES}

    def direction(v: np.ndarray) -> np.ndarray:
        return np.arctan2(flip * v[..., 1], v[..., 0])

    x_axis = direction(c["origin"] - c["axis"])
    pin = np.degrees(direction(c["pin"] - c["origin"]) - x_axis)
    bend = np.degrees(direction(c["wire_b"] - c["wire_a"]) - x_axis)
    return np.stack((wrap_deg(pin), wrap_deg(bend)), axis=-1)


def machine_angles(
    centres: Mapping[str, ArrayLike],
    covariances: Mapping[str, ArrayLike] | None = None,
    *,
    y_down: bool = True,
) -> MachineAngles:
    """Pin and bend angles from the five marker centres.

    Parameters
    ----------
    centres : {role: (x, y)} in one planar frame (px or mm).
    covariances : {role: (2, 2)} covariance of each centre in the same frame; zero when None.
    y_down : True when the frame has the image's handedness (x right, y down).

    Returns
    -------
    MachineAngles
        ``pin_angle_deg`` = angle of origin->pin from +x, ``bend_angle_deg`` = angle of
        wire_a->wire_b from +x, both wrapped to (-180, 180].
    """
    flip = -1.0 if y_down else 1.0
    c = {r: np.asarray(centres[r], dtype=np.float64).reshape(2) for r in ROLES}
    x_axis = c["origin"] - c["axis"]
    v_pin = c["pin"] - c["origin"]
    v_bend = c["wire_b"] - c["wire_a"]
    for name, v in (("axis->origin", x_axis), ("origin->pin", v_pin), ("wire_a->wire_b", v_bend)):
        if float(v @ v) < 1e-18:
            raise ValueError(f"degenerate geometry: the {name} markers coincide")
    pin, bend = (float(a) for a in pin_bend_deg(c, y_down=y_down))
    if covariances is None:  # no uncertainty to propagate
        return MachineAngles(pin, bend, 0.0, 0.0)

    idx = {r: 2 * i for i, r in enumerate(ROLES)}
    g_x = _grad_dir(x_axis, flip)
    g_pin = np.zeros(10)
    g_bend = np.zeros(10)
    gp = _grad_dir(v_pin, flip)
    g_pin[idx["pin"] : idx["pin"] + 2] += gp
    g_pin[idx["origin"] : idx["origin"] + 2] -= gp
    gb = _grad_dir(v_bend, flip)
    g_bend[idx["wire_b"] : idx["wire_b"] + 2] += gb
    g_bend[idx["wire_a"] : idx["wire_a"] + 2] -= gb
    for g in (g_pin, g_bend):
        g[idx["origin"] : idx["origin"] + 2] -= g_x
        g[idx["axis"] : idx["axis"] + 2] += g_x
    cov = np.zeros((10, 10))
    if covariances is not None:
        for r in ROLES:
            if r in covariances:
                i = idx[r]
                cov[i : i + 2, i : i + 2] = np.asarray(covariances[r], dtype=np.float64)
    s_pin = math.degrees(math.sqrt(max(0.0, float(g_pin @ cov @ g_pin))))
    s_bend = math.degrees(math.sqrt(max(0.0, float(g_bend @ cov @ g_bend))))
    return MachineAngles(pin, bend, s_pin, s_bend)


def to_machine_frame(
    points: ArrayLike, origin: ArrayLike, axis: ArrayLike, *, y_down: bool = True
) -> np.ndarray:
    """Points (N, 2) of the measurement frame -> machine-frame coordinates (N, 2), same units."""
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    o = np.asarray(origin, dtype=np.float64).reshape(2)
    ex = o - np.asarray(axis, dtype=np.float64).reshape(2)
    ex = ex / np.linalg.norm(ex)
    flip = -1.0 if y_down else 1.0
    d = p - o
    d[:, 1] *= flip
    ex = np.array([ex[0], flip * ex[1]])
    ey = np.array([-ex[1], ex[0]])
    return np.column_stack((d @ ex, d @ ey))


def springback_deg(loaded_bend_deg: float, unloaded_bend_deg: float) -> float:
    """Springback of one trial (spec): ``sign(loaded) * (loaded - unloaded)``, degrees.

    Positive when the wire opens back towards straight after the pin releases it.

    >>> springback_deg(47.5, 45.0)  # counter-clockwise bend opens by 2.5 deg
    2.5
    >>> springback_deg(-47.5, -45.0)  # clockwise: the same springback, same sign
    2.5
    """
    loaded = float(loaded_bend_deg)
    return float(np.sign(loaded) * wrap_deg(loaded - float(unloaded_bend_deg)))


def springback_sigma_deg(loaded_sigma_deg: float, unloaded_sigma_deg: float) -> float:
    """Standard uncertainty of a springback from the two photos' independent bend uncertainties."""
    return float(math.hypot(loaded_sigma_deg, unloaded_sigma_deg))
