"""Small geometric helpers shared by every stage (angles, rotations)."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["wrap_deg", "direction_deg", "fit_circle_taubin"]


def wrap_deg(angle_deg: ArrayLike) -> np.ndarray | float:
    """Wrap angles in degrees to (-180, 180] (spec: signed angles).

    >>> wrap_deg(190.0), wrap_deg(-180.0), wrap_deg(180.0)
    (-170.0, 180.0, 180.0)
    >>> wrap_deg([360.0, -270.0]).tolist()
    [0.0, 90.0]
    """
    a = np.asarray(angle_deg, dtype=np.float64)
    wrapped = 180.0 - np.mod(180.0 - a, 360.0)
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def direction_deg(from_xy: ArrayLike, to_xy: ArrayLike) -> np.ndarray | float:
    """Direction of the vector from -> to, in degrees, counter-clockwise from +x.

    Works in any right-handed (x, y) frame; for image pixels (y down) negate y
    first to get counter-clockwise-as-seen angles.

    >>> direction_deg((0.0, 0.0), (0.0, 1.0))
    90.0
    >>> direction_deg((1.0, 1.0), (0.0, 1.0))
    180.0
    """
    f = np.asarray(from_xy, dtype=np.float64)
    t = np.asarray(to_xy, dtype=np.float64)
    d = t - f
    return wrap_deg(np.degrees(np.arctan2(d[..., 1], d[..., 0])))


def fit_circle_taubin(points: ArrayLike) -> tuple[np.ndarray, float]:
    """Taubin's algebraic circle fit of points (N, 2), N >= 3; any length unit.

    Returns ``(centre (2,), radius)`` in the points' unit. Unbiased to first
    order (unlike Kasa's fit); the stages use it to start their robust
    geometric fits. Raises ValueError for fewer than 3, non-finite or collinear
    points.

    References: G. Taubin, "Estimation of planar curves, surfaces and nonplanar
    space curves ...", IEEE PAMI 13(11), 1991, doi:10.1109/34.103273.

    >>> t = np.linspace(0.0, np.pi, 7)
    >>> centre, radius = fit_circle_taubin(np.column_stack((3 + 2 * np.cos(t), -1 + 2 * np.sin(t))))
    >>> np.round(centre, 9).tolist(), round(radius, 9)
    ([3.0, -1.0], 2.0)
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {pts.shape}")
    if len(pts) < 3:
        raise ValueError(f"a circle fit needs at least 3 points, got {len(pts)}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points must be finite")
    mean = pts.mean(axis=0)
    x, y = (pts - mean).T
    z = x * x + y * y
    zm = z.mean()
    if zm <= 0:
        raise ValueError("points are all the same: no circle")
    z0 = (z - zm) / (2.0 * math.sqrt(zm))
    _, _, vt = np.linalg.svd(np.column_stack((z0, x, y)), full_matrices=False)
    a = vt[-1]
    a0 = a[0] / (2.0 * math.sqrt(zm))
    if abs(a0) < 1e-300 or abs(a0) * math.sqrt(zm) < 1e-12 * math.hypot(a[1], a[2]):
        raise ValueError("points are collinear: no circle")
    a3 = -zm * a0
    cx, cy = -a[1] / (2 * a0), -a[2] / (2 * a0)
    radius = math.sqrt(max(cx * cx + cy * cy - a3 / a0, 0.0))
    return np.array([cx, cy]) + mean, radius
