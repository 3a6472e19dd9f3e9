"""Small geometric helpers shared by every stage (angles, rotations)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["wrap_deg", "direction_deg"]


def wrap_deg(angle_deg: ArrayLike) -> np.ndarray | float:
    """Wrap angles in degrees to (-180, 180] (spec: signed angles)."""
    a = np.asarray(angle_deg, dtype=np.float64)
    wrapped = 180.0 - np.mod(180.0 - a, 360.0)
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def direction_deg(from_xy: ArrayLike, to_xy: ArrayLike) -> np.ndarray | float:
    """Direction of the vector from -> to, in degrees, counter-clockwise from +x.

    Works in any right-handed (x, y) frame; for image pixels (y down) negate y
    first to get counter-clockwise-as-seen angles.
    """
    f = np.asarray(from_xy, dtype=np.float64)
    t = np.asarray(to_xy, dtype=np.float64)
    d = t - f
    return wrap_deg(np.degrees(np.arctan2(d[..., 1], d[..., 0])))
