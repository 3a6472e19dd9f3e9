"""Checks that name what a part's fit cannot see: a lost chord, an inconsistent arc, a cut end.

A fit's sigma describes scatter about its model; these look for a stretch of centreline
or an end point wrong as a whole and say so (``part_centreline_gap``,
``part_arc_inconsistent``), or that the wire may go on beyond what is seen.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.contracts import PlaneModel
from cvmeasure.geometry import wrap_deg
from cvmeasure.part.arc import part_shape
from cvmeasure.part.fit import (
    PolylineFit,
    chord_coverage,
)
from cvmeasure.part.locate import MAX_WIRE_MM, board_exclusion
from cvmeasure.part.morph import dilated_at
from cvmeasure.part.result import ArcResult
from cvmeasure.warning import StageWarning

__all__ = [
    "ends_at_a_boundary",
    "END_BEND_DEG",
    "CHORD_MIN_COVERAGE",
    "widen_for_centreline_gaps",
    "ARC_BEND_DISAGREE_DEG",
    "arc_consistency_warning",
    "CHORD_LENGTH_DIFFER_SHARE",
    "chord_length_warning",
]

#: The part's chords between bend vertices (median) may differ from the polygon bent's by
#: this share before the part is said not to be that polygon's (``part_chords_longer`` /
#: ``part_chords_shorter``): the feed sets each chord, within its slip (about 1 %) and a
#: bend radius' take-up (``r (2 tan(b/2) - b)``: 1.3 mm at a 90 deg bend of a 3 mm radius,
#: under 0.05 mm at 15 deg), and the measured vertices lie within a few tenths of a mm.
#: A part of another design or job differs more.
CHORD_LENGTH_DIFFER_SHARE = 0.1


def ends_at_a_boundary(
    ends_px: np.ndarray,
    board: BoardSpec | None,
    plane: PlaneModel,
    shape: tuple[int, int],
    width_px: float,
) -> str:
    """'the board' / 'the photo's edge' when an end point lies within 3 wire widths of it."""
    h, w = shape
    reach = 3.0 * max(width_px, 1.0)
    # the wire search leaves out a frame about two widest wires wide
    edge = reach + 2.0 * MAX_WIRE_MM / plane.mm_per_px
    for x, y in ends_px:
        if min(x, y, w - 1 - x, h - 1 - y) < edge:
            return "the photo's edge"
    if board is None:
        return ""
    # the board's mask dilated by the reach, read at the end points only
    near_board = dilated_at(
        board_exclusion(board, plane, shape),
        cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * int(reach) + 1,) * 2),
        np.round(ends_px).astype(int),
    )
    return "the board" if near_board.any() else ""


#: An end point's uncertainty that could move the bend per chord by more than this (deg) is
#: warned about (``part_end_uncertain``).
END_BEND_DEG = 0.03

#: A chord with centreline points along less than this share of its fitted stretch has
#: no measured direction (``part_centreline_gap``).
CHORD_MIN_COVERAGE = 0.5


def widen_for_centreline_gaps(
    centreline_mm: np.ndarray, poly: PolylineFit, bend_sigma: np.ndarray, wire_width_mm: float
) -> tuple[np.ndarray, StageWarning | None]:
    """The vertex bends' sigmas widened where a chord is not seen, and the warning (or None).

    A chord seen along less than ``CHORD_MIN_COVERAGE`` of it (:func:`chord_coverage`, gaps
    wider than the wire not counted: the centreline lost there) gets its line from the
    centres at the gap's ends, which lie in the corners: its direction is uncertain by the
    angle half a wire's width subtends over the chord, added (in quadrature) to the sigmas
    of the bends at both its vertices. Where the gap holds two or more chords, their one
    line spans them all, each chord's direction anywhere between those of the seen chords
    either side: half the turn between those (:func:`_lost_run_turn_deg`), if larger.
    """
    cover = chord_coverage(centreline_mm, poly.vertices_mm, max_step_mm=wire_width_mm)
    if poly.across_gap is not None:  # placed across a gap: none of its own centres
        cover = np.where(poly.across_gap, 0.0, cover)
    lost = np.nonzero(cover < CHORD_MIN_COVERAGE)[0]
    if len(lost) == 0:
        return bend_sigma, None
    sigma = np.asarray(bend_sigma, dtype=float).copy()
    lengths = np.asarray(poly.segment_length_mm, dtype=float)
    seen = cover >= CHORD_MIN_COVERAGE
    for i in lost:
        dir_sigma = math.degrees(math.atan2(0.5 * wire_width_mm, max(lengths[i], 1e-9)))
        dir_sigma = max(dir_sigma, _lost_run_turn_deg(poly, seen, int(i)))
        for j in (i - 1, i):
            if 0 <= j < len(sigma):
                sigma[j] = math.hypot(sigma[j], dir_sigma)
    which = ", ".join(f"{int(i) + 1} ({100.0 * cover[i]:.0f} %)" for i in lost)
    warning = StageWarning(
        "part_centreline_gap",
        f"the centreline was lost along chord(s) {which} of "
        f"{poly.divisions} (share of the chord with centres): their direction is not "
        "measured, and the bends at their vertices may be off by degrees (their sigma widened)",
    )
    return sigma, warning


#: The arc's bend per chord and the vertex bends' mean may differ by this much (deg: the
#: bend per chord's target) plus three sigmas of the mean before they are warned about
#: (``part_arc_inconsistent``).
ARC_BEND_DISAGREE_DEG = 0.03


def arc_consistency_warning(
    ours: ArcResult,
    poly: PolylineFit | None,
    vpoly: PolylineFit | None,
    bend_sigma: np.ndarray | None,
) -> StageWarning | None:
    """The warning (or None) when the arc's bend per chord disagrees with the vertex bends.

    The circle through the chords' vertices gives the radius, the arc angle, the chord
    width and the height; on an arc of N equal chords its bend per chord
    (``arc_angle_deg / N``) is the mean of the N - 1 vertex bends. The vertex bends come
    from each chord's direction, the vertices from where neighbouring lines meet and from
    the end points: a centreline stretch off the wire (on its shadow, with the wire's
    width) shifts a chord's line sideways and moves its vertices along the chords by
    about the shift over the bend's sine, which the bends do not see (a last chord's
    centres 2.3 mm off on the shadow gave a radius 12.9 % low and a bend per chord 1.87 deg
    high while every vertex bend was within 0.26 deg); an end point placed wrong along its
    chord does the same on a smaller scale. A disagreement beyond
    ``ARC_BEND_DISAGREE_DEG`` plus three sigmas of the bends' mean (their sigmas taken as
    independent) is warned about; S-curves (no single arc) are not checked. ``poly`` is the
    polyline whose vertices the circle went through, ``vpoly`` the vertex bends' with their
    sigmas ``bend_sigma``.
    """
    if (
        poly is None
        or vpoly is None
        or bend_sigma is None
        or part_shape(poly) != "arc"
        or ours.segment_bend_deg is None
    ):
        return None
    bends = np.asarray(vpoly.bend_deg, dtype=float)
    sig = np.asarray(bend_sigma, dtype=float)
    if len(bends) < 1 or not (np.all(np.isfinite(bends)) and np.all(np.isfinite(sig))):
        return None
    mean = float(bends.mean())
    mean_sigma = float(np.sqrt(np.sum(sig**2))) / len(bends)
    diff = float(ours.segment_bend_deg) - mean
    if abs(diff) <= ARC_BEND_DISAGREE_DEG + 3.0 * mean_sigma:
        return None
    lengths = np.asarray(poly.segment_length_mm, dtype=float)
    return StageWarning(
        "part_arc_inconsistent",
        f"the circle through the chords' vertices turns "
        f"{ours.segment_bend_deg:.3f} deg per chord where the vertex bends average "
        f"{mean:.3f} +- {mean_sigma:.3f} deg (chords {lengths.min():.1f}-{lengths.max():.1f} "
        "mm): an end point or a stretch of the centreline is misplaced (e.g. on the wire's "
        f"shadow), and radius_mm, arc_angle_deg (by about {len(lengths) * diff:+.2f} deg), "
        "chord_width_mm and height_mm carry that error; the vertex bends do not",
    )


def _lost_run_turn_deg(poly: PolylineFit, seen: np.ndarray, i: int) -> float:
    """Half the turn (deg) between the seen chords either side of the run of lost chords
    holding chord ``i``; 0 where the run is that chord alone, 90 where it reaches an end of
    the wire (no seen chord beyond: its direction not measured at all; ``seen``: (N,) bool)."""
    lo = hi = i
    while lo > 0 and not seen[lo - 1]:
        lo -= 1
    while hi < len(seen) - 1 and not seen[hi + 1]:
        hi += 1
    if hi == lo or poly.direction_deg is None:
        return 0.0
    if lo == 0 or hi == len(seen) - 1:
        return 90.0
    directions = np.asarray(poly.direction_deg, dtype=float)
    return 0.5 * abs(float(wrap_deg(directions[hi + 1] - directions[lo - 1])))


def chord_length_warning(
    vertices_mm: np.ndarray, reference_mm: np.ndarray, source: str
) -> StageWarning | None:
    """Whether the part's inner chords are the polygon bent's: a warning where their median
    length differs from the reference's by over :data:`CHORD_LENGTH_DIFFER_SHARE`, else None.

    ``vertices_mm`` (N+1, 2): the part's chord vertices (mm, any frame); ``reference_mm``
    (N+1, 2): the polygon compared with (mm). Only the chords between two bend vertices
    count (the end chords end where the wire was cut, and where the photo saw it); a part
    of fewer than 3 chords has none and is not checked. Said so: a part photographed for
    another job's, or a design opened for the wrong part, would otherwise be compared and
    corrected vertex by vertex as if it were bent badly.
    """
    measured = np.hypot(*np.diff(np.asarray(vertices_mm, float)[1:-1], axis=0).T)
    wanted = np.hypot(*np.diff(np.asarray(reference_mm, float)[1:-1], axis=0).T)
    if len(measured) == 0 or len(measured) != len(wanted):
        return None
    part_mm, job_mm = float(np.median(measured)), float(np.median(wanted))
    if abs(part_mm - job_mm) <= CHORD_LENGTH_DIFFER_SHARE * job_mm:
        return None
    code = "part_chords_longer" if part_mm > job_mm else "part_chords_shorter"
    return StageWarning(
        code,
        f"the part's chords between its bends measure {part_mm:.2f} mm (median) where the "
        f"polygon it is compared with has {job_mm:.2f} mm: this is not that polygon's part "
        "(another design or job?); its bend errors are not bending errors",
        source,
    )
