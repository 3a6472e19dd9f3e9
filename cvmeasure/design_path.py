"""A design's paths and the polyline geometry they share with G-code and part measurement.

Design frame: x right, y **up**, millimetres (see :mod:`cvmeasure.design`). Signed bend
angles (:func:`bend_angles_deg`) are turning angles at the vertices, counter-clockwise
positive, wrapped to (-180, 180].
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from cvmeasure.errors import InputError
from cvmeasure.geometry import wrap_deg

__all__ = [
    "DesignArc",
    "DesignPath",
    "Design",
    "PathKind",
    "UNIT_MM",
    "arc_points_mm",
    "divide_into_chords",
    "bend_angles_deg",
    "chord_lengths_mm",
    "polyline_length_mm",
    "join_paths",
    "flatten_curve",
    "dedupe_flagged",
    "DEFAULT_TOLERANCE_MM",
]

#: Largest distance (mm) allowed between a curve and the chords that replace it.
DEFAULT_TOLERANCE_MM = 0.001

PathKind = Literal[
    "line", "polyline", "polygon", "rect", "arc", "circle", "ellipse", "spline", "path"
]


#: Millimetres per unit a drawing may be in (``units=`` of the readers, ``--units``).
UNIT_MM = {
    "mm": 1.0,
    "cm": 10.0,
    "in": 25.4,
    "pt": 25.4 / 72.0,
    "pc": 25.4 / 6.0,
    "px": 25.4 / 96.0,
}


@dataclass(frozen=True)
class DesignArc:
    """A circular arc of a design, in the design frame.

    Attributes
    ----------
    centre_mm : (x, y) of the centre, mm.
    radius_mm : radius, mm.
    start_deg : direction of the start point seen from the centre, degrees CCW from +x.
    sweep_deg : signed sweep, degrees; positive counter-clockwise (a left turn).
    """

    centre_mm: tuple[float, float]
    radius_mm: float
    start_deg: float
    sweep_deg: float

    @property
    def length_mm(self) -> float:
        return abs(math.radians(self.sweep_deg)) * self.radius_mm

    def points_mm(
        self, *, chords: int | None = None, tolerance_mm: float = DEFAULT_TOLERANCE_MM
    ) -> np.ndarray:
        """Vertices on the arc; see :func:`arc_points_mm`."""
        return arc_points_mm(
            self.centre_mm,
            self.radius_mm,
            self.start_deg,
            self.sweep_deg,
            chords=chords,
            tolerance_mm=tolerance_mm,
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "centre_mm": list(self.centre_mm),
            "radius_mm": self.radius_mm,
            "start_deg": self.start_deg,
            "sweep_deg": self.sweep_deg,
        }


@dataclass(frozen=True)
class DesignPath:
    """One connected path of a design.

    Attributes
    ----------
    points_mm : ndarray of shape (N, 2), float64
        Vertices in the design frame, mm. A closed path does not repeat its first point.
    closed : bool
        Whether the last vertex connects back to the first.
    kind : PathKind
        What the drawing element was (``"path"`` for SVG paths and joined chains).
    element : str
        The element it came from, for messages (``"<circle id=c1>"``, ``"DXF ARC #2A"``).
    arcs : tuple of DesignArc
        The circular arcs (and circles) the path contains, in path order.
    curve : tuple of bool, optional
        Per segment (``points_mm[i]`` to ``points_mm[i+1]``), whether it is a piece of a
        flattened curve (arc, Bézier, spline, ellipse) rather than a drawn straight
        line. None: from ``kind`` (arcs, circles, ellipses and splines are curves).
        The G-code generator divides curves into chords; straight lines keep their
        corners (:mod:`cvmeasure.wireplan`).
    """

    points_mm: np.ndarray
    closed: bool
    kind: PathKind
    element: str = ""
    arcs: tuple[DesignArc, ...] = field(default=())
    curve: tuple[bool, ...] | None = None

    def __post_init__(self) -> None:
        pts = np.asarray(self.points_mm, dtype=np.float64).reshape(-1, 2)
        object.__setattr__(self, "points_mm", pts)
        if self.curve is not None:
            flags = tuple(bool(c) for c in self.curve)
            if len(flags) != max(len(pts) - 1, 0):
                raise ValueError(f"{len(flags)} curve flags for {len(pts) - 1} segments")
            object.__setattr__(self, "curve", flags)

    @property
    def curve_mask(self) -> np.ndarray:
        """Per open segment (N-1,), whether it is a piece of a flattened curve."""
        if self.curve is not None:
            return np.array(self.curve, dtype=bool)
        is_curve = self.kind in ("arc", "circle", "ellipse", "spline")
        return np.full(max(len(self.points_mm) - 1, 0), is_curve, dtype=bool)

    @property
    def length_mm(self) -> float:
        """Length along the polyline (closing chord included when closed), mm."""
        return polyline_length_mm(self.points_mm, closed=self.closed)

    def chords(self, divisions: int) -> np.ndarray:
        """Divide the path into ``divisions`` equal chords (vertices (divisions+1, 2), mm).

        A path that is one circular arc is divided exactly on the arc; any other
        path with :func:`divide_into_chords` on its polyline (accurate to about
        the flattening tolerance).
        """
        if len(self.arcs) == 1 and not self.closed:
            arc = self.arcs[0]
            ends = arc.points_mm(chords=1)
            if np.allclose(ends, self.points_mm[[0, -1]], atol=1e-6):
                return arc.points_mm(chords=divisions)
        return divide_into_chords(self.points_mm, divisions)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "closed": self.closed,
            "element": self.element,
            "points_mm": self.points_mm.tolist(),
            "arcs": [a.to_dict() for a in self.arcs],
            "curve": self.curve_mask.tolist(),
        }


@dataclass(frozen=True)
class Design:
    """A design drawing: its source file, its paths (design frame, mm) and its units.

    ``units`` says where the millimetres came from (``"mm (width=100mm)"``,
    ``"px at 96 per inch (Inkscape)"``, ``"in ($INSUNITS 1)"``...).
    """

    source: str
    paths: tuple[DesignPath, ...]
    units: str = "mm"

    def wire(self, *, join_tolerance_mm: float = 0.05) -> DesignPath:
        """The design as ONE wire: all paths chained end to end.

        Raises
        ------
        InputError
            When the paths do not form a single chain (naming the source file).
        """
        joined = join_paths(self.paths, tolerance_mm=join_tolerance_mm)
        if len(joined) != 1:
            raise InputError(
                self.source,
                f"design has {len(joined)} separate paths; a wire part needs one connected path",
            )
        return joined[0]

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "units": self.units,
            "paths": [p.to_dict() for p in self.paths],
        }


# ---------------------------------------------------------------------------
# Polyline geometry used by designs, G-code and part measurement alike


def polyline_length_mm(points_mm: np.ndarray, *, closed: bool = False) -> float:
    """Total length of a polyline (N, 2), mm."""
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    if closed and len(pts) > 1:
        pts = np.vstack((pts, pts[:1]))
    return float(np.sum(np.hypot(*np.diff(pts, axis=0).T)))


def chord_lengths_mm(vertices_mm: np.ndarray) -> np.ndarray:
    """Lengths (N-1,) of the chords between successive vertices (N, 2), mm."""
    pts = np.asarray(vertices_mm, dtype=np.float64).reshape(-1, 2)
    return np.hypot(*np.diff(pts, axis=0).T)


def bend_angles_deg(vertices_mm: np.ndarray) -> np.ndarray:
    """Signed turning angle at each interior vertex of a polyline, degrees.

    Parameters
    ----------
    vertices_mm : ndarray of shape (N, 2)
        Polyline vertices in a right-handed (x, y-up) frame.

    Returns
    -------
    ndarray of shape (N-2,)
        Angle from chord ``i`` to chord ``i+1`` at vertex ``i+1``; positive
        counter-clockwise (a left turn), 0 straight, wrapped to (-180, 180].

    Examples
    --------
    >>> bend_angles_deg(np.array([[0, 0], [1, 0], [1, 1]])).tolist()
    [90.0]
    """
    pts = np.asarray(vertices_mm, dtype=np.float64).reshape(-1, 2)
    if len(pts) < 3:
        return np.zeros(0)
    d = np.diff(pts, axis=0)
    a, b = d[:-1], d[1:]
    cross = a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]
    dot = np.sum(a * b, axis=1)
    return np.asarray(wrap_deg(np.degrees(np.arctan2(cross, dot))), dtype=np.float64).reshape(-1)


def arc_points_mm(
    centre_mm: Sequence[float],
    radius_mm: float,
    start_deg: float,
    sweep_deg: float,
    *,
    chords: int | None = None,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
) -> np.ndarray:
    """Vertices on a circular arc, both ends included, mm.

    With ``chords=N`` the arc is divided into N equal chords (N+1 vertices; each
    chord turns by ``sweep_deg / N`` from the previous one). Without it, as few
    equal chords as keep the sagitta of every chord below ``tolerance_mm``.

    Examples
    --------
    >>> arc_points_mm((0, 0), 100.0, 180.0, -180.0, chords=20).shape
    (21, 2)
    """
    if radius_mm <= 0:
        raise ValueError(f"radius_mm must be positive, got {radius_mm}")
    if chords is None:
        if tolerance_mm <= 0:
            raise ValueError(f"tolerance_mm must be positive, got {tolerance_mm}")
        half = math.acos(max(-1.0, 1.0 - tolerance_mm / radius_mm))
        chords = max(1, math.ceil(abs(math.radians(sweep_deg)) / (2.0 * half)))
    if chords < 1:
        raise ValueError(f"chords must be >= 1, got {chords}")
    t = np.radians(start_deg + sweep_deg * np.linspace(0.0, 1.0, chords + 1))
    return np.column_stack(
        (centre_mm[0] + radius_mm * np.cos(t), centre_mm[1] + radius_mm * np.sin(t))
    )


def divide_into_chords(points_mm: np.ndarray, divisions: int) -> np.ndarray:
    """Divide a curve into ``divisions`` chords of equal length, vertices on the curve.

    The curve is the polyline ``points_mm`` (densely sampled, e.g. from a design).
    The first vertex is its start and the last its end; the common chord length
    is found by bisection so that stepping along the curve by circles of that
    radius ends exactly at the end point (the seed paper's "equal cord lengths").

    Parameters
    ----------
    points_mm : ndarray of shape (M, 2)
    divisions : int, >= 1

    Returns
    -------
    ndarray of shape (divisions + 1, 2)
    """
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    if divisions < 1:
        raise ValueError(f"divisions must be >= 1, got {divisions}")
    if len(pts) < 2:
        raise ValueError("a curve needs at least 2 points")
    seg = chord_lengths_mm(pts)
    keep = np.concatenate(([True], seg > 0))
    pts = pts[keep]
    cum = np.concatenate(([0.0], np.cumsum(chord_lengths_mm(pts))))
    total = cum[-1]
    if divisions == 1:
        return pts[[0, -1]].copy()

    def walk(chord: float) -> tuple[np.ndarray, float]:
        """Step ``divisions - 1`` chords; return the vertices and the leftover arc length."""
        verts = [pts[0]]
        s = 0.0
        for _ in range(divisions - 1):
            s = _next_at_distance(pts, cum, s, verts[-1], chord)
            if s is None:
                return np.array(verts), -1.0
            verts.append(_point_at(pts, cum, s))
        return np.array(verts), float(np.hypot(*(pts[-1] - verts[-1])))

    lo, hi = 0.0, total / divisions * 1.0000001
    # the last chord equals `chord` when walk(chord) leaves exactly `chord` to the end
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        verts, rest = walk(mid)
        if rest < 0 or rest < mid:
            hi = mid
        else:
            lo = mid
        if hi - lo < 1e-12 * max(1.0, total):
            break
    verts, rest = walk(0.5 * (lo + hi))
    if rest < 0:
        # a curve that doubles back (a noisy centreline) can lose the last step at the
        # bisection's midpoint: the longest chord known to step through is taken instead
        verts, rest = walk(lo)
    if rest < 0 or len(verts) != divisions:
        raise ValueError(f"the curve cannot be divided into {divisions} chords of equal length")
    return np.vstack((verts, pts[-1:]))


def _index_at(cum: np.ndarray, s: float) -> int:
    """The segment in which arc length ``s`` lies (clamped to the first and last)."""
    return min(max(int(np.searchsorted(cum, s, side="right")) - 1, 0), len(cum) - 2)


def _point_at(pts: np.ndarray, cum: np.ndarray, s: float) -> np.ndarray:
    i = _index_at(cum, s)
    f = (s - cum[i]) / (cum[i + 1] - cum[i])
    return pts[i] + f * (pts[i + 1] - pts[i])


def _next_at_distance(
    pts: np.ndarray, cum: np.ndarray, s0: float, origin: np.ndarray, dist: float
) -> float | None:
    """Arc length of the first point beyond ``s0`` at distance ``dist`` from ``origin``."""
    i = _index_at(cum, s0)
    start = _point_at(pts, cum, s0)
    # the first segment whose far end is not nearer than ``dist`` (all at once: a Python
    # loop over a dense curve's points was most of a part's chord count)
    ahead = pts[i + 1 :]
    far = np.flatnonzero(~(np.hypot(ahead[:, 0] - origin[0], ahead[:, 1] - origin[1]) < dist))
    if len(far) == 0:
        return None
    j = i + int(far[0])
    a = start if j == i else pts[j]
    b = pts[j + 1]
    # solve |a + u (b - a) - origin| = dist for the smallest u in [0, 1]
    d = b - a
    f = a - origin
    qa = float(d @ d)
    qb = 2.0 * float(f @ d)
    qc = float(f @ f) - dist * dist
    disc = max(qb * qb - 4 * qa * qc, 0.0)
    u = (-qb + math.sqrt(disc)) / (2 * qa)
    u = min(max(u, 0.0), 1.0)
    seg_start = s0 if j == i else cum[j]
    return seg_start + u * (cum[j + 1] - seg_start)


def join_paths(paths: Sequence[DesignPath], *, tolerance_mm: float = 0.05) -> list[DesignPath]:
    """Chain open paths whose end points meet (within ``tolerance_mm``) into longer paths.

    Paths are reversed where needed. Closed paths are kept as they are. A chain
    of more than one path gets ``kind="path"``.
    """
    open_paths = [p for p in paths if not p.closed and len(p.points_mm) >= 2]
    out = [p for p in paths if p.closed]
    used = [False] * len(open_paths)
    for i, first in enumerate(open_paths):
        if used[i]:
            continue
        used[i] = True
        chain = [first]
        pts = first.points_mm
        flags = first.curve_mask
        grown = True
        while grown:
            grown = False
            for j, other in enumerate(open_paths):
                if used[j]:
                    continue
                q = other.points_mm
                qf = other.curve_mask
                arcs = other.arcs
                # a gap within the tolerance is closed by moving the joining end point
                if np.hypot(*(q[0] - pts[-1])) <= tolerance_mm:
                    pts, flags = np.vstack((pts, q[1:])), np.concatenate((flags, qf))
                elif np.hypot(*(q[-1] - pts[-1])) <= tolerance_mm:
                    pts, flags = np.vstack((pts, q[::-1][1:])), np.concatenate((flags, qf[::-1]))
                    arcs = tuple(_reversed_arc(a) for a in arcs[::-1])
                elif np.hypot(*(q[-1] - pts[0])) <= tolerance_mm:
                    pts, flags = np.vstack((q[:-1], pts)), np.concatenate((qf, flags))
                    chain.insert(0, other)
                    used[j] = grown = True
                    continue
                elif np.hypot(*(q[0] - pts[0])) <= tolerance_mm:
                    pts, flags = np.vstack((q[::-1][:-1], pts)), np.concatenate((qf[::-1], flags))
                    chain.insert(0, _reversed_path(other))
                    used[j] = grown = True
                    continue
                else:
                    continue
                chain.append(DesignPath(q, False, other.kind, other.element, arcs))
                used[j] = grown = True
        if len(chain) == 1:
            out.append(first)
        else:
            out.append(
                DesignPath(
                    pts,
                    False,
                    "path",
                    " + ".join(p.element for p in chain),
                    tuple(a for p in chain for a in p.arcs),
                    tuple(bool(f) for f in flags),
                )
            )
    return out


def _reversed_arc(arc: DesignArc) -> DesignArc:
    return DesignArc(arc.centre_mm, arc.radius_mm, arc.start_deg + arc.sweep_deg, -arc.sweep_deg)


def _reversed_path(path: DesignPath) -> DesignPath:
    return DesignPath(
        path.points_mm[::-1],
        path.closed,
        path.kind,
        path.element,
        tuple(_reversed_arc(a) for a in path.arcs[::-1]),
        tuple(bool(f) for f in path.curve_mask[::-1]),
    )


def flatten_curve(
    fn: Callable[[np.ndarray], np.ndarray], tolerance_mm: float, *, min_chords: int = 4
) -> np.ndarray:
    """Sample a parametric curve ``fn(t)``, t in [0, 1], until every chord is within tolerance."""
    n = min_chords
    while True:
        t = np.linspace(0.0, 1.0, n + 1)
        pts = fn(t)
        mid = fn(0.5 * (t[:-1] + t[1:]))
        a, b = pts[:-1], pts[1:]
        d = b - a
        length = np.hypot(d[:, 0], d[:, 1])
        off = np.abs(d[:, 0] * (mid[:, 1] - a[:, 1]) - d[:, 1] * (mid[:, 0] - a[:, 0]))
        dev = np.where(length > 0, off / np.maximum(length, 1e-300), np.hypot(*(mid - a).T))
        if np.max(dev) <= tolerance_mm or n >= 1 << 16:
            return pts
        n *= 2


def dedupe_flagged(points: np.ndarray, flags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop repeated points and the flags of the zero-length segments ending at them."""
    if len(points) < 2:
        return points, flags[:0]
    keep = np.concatenate(([True], np.hypot(*np.diff(points, axis=0).T) > 1e-9))
    return points[keep], flags[keep[1:]]
