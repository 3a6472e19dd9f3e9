"""The arc a centreline describes: circle, chords, sagitta and its shape (arc or S-curve)."""

from __future__ import annotations

import math

import numpy as np

from cvmeasure.geometry import CircleFit, fit_circle_robust
from cvmeasure.part.fit import (
    ArcGeometry,
    PolylineFit,
    arc_geometry,
    fit_polyline,
)
from cvmeasure.part.result import ArcResult

__all__ = [
    "S_CURVE_BEND_DEG",
    "part_shape",
    "arc_from_points",
    "polygon_arc",
    "chord_and_height_mm",
    "net_turn_deg",
]


#: Vertex bends of both signs beyond this (deg) make a part an S-curve (saddle).
S_CURVE_BEND_DEG = 0.2


def part_shape(poly: PolylineFit | None) -> str:
    """``"s-curve"`` when the vertex bends change sign, else ``"arc"``."""
    if poly is None:
        return "arc"
    bends = np.asarray(poly.bend_deg, dtype=float)
    if np.any(bends > S_CURVE_BEND_DEG) and np.any(bends < -S_CURVE_BEND_DEG):
        return "s-curve"
    return "arc"


def arc_from_points(
    points_mm: np.ndarray, divisions: int | None, fractions: np.ndarray | None = None
) -> tuple[ArcResult, CircleFit, PolylineFit | None]:
    """Our arc quantities from an ordered centreline in mm (see the module notes).

    ``fractions``: where the polygon bent has its vertices (shares of its length, in the
    centreline's order; :func:`cvmeasure.part.fit.fit_polyline`), default equal chords.
    """
    pts = np.asarray(points_mm, dtype=np.float64)
    poly = None
    if divisions:
        poly = fit_polyline(pts, divisions, fractions=fractions)
        geo, circle = polygon_arc(_placed_vertices(poly))
        chord, height = geo.chord_width_mm, geo.height_mm
    else:
        circle = fit_circle_robust(pts)
        geo = arc_geometry(circle, pts)
        chord, height = geo.chord_width_mm, geo.height_mm
    result = ArcResult("centreline_fit", geo.radius_mm, chord, height, geo.arc_angle_deg, divisions)
    return result, circle, poly


def _placed_vertices(poly: PolylineFit) -> np.ndarray:
    """The polygon's vertices less those between two chords placed across a gap of the
    centreline (the intersection of two lines through the same gap's ends: not measured)."""
    if poly.across_gap is None:
        return poly.vertices_mm
    gap = np.asarray(poly.across_gap, dtype=bool)
    inner_unplaced = np.r_[False, gap[:-1] & gap[1:], False]
    return poly.vertices_mm[~inner_unplaced]


def polygon_arc(vertices_mm: np.ndarray) -> tuple[ArcGeometry, CircleFit]:
    """The arc quantities of a polygon's vertices (N+1, 2), mm, and the circle through them.

    Radius and arc angle from the robust circle through the vertices; chord and height
    from the vertices themselves (:func:`chord_and_height_mm`), so a part and its design
    are summarised alike. A polygon that no circle describes -- a straight wire (fewer
    than 3 vertices, or all on a line) or an S-curve symmetric about its middle, whose
    best-fitting circle is a line -- has the straight line's limit: an infinite radius
    (``null`` in JSON), no arc angle, and a circle of undefined centre.
    """
    v = np.asarray(vertices_mm, dtype=np.float64).reshape(-1, 2)
    if not np.all(np.isfinite(v)):
        raise ValueError("polygon vertices must be finite")
    chord, height = chord_and_height_mm(v) if len(v) else (0.0, 0.0)
    circle = _circle_or_line(v)
    if not math.isfinite(circle.radius):
        return ArcGeometry(math.inf, chord, height, 0.0), circle
    geo = arc_geometry(circle, v)
    return ArcGeometry(geo.radius_mm, chord, height, geo.arc_angle_deg), circle


def _circle_or_line(v: np.ndarray) -> CircleFit:
    """:func:`fit_circle_robust` of finite points, or an infinite-radius circle on their line.

    The points are finite and checked for count, so the fit's only remaining refusal is
    a degenerate set (all on a line, or all one point).
    """
    if len(v) >= 3:
        try:
            return fit_circle_robust(v)
        except ValueError:
            pass  # collinear (or one point): the line below
    centred = v - v.mean(axis=0) if len(v) else np.zeros((0, 2))
    rms = 0.0
    if len(v) >= 2:  # distance to the total-least-squares line
        normal = np.linalg.svd(centred, full_matrices=False)[2][-1]
        rms = float(np.sqrt(np.mean((centred @ normal) ** 2)))
    nan2 = np.full((2, 2), math.nan)
    return CircleFit((math.nan, math.nan), math.inf, nan2, rms, len(v), len(v), 0.0, math.nan)


def chord_and_height_mm(vertices_mm: np.ndarray) -> tuple[float, float]:
    """End-to-end distance of a polyline and its largest vertex distance from that line, mm.

    For vertices on a circular arc these are the seed's width d and height h
    (exactly when a vertex sits at the arc's middle); they stay meaningful for
    saddles and other shapes that have no single radius.
    """
    v = np.asarray(vertices_mm, dtype=np.float64)
    a, b = v[0], v[-1]
    chord = float(np.hypot(*(b - a)))
    if chord == 0.0:
        return 0.0, float(np.max(np.hypot(*(v - a).T)))
    d = (b - a) / chord
    rel = v - a
    return chord, float(np.max(np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])))


def net_turn_deg(points_mm: np.ndarray) -> float:
    """Total signed turning of an ordered centreline (board frame sense), degrees."""
    pts = np.asarray(points_mm, dtype=np.float64)
    step = max(1, len(pts) // 200)
    d = np.diff(pts[::step], axis=0)
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return float(np.degrees(heading[-1] - heading[0])) if len(heading) else 0.0
