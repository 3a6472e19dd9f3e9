"""The seed paper's arc measurements, reproduced as baselines (its part III, 3.3-3.5).

* :func:`seed_bending_angle` -- its Source code 1: bend angle per chord from
  measured arc heights and widths, with absolute and relative errors against
  the first (design) column. :data:`SEED_HALF_CIRCLE` and :data:`SEED_SADDLE`
  hold its published inputs; the test suite reproduces its printed errors.
* :func:`ellipse_method` -- contour -> convex hull -> ``cv2.fitEllipse``; the
  arc's end points where the minimum enclosing circle meets the ellipse
  (all real intersections, from a quartic: :func:`circle_ellipse_intersections`,
  never a seeded ``fsolve`` that can miss roots); then width, height and the
  sagitta radius.
* :func:`sagitta_method` -- the minimum-area (rotated) bounding rectangle's
  sides as arc width and height, r = d^2 / 8h + h / 2 (its 3.5).

The seed ran these on the wire's outline (both flanks), so its widths and
heights include the wire's thickness; so do these reproductions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from cvmeasure.part.fit import arc_angle_from_chord_deg, sagitta_radius_mm

__all__ = [
    "SeedErrorTable",
    "SEED_HALF_CIRCLE",
    "SEED_SADDLE",
    "seed_bending_angle",
    "trig_quadratic_roots",
    "circle_ellipse_intersections",
    "EllipseFit",
    "SeedArc",
    "ellipse_method",
    "sagitta_method",
]


# --------------------------------------------------------------------------
# Source code 1


@dataclass(frozen=True)
class SeedErrorTable:
    """Rows of the seed's Source code 1 output, one column per part.

    Attributes
    ----------
    bend_angle_deg : bend angle per chord, theta_arc / n_div, degrees.
    absolute_error_deg : ``bend[0] - bend`` (column 0 is the design).
    relative_error_pct : ``100 * absolute_error / bend[0]``.
    """

    bend_angle_deg: np.ndarray
    absolute_error_deg: np.ndarray
    relative_error_pct: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {
            "bend_angle_deg": self.bend_angle_deg.tolist(),
            "absolute_error_deg": self.absolute_error_deg.tolist(),
            "relative_error_pct": self.relative_error_pct.tolist(),
        }


#: Source code 1's half-circle inputs (mm): design first, then three bent parts.
SEED_HALF_CIRCLE: dict[str, tuple[float, ...]] = {
    "height_mm": (100.0, 105.0, 95.0, 100.0),
    "width_mm": (200.0, 235.0, 238.0, 202.0),
    "divisions": (20, 20, 20, 20),
}
#: Source code 1's saddle-curve inputs (mm).
SEED_SADDLE: dict[str, tuple[float, ...]] = {
    "height_mm": (20.0, 12.0, 15.0, 21.0),
    "width_mm": (200.0, 223.0, 213.0, 205.0),
    "divisions": (13, 13, 13, 13),
}


def seed_bending_angle(height_mm: Any, width_mm: Any, divisions: Any) -> SeedErrorTable:
    """The seed's Source code 1, verbatim in its arithmetic.

    ``r = h/2 + c^2/8h``, ``theta = 2 asin(c / 2r)``, bend = theta / div; errors
    against column 0. Note the ``asin`` folds arcs longer than 180 degrees
    back (a 105 mm high, 235 mm wide "half circle" comes out at 167 degrees);
    :func:`~cvmeasure.part.fit.arc_angle_from_chord_deg` does not.

    Examples
    --------
    >>> t = seed_bending_angle(**SEED_HALF_CIRCLE)
    >>> np.round(t.relative_error_pct, 2).tolist()
    [0.0, 7.15, 14.22, 0.63]
    """
    h = np.asarray(height_mm, dtype=np.float64)
    c = np.asarray(width_mm, dtype=np.float64)
    div = np.asarray(divisions, dtype=np.float64)
    r = (h / 2) + ((c**2) / (8 * h))
    ceta = 2 * np.arcsin(c / (2 * r))
    bended = np.rad2deg(ceta / div)
    absolute = bended[0] - bended
    relative = 100 * (absolute / bended[0])
    return SeedErrorTable(bended, absolute, relative)


# --------------------------------------------------------------------------
# All real intersections of a circle and an ellipse


def _trig_coeffs(samples: np.ndarray) -> tuple[float, float, float, float, float]:
    """(a0, a1, b1, a2, b2) of f(t) = a0 + a1 cos t + b1 sin t + a2 cos 2t + b2 sin 2t
    from 8 equally spaced samples t_k = 2 pi k / 8 (exact for such f)."""
    spec = np.fft.rfft(samples) / len(samples)
    a0 = float(spec[0].real)
    a1, b1 = float(2 * spec[1].real), float(-2 * spec[1].imag)
    a2, b2 = float(2 * spec[2].real), float(-2 * spec[2].imag)
    return a0, a1, b1, a2, b2


def trig_quadratic_roots(coeffs: tuple[float, float, float, float, float]) -> np.ndarray:
    """All real roots t in [0, 2 pi) of a0 + a1 cos t + b1 sin t + a2 cos 2t + b2 sin 2t.

    The half-angle substitution u = tan((t - t0) / 2) turns the equation into a
    quartic in u (``numpy.roots``); the offset t0 is chosen so that t0 + pi is
    far from a root (no root lost at u = infinity). Every real candidate is
    polished by Newton steps on f(t) and kept when its residual is tiny, which
    also recovers double (tangent) roots that the quartic returns with small
    imaginary parts.
    """
    a0, a1, b1, a2, b2 = (float(c) for c in coeffs)
    scale = max(abs(a0), abs(a1), abs(b1), abs(a2), abs(b2))
    if scale == 0.0:
        raise ValueError("f is identically zero: every t is a root")

    def f(t: np.ndarray) -> np.ndarray:
        return a0 + a1 * np.cos(t) + b1 * np.sin(t) + a2 * np.cos(2 * t) + b2 * np.sin(2 * t)

    def df(t: np.ndarray) -> np.ndarray:
        return -a1 * np.sin(t) + b1 * np.cos(t) - 2 * a2 * np.sin(2 * t) + 2 * b2 * np.cos(2 * t)

    grid = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    t0 = float(grid[int(np.argmax(np.abs(f(grid + np.pi))))])
    # coefficients of g(s) = f(s + t0) in the same basis
    c1, s1, c2, s2 = math.cos(t0), math.sin(t0), math.cos(2 * t0), math.sin(2 * t0)
    A1, B1 = a1 * c1 + b1 * s1, -a1 * s1 + b1 * c1
    A2, B2 = a2 * c2 + b2 * s2, -a2 * s2 + b2 * c2
    quartic = [a0 - A1 + A2, 2 * B1 - 4 * B2, 2 * a0 - 6 * A2, 2 * B1 + 4 * B2, a0 + A1 + A2]
    roots = np.roots(np.asarray(quartic) / scale)
    cand = roots[np.abs(roots.imag) <= 1e-3 * (1.0 + np.abs(roots))].real
    ts = 2.0 * np.arctan(cand) + t0
    out: list[float] = []
    for t in ts:
        for _ in range(30):
            d = df(np.asarray(t))
            if d == 0:
                break
            step = f(np.asarray(t)) / d
            t = t - float(step)
            if abs(step) < 1e-15:
                break
        if abs(float(f(np.asarray(t)))) <= 1e-9 * scale:
            out.append(float(np.mod(t, 2 * np.pi)))
    out.sort()
    uniq: list[float] = []
    for t in out:
        if not uniq or abs(t - uniq[-1]) > 1e-7:
            uniq.append(t)
    if len(uniq) > 1 and abs(uniq[0] + 2 * np.pi - uniq[-1]) <= 1e-7:
        uniq.pop()
    return np.array(uniq)


def _ellipse_on_circle_coeffs(
    circle_centre: np.ndarray,
    circle_radius: float,
    ellipse_centre: np.ndarray,
    ellipse_semi_axes: tuple[float, float],
    ellipse_angle_rad: float,
) -> tuple[float, float, float, float, float]:
    a, b = ellipse_semi_axes
    ca, sa = math.cos(ellipse_angle_rad), math.sin(ellipse_angle_rad)
    t = 2 * np.pi * np.arange(8) / 8

    def f(tt: np.ndarray) -> np.ndarray:
        x = circle_centre[0] + circle_radius * np.cos(tt) - ellipse_centre[0]
        y = circle_centre[1] + circle_radius * np.sin(tt) - ellipse_centre[1]
        u = x * ca + y * sa
        v = -x * sa + y * ca
        return (u / a) ** 2 + (v / b) ** 2 - 1.0

    return _trig_coeffs(f(t))


def circle_ellipse_intersections(
    circle_centre: Any,
    circle_radius: float,
    ellipse_centre: Any,
    ellipse_semi_axes: tuple[float, float],
    ellipse_angle_deg: float,
) -> np.ndarray:
    """Every real intersection (K, 2), K in 0..4, of a circle and an ellipse.

    Parameters
    ----------
    circle_centre, circle_radius : the circle (any length unit).
    ellipse_centre : (x, y) of the ellipse centre.
    ellipse_semi_axes : (a, b), the semi-axes along the rotated x and y axes.
    ellipse_angle_deg : rotation of the ellipse's first axis from +x (the
        frame's own sense, as ``cv2.fitEllipse`` reports it).

    The circle is parametrised by angle t; the ellipse equation becomes a
    trigonometric quadratic in t, solved by :func:`trig_quadratic_roots`.

    Examples
    --------
    >>> p = circle_ellipse_intersections((0, 0), 1.0, (0, 0), (2.0, 0.5), 0.0)
    >>> len(p)
    4
    """
    cc = np.asarray(circle_centre, dtype=np.float64)
    ec = np.asarray(ellipse_centre, dtype=np.float64)
    if circle_radius <= 0 or min(ellipse_semi_axes) <= 0:
        raise ValueError("radius and semi-axes must be positive")
    coeffs = _ellipse_on_circle_coeffs(
        cc, float(circle_radius), ec, ellipse_semi_axes, math.radians(ellipse_angle_deg)
    )
    ts = trig_quadratic_roots(coeffs)
    return np.column_stack((cc[0] + circle_radius * np.cos(ts), cc[1] + circle_radius * np.sin(ts)))


# --------------------------------------------------------------------------
# The seed's ellipse and bounding-box methods


@dataclass(frozen=True)
class EllipseFit:
    """``cv2.fitEllipse`` result with named fields (full axes halved)."""

    centre_mm: tuple[float, float]
    semi_axes_mm: tuple[float, float]
    angle_deg: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "centre_mm": list(self.centre_mm),
            "semi_axes_mm": list(self.semi_axes_mm),
            "angle_deg": self.angle_deg,
        }


@dataclass(frozen=True)
class SeedArc:
    """What one of the seed's methods measures on an arc.

    Attributes
    ----------
    method : ``"seed_ellipse"`` or ``"seed_sagitta"``.
    radius_mm, chord_width_mm, height_mm, arc_angle_deg : as in the spec.
    end_points_mm : ndarray (2, 2) the arc's end points it found (ellipse), or
        the rectangle's chord-side corners (sagitta).
    ellipse : the fitted ellipse (ellipse method only).
    intersections : how many circle-ellipse intersections there were.
    """

    method: str
    radius_mm: float
    chord_width_mm: float
    height_mm: float
    arc_angle_deg: float
    end_points_mm: np.ndarray
    ellipse: EllipseFit | None = None
    intersections: int = 0

    def segment_bend_deg(self, divisions: int) -> float:
        return self.arc_angle_deg / divisions

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "method": self.method,
            "radius_mm": self.radius_mm,
            "chord_width_mm": self.chord_width_mm,
            "height_mm": self.height_mm,
            "arc_angle_deg": self.arc_angle_deg,
            "end_points_mm": self.end_points_mm.tolist(),
        }
        if self.ellipse is not None:
            out["ellipse"] = self.ellipse.to_dict()
            out["intersections"] = self.intersections
        return out


def _hull(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float32).reshape(-1, 1, 2)
    return cv2.convexHull(pts, clockwise=False).reshape(-1, 2).astype(np.float64)


def ellipse_method(outline_mm: np.ndarray) -> SeedArc:
    """The seed's elliptical-arc method on a wire outline (N, 2), mm.

    Convex hull of the outline, ``cv2.fitEllipse`` through the hull points,
    ``cv2.minEnclosingCircle`` of the hull; the arc's end points are the
    circle-ellipse intersections nearest the two farthest-apart hull points on
    the circle (when the ellipse only touches the circle, the points of closest
    approach). Width d is their
    distance, height h the largest distance of the ellipse arc between them
    (on the wire's side) from their chord; r = d^2 / 8h + h / 2.

    Near 180 degrees the enclosing circle and the ellipse almost coincide
    along the whole arc, so the end points are ill-defined: a weakness of the
    method (the benchmark shows it), not of the root finder.
    """
    pts = np.asarray(outline_mm, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 5:
        raise ValueError("the ellipse method needs at least 5 outline points")
    shift = pts.mean(axis=0)
    hull = _hull(pts - shift)
    if len(hull) < 5:
        raise ValueError("the outline's convex hull has fewer than 5 points")
    (ex, ey), (w, h), ang = cv2.fitEllipse(hull.astype(np.float32))
    ellipse = EllipseFit(
        (float(ex + shift[0]), float(ey + shift[1])), (w / 2.0, h / 2.0), float(ang)
    )
    (cx, cy), cr = cv2.minEnclosingCircle(hull.astype(np.float32))
    cc, ec = np.array([cx, cy], dtype=np.float64), np.array([ex, ey], dtype=np.float64)
    semi = (max(w / 2.0, 1e-9), max(h / 2.0, 1e-9))
    coeffs = _ellipse_on_circle_coeffs(cc, float(cr), ec, semi, math.radians(ang))
    ts = trig_quadratic_roots(coeffs)
    n_cross = len(ts)
    if len(ts) < 2:
        # tangency (or a near miss): the closest approaches are roots of f'(t)
        a0, a1, b1, a2, b2 = coeffs
        dts = trig_quadratic_roots((0.0, b1, -a1, 2 * b2, -2 * a2))
        f = a0 + a1 * np.cos(dts) + b1 * np.sin(dts) + a2 * np.cos(2 * dts) + b2 * np.sin(2 * dts)
        ts = dts[np.argsort(np.abs(f))[:2]] if len(dts) >= 2 else ts
    if len(ts) < 2:
        raise ValueError("the enclosing circle and the ellipse have no usable contact points")
    cand = np.column_stack((cx + cr * np.cos(ts), cy + cr * np.sin(ts)))
    # the arc's ends are the hull points on the enclosing circle (the seed's
    # reason for the circle); take the intersection nearest each of the two
    # farthest-apart such points (as the seed's fsolve, started near them, would)
    on_circle = hull[np.abs(np.hypot(hull[:, 0] - cx, hull[:, 1] - cy) - cr) <= 0.01 * cr]
    touch = on_circle if len(on_circle) >= 2 else hull
    far = np.hypot(*(touch[:, None, :] - touch[None, :, :]).transpose(2, 0, 1))
    a_i, b_i = np.unravel_index(int(np.argmax(far)), far.shape)
    e1 = cand[int(np.argmin(np.hypot(*(cand - touch[a_i]).T)))]
    e2 = cand[int(np.argmin(np.hypot(*(cand - touch[b_i]).T)))]
    if np.allclose(e1, e2):
        i, j = max(
            ((a, b) for a in range(len(cand)) for b in range(a + 1, len(cand))),
            key=lambda ij: float(np.hypot(*(cand[ij[0]] - cand[ij[1]]))),
        )
        e1, e2 = cand[i], cand[j]
    d = float(np.hypot(*(e2 - e1)))
    # height: the ellipse arc between e1 and e2 on the side where the hull lies
    normal = np.array([-(e2 - e1)[1], (e2 - e1)[0]]) / max(d, 1e-300)
    side = np.sign(np.mean((hull - e1) @ normal)) or 1.0
    ca, sa = math.cos(math.radians(ang)), math.sin(math.radians(ang))
    tt = np.linspace(0, 2 * np.pi, 7200, endpoint=False)
    ell = np.column_stack(
        (
            ex + semi[0] * np.cos(tt) * ca - semi[1] * np.sin(tt) * sa,
            ey + semi[0] * np.cos(tt) * sa + semi[1] * np.sin(tt) * ca,
        )
    )
    dist = ((ell - e1) @ normal) * side
    height = float(dist.max())
    if height <= 0:
        raise ValueError("the ellipse lies on one side of its chord; no arc height")
    return SeedArc(
        method="seed_ellipse",
        radius_mm=sagitta_radius_mm(d, height),
        chord_width_mm=d,
        height_mm=height,
        arc_angle_deg=arc_angle_from_chord_deg(d, height),
        end_points_mm=np.vstack((e1, e2)) + shift,
        ellipse=ellipse,
        intersections=n_cross,
    )


def sagitta_method(outline_mm: np.ndarray) -> SeedArc:
    """The seed's fast approximation: the rotated bounding rectangle's sides as d and h.

    ``cv2.minAreaRect`` of the outline; the longer side is the arc width d,
    the shorter its height h; r = d^2 / 8h + h / 2 (the seed's Eq. 8).
    """
    pts = np.asarray(outline_mm, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 3:
        raise ValueError("the sagitta method needs at least 3 outline points")
    shift = pts.mean(axis=0)
    rect = cv2.minAreaRect((pts - shift).astype(np.float32))
    (rw, rh) = rect[1]
    d, h = float(max(rw, rh)), float(min(rw, rh))
    if h <= 0:
        raise ValueError("the outline is a straight line; no arc height")
    box = cv2.boxPoints(rect).astype(np.float64) + shift
    return SeedArc(
        method="seed_sagitta",
        radius_mm=sagitta_radius_mm(d, h),
        chord_width_mm=d,
        height_mm=h,
        arc_angle_deg=arc_angle_from_chord_deg(d, h),
        end_points_mm=box[:2],
    )
