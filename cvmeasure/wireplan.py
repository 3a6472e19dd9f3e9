"""The polygon the bender is asked to make: one design reader and one set of rules.

``cvmeasure gcode``, ``part --design``, ``correct`` and ``track`` all read a design
through :func:`load_plan` and compare a part with :attr:`WirePlan.vertices_mm`, the
polygon the machine was actually asked to bend:

* a drawn straight line keeps its corners (a zigzag of 40/42/40/42 mm chords is bent
  and measured as exactly that);
* a curve (arc, Bézier, spline, ellipse, bulge) is divided into equal chords, the most
  that are each at least ``min_segment_mm`` long (or ``divisions``), as the seed
  paper's Wireware did; each division is listed in :attr:`WirePlan.changes` with its
  largest deviation from the curve (mm);
* a job written by ``cvmeasure gcode`` carries its plan in its header
  (:func:`plan_from_job`), so a part is compared with the job it was bent from.

A design is never changed silently. These are refused (:class:`~cvmeasure.errors.InputError`,
exit 2) with the element and the number: a straight segment shorter than
``min_segment_mm``, a gap between elements wider than ``join_gap_mm``, a closed
shape, a wire touching itself (segments closer than ``clearance_mm``), a bend beyond
``max_bend_deg``, a drawing without physical units (:func:`cvmeasure.design.load_design`).
Explicit options change the design instead (``rechord``: runs of short segments are
divided into chords of at least ``min_segment_mm``; ``scale``; a wider ``join_gap_mm``);
the before/after bend table and the largest deviation (mm) are then printed by the CLI
and kept in the job's header.

Frames: the design frame (x right, y up, mm); turns counter-clockwise positive walking
from the first (fed-first) point; machine bends are minus the turns
(:func:`cvmeasure.gcode.bend_list`).

``scipy.spatial`` is imported only where two polylines' Hausdorff distance is taken
(half a second or more on import), not when this module is imported.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.design import (
    Design,
    DesignArc,
    DesignPath,
    bend_angles_deg,
    chord_lengths_mm,
    divide_into_chords,
    join_paths,
    load_design,
    polyline_length_mm,
)
from cvmeasure.errors import InputError
from cvmeasure.gcode import GcodeJob
from cvmeasure.gcode_line import comment_text

__all__ = [
    "DesignChange",
    "WirePlan",
    "plan_design",
    "load_plan",
    "plan_from_job",
    "polygon_from_chords",
    "plan_for_part",
    "bent_polygon",
    "job_strokes",
    "DEFAULT_JOIN_GAP_MM",
    "DEFAULT_CLEARANCE_MM",
    "MIN_SEGMENT_MM",
    "MAX_BEND_DEG",
    "MAX_WIRE_MM",
]

#: Shortest straight segment the DIWire can grip and bend (seed paper, Wireware), mm.
MIN_SEGMENT_MM = 12.0
#: Largest bend the rules allow (Berkeley DI-WIRE DFM rule, 1/8" wire), deg.
MAX_BEND_DEG = 135.0
#: Element ends closer than this are the same point (an export's rounding), mm.
DEFAULT_JOIN_GAP_MM = 0.01
#: Segments of the wire closer than this touch (self-contact), mm.
DEFAULT_CLEARANCE_MM = 1.0
#: A longer wire is a unit error, not a part (the feed of a desktop bender), mm.
MAX_WIRE_MM = 3000.0
#: Turns below this are straight (no bend), deg (as :mod:`cvmeasure.gcode`).
_STRAIGHT_DEG = 0.01
_PLAN_TAG = "; plan "


@dataclass(frozen=True)
class DesignChange:
    """One change between the drawn design and the polygon bent (mm, deg)."""

    element: str
    what: str
    detail: str
    deviation_mm: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "element": self.element,
            "what": self.what,
            "detail": self.detail,
            "deviation_mm": self.deviation_mm,
        }


@dataclass(frozen=True)
class WirePlan:
    """The polygon the machine is asked to bend, and how it came from the design.

    Attributes
    ----------
    source : the design file (or job) it came from.
    units : where the millimetres came from (:attr:`cvmeasure.design.Design.units`).
    vertices_mm : ndarray (N+1, 2), the polygon bent (design frame, mm), fed from vertex 0.
    changes : the curves divided and any change made on request (re-chord, scale, gap).
    before_mm : the design's corners before a requested change (None when there was none).
    from_job : read from a job's header rather than from the design.
    """

    source: str
    units: str
    vertices_mm: np.ndarray
    changes: tuple[DesignChange, ...] = ()
    before_mm: np.ndarray | None = None
    from_job: bool = False

    @property
    def divisions(self) -> int:
        return len(self.vertices_mm) - 1

    @property
    def chords_mm(self) -> np.ndarray:
        return chord_lengths_mm(self.vertices_mm)

    @property
    def turns_deg(self) -> np.ndarray:
        """Turn at every inner vertex (design frame, CCW positive), deg."""
        return bend_angles_deg(self.vertices_mm)

    @property
    def bends_deg(self) -> np.ndarray:
        """Machine-frame wanted bends, deg (minus the turns)."""
        return -self.turns_deg

    @property
    def max_deviation_mm(self) -> float:
        return max((c.deviation_mm for c in self.changes), default=0.0)

    @property
    def requested_change(self) -> bool:
        """Whether the design's own corners were changed on request (re-chord, scale, gap)."""
        return self.before_mm is not None

    def as_path(self) -> DesignPath:
        """The polygon as a design path (straight segments, fed from its first point)."""
        return DesignPath(self.vertices_mm, False, "polyline", os.path.basename(self.source))

    def table_lines(self) -> list[str]:
        """Changes, and the before/after table of feeds and bends when corners changed."""
        out = [f"design units: {self.units}"]
        for c in self.changes:
            out.append(
                f"{c.what}: {c.element}: {c.detail}; largest deviation {c.deviation_mm:.3f} mm"
            )
        if self.before_mm is not None:
            b_len, b_turn = chord_lengths_mm(self.before_mm), bend_angles_deg(self.before_mm)
            a_len, a_turn = self.chords_mm, self.turns_deg
            out.append("step  design feed_mm bend_deg  ->  bent feed_mm bend_deg")
            for i in range(max(len(b_len), len(a_len))):
                left = _cell(b_len, -b_turn, i)
                right = _cell(a_len, -a_turn, i)
                out.append(f"{i + 1:4d}  {left}  ->  {right}")
            out.append(f"largest deviation from the design: {self.max_deviation_mm:.3f} mm")
        return out

    def header_lines(self) -> list[str]:
        """The job header's comment lines: the table and the plan itself (for part/correct)."""
        keep = {
            "source": os.path.basename(self.source),
            "units": self.units,
            "chords_mm": [round(float(v), 4) for v in self.chords_mm],
            "turns_deg": [round(float(v), 4) for v in self.turns_deg],
            "max_deviation_mm": round(self.max_deviation_mm, 4),
        }
        lines = [f"; {line}" for line in self.table_lines()]
        lines.append(_PLAN_TAG + json.dumps(keep, separators=(",", ":")))
        return [comment_text(h) for h in lines]

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "units": self.units,
            "from_job": self.from_job,
            "vertices_mm": self.vertices_mm.tolist(),
            "chords_mm": self.chords_mm.tolist(),
            "bends_deg": self.bends_deg.tolist(),
            "changes": [c.to_dict() for c in self.changes],
            "before_mm": None if self.before_mm is None else self.before_mm.tolist(),
            "max_deviation_mm": self.max_deviation_mm,
        }


def _cell(lengths: np.ndarray, bends: np.ndarray, i: int) -> str:
    if i >= len(lengths):
        return " " * 17
    bend = f"{bends[i]:8.2f}" if i < len(bends) else "       -"
    return f"{lengths[i]:8.2f} {bend}"


def polygon_from_chords(chords_mm: Any, turns_deg: Any) -> np.ndarray:
    """Vertices (N+1, 2) of a polygon from its chord lengths and turns (design frame)."""
    lengths = np.asarray(chords_mm, dtype=np.float64).ravel()
    turns = np.asarray(turns_deg, dtype=np.float64).ravel()
    if len(turns) != len(lengths) - 1:
        raise ValueError(f"{len(lengths)} chords need {len(lengths) - 1} turns, got {len(turns)}")
    heading = np.concatenate(([0.0], np.cumsum(np.radians(turns))))
    steps = lengths[:, None] * np.column_stack((np.cos(heading), np.sin(heading)))
    return np.vstack(([0.0, 0.0], np.cumsum(steps, axis=0)))


def load_plan(path: str | os.PathLike[str], *, units: str | None = None, **rules: Any) -> WirePlan:
    """Read a design file and plan it (:func:`cvmeasure.design.load_design`, :func:`plan_design`)."""
    return plan_design(load_design(path, units=units), **rules)


def plan_design(
    design: Design,
    *,
    min_segment_mm: float = MIN_SEGMENT_MM,
    max_bend_deg: float = MAX_BEND_DEG,
    divisions: int | None = None,
    rechord: bool = False,
    scale: float = 1.0,
    join_gap_mm: float = DEFAULT_JOIN_GAP_MM,
    clearance_mm: float = DEFAULT_CLEARANCE_MM,
) -> WirePlan:
    """The polygon to bend for a design, by the rules in the module notes.

    Raises
    ------
    InputError
        A closed shape, a gap, a segment too short, self-contact, a bend too large or a
        wire too long (named, with the number), on the design's file.
    """
    src = design.source
    if divisions is not None and divisions < 1:
        raise InputError("--divisions", f"must be >= 1, got {divisions}")
    if not scale > 0:
        raise InputError("--scale", f"must be positive, got {scale}")
    for p in design.paths:
        if p.closed:
            raise InputError(
                src, f"closed shape {p.element or p.kind}: a wire part needs two free ends"
            )
    wire, bridged = _one_wire(design, join_gap_mm)
    changes: list[DesignChange] = []
    if bridged > 0:
        detail = f"gaps up to {bridged:.3f} mm closed (--join-gap-mm {join_gap_mm:g})"
        changes.append(DesignChange(wire.element, "gap bridged", detail, bridged))
    drawn, _ = _divide_curves(wire, min_segment_mm, divisions)
    drawn = _merge_straight(drawn)
    if scale != 1.0:
        wire = _scaled(wire, scale)
        centre = wire.points_mm.mean(axis=0)
        dev = float(np.max(np.hypot(*(wire.points_mm - centre).T))) * abs(1.0 - 1.0 / scale)
        changes.append(DesignChange(wire.element, "scaled", f"x {scale:g} (--scale)", dev))
    length = wire.length_mm
    if length > MAX_WIRE_MM:
        raise InputError(
            src,
            f"the wire is {length:.0f} mm long, beyond {MAX_WIRE_MM:g} mm: wrong units? "
            f"(read as {design.units})",
        )
    corners, curve_changes = _divide_curves(wire, min_segment_mm, divisions)
    changes += curve_changes
    corners = _merge_straight(corners)
    lengths = chord_lengths_mm(corners)
    short = np.flatnonzero(lengths < min_segment_mm - 1e-9)
    if short.size and rechord:
        count = len(corners) - 1
        corners = _rechord(corners, min_segment_mm)
        detail = (
            f"{short.size} segments under {min_segment_mm:g} mm: {count} -> "
            f"{len(corners) - 1} chords (--rechord)"
        )
        dev = _hausdorff_mm(wire.points_mm, corners)
        changes.append(DesignChange(wire.element, "re-chorded", detail, dev))
    elif short.size:
        i = int(short[0])
        raise InputError(
            src,
            f"segment {i + 1} of {_element_at(design, corners[i : i + 2] / scale)} at "
            f"({corners[i, 0]:.2f}, {corners[i, 1]:.2f}) mm is {lengths[i]:.2f} mm long, under "
            f"the bender's {min_segment_mm:g} mm ({short.size} such; --rechord or --scale "
            "change the design)",
        )
    before = drawn if (scale != 1.0 or bridged > 0 or (short.size and rechord)) else None
    _check_bends(src, design, corners, max_bend_deg, scale)
    _check_contact(src, design, corners, clearance_mm, scale)
    return WirePlan(src, design.units, corners, tuple(changes), before, False)


def bent_polygon(
    wire: DesignPath, divisions: int, *, min_segment_mm: float = MIN_SEGMENT_MM
) -> np.ndarray:
    """The polygon of ``divisions`` chords a design wire is bent as, by the planner's rules.

    For a caller that has the wire and the chord count but no plan (no job): a wire that
    is all curve is divided into ``divisions`` equal chords (:meth:`DesignPath.chords`);
    one with drawn corners keeps them and divides its curves, each into the chords the
    planner would make, or all into ``divisions`` chords in total when that matches
    instead. When no such polygon has ``divisions`` chords, the wire's equal chords.
    """
    if wire.curve_mask.all() or len(wire.points_mm) < 2:
        return wire.chords(divisions)
    corners = _merge_straight(_divide_curves(wire, min_segment_mm, None)[0])
    if len(corners) - 1 == divisions:
        return corners
    runs = int(np.sum(np.diff(np.concatenate(([0], wire.curve_mask.astype(int)))) == 1))
    straight = len(_merge_straight(_divide_curves(wire, min_segment_mm, 1)[0])) - 1 - runs
    if runs == 1 and divisions - straight >= 1:
        corners = _merge_straight(_divide_curves(wire, min_segment_mm, divisions - straight)[0])
        if len(corners) - 1 == divisions:
            return corners
    return wire.chords(divisions)


def _one_wire(design: Design, join_gap_mm: float) -> tuple[DesignPath, float]:
    """The design's paths chained into one wire; (wire, largest gap bridged in mm)."""
    joined = join_paths(design.paths, tolerance_mm=join_gap_mm)
    if len(joined) == 1:
        strict = join_paths(design.paths, tolerance_mm=1e-6)
        bridged = _nearest_gap(strict)[0] if len(strict) > 1 else 0.0
        return joined[0], bridged if bridged > 1e-6 else 0.0
    gap, a, b = _nearest_gap(joined)
    if gap <= 5.0:
        raise InputError(
            design.source,
            f"gap of {gap:.3f} mm between {a} and {b}: the wire is not one connected path (join them in the drawing, or --join-gap-mm {math.ceil(gap * 1000) / 1000:g} to close it)",
        )
    raise InputError(
        design.source,
        f"design has {len(joined)} separate paths (nearest ends {gap:.1f} mm apart, {a} and {b}); a wire part needs one connected path",
    )


def _nearest_gap(paths: list[DesignPath]) -> tuple[float, str, str]:
    best = (math.inf, "", "")
    for i, p in enumerate(paths):
        for q in paths[i + 1 :]:
            for e in (p.points_mm[0], p.points_mm[-1]):
                for f in (q.points_mm[0], q.points_mm[-1]):
                    d = float(np.hypot(*(e - f)))
                    if d < best[0]:
                        best = (d, p.element or p.kind, q.element or q.kind)
    return best


def _scaled(path: DesignPath, scale: float) -> DesignPath:
    arcs = tuple(
        DesignArc(
            (a.centre_mm[0] * scale, a.centre_mm[1] * scale),
            a.radius_mm * scale,
            a.start_deg,
            a.sweep_deg,
        )
        for a in path.arcs
    )
    return DesignPath(
        path.points_mm * scale, path.closed, path.kind, path.element, arcs, path.curve
    )


def _divide_curves(
    wire: DesignPath, min_segment_mm: float, divisions: int | None
) -> tuple[np.ndarray, list[DesignChange]]:
    """Corners kept, each run of curve segments divided into equal chords."""
    pts, curve = wire.points_mm, wire.curve_mask
    out = [pts[0]]
    changes: list[DesignChange] = []
    i = 0
    while i < len(curve):
        if not curve[i]:
            out.append(pts[i + 1])
            i += 1
            continue
        j = i
        while j < len(curve) and curve[j]:
            j += 1
        run = pts[i : j + 1]
        length = polyline_length_mm(run)
        n = divisions if divisions is not None else max(1, int(length // min_segment_mm))
        arc = _matching_arc(wire.arcs, run[0], run[-1])
        chords = arc.points_mm(chords=n) if arc is not None else divide_into_chords(run, n)
        out.extend(chords[1:])
        turn = bend_angles_deg(chords)
        what = f"{length:.2f} mm of curve into {n} chords of {float(chord_lengths_mm(chords)[0]):.2f} mm"
        if len(turn):
            what += f", bends {float(np.min(turn)):.2f}..{float(np.max(turn)):.2f} deg"
        changes.append(
            DesignChange(
                wire.element or wire.kind, "curve divided", what, _hausdorff_mm(run, chords)
            )
        )
        i = j
    return np.asarray(out), changes


def _matching_arc(
    arcs: tuple[DesignArc, ...], start: np.ndarray, end: np.ndarray
) -> DesignArc | None:
    for arc in arcs:
        ends = arc.points_mm(chords=1)
        if np.allclose(ends[0], start, atol=1e-6) and np.allclose(ends[-1], end, atol=1e-6):
            return arc
    return None


def _merge_straight(vertices: np.ndarray) -> np.ndarray:
    """Drop inner vertices with no turn (collinear) and repeated points."""
    pts = vertices[np.concatenate(([True], chord_lengths_mm(vertices) > 1e-9))]
    if len(pts) < 3:
        return pts
    turns = bend_angles_deg(pts)
    keep = np.concatenate(([True], np.abs(turns) >= _STRAIGHT_DEG, [True]))
    return pts[keep]


def _rechord(corners: np.ndarray, min_segment_mm: float) -> np.ndarray:
    """Runs of short segments (grown to at least one chord) divided into equal chords."""
    pts = corners
    for _ in range(len(corners)):
        lengths = chord_lengths_mm(pts)
        short = np.flatnonzero(lengths < min_segment_mm - 1e-9)
        if not short.size:
            return pts
        i = j = int(short[0])
        while j + 1 < len(lengths) and lengths[j + 1] < min_segment_mm - 1e-9:
            j += 1
        while lengths[i : j + 1].sum() < min_segment_mm and (i > 0 or j + 1 < len(lengths)):
            if j + 1 < len(lengths) and (i == 0 or lengths[j + 1] <= lengths[i - 1]):
                j += 1
            else:
                i -= 1
        run = pts[i : j + 2]
        n = max(1, int(polyline_length_mm(run) // min_segment_mm))
        pts = np.vstack((pts[:i], divide_into_chords(run, n), pts[j + 2 :]))
        pts = _merge_straight(pts)
    return pts


def _hausdorff_mm(a: np.ndarray, b: np.ndarray, step_mm: float = 0.05) -> float:
    """Largest distance between two polylines (both ways, sampled every ``step_mm``)."""
    from scipy.spatial import cKDTree

    def dense(p: np.ndarray) -> np.ndarray:
        seg = chord_lengths_mm(p)
        out = [p[:1]]
        for k, s in enumerate(seg):
            m = max(1, int(math.ceil(s / step_mm)))
            t = np.linspace(0.0, 1.0, m + 1)[1:, None]
            out.append(p[k] + t * (p[k + 1] - p[k]))
        return np.vstack(out)

    da, db = dense(np.asarray(a, float)), dense(np.asarray(b, float))
    return float(max(cKDTree(db).query(da)[0].max(), cKDTree(da).query(db)[0].max()))


def _element_at(design: Design, segment: np.ndarray) -> str:
    """The drawing element a polygon segment lies on (its midpoint's nearest path)."""
    mid = np.asarray(segment, float).mean(axis=0)
    best = (math.inf, "")
    for p in design.paths:
        d = float(np.min(np.hypot(*(p.points_mm - mid).T))) if len(p.points_mm) else math.inf
        for a, b in zip(p.points_mm[:-1], p.points_mm[1:], strict=True):
            ab = b - a
            u = float(np.clip(np.dot(mid - a, ab) / max(float(ab @ ab), 1e-300), 0.0, 1.0))
            d = min(d, float(np.hypot(*(a + u * ab - mid))))
        if d < best[0]:
            best = (d, p.element or p.kind)
    return best[1] or "the wire"


def _check_bends(
    src: str, design: Design, corners: np.ndarray, max_bend_deg: float, scale: float
) -> None:
    for i, t in enumerate(bend_angles_deg(corners), start=1):
        if abs(t) > max_bend_deg:
            raise InputError(
                src,
                f"bend at vertex {i} ({corners[i, 0]:.2f}, {corners[i, 1]:.2f}) mm of "
                f"{_element_at(design, corners[i - 1 : i + 2] / scale)} is {t:.1f} deg; the "
                f"machine bends at most {max_bend_deg:g} deg",
            )


def _segment_distance(p: np.ndarray, q: np.ndarray, r: np.ndarray, s: np.ndarray) -> float:
    """Shortest distance between segments pq and rs (0 when they cross)."""

    def cross(a: np.ndarray, b: np.ndarray) -> float:
        return float(a[0] * b[1] - a[1] * b[0])

    d1, d2 = q - p, s - r
    den = cross(d1, d2)
    if abs(den) > 1e-12:
        t = cross(r - p, d2) / den
        u = cross(r - p, d1) / den
        if 0.0 <= t <= 1.0 and 0.0 <= u <= 1.0:
            return 0.0

    def to_seg(x: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
        ab = b - a
        w = float(np.clip(np.dot(x - a, ab) / max(float(ab @ ab), 1e-300), 0.0, 1.0))
        return float(np.hypot(*(a + w * ab - x)))

    return min(to_seg(p, r, s), to_seg(q, r, s), to_seg(r, p, q), to_seg(s, p, q))


def _check_contact(
    src: str, design: Design, corners: np.ndarray, clearance_mm: float, scale: float
) -> None:
    n = len(corners) - 1
    for i in range(n):
        for j in range(i + 2, n):
            d = _segment_distance(corners[i], corners[i + 1], corners[j], corners[j + 1])
            if d < clearance_mm:
                where = "cross" if d == 0.0 else f"come within {d:.2f} mm of each other"
                raise InputError(
                    src,
                    f"self-contact: segments {i + 1} and {j + 1} of the wire "
                    f"({_element_at(design, corners[i : i + 2] / scale)}) {where}; the wire "
                    f"would touch itself (clearance {clearance_mm:g} mm)",
                )


_FEED = re.compile(r"G91\s+G1\s+Y(-?[\d.]+)")
_STROKE = re.compile(r"G90\s+G1\s+X(-?[\d.]+)")


def plan_from_job(text: str, source: str) -> WirePlan | None:
    """The plan a job was written from (its ``; plan`` header line); None without one."""
    for line in text.splitlines():
        if not line.startswith(_PLAN_TAG):
            if line.startswith(";") or not line.strip():
                continue
            break
        try:
            data = json.loads(line[len(_PLAN_TAG) :])
            verts = polygon_from_chords(data["chords_mm"], data["turns_deg"])
        except (ValueError, KeyError, TypeError) as exc:
            raise InputError(source, f"unreadable plan line in the job header: {exc}") from None
        return WirePlan(source, str(data.get("units", "mm")), verts, from_job=True)
    return None


def plan_for_part(
    design: str | os.PathLike[str] | Design,
    *,
    job: str | os.PathLike[str] | GcodeJob | None = None,
    units: str | None = None,
    **rules: Any,
) -> WirePlan:
    """The polygon a finished part is compared with (``part``, ``correct``, ``track``).

    With the job it was bent from (its file, or the :class:`~cvmeasure.gcode.GcodeJob`
    itself): the plan in the job's header; a job without one (another generator) must
    bend as many times as the design's plan, which is used. Without a job: the design
    (a file, or loaded) planned by the same rules as ``cvmeasure gcode``.
    """
    if job is None:
        return _plan_of(design, units, rules)
    if isinstance(job, GcodeJob):
        text, source = job.text(), job.bends.source
    else:
        source = str(job)
        try:
            with open(job, encoding="utf-8", errors="replace") as fh:
                text = fh.read()
        except OSError as exc:
            raise InputError(job, f"cannot read: {exc.strerror or exc}") from None
    _, strokes = job_strokes(text)
    if strokes == 0:
        raise InputError(source, "no bend strokes (G90 G1 X...) in the job")
    plan = plan_from_job(text, source)
    if plan is None:
        plan = _plan_of(design, units, rules)
        if plan.divisions - 1 != strokes:
            raise InputError(
                source,
                f"the job bends {strokes} times but the design's plan has "
                f"{plan.divisions - 1} bends: it was not made from this design with these "
                "options (write the job with cvmeasure gcode, which keeps its plan)",
            )
    elif plan.divisions - 1 != strokes:
        raise InputError(
            source, f"the job's plan has {plan.divisions - 1} bends but it bends {strokes} times"
        )
    return plan


def _plan_of(design: str | os.PathLike[str] | Design, units: str | None, rules: Any) -> WirePlan:
    if isinstance(design, Design):
        return plan_design(design, **rules)
    return load_plan(design, units=units, **rules)


def job_strokes(text: str) -> tuple[list[float], int]:
    """(feeds in mm, number of bend strokes) of a job's G-code."""
    return [float(v) for v in _FEED.findall(text)], len(_STROKE.findall(text))
