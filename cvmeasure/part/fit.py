"""Circle and polyline fits of a wire centreline, and the arc quantities they give.

Our default method (issue 5): a robust *geometric* circle fit of the sub-pixel
centreline (Taubin's algebraic fit as the start, then orthogonal distances
with a soft-L1 loss), and, when the part was bent in ``N`` chords, a
polyline fit with ``N`` straight segments whose vertices give the per-segment
bend angles directly.

Frame: any right-handed planar frame in mm (the part module uses the board
plane as seen by the camera, y up, so counter-clockwise as seen in the photo is
positive). Signed angles are wrapped to (-180, 180].

References
----------
G. Taubin, "Estimation of planar curves, surfaces and nonplanar space curves
defined by implicit equations", IEEE TPAMI 13(11) (1991) 1115-1138,
doi:10.1109/34.103273.
N. Chernov, *Circular and Linear Regression: Fitting Circles and Lines by Least
Squares*, CRC Press (2010), doi:10.1201/EBK1439835906.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.design import divide_into_chords
from cvmeasure.geometry import CircleFit, arclength_mm, fit_circle_robust, wrap_deg
from cvmeasure.part.chord_period import (
    MAX_MISFIT,
    MIN_DIVISIONS,
    PeriodicChords,
    centreline_noise_mm,
    periodic_chords,
)
from cvmeasure.part.compare import point_to_polyline
from cvmeasure.part.peaks import find_peaks

__all__ = [
    "chord_coverage",
    "ChordCount",
    "count_chords",
    "PolylineFit",
    "ArcGeometry",
    "fit_polyline",
    "arc_geometry",
    "arc_sweep_rad",
    "arc_angle_from_chord_deg",
    "sagitta_radius_mm",
    "fit_line",
]


@dataclass(frozen=True)
class ArcGeometry:
    """The seed paper's arc quantities (its Fig. 7) of one circular arc.

    Attributes
    ----------
    radius_mm : r.
    chord_width_mm : d, the straight distance between the arc's end points.
    height_mm : h, the sagitta (chord to arc top); exceeds r for arcs over 180 deg.
    arc_angle_deg : theta_arc, the angle the arc subtends at its centre (0, 360).
    """

    radius_mm: float
    chord_width_mm: float
    height_mm: float
    arc_angle_deg: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "radius_mm": self.radius_mm,
            "chord_width_mm": self.chord_width_mm,
            "height_mm": self.height_mm,
            "arc_angle_deg": self.arc_angle_deg,
        }


def sagitta_radius_mm(chord_width_mm: float, height_mm: float) -> float:
    """Radius from chord width d and height h: r = d^2 / 8h + h / 2 (seed Eq. 1)."""
    if height_mm <= 0:
        raise ValueError(f"height_mm must be positive, got {height_mm}")
    return chord_width_mm**2 / (8.0 * height_mm) + height_mm / 2.0


def arc_angle_from_chord_deg(chord_width_mm: float, height_mm: float) -> float:
    """Arc angle from chord width d and height h, valid on (0, 360): 4 atan(2h / d).

    The seed's ``2 asin(d / 2r)`` (its Eq. 2) is the same below 180 degrees
    but folds longer arcs back below 180.
    """
    return float(np.degrees(4.0 * math.atan2(2.0 * height_mm, chord_width_mm)))


def _check_points(points: np.ndarray, minimum: int) -> np.ndarray:
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {pts.shape}")
    if len(pts) < minimum:
        raise ValueError(f"need at least {minimum} points, got {len(pts)}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points must be finite")
    return pts


def arc_sweep_rad(centre: Any, ordered_points: np.ndarray) -> float:
    """The total unwrapped angle (rad, >= 0) ordered points (N, 2) sweep about ``centre``,
    first to last (any length unit)."""
    c = np.asarray(centre, dtype=np.float64)
    ang = np.unwrap(np.arctan2(ordered_points[:, 1] - c[1], ordered_points[:, 0] - c[0]))
    return abs(float(ang[-1] - ang[0]))


def arc_geometry(circle: CircleFit, ordered_points_mm: np.ndarray) -> ArcGeometry:
    """Arc quantities of ordered points (N, 2) lying along ``circle``.

    The arc runs from the first to the last point; its angle is the total
    unwrapped angle the points sweep around the centre (so arcs past 180
    degrees are measured as such).
    """
    pts = _check_points(ordered_points_mm, 2)
    sweep = arc_sweep_rad(circle.centre, pts)
    r = circle.radius
    return ArcGeometry(
        radius_mm=r,
        chord_width_mm=2.0 * r * math.sin(min(sweep, 2 * math.pi) / 2.0),
        height_mm=r * (1.0 - math.cos(sweep / 2.0)),
        arc_angle_deg=math.degrees(sweep),
    )


@dataclass(frozen=True)
class PolylineFit:
    """A polyline of straight segments fitted to a centreline.

    Attributes
    ----------
    vertices_mm : ndarray (N+1, 2), the chord end points (the bend vertices
        between them, the wire's ends at both extremes), mm.
    bend_deg : ndarray (N-1,), signed bend at each interior vertex, from the
        fitted segment directions; counter-clockwise positive.
    segment_length_mm : ndarray (N,), vertex-to-vertex lengths, mm.
    rms_residual_mm : RMS distance of the inlier points to their segment, mm.
    bend_sigma_deg : ndarray (N-1,), one standard uncertainty of each bend from
        the scatter of the centreline about its two lines, counting the scatter's
        correlation along each line (:func:`_correlation_factor`; sampling only: not
        calibration, not a bias common to a whole chord).
    direction_deg : ndarray (N,), each chord's fitted direction (atan2 of its unit
        vector, board frame), degrees; ``direction_sigma_deg`` its standard uncertainty
        from the same scatter (the two of a vertex are independent: their fits share no
        point), so ``bend_sigma_deg`` is the pairs' quadrature sum.
    across_gap : ndarray (N,) bool, the chords without centres of their own, placed on the
        line across the centreline's gap (their directions, and the bends at their vertices,
        not measured; None: every chord has its own).
    """

    vertices_mm: np.ndarray
    bend_deg: np.ndarray
    segment_length_mm: np.ndarray
    rms_residual_mm: float
    bend_sigma_deg: np.ndarray | None = None
    direction_deg: np.ndarray | None = None
    direction_sigma_deg: np.ndarray | None = None
    across_gap: np.ndarray | None = None

    @property
    def divisions(self) -> int:
        return len(self.vertices_mm) - 1

    def to_dict(self) -> dict[str, Any]:
        return {
            "vertices_mm": self.vertices_mm.tolist(),
            "bend_deg": self.bend_deg.tolist(),
            "segment_length_mm": self.segment_length_mm.tolist(),
            "rms_residual_mm": self.rms_residual_mm,
            "bend_sigma_deg": None if self.bend_sigma_deg is None else self.bend_sigma_deg.tolist(),
        }


def fit_line(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robust total-least-squares line: (point on it, unit direction, inlier mask).

    Two trimming passes drop points farther than 3 robust sigmas (1.4826 MAD)
    from the line, so a stray centre (a shadow or a crossing) cannot tilt it.
    """
    keep = np.ones(len(points), dtype=bool)
    mean, direction = points.mean(axis=0), np.array([1.0, 0.0])
    for _ in range(3):
        mean = points[keep].mean(axis=0)
        _, _, vt = np.linalg.svd(points[keep] - mean, full_matrices=False)
        direction = vt[0]
        off = (points - mean) @ np.array([-direction[1], direction[0]])
        sigma = 1.4826 * float(np.median(np.abs(off[keep])))
        new = np.abs(off) <= max(3.0 * sigma, 1e-12)
        if new.sum() < 2 or np.array_equal(new, keep):
            break
        keep = new
    return mean, direction, keep


#: Longest lag (share of a chord's points) over which the residuals' correlation is summed.
MAX_LAG_SHARE = 0.25


def _correlation_factor(residuals: np.ndarray) -> float:
    """How much a line's direction variance grows because its residuals are correlated.

    The TLS direction variance ``sigma^2 / sum (t - mean t)^2`` counts every centre as an
    independent sample; neighbouring centres are not (the blur, the profiles' sampling and
    a shading bump span several of them). The factor ``1 + 2 sum_k rho_k`` (the residuals'
    autocorrelation at lags ``k``, ordered along the chord, summed up to its first
    non-positive value and at most ``MAX_LAG_SHARE`` of the points) is the number of
    centres per independent one; at least 1.
    """
    r = np.asarray(residuals, dtype=float)
    r = r - r.mean()
    power = float(r @ r)
    if len(r) < 8 or power <= 0.0:
        return 1.0
    total = 1.0
    for lag in range(1, max(2, int(MAX_LAG_SHARE * len(r)))):
        rho = float(r[:-lag] @ r[lag:]) / power
        if rho <= 0.0:
            break
        total += 2.0 * rho
    return max(1.0, total)


def _intersect(p1: np.ndarray, d1: np.ndarray, p2: np.ndarray, d2: np.ndarray) -> np.ndarray:
    cross = d1[0] * d2[1] - d1[1] * d2[0]
    if abs(cross) < 1e-12:
        return 0.5 * (p1 + p2)
    t = ((p2[0] - p1[0]) * d2[1] - (p2[1] - p1[1]) * d2[0]) / cross
    return p1 + t * d1


def _start_vertices(
    pts: np.ndarray, s: np.ndarray, divisions: int, fractions: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`fit_polyline`'s starting vertices and, with ``fractions``, each split's window.

    ``s``: the arc length (mm) at each point. Without ``fractions``: equal chords and no
    window (the caller keeps each split within a quarter of the mean chord).
    """
    if fractions is None:
        return divide_into_chords(pts, divisions), None
    f = np.asarray(fractions, dtype=np.float64).ravel()
    if f.size != divisions + 1:
        raise ValueError(f"{f.size} vertex fractions for {divisions} chords")
    at = f * s[-1]
    verts = np.column_stack((np.interp(at, s, pts[:, 0]), np.interp(at, s, pts[:, 1])))
    chord = np.diff(at)
    return verts, 0.25 * np.minimum(np.r_[chord[:1], chord], np.r_[chord, chord[-1:]])


def fit_polyline(
    ordered_points_mm: np.ndarray,
    divisions: int,
    *,
    corner_margin: float = 0.12,
    iterations: int = 3,
    fractions: np.ndarray | None = None,
) -> PolylineFit:
    """Fit ``divisions`` straight segments to an ordered centreline.

    Each segment is a robust total-least-squares line through the points between two
    vertices, leaving out a ``corner_margin`` fraction of the segment length at
    both ends (where the wire is rounded around the bending pin); a segment in a gap of
    the centreline is the line through the points at the gap's ends. Inner vertices
    are the intersections of neighbouring lines; the end vertices are the first
    and last points projected onto the end lines. The split points start at an
    equal-chord division of the centreline and follow the vertices for a few
    ``iterations`` (at most a quarter chord away from the start).

    Parameters
    ----------
    ordered_points_mm : ndarray (M, 2), ordered from one wire end to the other.
    divisions : number of straight chords N >= 1.
    fractions : ndarray (N+1,), optional
        Where the vertices of the polygon bent lie, as shares of its length (0 .. 1, in
        this centreline's order; :mod:`cvmeasure.wireplan`). The split points then start
        there and each stays within a quarter of its shorter neighbouring chord (a part
        of unequal chords); default: equal chords.
    """
    pts = _check_points(ordered_points_mm, 2 * divisions + 2)
    if divisions < 1:
        raise ValueError(f"divisions must be >= 1, got {divisions}")
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    verts, window = _start_vertices(pts, s, divisions, fractions)
    lines: list[tuple[np.ndarray, np.ndarray]] = []
    gap_ends: dict[int, np.ndarray] = {}
    rms = float("nan")
    vs0: np.ndarray | None = None
    for _ in range(max(1, iterations)):
        # arc-length positions of the vertices: nearest centreline point, kept
        # within a quarter chord of the equal-chord start (no run-away splits)
        vs = np.array([s[int(np.argmin(np.hypot(*(pts - v).T)))] for v in verts])
        vs[0], vs[-1] = 0.0, s[-1]
        if vs0 is None:
            vs0 = vs.copy()
        quarter = 0.25 * s[-1] / divisions if window is None else window
        vs = np.maximum.accumulate(np.clip(vs, vs0 - quarter, vs0 + quarter))
        lines = []
        dir_var: list[float] = []
        sq, count = 0.0, 0
        for i in range(divisions):
            a, b = vs[i], vs[i + 1]
            margin = corner_margin * (b - a)
            lo = a + (margin if i > 0 else 0.0)
            hi = b - (margin if i < divisions - 1 else 0.0)
            sel = (s >= lo) & (s <= hi)
            if sel.sum() < 2:
                sel = (s >= a) & (s <= b)
            if sel.sum() < 2 and i not in gap_ends:
                # a chord in a gap of the centreline: its line through the centres at the
                # gap's ends, in the corners (its direction not measured: ``across_gap``),
                # as first placed (moved vertices would give it a neighbour's centres)
                gap_ends[i] = np.r_[np.nonzero(s < a)[0][-1:], np.nonzero(s > b)[0][:1]]
            if i in gap_ends:
                sel = np.zeros(len(s), dtype=bool)
                sel[gap_ends[i]] = True
            if sel.sum() < 2:
                raise ValueError("too few centreline points for the number of divisions")
            p0, d, inl = fit_line(pts[sel])
            # orient along the traversal
            if np.dot(pts[sel][-1] - pts[sel][0], d) < 0:
                d = -d
            lines.append((p0, d))
            off = (pts[sel][inl] - p0) @ np.array([-d[1], d[0]])
            sq += float(off @ off)
            count += int(inl.sum())
            # direction variance of a TLS line: sigma^2 / sum (t - mean t)^2
            along = (pts[sel][inl] - p0) @ d
            spread = float(np.sum((along - along.mean()) ** 2))
            dof = max(int(inl.sum()) - 2, 1)
            white = float(off @ off) / dof / spread if spread > 0 else math.inf
            dir_var.append(white * _correlation_factor(off))
        rms = math.sqrt(sq / max(count, 1))
        new = [lines[0][0] + np.dot(pts[0] - lines[0][0], lines[0][1]) * lines[0][1]]
        for i in range(divisions - 1):
            new.append(_intersect(*lines[i], *lines[i + 1]))
        pl, dl = lines[-1]
        new.append(pl + np.dot(pts[-1] - pl, dl) * dl)
        verts = np.array(new)
    dirs = np.array([d for _, d in lines])
    cross = dirs[:-1, 0] * dirs[1:, 1] - dirs[:-1, 1] * dirs[1:, 0]
    dot = np.sum(dirs[:-1] * dirs[1:], axis=1)
    bends = np.asarray(wrap_deg(np.degrees(np.arctan2(cross, dot))), dtype=np.float64).reshape(-1)
    var = np.asarray(dir_var)
    return PolylineFit(
        vertices_mm=verts,
        bend_deg=bends,
        segment_length_mm=np.hypot(*np.diff(verts, axis=0).T),
        rms_residual_mm=rms,
        bend_sigma_deg=np.degrees(np.sqrt(var[:-1] + var[1:])),
        direction_deg=np.degrees(np.arctan2(dirs[:, 1], dirs[:, 0])),
        direction_sigma_deg=np.degrees(np.sqrt(var)),
        across_gap=np.isin(np.arange(divisions), list(gap_ends)) if gap_ends else None,
    )


def chord_coverage(
    ordered_points_mm: np.ndarray,
    vertices_mm: np.ndarray,
    *,
    corner_margin: float = 0.12,
    max_step_mm: float = 1.0,
) -> np.ndarray:
    """The share of each chord's fitted stretch that has centreline points along it.

    The stretch is the chord between its vertices less ``corner_margin`` of its length at
    each inner vertex (what :func:`fit_polyline` fits). Points are projected on the chord
    (those within a quarter chord of it); the covered length is the sum of the steps
    between consecutive projections no longer than ``max_step_mm``. A chord seen along
    little of it has a line from the few centres there, or from the centres bracketing
    the gap: its direction, and the bends at both its vertices, are not measured.

    Returns ndarray (N,), 0..1, one per chord.
    """
    pts = np.asarray(ordered_points_mm, dtype=np.float64)
    v = np.asarray(vertices_mm, dtype=np.float64)
    n = len(v) - 1
    out = np.zeros(n)
    for i in range(n):
        a, b = v[i], v[i + 1]
        length = float(np.hypot(*(b - a)))
        if length <= 0.0:
            continue
        d = (b - a) / length
        lo = corner_margin * length if i > 0 else 0.0
        hi = length - (corner_margin * length if i < n - 1 else 0.0)
        rel = pts - a
        t = rel @ d
        off = np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])
        t = np.sort(t[(t >= lo) & (t <= hi) & (off <= 0.25 * length)])
        steps = np.diff(t)
        out[i] = float(steps[steps <= max_step_mm].sum()) / max(hi - lo, 1e-12)
    return out


@dataclass(frozen=True)
class ChordCount:
    """How many straight chords a centreline shows (vertices found from the photo).

    Attributes
    ----------
    divisions : the number of chords N, or None when the wire shows no clear
        vertices (a smooth curve, or a straight wire: N = 1 is reported as None).
    vertex_arclength_mm : arc-length positions of the inner vertices found (mm from
        the first end).
    turn_deg : the direction change at each of them, over ``window_mm`` (deg).
    polyline_rms_mm, circle_rms_mm : RMS residual of the N-chord polyline fit and of a
        circle fit to the same centreline (mm): the chords must fit far better.
    reason : why this count, in words.
    periodic : the equal-chord test of an arc (:mod:`cvmeasure.part.chord_period`: its
        count, significance and the centreline noise), None when the wire is no arc.
    """

    divisions: int | None
    vertex_arclength_mm: tuple[float, ...]
    turn_deg: tuple[float, ...]
    polyline_rms_mm: float | None
    circle_rms_mm: float
    reason: str
    periodic: PeriodicChords | None = None

    def to_dict(self) -> dict[str, Any]:
        p = self.periodic
        return {
            "divisions": self.divisions,
            "vertex_arclength_mm": [round(v, 3) for v in self.vertex_arclength_mm],
            "turn_deg": [round(v, 3) for v in self.turn_deg],
            "polyline_rms_mm": self.polyline_rms_mm,
            "circle_rms_mm": self.circle_rms_mm,
            "reason": self.reason,
            "noise_mm": None if p is None else round(p.noise_mm, 4),
            # the bend per chord from the vertices' spacing (ends left out), with its sigma
            "chord_angle_deg": None if p is None or p.divisions is None else p.chord_angle_deg,
            "chord_angle_sigma_deg": (
                None if p is None or p.divisions is None else p.chord_angle_sigma_deg
            ),
        }


def count_chords(
    ordered_points_mm: np.ndarray,
    *,
    step_mm: float = 0.25,
    window_mm: float = 3.0,
    min_turn_deg: float = 0.5,
    min_chord_mm: float = 6.0,
) -> ChordCount:
    """Find how many straight chords a wire was bent in, from its centreline.

    An arc is tested for equal chords as a whole (:func:`~cvmeasure.part.chord_period.
    periodic_chords`: the scallop its vertices leave, against the centreline's own noise,
    every count tried), which finds vertices far below the noise of one; a count is
    reported only when significant and clearly better than the others. Other shapes (an
    S-curve, a saddle, unequal chords: a scallop unlike equal chords') and counts below
    ``MIN_DIVISIONS`` are searched vertex by vertex (:func:`_vertex_search`); on an arc
    of equal chords whose count the test cannot establish, none is reported.
    """
    pts = _check_points(ordered_points_mm, 8)
    periodic = periodic_chords(pts, min_chord_mm=min_chord_mm)
    if periodic is not None and periodic.divisions is not None:
        circle_rms = float(fit_circle_robust(pts).rms_residual)
        try:
            poly = fit_polyline(pts, periodic.divisions)
        except ValueError:
            # the scallop's count, but a chord falls in a gap of the centreline: no line to
            # place there, so the count is not established on this centreline
            return ChordCount(
                None, (), (), None, circle_rms,
                f"the centreline's scallop shows {periodic.divisions} equal chords, but one "
                "of them falls in a gap of the centreline (no points to place it on)",
                periodic,
            )  # fmt: skip
        s = arclength_mm(pts)
        positions = tuple(
            float(s[int(np.argmin(np.hypot(*(pts - v).T)))]) for v in poly.vertices_mm[1:-1]
        )
        turns = tuple(float(b) for b in poly.bend_deg)
        return ChordCount(
            periodic.divisions, positions, turns, poly.rms_residual_mm, circle_rms,
            periodic.reason, periodic,
        )  # fmt: skip
    found = _vertex_search(
        pts, step_mm=step_mm, window_mm=window_mm, min_turn_deg=min_turn_deg,
        min_chord_mm=min_chord_mm,
    )  # fmt: skip
    if periodic is None:
        return found
    if not periodic.applies or (found.divisions is not None and found.divisions < MIN_DIVISIONS):
        return dataclasses.replace(found, periodic=periodic)  # no arc of equal chords
    # an arc of equal chords whose count is not significant (or is ambiguous): vertices
    # found one by one there would stand on less evidence still
    return dataclasses.replace(found, divisions=None, reason=periodic.reason, periodic=periodic)


def _vertex_search(
    pts: np.ndarray,
    *,
    step_mm: float,
    window_mm: float,
    min_turn_deg: float,
    min_chord_mm: float,
) -> ChordCount:
    """Find the vertices of a wire bent in straight chords from its centreline, one by one.

    The direction of the centreline (resampled every ``step_mm``) is compared
    across a ``window_mm`` window: on a straight chord it does not change, at a
    vertex it turns by the bend. Peaks of that turn at least ``min_turn_deg``
    above the wire's own noise and ``min_chord_mm`` apart are vertices. The count
    is kept only when the N-chord polyline fits the centreline far better than a
    circle does (a smooth arc turns evenly and has no peaks) and the centreline's robust
    scatter about it is within ``MAX_MISFIT`` times its noise below a chord
    (:func:`~cvmeasure.part.chord_period.centreline_noise_mm`: a centreline stepping or
    drifting off the axis bends where the wire does not).
    """
    seg = np.hypot(*np.diff(pts, axis=0).T)
    s = np.concatenate(([0.0], np.cumsum(seg)))
    circle_rms = float(fit_circle_robust(pts).rms_residual)
    grid = np.arange(0.0, s[-1], step_mm)
    half = max(1, round(window_mm / step_mm / 2))
    k = max(1, round(1.0 / step_mm))  # direction from points 2 mm apart, smoothed over 1 mm
    if len(grid) < 2 * half + 2 * k + 8:
        return ChordCount(
            None, (), (), None, circle_rms, "the wire is too short to look for vertices"
        )
    xy = np.column_stack((np.interp(grid, s, pts[:, 0]), np.interp(grid, s, pts[:, 1])))
    box = np.ones(k) / k
    xy = np.column_stack(
        (np.convolve(xy[:, 0], box, mode="valid"), np.convolve(xy[:, 1], box, mode="valid"))
    )
    d = xy[2 * k :] - xy[: -2 * k]
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    turn = np.degrees(heading[2 * half :] - heading[: -2 * half])  # turn across the window
    baseline = float(np.median(turn))
    dev = np.abs(turn - baseline)
    # the wire's own noise from the quietest windows (straight chords or a smooth arc;
    # short chords leave few): |N(0, sigma)| has its 10th percentile at 0.126 sigma. Then
    # once more from the windows away from the peaks found
    distance = max(1, round(min_chord_mm / step_mm))
    sigma = float(np.percentile(dev, 10)) / 0.126 + 1e-9
    peaks = find_peaks(dev, height=max(min_turn_deg, 5.0 * sigma), distance=distance)
    quiet = np.ones(len(dev), dtype=bool)
    for p in peaks:
        quiet[max(0, p - 2 * half - k) : p + 2 * half + k + 1] = False
    if quiet.sum() >= 20:
        sigma = 1.4826 * float(np.median(dev[quiet])) / 0.6745 + 1e-9
    height = max(min_turn_deg, 5.0 * sigma)
    peaks = find_peaks(dev, height=height, distance=distance)
    fits: dict[int, PolylineFit] = {}
    if len(peaks) == 0:
        # chords so short that no window is quiet hide their peaks: try every count
        for n in range(2, int(min(60, s[-1] // min_chord_mm)) + 1):
            try:
                fits[n] = fit_polyline(pts, n)
            except ValueError:
                break
        best0 = min((f.rms_residual_mm for f in fits.values()), default=math.inf)
        if not best0 <= 0.2 * circle_rms:
            why = "no vertices: the wire turns evenly (a smooth curve) or not at all"
            return ChordCount(None, (), (), None, circle_rms, why)
    else:
        # weak peaks may be noise, and the weakest bends may hide in it: the count whose
        # chords fit best wins (the fewest chords within 1.5x of the best fit)
        weak = int(np.sum(dev[peaks] < 3.0 * height))
        for n in range(len(peaks) + 1 - min(weak, 3), len(peaks) + 4):
            if n < 2:
                continue
            try:
                fits[n] = fit_polyline(pts, n)
            except ValueError:
                continue
    if not fits:
        return ChordCount(None, (), (), None, circle_rms, "no chord fit")
    best_rms = min(f.rms_residual_mm for f in fits.values())
    divisions = min(n for n, f in fits.items() if f.rms_residual_mm <= 1.5 * best_rms)
    poly = fits[divisions]
    inner = poly.vertices_mm[1:-1]
    positions = tuple(float(s[int(np.argmin(np.hypot(*(pts - v).T)))]) for v in inner)
    turns = tuple(float(b) for b in poly.bend_deg)
    if not poly.rms_residual_mm <= 0.5 * circle_rms:
        why = (
            f"{divisions - 1} direction changes found, but {divisions} chords fit no better than "
            f"a circle (RMS {poly.rms_residual_mm:.4f} vs {circle_rms:.4f} mm)"
        )
        return ChordCount(None, positions, turns, poly.rms_residual_mm, circle_rms, why)
    # chords the wire was bent in describe its centreline to within the centreline's own
    # noise below a chord (as the equal-chord test asks of its model), rounded vertices
    # aside: the robust scatter about the chords, which a vertex's rounding (a few centres
    # either side) does not move. Chords that leave several times the noise along most of
    # the wire stand on something else, steps and drifts in the centreline (its centre
    # pulled off the axis by a shadow, then back), and their count is not the wire's
    noise_mm = centreline_noise_mm(pts)
    # robust scatter (1.4826 median distance) about the chords
    scatter_mm = 1.4826 * float(np.median(np.abs(point_to_polyline(pts, poly.vertices_mm)[1])))
    if math.isfinite(noise_mm) and not scatter_mm <= MAX_MISFIT * noise_mm:
        why = (
            f"{divisions - 1} direction changes found, but the centreline scatters by "
            f"{scatter_mm:.4f} mm about {divisions} chords, {scatter_mm / noise_mm:.1f} times "
            f"its noise below a chord ({noise_mm:.4f} mm): it has structure the chords do not "
            "describe (steps, a centre pulled off the wire's axis)"
        )
        return ChordCount(None, positions, turns, poly.rms_residual_mm, circle_rms, why)
    why = (
        f"{divisions - 1} vertices (bends of {min(np.abs(turns)):.2f}-{max(np.abs(turns)):.2f} deg); "
        f"{divisions} chords fit with RMS {poly.rms_residual_mm:.4f} mm vs {circle_rms:.4f} mm "
        "for a circle"
    )
    return ChordCount(divisions, positions, turns, poly.rms_residual_mm, circle_rms, why)
