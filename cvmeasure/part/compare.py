"""A measured part against its design: rigid registration, deviation profile, seed errors.

The measured centreline and the design wire (both in mm, y up as seen) are
resampled by arc length and matched by the best rigid transform (Kabsch),
trying both traversal directions and, unless forbidden, the mirror image (a
part can lie upside down); iterative closest points on the design polyline
refine it. The deviation profile is the signed distance of every measured
point to the registered design (positive to the left of the design's
direction of travel), along the measured arc length.

With ``N`` divisions the per-vertex bend angles of the polyline fit are
compared with the design's (the design divided into N equal chords), and the
seed paper's absolute and relative errors of the bend per chord are given
(``absolute = design - measured``, ``relative = 100 * absolute / design``, its
Source code 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial import cKDTree

from cvmeasure.design import bend_angles_deg
from cvmeasure.geometry import arclength_mm

__all__ = [
    "Registration",
    "Deviation",
    "BendComparison",
    "register_to_design",
    "deviation_profile",
    "compare_bends",
    "resample_by_length",
    "point_to_polyline",
    "PolylineIndex",
    "kabsch",
]


def resample_by_length(points_mm: np.ndarray, count: int) -> np.ndarray:
    """``count`` points equally spaced by arc length along a polyline (N, 2)."""
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    s = arclength_mm(pts)
    t = np.linspace(0.0, s[-1], count)
    return np.column_stack((np.interp(t, s, pts[:, 0]), np.interp(t, s, pts[:, 1])))


def point_to_polyline(
    points_mm: np.ndarray, vertices_mm: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points on a polyline: (foot points (N, 2), signed distance (N,), arc length (N,)).

    The sign is positive to the left of the polyline's direction of travel.
    Exact: every segment is tried for every point (in chunks); see
    :class:`PolylineIndex` for the fast variant used by the registration.
    """
    p = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    v = np.asarray(vertices_mm, dtype=np.float64).reshape(-1, 2)
    a, b = v[:-1], v[1:]
    d = b - a
    len2 = np.maximum(np.sum(d * d, axis=1), 1e-300)
    s0 = np.concatenate(([0.0], np.cumsum(np.sqrt(len2))))[:-1]
    feet = np.empty_like(p)
    signed = np.empty(len(p))
    along = np.empty(len(p))
    chunk = max(1, 2_000_000 // max(len(a), 1))
    for lo in range(0, len(p), chunk):
        q = p[lo : lo + chunk]
        rel = q[:, None, :] - a[None]
        u = np.clip(np.sum(rel * d[None], axis=2) / len2[None], 0.0, 1.0)
        foot = a[None] + u[..., None] * d[None]
        dist2 = np.sum((q[:, None, :] - foot) ** 2, axis=2)
        k = np.argmin(dist2, axis=1)
        idx = np.arange(len(q))
        feet[lo : lo + chunk] = foot[idx, k]
        cross = d[k, 0] * (q[:, 1] - a[k, 1]) - d[k, 1] * (q[:, 0] - a[k, 0])
        signed[lo : lo + chunk] = np.where(cross < 0, -1.0, 1.0) * np.sqrt(dist2[idx, k])
        along[lo : lo + chunk] = s0[k] + u[idx, k] * np.sqrt(len2[k])
    return feet, signed, along


class PolylineIndex:
    """Closest points on a dense polyline via a k-d tree of its vertices.

    The nearest of the ``k`` nearest vertices' adjacent segments; exact whenever
    the true foot lies on a segment next to one of those vertices (always, for
    points near a densely sampled curve).
    """

    def __init__(self, vertices_mm: np.ndarray, k: int = 4) -> None:
        self.v = np.asarray(vertices_mm, dtype=np.float64).reshape(-1, 2)
        self.tree = cKDTree(self.v)
        self.k = min(k, len(self.v))

    def feet(self, points_mm: np.ndarray) -> np.ndarray:
        """The closest point on the polyline (N, 2) to each of ``points_mm`` (N, 2), mm."""
        p = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
        _, idx = self.tree.query(p, k=self.k)
        idx = np.asarray(idx).reshape(len(p), -1)
        n = len(self.v)
        segs = np.concatenate((idx - 1, idx), axis=1).clip(0, n - 2)
        a = self.v[segs]
        d = self.v[segs + 1] - a
        len2 = np.maximum(np.sum(d * d, axis=2), 1e-300)
        u = np.clip(np.sum((p[:, None, :] - a) * d, axis=2) / len2, 0.0, 1.0)
        foot = a + u[..., None] * d
        best = np.argmin(np.sum((p[:, None, :] - foot) ** 2, axis=2), axis=1)
        return foot[np.arange(len(p)), best]


def kabsch(src: np.ndarray, dst: np.ndarray, *, mirror: bool) -> tuple[np.ndarray, np.ndarray]:
    """Rotation (or mirror-rotation) R and translation t minimising |R src + t - dst|."""
    ms, md = src.mean(axis=0), dst.mean(axis=0)
    h = (src - ms).T @ (dst - md)
    u, _, vt = np.linalg.svd(h)
    det = np.linalg.det(vt.T @ u.T)
    want = -1.0 if mirror else 1.0
    fix = np.diag([1.0, want * np.sign(det) if det != 0 else want])
    r = vt.T @ fix @ u.T
    return r, md - r @ ms


@dataclass(frozen=True)
class Registration:
    """The rigid transform taking measured points onto the design.

    ``design = rotation @ measured + translation_mm``. ``mirrored`` when the
    part lies upside down (the transform has determinant -1); ``reversed`` when
    the measured centreline runs from the design's end to its start.
    """

    rotation: np.ndarray
    translation_mm: np.ndarray
    mirrored: bool
    reversed: bool
    rms_mm: float

    @property
    def rotation_deg(self) -> float:
        r = self.rotation * np.array([[1.0, 1.0], [1.0, -1.0]]) if self.mirrored else self.rotation
        return float(math.degrees(math.atan2(r[1, 0], r[0, 0])))

    def apply(self, points_mm: np.ndarray) -> np.ndarray:
        pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
        return pts @ self.rotation.T + self.translation_mm

    def to_dict(self) -> dict[str, Any]:
        return {
            "rotation_deg": self.rotation_deg,
            "translation_mm": self.translation_mm.tolist(),
            "mirrored": self.mirrored,
            "reversed": self.reversed,
            "rms_mm": self.rms_mm,
        }


def register_to_design(
    measured_mm: np.ndarray,
    design_mm: np.ndarray,
    *,
    allow_mirror: bool = True,
    samples: int = 400,
    iterations: int = 50,
) -> Registration:
    """Best rigid fit of an ordered measured centreline onto a design polyline.

    Parameters
    ----------
    measured_mm : ndarray (N, 2), ordered along the wire.
    design_mm : ndarray (M, 2), the design wire's polyline.
    allow_mirror : also try the mirror image (part lying upside down).
    """
    meas = np.asarray(measured_mm, dtype=np.float64).reshape(-1, 2)
    des = np.asarray(design_mm, dtype=np.float64).reshape(-1, 2)
    if len(meas) < 3 or len(des) < 2:
        raise ValueError("need >= 3 measured points and >= 2 design points")
    src = resample_by_length(meas, samples)
    dst = resample_by_length(des, samples)
    index = PolylineIndex(des)
    best: Registration | None = None
    for rev in (False, True):
        target = dst[::-1] if rev else dst
        for mirror in (False, True) if allow_mirror else (False,):
            r, t = kabsch(src, target, mirror=mirror)
            for _ in range(iterations):
                r_new, t_new = kabsch(src, index.feet(src @ r.T + t), mirror=mirror)
                change = np.abs(r_new - r).max() + np.abs(t_new - t).max()
                r, t = r_new, t_new
                if change < 1e-12:
                    break
            moved = src @ r.T + t
            rms = float(np.sqrt(np.mean(np.sum((index.feet(moved) - moved) ** 2, axis=1))))
            if best is None or rms < best.rms_mm - 1e-12:
                best = Registration(r, t, mirror, rev, rms)
    return best  # type: ignore[return-value]  # the loop always runs


@dataclass(frozen=True)
class Deviation:
    """Signed distances of the registered part from its design along the part.

    Attributes
    ----------
    arc_length_mm : ndarray (N,), position along the measured centreline.
    distance_mm : ndarray (N,), signed distance to the design (left positive).
    max_mm : largest absolute distance; ``rms_mm`` its RMS; ``mean_mm`` the mean.
    """

    arc_length_mm: np.ndarray
    distance_mm: np.ndarray
    max_mm: float
    rms_mm: float
    mean_mm: float

    def to_dict(self, *, profile: bool = True) -> dict[str, Any]:
        out: dict[str, Any] = {
            "max_mm": self.max_mm,
            "rms_mm": self.rms_mm,
            "mean_mm": self.mean_mm,
        }
        if profile:
            out["arc_length_mm"] = self.arc_length_mm.tolist()
            out["distance_mm"] = self.distance_mm.tolist()
        return out


def deviation_profile(
    measured_mm: np.ndarray, design_mm: np.ndarray, registration: Registration
) -> Deviation:
    """The deviation of each measured point (registered) from the design polyline."""
    meas = np.asarray(measured_mm, dtype=np.float64).reshape(-1, 2)
    s = arclength_mm(meas)
    _, dist, _ = point_to_polyline(registration.apply(meas), design_mm)
    if registration.reversed:
        dist = -dist  # measured in the part's own direction of travel
    return Deviation(
        arc_length_mm=s,
        distance_mm=dist,
        max_mm=float(np.max(np.abs(dist))),
        rms_mm=float(np.sqrt(np.mean(dist**2))),
        mean_mm=float(np.mean(dist)),
    )


@dataclass(frozen=True)
class BendComparison:
    """Per-vertex bends of the part against its design, and the seed's error figures.

    Attributes
    ----------
    design_bend_deg, measured_bend_deg : ndarray (N-1,), in the design's
        vertex order and sign convention (mirroring and reversal undone).
    error_deg : measured - design per vertex; ``max_abs_error_deg``, ``rms_error_deg``.
    design_segment_bend_deg, measured_segment_bend_deg : arc angle / N.
    seed_absolute_error_deg : design - measured bend per chord (seed Source code 1).
    seed_relative_error_pct : 100 * absolute / design.
    """

    design_bend_deg: np.ndarray
    measured_bend_deg: np.ndarray
    error_deg: np.ndarray
    max_abs_error_deg: float
    rms_error_deg: float
    design_segment_bend_deg: float
    measured_segment_bend_deg: float
    seed_absolute_error_deg: float
    seed_relative_error_pct: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "design_bend_deg": self.design_bend_deg.tolist(),
            "measured_bend_deg": self.measured_bend_deg.tolist(),
            "error_deg": self.error_deg.tolist(),
            "max_abs_error_deg": self.max_abs_error_deg,
            "rms_error_deg": self.rms_error_deg,
            "design_segment_bend_deg": self.design_segment_bend_deg,
            "measured_segment_bend_deg": self.measured_segment_bend_deg,
            "seed_absolute_error_deg": self.seed_absolute_error_deg,
            "seed_relative_error_pct": self.seed_relative_error_pct,
        }


def compare_bends(
    measured_bend_deg: np.ndarray,
    design_vertices_mm: np.ndarray,
    registration: Registration,
    *,
    measured_segment_bend_deg: float,
    design_segment_bend_deg: float,
) -> BendComparison:
    """Compare measured vertex bends (part's order, y-up sense) with the design's chords.

    Reversal reverses the order and flips the sign of the bends; mirroring
    flips the sign again. Segment bends (arc / N) are unsigned magnitudes.
    """
    design_bends = bend_angles_deg(design_vertices_mm)
    meas = np.asarray(measured_bend_deg, dtype=np.float64).reshape(-1)
    if len(meas) != len(design_bends):
        raise ValueError(
            f"{len(meas)} measured bends but the design has {len(design_bends)} vertices"
        )
    sign = (-1.0 if registration.reversed else 1.0) * (-1.0 if registration.mirrored else 1.0)
    meas = sign * (meas[::-1] if registration.reversed else meas)
    err = meas - design_bends
    absolute = design_segment_bend_deg - measured_segment_bend_deg
    relative = 100.0 * absolute / design_segment_bend_deg if design_segment_bend_deg else math.nan
    return BendComparison(
        design_bend_deg=design_bends,
        measured_bend_deg=meas,
        error_deg=err,
        max_abs_error_deg=float(np.max(np.abs(err))) if len(err) else 0.0,
        rms_error_deg=float(np.sqrt(np.mean(err**2))) if len(err) else 0.0,
        design_segment_bend_deg=design_segment_bend_deg,
        measured_segment_bend_deg=measured_segment_bend_deg,
        seed_absolute_error_deg=absolute,
        seed_relative_error_pct=relative,
    )
