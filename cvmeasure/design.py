"""Wire designs from SVG and DXF drawings, as polylines in millimetres.

A design is what a part was bent from: one or more paths (lines, polylines,
arcs, circles, ellipses, splines, SVG paths with Bézier curves). Every path is
flattened into a polyline whose chords stay within ``tolerance_mm`` of the true
curve; straight pieces keep exactly their end points, and circular arcs are
also kept as :class:`DesignArc` records so that a caller (G-code generation)
can divide them into equal chords itself (:func:`arc_points_mm`,
:func:`divide_into_chords`).

Design frame: x right, y **up**, millimetres, as a CAD viewer shows the
drawing. DXF coordinates are used as they are (scaled by ``$INSUNITS``); SVG's
y-down user space (96 px per inch, as CSS and svgelements define it) is mirrored
to y up, so counter-clockwise as seen in the drawing is positive in both.
Signed bend angles (:func:`bend_angles_deg`) are turning angles at the
vertices, counter-clockwise positive, wrapped to (-180, 180].

Readers raise :class:`~cvmeasure.errors.InputError` naming the file and, for
an unsupported element (SVG ``<text>``, DXF ``TEXT``, ``INSERT``, ...), the
element.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from cvmeasure.errors import InputError
from cvmeasure.geometry import wrap_deg

__all__ = [
    "DesignArc",
    "DesignPath",
    "Design",
    "PathKind",
    "load_design",
    "read_svg",
    "read_dxf",
    "arc_points_mm",
    "divide_into_chords",
    "bend_angles_deg",
    "chord_lengths_mm",
    "polyline_length_mm",
    "join_paths",
    "DEFAULT_TOLERANCE_MM",
]

#: Largest distance (mm) allowed between a curve and the chords that replace it.
DEFAULT_TOLERANCE_MM = 0.001

PathKind = Literal[
    "line", "polyline", "polygon", "rect", "arc", "circle", "ellipse", "spline", "path"
]

# svgelements' own px-per-mm at 96 ppi (3.7795296, not 96 / 25.4), so that a
# drawing made in mm reads back in exact mm.
_SVG_PX_PER_MM: float | None = None

# DXF $INSUNITS code -> millimetres per drawing unit (0 = unitless, read as mm).
_DXF_UNIT_MM = {
    0: 1.0,
    1: 25.4,
    2: 304.8,
    4: 1.0,
    5: 10.0,
    6: 1000.0,
    8: 25.4e-6,
    9: 25.4e-3,
    10: 914.4,
    13: 1e-3,
    14: 100.0,
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
    verts, _ = walk(0.5 * (lo + hi))
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


# ---------------------------------------------------------------------------
# Readers


def load_design(
    path: str | os.PathLike[str],
    *,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    ignore_unknown: bool = False,
    units: str | None = None,
) -> Design:
    """Read an SVG or DXF design (chosen by the file suffix).

    Parameters
    ----------
    path : the ``.svg`` or ``.dxf`` file.
    tolerance_mm : largest chord-to-curve distance when curves are flattened, mm.
    ignore_unknown : skip unsupported elements (text, images, blocks) instead of failing.
    units : the unit of a drawing that declares none (a key of :data:`UNIT_MM`); such a
        drawing is refused without it.

    Raises
    ------
    InputError
        The file is missing or unreadable, has an unsupported element (named),
        or holds no geometry.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise InputError(path, "design file not found")
    if units is not None and units not in UNIT_MM:
        raise InputError("--units", f"unknown unit {units!r}; valid: {', '.join(UNIT_MM)}")
    if suffix == ".svg":
        design = read_svg(
            path, tolerance_mm=tolerance_mm, ignore_unknown=ignore_unknown, units=units
        )
    elif suffix == ".dxf":
        design = read_dxf(
            path, tolerance_mm=tolerance_mm, ignore_unknown=ignore_unknown, units=units
        )
    else:
        raise InputError(path, f"unknown design format {suffix or '(no suffix)'}; use .svg or .dxf")
    check_design_coordinates(design)
    return design


#: Largest coordinate a design may have, mm (a 100 m drawing is a unit error, not a part).
MAX_DESIGN_COORDINATE_MM = 100_000.0


def check_design_coordinates(design: Design) -> None:
    """InputError naming the file and element when a coordinate is NaN, infinite or beyond
    :data:`MAX_DESIGN_COORDINATE_MM` (a NaN once went on to write a job of 0-degree bends)."""
    for p in design.paths:
        pts = np.asarray(p.points_mm, dtype=np.float64)
        if not np.all(np.isfinite(pts)):
            raise InputError(design.source, f"{p.element}: a coordinate is not a finite number")
        if pts.size and np.max(np.abs(pts)) > MAX_DESIGN_COORDINATE_MM:
            raise InputError(
                design.source,
                f"{p.element}: a coordinate of {np.max(np.abs(pts)):.3g} mm is beyond "
                f"{MAX_DESIGN_COORDINATE_MM:g} mm (wrong units?)",
            )


def _flatten(
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


#: SVG attributes that hold coordinates (svgelements drops a token it cannot read, such
#: as ``nan``, silently: a polyline then loses a point and a bend).
_SVG_GEOMETRY_ATTRIBUTES = (
    "points",
    "d",
    "x",
    "y",
    "x1",
    "y1",
    "x2",
    "y2",
    "cx",
    "cy",
    "r",
    "rx",
    "ry",
    "width",
    "height",
    "transform",
    "viewBox",
)
_NON_NUMBER = re.compile(r"(?<![a-z])(nan|inf|infinity)(?![a-z])", re.IGNORECASE)


def _refuse_non_numbers(path: Path) -> dict[str, str] | None:
    """InputError naming the element when a geometry attribute holds nan or inf.

    Returns the root element's attributes (None when the XML does not parse).
    """
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError, ValueError):
        return None  # the SVG parser says what is wrong
    for element in root.iter():
        for name in _SVG_GEOMETRY_ATTRIBUTES:
            value = element.attrib.get(name)
            if value and _NON_NUMBER.search(value):
                tag = element.tag.rsplit("}", 1)[-1]
                raise InputError(path, f"<{tag}> {name}={value[:60]!r}: not a finite number")
    return dict(root.attrib)


#: Millimetres per unit a drawing may be in (``units=`` of the readers, ``--units``).
UNIT_MM = {
    "mm": 1.0,
    "cm": 10.0,
    "in": 25.4,
    "pt": 25.4 / 72.0,
    "pc": 25.4 / 6.0,
    "px": 25.4 / 96.0,
}
_SVG_LENGTH = re.compile(r"^\s*([-+0-9.eE]+)\s*([a-zA-Z%]*)\s*$")


def _svg_units(path: Path, root_attrib: Mapping[str, str], units: str | None) -> tuple[float, str]:
    """Scale onto svgelements' 96-per-inch reading, and where the units came from.

    A document whose ``width`` carries a physical unit (mm, cm, in, pt, pc) is read in
    it (viewBox applied). One in px, or unitless, has a physical size only when the
    program that wrote it declares it: Adobe Illustrator's px are points (72 per inch),
    Inkscape's are CSS px (96 per inch). Otherwise ``units`` (the operator's word) or
    an InputError: no design is read at a guessed scale.
    """
    width = root_attrib.get("width", "")
    match = _SVG_LENGTH.match(width)
    unit = match.group(2).lower() if match else ""
    if unit in ("mm", "cm", "in", "pt", "pc", "q"):
        return 1.0, f"{unit} (width={width.strip()})"
    try:
        head = path.read_text(encoding="utf-8", errors="replace")[:6000]
    except OSError:
        head = ""
    described = f"width={width.strip()}" if width else "no width"
    if "Adobe Illustrator" in head:
        return 96.0 / 72.0, f"pt: px at 72 per inch (Adobe Illustrator, {described})"
    if "inkscape.org/namespaces/inkscape" in head or "sodipodi" in head:
        return 1.0, f"px at 96 per inch (Inkscape, {described})"
    if units is not None:
        return UNIT_MM[units] / UNIT_MM[
            "px"
        ], f"{units} (given by --units; the file has {described})"
    raise InputError(
        path,
        f"no physical units (size {width.strip() or 'not given'}, no program declaring its "
        "px): re-export in mm, or pass --units px (96/in, Inkscape) or --units pt (72/in, "
        "Illustrator)",
    )


def read_svg(
    path: str | os.PathLike[str],
    *,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    ignore_unknown: bool = False,
    units: str | None = None,
) -> Design:
    """Read an SVG drawing with svgelements (units, viewBox and transforms applied).

    ``units``: the unit of a drawing that declares no physical size (see
    :func:`_svg_units`); refused without it.
    """
    import svgelements as se

    path = Path(path)
    root = _refuse_non_numbers(path)
    try:
        svg = se.SVG.parse(str(path), reify=True)
    except Exception as exc:  # svgelements raises assorted parser errors
        raise InputError(path, f"unreadable SVG: {exc}") from None
    if root is None:
        raise InputError(path, "unreadable SVG: not well-formed XML")
    scale, unit_text = _svg_units(path, root, units)

    structural = (
        (se.SVG, se.Group, se.Desc, se.Title)
        if hasattr(se, "Title")
        else (se.SVG, se.Group, se.Desc)
    )
    paths: list[DesignPath] = []
    for element in svg.elements():
        if isinstance(element, structural):
            continue
        name = _svg_name(element)
        if not isinstance(element, se.Shape) and _svg_not_drawn(element):
            continue  # an editor's metadata (Inkscape's sodipodi:namedview), styles, defs
        if not isinstance(element, se.Shape):
            if ignore_unknown:
                continue
            raise InputError(path, f"unsupported SVG element {name}; use lines, paths and shapes")
        if element.values.get("visibility") == "hidden" or element.values.get("display") == "none":
            continue
        kind = _svg_kind(element)
        paths.extend(_svg_shape_paths(se.Path(element), kind, name, tolerance_mm, scale))
    if not paths:
        raise InputError(path, "no drawable geometry in the SVG")
    return Design(str(path), tuple(paths), unit_text)


#: SVG elements that draw nothing themselves.
_SVG_NOT_DRAWN = {
    "metadata", "style", "defs", "title", "desc", "symbol", "marker", "clippath", "mask",
    "pattern", "lineargradient", "radialgradient", "stop", "filter", "script", "namedview",
}  # fmt: skip


def _svg_not_drawn(element: Any) -> bool:
    """Metadata, styles and definitions, or an element of another program's namespace."""
    tag = str(element.values.get("tag", "")) if hasattr(element, "values") else ""
    if tag.startswith("{") and not tag.startswith("{http://www.w3.org/2000/svg}"):
        return True
    return tag.rsplit("}", 1)[-1].lower() in _SVG_NOT_DRAWN


def _svg_name(element: Any) -> str:
    tag = element.values.get("tag") if hasattr(element, "values") else None
    tag = tag or type(element).__name__.lower()
    ident = getattr(element, "id", None)
    return f"<{tag} id={ident}>" if ident else f"<{tag}>"


def _svg_kind(element: Any) -> PathKind:
    import svgelements as se

    if isinstance(element, se.SimpleLine):
        return "line"
    if isinstance(element, se.Polygon):
        return "polygon"
    if isinstance(element, se.Polyline):
        return "polyline"
    if isinstance(element, se.Rect):
        return "rect"
    if isinstance(element, se.Circle):
        return "circle"
    if isinstance(element, se.Ellipse):
        rx, ry = float(element.rx), float(element.ry)
        return "circle" if math.isclose(rx, ry, rel_tol=1e-9) else "ellipse"
    return "path"


def _svg_px_per_mm() -> float:
    global _SVG_PX_PER_MM
    if _SVG_PX_PER_MM is None:
        import svgelements as se

        _SVG_PX_PER_MM = float(se.Length("1mm").value(ppi=96.0))
    return _SVG_PX_PER_MM


def _svg_xy(points_px: np.ndarray) -> np.ndarray:
    """SVG user units (px, y down) -> design frame (mm, y up)."""
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2) / _svg_px_per_mm()
    pts[:, 1] *= -1.0
    return pts


def _svg_shape_paths(
    svg_path: Any, kind: PathKind, name: str, tolerance_mm: float, scale: float = 1.0
) -> list[DesignPath]:
    import svgelements as se

    out: list[DesignPath] = []
    pts: list[np.ndarray] = []
    flags: list[bool] = []  # per point after the first: is the segment ending there a curve
    arcs: list[DesignArc] = []
    closed = False

    def xy(points_px: Any) -> np.ndarray:
        return _svg_xy(points_px) * scale

    def flush() -> None:
        nonlocal pts, arcs, closed, flags
        if pts:
            joined, curve = _dedupe_flagged(np.vstack(pts), np.array(flags, dtype=bool))
            if closed and len(joined) > 1 and np.hypot(*(joined[0] - joined[-1])) < 1e-9:
                joined, curve = joined[:-1], curve[:-1]
            if len(joined) >= 2:
                out.append(DesignPath(joined, closed, kind, name, tuple(arcs), tuple(curve)))
        pts, arcs, closed, flags = [], [], False, []

    for seg in svg_path:
        if isinstance(seg, se.Move):
            flush()
            pts = [xy([seg.end.x, seg.end.y])]
            continue
        if isinstance(seg, se.Close):
            if seg.start is not None and seg.end is not None:
                pts.append(xy([seg.end.x, seg.end.y]))
                flags.append(False)
            closed = True
            continue
        if isinstance(seg, se.Line):
            pts.append(xy([seg.end.x, seg.end.y]))
            flags.append(False)
            continue
        curve = _flatten(lambda t, s=seg: xy(s.npoint(t)), tolerance_mm)
        pts.append(curve[1:])
        flags.extend([True] * (len(curve) - 1))
        if isinstance(seg, se.Arc) and math.isclose(float(seg.rx), float(seg.ry), rel_tol=1e-9):
            centre = xy([seg.center.x, seg.center.y])[0]
            start = curve[0] - centre
            arcs.append(
                DesignArc(
                    (float(centre[0]), float(centre[1])),
                    float(seg.rx) / _svg_px_per_mm() * scale,
                    float(np.degrees(np.arctan2(start[1], start[0]))),
                    -float(np.degrees(seg.sweep)),
                )
            )
    flush()
    if kind == "circle" and len(out) == 1 and out[0].arcs:
        a0 = out[0].arcs[0]
        sweep = math.copysign(360.0, sum(a.sweep_deg for a in out[0].arcs))
        out[0] = DesignPath(
            out[0].points_mm,
            True,
            "circle",
            name,
            (DesignArc(a0.centre_mm, a0.radius_mm, a0.start_deg, sweep),),
            out[0].curve,
        )
    return out


def _dedupe_flagged(points: np.ndarray, flags: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Drop repeated points and the flags of the zero-length segments ending at them."""
    if len(points) < 2:
        return points, flags[:0]
    keep = np.concatenate(([True], np.hypot(*np.diff(points, axis=0).T) > 1e-9))
    return points[keep], flags[keep[1:]]


def _dedupe(points: np.ndarray, eps: float = 1e-9) -> np.ndarray:
    if len(points) < 2:
        return points
    keep = np.concatenate(([True], np.hypot(*np.diff(points, axis=0).T) > eps))
    return points[keep]


_DXF_UNIT_NAME = {1: "in", 2: "ft", 4: "mm", 5: "cm", 6: "m", 8: "microinch", 9: "mil",
                  10: "yd", 13: "um", 14: "dm"}  # fmt: skip
_DXF_SUPPORTED = {"LINE", "LWPOLYLINE", "POLYLINE", "ARC", "CIRCLE", "ELLIPSE", "SPLINE"}
_DXF_KIND: dict[str, PathKind] = {
    "LINE": "line",
    "LWPOLYLINE": "polyline",
    "POLYLINE": "polyline",
    "ARC": "arc",
    "CIRCLE": "circle",
    "ELLIPSE": "ellipse",
    "SPLINE": "spline",
}


def read_dxf(
    path: str | os.PathLike[str],
    *,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    ignore_unknown: bool = False,
    units: str | None = None,
) -> Design:
    """Read the model space of a DXF drawing with ezdxf (scaled to mm by ``$INSUNITS``).

    A drawing without units (``$INSUNITS`` 0) is refused unless ``units`` says
    what they are (``"mm"``, ``"in"``, ...).
    """
    import ezdxf

    path = Path(path)
    try:
        doc = ezdxf.readfile(str(path))
    except (
        OSError,
        ezdxf.DXFError,
        ValueError,
        StopIteration,
        EOFError,
        KeyError,
        IndexError,
    ) as exc:
        # a truncated file makes ezdxf's reader run out of tags (StopIteration)
        raise InputError(path, f"unreadable DXF: {exc or type(exc).__name__}") from None
    code = int(doc.header.get("$INSUNITS", 0) or 0)
    if code not in _DXF_UNIT_MM:
        raise InputError(path, f"unsupported DXF drawing units ($INSUNITS = {code})")
    scale = _DXF_UNIT_MM[code]
    unit_text = f"{_DXF_UNIT_NAME.get(code, 'units')} ($INSUNITS {code})"
    if code == 0:
        if units is None:
            raise InputError(
                path,
                "no drawing units ($INSUNITS 0, unitless): set the drawing's units in the CAD "
                "program, or pass --units mm (or in, cm)",
            )
        scale, unit_text = UNIT_MM[units], f"{units} (given by --units; $INSUNITS 0)"
    paths: list[DesignPath] = []
    for entity in doc.modelspace():
        kind_name = entity.dxftype()
        name = f"DXF {kind_name} #{entity.dxf.handle}"
        if kind_name not in _DXF_SUPPORTED:
            if ignore_unknown:
                continue
            raise InputError(
                path, f"unsupported DXF entity {name}; use lines, polylines, arcs and circles"
            )
        kind = _DXF_KIND[kind_name]
        if kind_name == "ELLIPSE" and math.isclose(entity.dxf.ratio, 1.0, rel_tol=1e-9):
            kind = "circle" if _ellipse_full(entity) else "arc"
        try:
            pts, arcs, closed, flags = _dxf_geometry(entity, tolerance_mm / scale)
        except (TypeError, ValueError, ZeroDivisionError) as exc:
            raise InputError(path, f"cannot read DXF entity {name}: {exc}") from None
        pts, flags = _dedupe_flagged(pts * scale, np.asarray(flags, dtype=bool))
        arcs = tuple(_scaled_arc(a, scale) for a in arcs)
        if closed and len(pts) > 1 and np.hypot(*(pts[0] - pts[-1])) < 1e-9:
            pts, flags = pts[:-1], flags[:-1]
        if len(pts) < 2:
            continue
        paths.append(DesignPath(pts, closed, kind, name, arcs, tuple(flags)))
    if not paths:
        raise InputError(path, "no drawable geometry in the DXF model space")
    return Design(str(path), tuple(paths), unit_text)


def _ellipse_full(entity: Any) -> bool:
    span = (entity.dxf.end_param - entity.dxf.start_param) % (2 * math.pi)
    return math.isclose(span, 0.0, abs_tol=1e-9) or math.isclose(span, 2 * math.pi, abs_tol=1e-9)


def _scaled_arc(arc: DesignArc, scale: float) -> DesignArc:
    c = arc.centre_mm
    return DesignArc(
        (c[0] * scale, c[1] * scale), arc.radius_mm * scale, arc.start_deg, arc.sweep_deg
    )


def _dxf_geometry(
    entity: Any, tolerance: float
) -> tuple[np.ndarray, tuple[DesignArc, ...], bool, list[bool]]:
    """Exact points (drawing units), circular arcs, closed flag and curve flags of an entity.

    Arcs and bulges are sampled on the true circle (ezdxf's path conversion
    would approximate them by Bézier curves); ellipses and splines are
    evaluated with ezdxf's construction tools.
    """
    kind = entity.dxftype()
    if kind == "LINE":
        s, e = entity.dxf.start, entity.dxf.end
        return np.array([[s.x, s.y], [e.x, e.y]], dtype=np.float64), (), False, [False]
    if kind in ("ARC", "CIRCLE"):
        (arc,) = _dxf_arcs(entity, 1.0) or (None,)
        if arc is None:
            raise ValueError("arc not in the xy plane")
        pts = arc.points_mm(tolerance_mm=tolerance)
        return pts, (arc,), kind == "CIRCLE", [True] * (len(pts) - 1)
    if kind == "LWPOLYLINE":
        xyb = np.array([(x, y, b) for x, y, b in entity.get_points("xyb")], dtype=np.float64)
        mirror = float(entity.dxf.extrusion.z) < 0
        return _bulge_polyline(xyb, bool(entity.closed), mirror, tolerance)
    if kind == "POLYLINE":
        if entity.is_3d_polyline or entity.is_poly_face_mesh or entity.is_polygon_mesh:
            raise ValueError("only 2D polylines are supported")
        xyb = np.array(
            [(v.dxf.location.x, v.dxf.location.y, v.dxf.bulge) for v in entity.vertices],
            dtype=np.float64,
        )
        mirror = float(entity.dxf.extrusion.z) < 0
        return _bulge_polyline(xyb, bool(entity.is_closed), mirror, tolerance)
    if kind == "ELLIPSE":
        ellipse = entity.construction_tool()
        start, span = ellipse.start_param, ellipse.param_span

        def on_ellipse(t: np.ndarray) -> np.ndarray:
            return np.array([(v.x, v.y) for v in ellipse.vertices(start + span * t)])

        full = _ellipse_full(entity)
        pts = _flatten(on_ellipse, tolerance, min_chords=8)
        return pts, (), full, [True] * (len(pts) - 1)
    if kind == "SPLINE":
        spline = entity.construction_tool()

        def on_spline(t: np.ndarray) -> np.ndarray:
            return np.array([(v.x, v.y) for v in spline.points(t * spline.max_t)])

        pts = _flatten(on_spline, tolerance, min_chords=8)
        return pts, (), bool(entity.closed), [True] * (len(pts) - 1)
    raise ValueError(f"unsupported entity {kind}")


def _bulge_polyline(
    xyb: np.ndarray, closed: bool, mirror: bool, tolerance: float
) -> tuple[np.ndarray, tuple[DesignArc, ...], bool, list[bool]]:
    """Vertices with DXF bulges (tan of a quarter of each arc's included angle) -> points, arcs."""
    if mirror:  # OCS with extrusion -z: x mirrored, arcs turn the other way
        xyb = xyb * np.array([-1.0, 1.0, -1.0])
    n = len(xyb)
    pts: list[np.ndarray] = [xyb[:1, :2]]
    arcs: list[DesignArc] = []
    flags: list[bool] = []
    last = n if closed else n - 1
    for i in range(last):
        p0, p1, bulge = xyb[i, :2], xyb[(i + 1) % n, :2], xyb[i, 2]
        chord = float(np.hypot(*(p1 - p0)))
        if abs(bulge) < 1e-12 or chord == 0.0:
            pts.append(p1[None])
            flags.append(False)
            continue
        theta = 4.0 * math.atan(bulge)  # signed included angle, CCW positive
        d = (p1 - p0) / chord
        left = np.array([-d[1], d[0]])
        centre = 0.5 * (p0 + p1) + left * (0.5 * chord / math.tan(0.5 * theta))
        radius = 0.5 * chord / abs(math.sin(0.5 * theta))
        start = math.degrees(math.atan2(p0[1] - centre[1], p0[0] - centre[0]))
        arc = DesignArc((float(centre[0]), float(centre[1])), radius, start, math.degrees(theta))
        arcs.append(arc)
        pts.append(arc.points_mm(tolerance_mm=tolerance)[1:])
        flags.extend([True] * len(pts[-1]))
    return np.vstack(pts), tuple(arcs), closed, flags


def _dxf_arcs(entity: Any, scale: float) -> tuple[DesignArc, ...]:
    """Circular arcs of an ARC/CIRCLE entity in the world frame (extrusion +z or -z)."""
    kind = entity.dxftype()
    if kind not in ("ARC", "CIRCLE"):
        return ()
    ez = float(entity.dxf.extrusion.z) if entity.dxf.hasattr("extrusion") else 1.0
    if abs(abs(ez) - 1.0) > 1e-9:
        return ()  # not in the xy plane; the flattened points still describe it
    c = entity.dxf.center
    centre = (float(c.x) * scale, float(c.y) * scale)
    r = float(entity.dxf.radius) * scale
    if kind == "CIRCLE":
        start, sweep = 0.0, 360.0
    else:
        start = float(entity.dxf.start_angle)
        sweep = (float(entity.dxf.end_angle) - start) % 360.0 or 360.0
    if ez < 0:  # OCS mirrored in x: angles run clockwise in the world frame
        centre = (-centre[0], centre[1])
        start, sweep = 180.0 - start, -sweep
    return (DesignArc(centre, r, float(wrap_deg(start)), sweep),)
