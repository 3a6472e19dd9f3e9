"""One photo of a finished part -> its arc quantities, bends and deviation from the design.

Pipeline: the ChArUco board fixes the plane (:func:`cvmeasure.calibration.plane.estimate_plane`:
undistorted pixels -> board mm); the wire is segmented beside the board
(:mod:`~cvmeasure.part.segment`); its sub-pixel centreline
(:mod:`~cvmeasure.part.centreline`) is mapped to board mm; then

* ``method="ours"`` (default): with ``divisions`` N, a polyline of N chords is
  fitted (:func:`~cvmeasure.part.fit.fit_polyline`), its vertex bends are the
  per-segment bends, and the circle through its vertices gives the radius and
  the arc angle; without N, a robust geometric circle fit of the centreline;
* ``"ellipse"`` / ``"sagitta"``: the seed paper's methods on the wire's outline
  (:mod:`~cvmeasure.part.seed_methods`). All three are always computed and
  reported under ``methods``; ``method`` chooses the headline values.

Sign and frames: positions in the board frame (mm). Signed bends are
counter-clockwise positive in the board frame's (x, y) -- the sense the
renderer's truth uses -- and the centreline is ordered so that the part's net
turn is counter-clockwise (positive bends on an arc); against a design (y up
as drawn) the part is compared as the camera sees it, so ``mirrored`` means
the part lies upside down.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.camera import CameraModel
from cvmeasure.contracts import PlaneModel
from cvmeasure.design import DesignPath
from cvmeasure.errors import InputError
from cvmeasure.geometry import CircleFit, fit_circle_robust
from cvmeasure.part.centreline import (
    SYMMETRIC_WIRE_MAX,
    Centreline,
    EndShape,
    measure_centreline,
    profile_polyline,
)
from cvmeasure.part.compare import (
    BendComparison,
    Deviation,
    Registration,
    compare_bends,
    deviation_profile,
    register_to_design,
)
from cvmeasure.part.fit import (
    ArcGeometry,
    ChordCount,
    PolylineFit,
    arc_geometry,
    chord_coverage,
    count_chords,
    fit_polyline,
)
from cvmeasure.part.lift import (
    MAX_LIFT_MM,
    LiftEstimate,
    estimate_lift,
    estimate_lift_moved,
    lift_bound_mm,
    points_at_heights_mm,
    rocked_lift,
    unroll_mm,
)
from cvmeasure.part.seed_methods import SeedArc, ellipse_method, sagitta_method
from cvmeasure.part.segment import WireMask, gray_float, segment_wire
from cvmeasure.part.shadow import estimate_lift_shadow
from cvmeasure.wireplan import bent_polygon

__all__ = [
    "Method",
    "METHODS",
    "ArcResult",
    "DesignComparison",
    "PartMeasurement",
    "measure_part",
    "measure_centreline_mm",
    "compare_with_design",
    "arc_from_points",
    "chord_and_height_mm",
]

Method = Literal["ours", "ellipse", "sagitta"]
METHODS: tuple[str, ...] = ("ours", "ellipse", "sagitta")

#: Widest wire looked for (mm): 1/4 inch with margin; sets the filters' sizes.
MAX_WIRE_MM = 7.0
#: Shortest wire accepted as a part (mm).
MIN_WIRE_MM = 15.0
#: Least share of a candidate's cross-profiles that must have a symmetric centre.
MIN_COVERAGE = 0.5
#: Largest remaining asymmetry (relative to the profile's variance) of a round
#: wire's cross-profiles: rendered wires give 0.001-0.08 (0.25-1x size, both
#: sheets), thin lines on a cluttered real desk 0.27-0.84.
MAX_ASYMMETRY = SYMMETRIC_WIRE_MAX
#: Margin around the board left out of the wire search (mm).
BOARD_MARGIN_MM = 4.0


@dataclass(frozen=True)
class ArcResult:
    """The spec's part quantities from one method.

    ``segment_bend_deg`` is ``arc_angle_deg / divisions`` (None without divisions).
    """

    method: str
    radius_mm: float
    chord_width_mm: float
    height_mm: float
    arc_angle_deg: float
    divisions: int | None

    @property
    def segment_bend_deg(self) -> float | None:
        return None if not self.divisions else self.arc_angle_deg / self.divisions

    def to_dict(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "radius_mm": self.radius_mm,
            "chord_width_mm": self.chord_width_mm,
            "height_mm": self.height_mm,
            "arc_angle_deg": self.arc_angle_deg,
            "segment_bend_deg": self.segment_bend_deg,
        }


@dataclass(frozen=True)
class DesignComparison:
    """The part registered to its design and how far it deviates.

    ``bends`` only with divisions: per-vertex bends (design order and sense)
    and the seed's absolute / relative errors of the bend per chord.
    """

    source: str
    registration: Registration
    deviation: Deviation
    design_arc: ArcResult
    bends: BendComparison | None

    def to_dict(self) -> dict[str, Any]:
        return {
            "design": self.source,
            "registration": self.registration.to_dict(),
            "deviation": self.deviation.to_dict(),
            "design_arc": self.design_arc.to_dict(),
            "bends": None if self.bends is None else self.bends.to_dict(),
        }


@dataclass(frozen=True)
class PartMeasurement:
    """Everything measured on one part photo.

    Attributes
    ----------
    source : the photo.
    result : the headline :class:`ArcResult` (from ``method``).
    methods : the result of every method, by name.
    vertex_bend_deg : ndarray (N-1,) signed bends at the fitted vertices (ours,
        with divisions), counter-clockwise positive in the board frame; else None.
    vertex_bend_sigma_deg : their standard uncertainties (sampling only), degrees.
    vertices_mm : ndarray (N+1, 2) fitted chord vertices, board mm; else None.
    vertices_px : the same vertices in photo pixels.
    centreline_mm : ndarray (M, 2) the wire's centreline, board mm, end to end.
    centreline_px : ndarray (M, 2) the same in photo pixels.
    wire_width_mm : apparent wire width (flanks at half contrast), mm.
    circle : the circle fit behind ``ours``.
    plane : summary of the board plane (tilt, scale, reprojection RMS).
    wire : summary of the segmentation.
    comparison : against the design, when one was given.
    warnings : things a user should know (e.g. arcs too short for a stable radius).
    shape : ``"arc"`` (bends of one sign) or ``"s-curve"`` (a saddle: the bends change
        sign, so radius and arc angle describe no real arc).
    divisions_from : where the chord count came from: ``"--divisions"``, ``"plan"`` (the
        polygon bent, ``reference_mm``), ``"photo"`` (vertices found on the centreline)
        or None (none: a smooth curve).
    chords_found : what the vertex search on the centreline found.
    lift : with a wire diameter, the part's lift off the plate
        (:mod:`cvmeasure.part.lift`): ``lift_mm`` (bounded: the width's estimate; corrected:
        the lift corrected with, the reading or the bound it was read above, the reading
        itself in ``read_lift_mm``), ``lift_sigma_mm`` (the estimate's or the reading's; None
        without one), ``used`` (``"bound"``, or ``"correction"``
        when a lift was measured and corrected), ``source`` (where the lift came from:
        ``"width"`` for the bound, ``"moved_photo"`` or ``"shadow"`` for a correction),
        ``bound_mm`` and the bound's worst effect on the radius (``effect_radius_pct``),
        the bend per chord and a vertex bend (``effect_segment_bend_deg``,
        ``effect_bend_deg``); else None.
    """

    source: str
    result: ArcResult
    methods: dict[str, ArcResult]
    vertex_bend_deg: np.ndarray | None
    vertex_bend_sigma_deg: np.ndarray | None
    vertices_mm: np.ndarray | None
    vertices_px: np.ndarray | None
    centreline_mm: np.ndarray
    centreline_px: np.ndarray
    wire_width_mm: float
    circle: CircleFit
    plane: dict[str, Any]
    wire: dict[str, Any]
    seed_arcs: dict[str, SeedArc] = field(default_factory=dict)
    comparison: DesignComparison | None = None
    warnings: tuple[str, ...] = ()
    shape: str = "arc"
    divisions_from: str | None = None
    chords_found: ChordCount | None = None
    lift: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"photo": self.source, **self.result.to_dict()}
        out["divisions"] = self.result.divisions
        out["divisions_from"] = self.divisions_from
        out["shape"] = self.shape
        out["chords_found"] = None if self.chords_found is None else self.chords_found.to_dict()
        out["vertex_bend_deg"] = (
            None if self.vertex_bend_deg is None else self.vertex_bend_deg.tolist()
        )
        out["vertex_bend_sigma_deg"] = (
            None if self.vertex_bend_sigma_deg is None else self.vertex_bend_sigma_deg.tolist()
        )
        out["bend_sense"] = "counter-clockwise positive in the board frame (x, y)"
        out["vertices_mm"] = None if self.vertices_mm is None else self.vertices_mm.tolist()
        out["wire_width_mm"] = self.wire_width_mm
        out["circle"] = self.circle.to_dict("mm")
        out["methods"] = {k: v.to_dict() for k, v in self.methods.items()}
        out["seed_arcs"] = {k: v.to_dict() for k, v in self.seed_arcs.items()}
        out["plane"] = self.plane
        out["wire"] = self.wire
        out["centreline_mm"] = self.centreline_mm.tolist()
        # for overlays: the centreline in photo pixels, at most 400 points
        step = max(1, len(self.centreline_px) // 400)
        line_px = np.vstack((self.centreline_px[::step], self.centreline_px[-1:]))
        out["centreline_px"] = np.round(line_px, 2).tolist()
        out["vertices_px"] = (
            None if self.vertices_px is None else np.round(self.vertices_px, 2).tolist()
        )
        out["comparison"] = None if self.comparison is None else self.comparison.to_dict()
        out["lift"] = self.lift
        out["warnings"] = list(self.warnings)
        return out


#: A seed method's arc angle this far (deg) from the centreline's is warned about.
ARC_DISAGREE_DEG = 10.0
#: Vertex bends of both signs beyond this (deg) make a part an S-curve (saddle).
S_CURVE_BEND_DEG = 0.2


def _shape(poly: PolylineFit | None) -> str:
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
        circle = fit_circle_robust(poly.vertices_mm)
        geo: ArcGeometry = arc_geometry(circle, poly.vertices_mm)
        chord, height = chord_and_height_mm(poly.vertices_mm)
    else:
        circle = fit_circle_robust(pts)
        geo = arc_geometry(circle, pts)
        chord, height = geo.chord_width_mm, geo.height_mm
    result = ArcResult("ours", geo.radius_mm, chord, height, geo.arc_angle_deg, divisions)
    return result, circle, poly


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


def _board_exclusion(board: BoardSpec, plane: PlaneModel, shape: tuple[int, int]) -> np.ndarray:
    import cv2

    w_mm, h_mm = board.size_mm
    m = BOARD_MARGIN_MM
    s = np.linspace(0.0, 1.0, 25)
    x0, y0, x1, y1 = -m, -m, w_mm + m, h_mm + m
    outline = np.vstack(
        (
            np.column_stack((x0 + (x1 - x0) * s, np.full_like(s, y0))),
            np.column_stack((np.full_like(s, x1), y0 + (y1 - y0) * s)),
            np.column_stack((x1 - (x1 - x0) * s, np.full_like(s, y1))),
            np.column_stack((np.full_like(s, x0), y1 - (y1 - y0) * s)),
        )
    )
    px = plane.plane_to_image_px(outline)
    mask = np.zeros(shape, dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(px).astype(np.int32)], 1)
    return mask.astype(bool)


def measure_centreline_mm(
    image: np.ndarray,
    board: BoardSpec | None,
    camera: CameraModel | None,
    *,
    axis_height_mm: float | None = None,
    end_shape: EndShape = "round",
    source: str = "photo",
    wire_diameter_mm: float | None = None,
    plane: PlaneModel | None = None,
) -> tuple[Any, WireMask, Centreline, np.ndarray]:
    """Board plane, wire mask, pixel centreline and centreline in board mm of one photo.

    ``axis_height_mm`` is how far the wire's axis lies above the board's
    plane, towards the camera (see :func:`measure_part`). With ``wire_diameter_mm``
    the centreline lies between the wire's silhouette edges. ``plane`` (e.g. from
    ``cvmeasure plane``) replaces the board's plane in the photo; ``board`` is then
    only left out of the wire search (None: nothing is).

    Raises
    ------
    InputError
        No board (named by the calibration stage), or no wire beside it.
    """
    from cvmeasure.calibration.plane import estimate_plane

    if plane is None:
        if board is None or camera is None:
            raise ValueError("need a plane, or a board and a camera")
        plane = estimate_plane(image, board, camera, source=source)
    height = _axis_height(axis_height_mm, wire_diameter_mm)
    mm_per_px = plane.mm_per_px
    exclude = None if board is None else _board_exclusion(board, plane, image.shape[:2])
    wire = segment_wire(
        image,
        exclude=exclude,
        max_wire_width_px=MAX_WIRE_MM / mm_per_px,
        min_length_px=MIN_WIRE_MM / mm_per_px,
    )
    if wire is None:
        raise InputError(source, "no wire found beside the board")
    width_px = None
    if wire_diameter_mm is not None:
        # the diameter over the local scale at the axis' height, about the wire's middle
        mid = wire.path_px[len(wire.path_px) // 2]
        probe = plane.image_to_plane_mm(mid + np.array([[0, 0], [1, 0], [0, 1]]), height_mm=height)
        scale = float(
            np.sqrt(abs(np.linalg.det(np.vstack((probe[1] - probe[0], probe[2] - probe[0])))))
        )
        width_px = wire_diameter_mm / scale
    try:
        centre = measure_centreline(
            gray_float(image),
            wire.path_px,
            width_guess_px=wire.width_px,
            end_shape=end_shape,
            wire_width_px=width_px,
        )
    except ValueError as exc:
        raise InputError(source, f"the wire's centreline could not be measured ({exc})") from None
    # a side-lit round wire is not symmetric across; between silhouette edges a wire
    # wide along most of its length is the test instead
    asymmetric = centre.asymmetry > MAX_ASYMMETRY and centre.centre_from != "silhouette"
    if centre.coverage < MIN_COVERAGE or asymmetric:
        raise InputError(
            source,
            f"no wire found beside the board (the longest thin line, {wire.length_px:.0f} px, "
            f"has a round wire's symmetric profile along {100 * centre.coverage:.0f} % of it, "
            f"asymmetry {centre.asymmetry:.2f} > {MAX_ASYMMETRY})"
            if asymmetric
            else f"no wire found beside the board (the longest thin line, "
            f"{wire.length_px:.0f} px, looks like a round wire along only "
            f"{100 * centre.coverage:.0f} % of it)",
        )
    return plane, wire, centre, plane.image_to_plane_mm(centre.points_px, height_mm=height)


def _axis_height(axis_height_mm: float | None, wire_diameter_mm: float | None) -> float:
    """The axis' height above the plate: as given; else the radius of a known wire; else 0."""
    if axis_height_mm is not None:
        return float(axis_height_mm)
    return 0.0 if wire_diameter_mm is None else 0.5 * float(wire_diameter_mm)


def _outline_mm(image: np.ndarray, wire: WireMask, plane: PlaneModel) -> np.ndarray:
    """The wire's outer contour at full resolution, board mm (the seed's input).

    Pixels near the mask that differ from the background by more than half the
    wire's contrast (a seed-style binary threshold, so a dark shadow joins in
    as it did in the paper); the largest such region's outer contour.
    """
    import cv2

    gray = gray_float(image)
    near = max(3, int(round(0.5 * wire.width_px)) | 1)
    band = cv2.dilate(
        wire.mask.astype(np.uint8), cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (near, near))
    ).astype(bool)
    level = max(wire.threshold, 0.5 * wire.contrast)
    binary = (band & (np.abs(gray - wire.background_level) > level)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if count > 1:
        biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        binary = (labels == biggest).astype(np.uint8)
    else:
        binary = wire.mask.astype(np.uint8)
    binary = cv2.morphologyEx(binary, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    pts = np.vstack([c.reshape(-1, 2) for c in contours]).astype(np.float64)
    return plane.image_to_plane_mm(pts)


def _ends_at_a_boundary(
    ends_px: np.ndarray,
    board: BoardSpec | None,
    plane: PlaneModel,
    shape: tuple[int, int],
    width_px: float,
) -> str:
    """'the board' / 'the photo's edge' when an end point lies within 3 wire widths of it."""
    import cv2

    h, w = shape
    reach = 3.0 * max(width_px, 1.0)
    # the wire search leaves out a frame about two widest wires wide
    edge = reach + 2.0 * MAX_WIRE_MM / plane.mm_per_px
    for x, y in ends_px:
        if min(x, y, w - 1 - x, h - 1 - y) < edge:
            return "the photo's edge"
    if board is None:
        return ""
    near_board = cv2.dilate(
        _board_exclusion(board, plane, shape).astype(np.uint8),
        cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * int(reach) + 1,) * 2),
    )
    for x, y in np.round(ends_px).astype(int):
        if 0 <= y < h and 0 <= x < w and near_board[y, x]:
            return "the board"
    return ""


#: What a lift may change before it is warned about: the parts targets.
LIFT_RADIUS_PCT = 0.3
LIFT_BEND_DEG = 0.03
#: An end point's uncertainty that could move the bend per chord by more than this (deg) is
#: warned about (``part_end_uncertain``).
END_BEND_DEG = 0.03


#: A chord with centreline points along less than this share of its fitted stretch has
#: no measured direction (``part_centreline_gap``).
CHORD_MIN_COVERAGE = 0.5


def _centreline_gaps(
    centreline_mm: np.ndarray, poly: PolylineFit, bend_sigma: np.ndarray, wire_width_mm: float
) -> tuple[np.ndarray, str]:
    """The vertex bends' sigmas widened where a chord is not seen, and the warning ('' if none).

    A chord seen along less than ``CHORD_MIN_COVERAGE`` of it (:func:`chord_coverage`, gaps
    wider than the wire not counted: the centreline lost there) gets its line from the
    centres at the gap's ends, which lie in the corners: its direction is uncertain by the
    angle half a wire's width subtends over the chord, added (in quadrature) to the sigmas
    of the bends at both its vertices.
    """
    cover = chord_coverage(centreline_mm, poly.vertices_mm, max_step_mm=wire_width_mm)
    lost = np.nonzero(cover < CHORD_MIN_COVERAGE)[0]
    if len(lost) == 0:
        return bend_sigma, ""
    sigma = np.asarray(bend_sigma, dtype=float).copy()
    lengths = np.asarray(poly.segment_length_mm, dtype=float)
    for i in lost:
        dir_sigma = math.degrees(math.atan2(0.5 * wire_width_mm, max(lengths[i], 1e-9)))
        for j in (i - 1, i):
            if 0 <= j < len(sigma):
                sigma[j] = math.hypot(sigma[j], dir_sigma)
    which = ", ".join(f"{int(i) + 1} ({100.0 * cover[i]:.0f} %)" for i in lost)
    warning = (
        f"part_centreline_gap: the centreline was lost along chord(s) {which} of "
        f"{poly.divisions} (share of the chord with centres): their direction is not "
        "measured, and the bends at their vertices may be off by degrees (their sigma widened)"
    )
    return sigma, warning


#: The arc's bend per chord and the vertex bends' mean may differ by this much (deg: the
#: bend per chord's target) plus three sigmas of the mean before they are warned about
#: (``part_arc_inconsistent``).
ARC_BEND_DISAGREE_DEG = 0.03


def _arc_consistency(
    ours: ArcResult,
    poly: PolylineFit | None,
    vpoly: PolylineFit | None,
    bend_sigma: np.ndarray | None,
) -> str:
    """The warning ('' if none) when the arc's bend per chord disagrees with the vertex bends.

    The circle through the chords' vertices gives the radius, the arc angle, the chord
    width and the height; on an arc of N equal chords its bend per chord
    (``arc_angle_deg / N``) is the mean of the N - 1 vertex bends. The vertex bends come
    from each chord's direction, the vertices from where neighbouring lines meet and from
    the end points: a centreline stretch off the wire (on its shadow, with the wire's
    width) shifts a chord's line sideways and moves its vertices along the chords by
    about the shift over the bend's sine, which the bends do not see (dev part B4: the
    last chord's centres 2.3 mm off on the shadow, radius -12.9 %, bend per chord
    +1.87 deg, every vertex bend within 0.26 deg); an end point placed wrong along its
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
        or _shape(poly) != "arc"
        or ours.segment_bend_deg is None
    ):
        return ""
    bends = np.asarray(vpoly.bend_deg, dtype=float)
    sig = np.asarray(bend_sigma, dtype=float)
    if len(bends) < 1 or not (np.all(np.isfinite(bends)) and np.all(np.isfinite(sig))):
        return ""
    mean = float(bends.mean())
    mean_sigma = float(np.sqrt(np.sum(sig**2))) / len(bends)
    diff = float(ours.segment_bend_deg) - mean
    if abs(diff) <= ARC_BEND_DISAGREE_DEG + 3.0 * mean_sigma:
        return ""
    lengths = np.asarray(poly.segment_length_mm, dtype=float)
    return (
        f"part_arc_inconsistent: the circle through the chords' vertices turns "
        f"{ours.segment_bend_deg:.3f} deg per chord where the vertex bends average "
        f"{mean:.3f} +- {mean_sigma:.3f} deg (chords {lengths.min():.1f}-{lengths.max():.1f} "
        "mm): an end point or a stretch of the centreline is misplaced (e.g. on the wire's "
        f"shadow), and radius_mm, arc_angle_deg (by about {len(lengths) * diff:+.2f} deg), "
        "chord_width_mm and height_mm carry that error; the vertex bends do not"
    )


def _lifted_mm(
    plane: PlaneModel, points_px: np.ndarray, base_mm: float, lift: LiftEstimate, factor: float
) -> np.ndarray:
    """The centreline with each point on its own height (``factor`` x the lift), unrolled."""
    pts = points_at_heights_mm(plane, points_px, base_mm + factor * lift.height_mm)
    return unroll_mm(pts, (factor * lift.slope[0], factor * lift.slope[1]))


def _lift_effects(
    plane: PlaneModel,
    points_px: np.ndarray,
    used_mm: np.ndarray,
    lift: LiftEstimate | None,
    ours: ArcResult,
    poly: PolylineFit | None,
    divisions: int | None,
    base_mm: float,
    max_lift_mm: float = MAX_LIFT_MM,
    standard: bool = False,
    fractions: np.ndarray | None = None,
) -> tuple[dict[str, Any], np.ndarray | None, str]:
    """The lift's bound, the bends' extra sigma (deg) and a warning ('' when none).

    The lift is bounded by :func:`cvmeasure.part.lift.lift_bound_mm` (the width's
    estimate + 2 sigma, at most ``max_lift_mm``); its effect is the largest change of
    the radius and of each vertex bend when the part, rocked that much towards any of
    16 directions, is measured with each point on the plane of its own height (the
    tilted plane unrolled into the part's own) instead of flat. Half the worst change
    of each vertex bend is added to its sigma (so 2 sigma covers the bound); with
    ``standard`` (a measured lift whose 2 sigma is ``max_lift_mm``) half the rms change
    over the 16 directions instead: the standard uncertainty of a tilt error of one
    sigma in a direction not known (part14n).
    """

    def effect(other_mm: np.ndarray) -> tuple[float, float, np.ndarray | None]:
        try:
            res, _, p = arc_from_points(other_mm, divisions, fractions)
        except ValueError:
            return float("nan"), float("nan"), None
        d_r = 100.0 * (res.radius_mm / ours.radius_mm - 1.0)
        d_s = float((res.segment_bend_deg or 0.0) - (ours.segment_bend_deg or 0.0))
        if p is None or poly is None or len(p.bend_deg) != len(poly.bend_deg):
            return d_r, d_s, None
        return d_r, d_s, np.abs(np.asarray(p.bend_deg) - np.asarray(poly.bend_deg))

    bound = lift_bound_mm(lift, max_lift_mm)
    worst_r, worst_s = 0.0, 0.0
    changes: list[np.ndarray] = []  # each direction's change of every vertex bend
    if bound > 0:
        for direction in np.arange(0.0, 360.0, 22.5):
            rocked = rocked_lift(used_mm, float(direction), bound)
            d_r, d_s, d_b = effect(_lifted_mm(plane, points_px, base_mm, rocked, 1.0))
            if not np.isfinite(d_r):
                continue
            worst_r, worst_s = max(worst_r, abs(d_r)), max(worst_s, abs(d_s))
            if d_b is not None:
                changes.append(d_b)
    worst_b = np.max(changes, axis=0) if changes else None
    worst_vertex = float(np.max(worst_b)) if worst_b is not None and len(worst_b) else 0.0
    info = {
        **(lift.to_dict() if lift is not None else {"lift_mm": None, "lift_sigma_mm": None}),
        "used": "bound",
        "source": "width",
        "bound_mm": bound,
        "effect_radius_pct": worst_r,
        "effect_segment_bend_deg": worst_s,
        "effect_bend_deg": worst_vertex,
    }
    warning = ""
    if worst_r > LIFT_RADIUS_PCT or worst_s > LIFT_BEND_DEG or worst_vertex > LIFT_BEND_DEG:
        seen = (
            "the wire's apparent width gives no usable estimate"
            if lift is None or bound >= max_lift_mm
            else f"the wire's apparent width puts it at {lift.lift_mm:.2f} +- "
            f"{lift.lift_sigma_mm:.2f} mm"
        )
        warning = (
            f"part_lifted: the part may not lie flat and its lift is not measured ({seen}); "
            f"a lift of up to {bound:.1f} mm at one end would move the radius by up to "
            f"{worst_r:.2f} %, the bend per chord by up to {worst_s:.3f} deg and a vertex bend "
            f"by up to {worst_vertex:.3f} deg (half of it is in the vertex bends' sigmas): lay "
            "the part flat, or press it down, to measure it within "
            f"{LIFT_RADIUS_PCT} % / {LIFT_BEND_DEG} deg"
        )
    if worst_b is None:
        return info, None, warning
    if standard:
        return info, 0.5 * np.sqrt(np.mean(np.square(changes), axis=0)), warning
    return info, 0.5 * worst_b, warning


#: The shadow's lift (one photo, ``shadow_lift=True``) is corrected when its 2 sigma is at
#: most this (mm): the part's radius needs its mean height to about 1 mm (0.3 % of 550 mm
#: is 1.6 mm of camera distance).
SHADOW_MAX_2SIGMA_MM = 1.0


#: A shadow's lift wider than :data:`SHADOW_MAX_2SIGMA_MM` is still corrected when its 2
#: sigma is at most this (mm) (and :func:`_shadow_unusable` finds it consistent): wider,
#: its stated effect on the radius (0.5-1.4 % on the dev parts, 2 sigma 2-3 mm) is over
#: issue 14's 0.3 % anyway, and the bound covers the lift by construction where the shadow
#: covers it at 2 sigma only (a flat lab part on a textured sheet, dev seed 2000, read
#: 3.00 +- 1.43 mm).
SHADOW_WIDE_MAX_2SIGMA_MM = 2.0


@dataclass(frozen=True)
class ShadowRefusal:
    """Why a shadow's lift reading is not corrected (:func:`_shadow_unusable`).

    ``message``: the reason in words; ``inconsistent``: the reading is more than 2 sigma
    above the lift bound (an edge misread), warned about whatever the bound's effect, where
    a reading only too uncertain to correct is named in the bound's own warning, if any.
    """

    message: str
    inconsistent: bool


def _shadow_unusable(shadow: LiftEstimate, bound_mm: float) -> ShadowRefusal | None:
    """Why a shadow's lift is not corrected (None if it is).

    ``bound_mm``: the lift bound otherwise used (the width's estimate + 2 sigma, at most
    the largest lift a part rocks to), what the photo says about the lift without the
    shadow. Any reading more than 2 sigma above it is inconsistent with it and not used (a
    shadow edge taken for another: a full-size 3 mm lift once read 6.39 +- 1.20 mm, and a
    confident 7.42 +- 0.29 mm, part14r). A reading wider than :data:`SHADOW_MAX_2SIGMA_MM`
    is also not corrected when its 2 sigma is no smaller than that bound (it tells nothing
    the bound does not), or over :data:`SHADOW_WIDE_MAX_2SIGMA_MM`.
    """
    two_sigma = 2.0 * shadow.lift_sigma_mm
    if not np.isfinite(two_sigma) or two_sigma > SHADOW_WIDE_MAX_2SIGMA_MM:
        return ShadowRefusal(
            f"too uncertain to correct (2 sigma over {SHADOW_WIDE_MAX_2SIGMA_MM:.1f} mm)", False
        )
    if shadow.lift_mm - two_sigma > bound_mm:
        return ShadowRefusal(
            f"more than 2 sigma above the lift bound of {bound_mm:.1f} mm, inconsistent with "
            "it (a shadow edge taken for another?): not corrected",
            True,
        )
    if two_sigma > SHADOW_MAX_2SIGMA_MM and two_sigma >= bound_mm:
        return ShadowRefusal(
            f"too uncertain to correct (2 sigma is not below the bound of {bound_mm:.1f} mm)",
            False,
        )
    return None


def _shadow_lift_scale(shadow: LiftEstimate, bound_mm: float) -> float:
    """The factor a shadow's lift is corrected with (1, or less when the lift is read above
    ``bound_mm``, the lift bound otherwise used: it is then scaled down to it)."""
    return min(1.0, bound_mm / max(shadow.lift_mm, 1e-9))


#: Two views of a slid part whose registered centrelines differ by more than this rms
#: (photo pixels) disagree beyond their noise (a centreline defect in one of them, e.g. an
#: edge lost to a shadow): their lift is not used. Measured on the round-wire renders at
#: half size: 0.08-0.12 px where the lift came out right, 0.43 px on one that read 6 mm
#: for 1.5 mm.
MOVED_MAX_RMS_PX = 0.25


def _moved_lift(
    moved_image: np.ndarray,
    moved_plane: PlaneModel | None,
    board: BoardSpec | None,
    camera: CameraModel | None,
    plane: PlaneModel,
    points_px: np.ndarray,
    wire_diameter_mm: float,
    axis_height_mm: float | None,
    end_shape: EndShape,
    centre_from: str,
) -> tuple[dict[str, Any], Any, str]:
    """The lift from a second photo of the slid part: (info, the MovedLift when usable, warning)."""
    plane2, _, centre2, _ = measure_centreline_mm(
        moved_image, board, camera, axis_height_mm=axis_height_mm, end_shape=end_shape,
        source="moved photo", wire_diameter_mm=wire_diameter_mm, plane=moved_plane,
    )  # fmt: skip
    if centre_from != "silhouette" or centre2.centre_from != "silhouette":
        return (
            {"lift_mm": None, "message": "silhouette edges lost"},
            None,
            "moved_photo_unused: the wire's silhouette edges were not found along the whole wire "
            "in "
            + ("the first photo" if centre_from != "silhouette" else "the moved photo")
            + ": the profiles' centre of symmetry follows the highlight, which moves with the "
            "view, so the two views' difference is not the lift; the lift is bounded instead",
        )
    moved = estimate_lift_moved(
        plane, points_px, plane2, centre2.points_px,
        axis_height_mm=_axis_height(axis_height_mm, wire_diameter_mm),
        wire_diameter_mm=wire_diameter_mm,
    )  # fmt: skip
    info = moved.to_dict()
    if moved.lift is None:
        return info, None, f"moved_photo_unused: {moved.message}; the lift is bounded instead"
    rms_px = moved.residual_rms_mm / plane.mm_per_px
    info["residual_rms_px"] = rms_px
    if rms_px > MOVED_MAX_RMS_PX:
        return (
            info,
            None,
            f"moved_photo_unused: the two views of the part disagree ({rms_px:.2f} px rms after "
            f"registration > {MOVED_MAX_RMS_PX} px: a centreline defect in one of them), so their "
            f"lift ({moved.lift.lift_mm:.2f} mm) is not used; the lift is bounded instead",
        )
    return info, moved, ""


#: A part whose lift is measured (two photos, the shadow) at least this high (mm) has its
#: vertex bends from the pairs' and the lit side's chords combined (:func:`_vertex_polyline`).
#: The pairs' midpoints drift with the shadow's gap in proportion to the lift (0.05-0.13 deg
#: at 3 mm on full-size dev parts); the lit edge alone has a shading error of its own (0.071
#: deg on a flat noise-free dev part at half size where the pairs gave 0.020), which the
#: combination would read as the pairs' drift, so a part lying about flat keeps the pairs.
LIT_MIN_LIFT_MM = 2.0


def _vertex_polyline(
    lit_points_px: np.ndarray | None,
    to_mm: Any,
    divisions: int | None,
    poly: PolylineFit | None,
    fractions: np.ndarray | None = None,
) -> PolylineFit | None:
    """The polyline whose bends are the vertex bends: the pairs' and the lit side's chords.

    A round wire's centres between its silhouette edges bend where a lifted part's shadow
    parts from it (the shadow side's edge shifts with the gap;
    :func:`cvmeasure.part.centreline._silhouette_centres`); the centres on the lit side's
    edge (``lit_points_px``, mapped to mm by ``to_mm``) do not, but carry one edge's noise
    instead of two's. Each chord's direction is combined from both fits
    (:func:`_combine_chords`). ``poly`` (the pairs' midpoints) when there are no lit
    centres.
    """
    if poly is None or lit_points_px is None or not divisions:
        return poly
    try:
        lit = fit_polyline(to_mm(lit_points_px), divisions, fractions=fractions)
    except ValueError:
        return poly
    return _combine_chords(poly, lit)


def _profile_vertices(
    image: np.ndarray,
    centre: Centreline,
    to_mm: Any,
    poly: PolylineFit | None,
    fractions: np.ndarray | None = None,
) -> PolylineFit | None:
    """The vertex bends' polyline from each chord's whole cross-profile (lit side).

    :func:`cvmeasure.part.centreline.profile_polyline` on a centreline between silhouette
    edges (``poly`` splits it into chords); None when there are no silhouette edges or the
    fit fails (the caller keeps its edge-based polyline).
    """
    widths = centre.edge_width_px
    if poly is None or widths is None or not np.isfinite(widths).any():
        return None
    return profile_polyline(
        gray_float(image),
        centre.points_px,
        to_mm,
        poly,
        width_px=float(np.nanmedian(widths)),
        fractions=fractions,
    )


def _combine_chords(pairs: PolylineFit, lit: PolylineFit) -> PolylineFit:
    """Each chord's direction from the pairs' fit and the lit side's, by their errors.

    With ``S``, ``L`` the two edges' noise on a chord's direction and ``b`` the shadow
    side's bias (halved in the pairs' midpoints), the pairs read ``b + (S + L) / 2``
    (variance ``sp^2``) and the lit side ``L`` (``sl^2``), so their difference ``D`` is ``b``
    plus noise of variance ``sp^2`` (``S`` and ``L`` independent). The direction
    ``lit + w (pairs - lit)`` has the mean square error
    ``(1 - w/2)^2 sl^2 + w^2 ss^2 / 4 + w^2 b^2`` (``ss^2 = 4 sp^2 - sl^2``, the shadow
    side's noise), least at ``w = (sl^2 / 2) / (sp^2 + b^2)``; ``b^2`` is estimated as
    ``max(D^2 - sp^2, 0)``, so a chord whose two fits agree within their noise takes
    about the pairs (less noise) and one whose pairs drift with the shadow takes the lit
    edge. The bend's sigma is the two chords' errors (their fits share no point) in
    quadrature. The vertices and the rest are the lit fit's.
    """
    if (
        pairs.direction_deg is None
        or lit.direction_deg is None
        or pairs.direction_sigma_deg is None
        or lit.direction_sigma_deg is None
        or len(pairs.direction_deg) != len(lit.direction_deg)
    ):
        return lit
    sp2 = np.radians(pairs.direction_sigma_deg) ** 2
    sl2 = np.radians(lit.direction_sigma_deg) ** 2
    diff = np.radians((pairs.direction_deg - lit.direction_deg + 180.0) % 360.0 - 180.0)
    if not (np.all(np.isfinite(sp2)) and np.all(np.isfinite(sl2)) and np.all(sp2 > 0)):
        return lit
    b2 = np.maximum(diff**2 - sp2, 0.0)
    w = np.clip(0.5 * sl2 / (sp2 + b2), 0.0, 1.0)
    ss2 = np.maximum(4.0 * sp2 - sl2, 0.0)
    mse = (1.0 - 0.5 * w) ** 2 * sl2 + 0.25 * w**2 * ss2 + w**2 * b2
    turn = np.degrees(w * diff)  # each chord's direction moved from the lit fit's
    return replace(
        lit,
        bend_deg=lit.bend_deg + np.diff(turn),
        bend_sigma_deg=np.degrees(np.sqrt(mse[:-1] + mse[1:])),
        direction_deg=lit.direction_deg + turn,
        direction_sigma_deg=np.degrees(np.sqrt(mse)),
    )


def _reference_fractions(centreline_mm: np.ndarray, reference_mm: np.ndarray) -> np.ndarray:
    """The polygon bent's vertex positions (shares of its length) in the centreline's order.

    The centreline runs either way along the part; the order whose chord fit leaves the
    smaller residual is the part's (a polygon symmetric end to end gives the same).
    """
    ref = np.asarray(reference_mm, dtype=np.float64).reshape(-1, 2)
    cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(ref, axis=0).T))))
    f = cum / cum[-1]
    if len(ref) < 3:
        return f
    back = 1.0 - f[::-1]
    if np.allclose(f, back, atol=1e-9):
        return f
    fits = []
    for cand in (f, back):
        try:
            fits.append(fit_polyline(centreline_mm, len(ref) - 1, fractions=cand).rms_residual_mm)
        except ValueError:
            fits.append(np.inf)
    return f if fits[0] <= fits[1] else back


def _net_turn_deg(points_mm: np.ndarray) -> float:
    """Total signed turning of an ordered centreline (board frame sense), degrees."""
    pts = np.asarray(points_mm, dtype=np.float64)
    step = max(1, len(pts) // 200)
    d = np.diff(pts[::step], axis=0)
    heading = np.unwrap(np.arctan2(d[:, 1], d[:, 0]))
    return float(np.degrees(heading[-1] - heading[0])) if len(heading) else 0.0


def compare_with_design(
    centreline_mm: np.ndarray,
    vertex_bend_deg: np.ndarray | None,
    result: ArcResult,
    design: DesignPath,
    *,
    design_source: str = "design",
    allow_mirror: bool = True,
    reference_mm: np.ndarray | None = None,
) -> DesignComparison:
    """Register a board-frame centreline to a design and compare (see the module notes).

    The reference is the polygon the machine was asked to bend (``reference_mm``,
    design frame: :attr:`cvmeasure.wireplan.WirePlan.vertices_mm`, whose chord count
    must be the result's); without it, with divisions N, the polygon of N chords the
    planner makes of the design (:func:`cvmeasure.wireplan.bent_polygon`: drawn corners
    kept, curves in equal chords), else the design curve. ``allow_mirror=False`` refuses the mirror
    image (the part lies as it left the machine): a design symmetric end to end is
    then matched vertex for vertex.
    """
    seen = np.asarray(centreline_mm, dtype=np.float64) * np.array([1.0, -1.0])
    n = result.divisions
    if reference_mm is not None:
        verts = np.asarray(reference_mm, dtype=np.float64).reshape(-1, 2)
        if n and n != len(verts) - 1:
            raise ValueError(
                f"the part was fitted with {n} chords, the polygon bent has {len(verts) - 1}"
            )
    else:
        # the polygon the planner makes of this wire in n chords (drawn corners kept)
        verts = bent_polygon(design, n) if n else design.points_mm
    reg = register_to_design(seen, verts, allow_mirror=allow_mirror)
    dev = deviation_profile(seen, verts, reg)
    d_geo = arc_geometry(fit_circle_robust(verts), verts)
    design_arc = ArcResult(
        "design", d_geo.radius_mm, d_geo.chord_width_mm, d_geo.height_mm, d_geo.arc_angle_deg, n
    )
    bends = None
    if n and vertex_bend_deg is not None:
        bends = compare_bends(
            -np.asarray(vertex_bend_deg),  # board frame -> as seen (y up)
            verts,
            reg,
            measured_segment_bend_deg=float(result.segment_bend_deg or 0.0),
            design_segment_bend_deg=float(design_arc.segment_bend_deg or 0.0),
        )
    return DesignComparison(design_source, reg, dev, design_arc, bends)


def measure_part(
    image: np.ndarray,
    board: BoardSpec | None,
    camera: CameraModel | None,
    *,
    divisions: int | None = None,
    design: DesignPath | None = None,
    design_source: str = "design",
    method: Method = "ours",
    axis_height_mm: float | None = None,
    end_shape: EndShape = "round",
    source: str = "photo",
    allow_mirror: bool = True,
    wire_diameter_mm: float | None = None,
    plane: PlaneModel | None = None,
    max_lift_mm: float = MAX_LIFT_MM,
    moved_image: np.ndarray | None = None,
    moved_plane: PlaneModel | None = None,
    shadow_lift: bool = True,
    reference_mm: np.ndarray | None = None,
) -> PartMeasurement:
    """Measure a finished part in a photo (see the module notes).

    Parameters
    ----------
    image : ndarray (H, W, 3) BGR, uint8 or uint16, at the camera's calibrated size.
    board : the board lying in the part's plane.
    camera : the calibrated camera.
    divisions : the number of chords N the part was bent in; None finds the
        vertices on the centreline (:func:`cvmeasure.part.fit.count_chords`). Given,
        it is used, with a warning when the photo shows another count.
    design : the design wire (:meth:`cvmeasure.design.Design.wire`), optional.
    method : which method gives the headline values.
    axis_height_mm : height of the wire's axis above the board's plane (mm,
        towards the camera) where the part rests. None: the wire's radius with
        ``wire_diameter_mm`` (a part lying on the plate), else 0 (the board's plane,
        the flat photo lab's convention). Ignoring a raised axis scales the part by
        about height / distance (0.1-0.3 %).
    wire_diameter_mm : the wire's diameter (e.g. the kit's ``wire_diameter_mm``).
        With it the centreline lies between the wire's two silhouette edges (not
        on a side-lit highlight or a shadow's edge) and the part's lift off the
        plate is measured from the wire's cast shadow and corrected where that is
        good enough (``shadow_lift``), else estimated from the wire's apparent width
        and bounded (:mod:`cvmeasure.part.lift`, ``max_lift_mm``): the worst effect of
        the lift (or of its correction's uncertainty) on the radius and the bends is
        reported under ``lift``, half of it (of a corrected lift: half the rms over the
        rocking directions) is added to the vertex bends' sigmas, and it
        is warned about (``part_lifted``) when it exceeds 0.3 % or 0.03 deg
        (docs/part-measurement.md).
    plane : the plane measured elsewhere (``cvmeasure plane``); then ``board`` is
        only left out of the wire search and may be None, ``camera`` is unused.
    max_lift_mm : with ``wire_diameter_mm``, the largest lift the part may rock to
        when the width does not bound it better (mm; 0 for a part pressed flat).
    moved_image : with ``wire_diameter_mm``, a second photo of the same part slid on the
        plate (tens of mm, keeping its pose; same camera): its lift is then measured from
        the two views' perspective difference
        (:func:`cvmeasure.part.lift.estimate_lift_moved`) and corrected (each point on the
        plane of its own height, unrolled); only its uncertainty (2 sigma, any direction)
        is bounded and warned about. When the part was not moved, or the two centrelines
        disagree (residual above :data:`MOVED_MAX_RMS_PX`), a warning says so and the lift
        is bounded as with one photo.
    shadow_lift : with ``wire_diameter_mm`` and one photo (no ``moved_image``), measure the
        lift from the wire's cast shadow (:func:`cvmeasure.part.shadow.estimate_lift_shadow`)
        and correct it when it is consistent with the lift bound (not more than 2 sigma
        above it; read above it, corrected at the bound) and its 2 sigma is at most
        :data:`SHADOW_MAX_2SIGMA_MM`, or, wider (e.g. a textured sheet), below the bound
        (:func:`_shadow_unusable`; its 2 sigma then carried as a bound, in any direction,
        into the stated effects and the vertex bends' sigmas; ``part_lifted``); else (no
        clear shadow, no better than the bound, or inconsistent with it: ``part_lifted``
        says why) the lift is bounded as without it. On by default; False bounds the lift
        from the width only.
    moved_plane : the second photo's plane (default: ``plane`` when given, else measured
        from the board in ``moved_image``).
    end_shape : ``"round"`` wire ends (hemispherical, as rendered) or
        ``"flat"`` (square-cut); decides where the centreline's end points are.
    source : the photo's name, used in errors.
    allow_mirror : the part may lie upside down (the design comparison tries the
        mirror image); False when it lies as it left the machine.
    reference_mm : ndarray (N+1, 2), the polygon the machine was asked to bend (design
        frame, mm; :attr:`cvmeasure.wireplan.WirePlan.vertices_mm`). With it the part is
        fitted with its N chords, each vertex starting where the polygon has it (unequal
        chords), and compared with it; ``divisions`` is then N. Default: N equal chords
        of ``design``.

    Raises
    ------
    InputError
        No board, no wire, or a part that the given divisions cannot describe.
    ValueError
        An unknown ``method`` or ``divisions < 1``.
    """
    moved_given = plane is not None
    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}; got {method!r}")
    if divisions is not None and divisions < 1:
        raise ValueError(f"divisions must be >= 1, got {divisions}")
    plane, wire, centre, centreline_mm = measure_centreline_mm(
        image,
        board,
        camera,
        axis_height_mm=axis_height_mm,
        end_shape=end_shape,
        source=source,
        wire_diameter_mm=wire_diameter_mm,
        plane=plane,
    )
    if _net_turn_deg(centreline_mm) < 0:  # run so that the part turns counter-clockwise
        centreline_mm = centreline_mm[::-1]
        widths = None if centre.edge_width_px is None else centre.edge_width_px[::-1]
        centre = replace(
            centre,
            points_px=centre.points_px[::-1],
            lit_points_px=None if centre.lit_points_px is None else centre.lit_points_px[::-1],
            ends_px=centre.ends_px[::-1],
            edge_width_px=widths,
            end_uncertainty_px=centre.end_uncertainty_px[::-1],
        )
    warnings: list[str] = []
    if wire_diameter_mm is not None and centre.centre_from != "silhouette":
        warnings.append(
            "round_wire_edges_lost: the wire's silhouette edges were not found along the whole "
            "wire, so the centreline is the profiles' centre of symmetry, which a side-lit "
            "highlight or a shadow can pull off the axis; the lift was not bounded"
        )
    base_mm = _axis_height(axis_height_mm, wire_diameter_mm)
    lift = None
    if wire_diameter_mm is not None and centre.edge_width_px is not None:
        lift = estimate_lift(
            plane,
            centre.points_px,
            centre.edge_width_px,
            wire_diameter_mm=wire_diameter_mm,
            axis_height_mm=base_mm,
        )
    chords = count_chords(centreline_mm)
    given = "plan" if reference_mm is not None else "--divisions"
    if reference_mm is not None:
        divisions = len(reference_mm) - 1
    divisions_from = given if divisions is not None else None
    if divisions is None and chords.divisions is not None:
        divisions, divisions_from = chords.divisions, "photo"
    elif divisions is not None and chords.divisions not in (None, divisions):
        what = "the polygon bent has" if given == "plan" else "--divisions"
        warnings.append(
            f"{what} {divisions}, but the photo shows {chords.divisions} chords "
            f"({chords.reason}); measured with {divisions}"
        )
    elif divisions is not None and chords.divisions is None:
        what = "the polygon bent has" if given == "plan" else "--divisions"
        warnings.append(
            f"{what} {divisions}, but no chord vertices were found in the photo ({chords.reason})"
        )
    if reference_mm is None and design is not None and divisions and not design.curve_mask.all():
        # a design with drawn corners: the polygon the planner bends in that many chords
        reference_mm = bent_polygon(design, divisions)
    fractions = None if reference_mm is None else _reference_fractions(centreline_mm, reference_mm)
    flat_mm = centreline_mm
    try:
        ours, circle, poly = arc_from_points(centreline_mm, divisions, fractions)
    except ValueError as exc:
        raise InputError(source, f"cannot fit the part ({exc})") from None
    lift_info = None
    moved_info = None
    shadow_info = None
    corrected = None  # a lift measured and corrected: from the moved photo or the shadow
    # an uncertain shadow's lift (2 sigma above SHADOW_MAX_2SIGMA_MM) corrected: read above
    # the bound, it is scaled down to it; its 2 sigma is carried as a bound is (the worst
    # direction), not as the standard tilt error of a well-measured lift
    uncertain, scale = False, 1.0
    refusal: ShadowRefusal | None = None  # why a shadow's lift was read but not used
    if wire_diameter_mm is not None and moved_image is not None:
        moved_info, corrected, moved_warning = _moved_lift(
            moved_image, moved_plane if moved_plane is not None else plane if moved_given else None,
            board, camera, plane, centre.points_px, wire_diameter_mm, axis_height_mm, end_shape,
            centre.centre_from,
        )  # fmt: skip
        if moved_warning:
            warnings.append(moved_warning)
    elif shadow_lift and wire_diameter_mm is not None and centre.centre_from == "silhouette":
        shadow = estimate_lift_shadow(
            image, plane, centre.points_px, wire_diameter_mm=wire_diameter_mm,
            axis_height_mm=base_mm,
        )  # fmt: skip
        shadow_info = shadow.to_dict()
        if shadow.lift is not None:
            # every reading is checked against the lift bound (what the photo says without
            # the shadow); one read above it, within 2 sigma, is corrected at the bound
            bound_mm = lift_bound_mm(lift, max_lift_mm)
            refusal = _shadow_unusable(shadow.lift, bound_mm)
            if refusal is not None:
                shadow_info["message"] = (
                    f"the shadow puts the lift at {shadow.lift.lift_mm:.2f} +- "
                    f"{shadow.lift.lift_sigma_mm:.2f} mm: {refusal.message}"
                )
            else:  # corrected; wider than SHADOW_MAX_2SIGMA_MM, its sigma carried as a bound
                corrected = shadow
                uncertain = 2.0 * shadow.lift.lift_sigma_mm > SHADOW_MAX_2SIGMA_MM
                scale = _shadow_lift_scale(shadow.lift, bound_mm)
    if corrected is not None:
        flat = (ours, poly)
        measured = corrected.lift

        def lifted_mm(points_px: np.ndarray) -> np.ndarray:
            return _lifted_mm(plane, points_px, base_mm, measured, scale)

        centreline_mm = lifted_mm(centre.points_px)
        try:
            ours, circle, poly = arc_from_points(centreline_mm, divisions, fractions)
        except ValueError as exc:
            raise InputError(source, f"cannot fit the part ({exc})") from None
        vpoly = _profile_vertices(image, centre, lifted_mm, poly, fractions)
        if vpoly is None:  # no silhouette edges' profile fit: the edges' centres
            vpoly = poly
            if scale * corrected.lift.lift_mm >= LIT_MIN_LIFT_MM:
                vpoly = _vertex_polyline(
                    centre.lit_points_px, lifted_mm, divisions, poly, fractions
                )
        bend_sigma = None if vpoly is None else np.asarray(vpoly.bend_sigma_deg, dtype=float)
        lift_info, extra_sigma, _ = _lift_effects(
            plane, centre.points_px, flat_mm, None, flat[0], flat[1], divisions, base_mm,
            2.0 * corrected.lift.lift_sigma_mm, standard=not uncertain, fractions=fractions,
        )  # fmt: skip
        by_shadow = shadow_info is not None
        # lift_mm: the lift corrected with (the reading, or the bound it was read above);
        # read_lift_mm: the shadow's or the two photos' own reading
        lift_info = {**lift_info, **(shadow_info if by_shadow else moved_info),
                     "used": "correction", "source": "shadow" if by_shadow else "moved_photo",
                     "bound_mm": 2.0 * corrected.lift.lift_sigma_mm,
                     "lift_mm": scale * corrected.lift.lift_mm,
                     "read_lift_mm": corrected.lift.lift_mm}  # fmt: skip
        if bend_sigma is not None and extra_sigma is not None:
            bend_sigma = np.hypot(bend_sigma, extra_sigma)
        if (
            lift_info["effect_radius_pct"] > LIFT_RADIUS_PCT
            or lift_info["effect_segment_bend_deg"] > LIFT_BEND_DEG
            or lift_info["effect_bend_deg"] > LIFT_BEND_DEG
        ):
            corrected_as = "corrected"
            if scale < 1.0:  # read above the bound: corrected at the bound
                corrected_as = (
                    f"above the lift bound: corrected at {scale * corrected.lift.lift_mm:.2f} mm"
                )
            warnings.append(
                f"part_lifted: the {'shadow' if by_shadow else 'two photos'} put the lift "
                f"at {corrected.lift.lift_mm:.2f} +- "
                f"{corrected.lift.lift_sigma_mm:.2f} mm ({corrected_as}); its uncertainty (2 "
                f"sigma) would move the radius by up to {lift_info['effect_radius_pct']:.2f} %"
                f", the bend per chord by up to {lift_info['effect_segment_bend_deg']:.3f} deg "
                f"and a vertex bend by up to {lift_info['effect_bend_deg']:.3f} deg"
            )
    else:  # measured on the plate (a lift, if any, bounded below), not re-fitted lifted
        # a round wire's vertex bends from each chord's whole cross-profile (part14s)
        vpoly = _profile_vertices(
            image, centre, lambda q: plane.image_to_plane_mm(q, height_mm=base_mm), poly, fractions
        )
        vpoly = poly if vpoly is None else vpoly
        bend_sigma = None if vpoly is None else np.asarray(vpoly.bend_sigma_deg, dtype=float)
    if wire_diameter_mm is not None and lift_info is None:
        # a round wire on the plate may rock: its lift is bounded (the width's estimate
        # where it is good enough, else the largest lift a part rocks to)
        lift_info, extra_sigma, lift_warning = _lift_effects(
            plane, centre.points_px, centreline_mm, lift, ours, poly, divisions, base_mm,
            max_lift_mm, fractions=fractions,
        )  # fmt: skip
        if bend_sigma is not None and extra_sigma is not None:
            bend_sigma = np.hypot(bend_sigma, extra_sigma)
        if refusal is not None and (lift_warning or refusal.inconsistent):
            # a shadow read but not used: the bound's warning says why (one inconsistent
            # with the bound is warned about whatever the bound's effect: an edge misread)
            lift_warning = (
                lift_warning or "part_lifted: the part may not lie flat"
            ) + f"; the cast shadow was not used: {shadow_info['message']}"
        if lift_warning:
            warnings.append(lift_warning)
        if moved_info is not None:
            lift_info = {**lift_info, "moved": moved_info}
        if shadow_info is not None:
            lift_info = {**lift_info, "shadow": shadow_info}
    if poly is not None and bend_sigma is not None and divisions and divisions > 1:
        bend_sigma, gap_warning = _centreline_gaps(
            centreline_mm, poly, bend_sigma, 2.0 * centre.half_width_px * plane.mm_per_px
        )
        if gap_warning:
            warnings.append(gap_warning)
    arc_warning = _arc_consistency(ours, poly, vpoly, bend_sigma)
    if arc_warning:
        warnings.append(arc_warning)
    methods: dict[str, ArcResult] = {"ours": ours}
    seed_arcs: dict[str, SeedArc] = {}
    outline = _outline_mm(image, wire, plane)
    for name, fn in (("ellipse", ellipse_method), ("sagitta", sagitta_method)):
        try:
            arc = fn(outline)
        except ValueError as exc:
            warnings.append(f"the seed's {name} method failed: {exc}")
            continue
        seed_arcs[name] = arc
        methods[name] = ArcResult(
            name, arc.radius_mm, arc.chord_width_mm, arc.height_mm, arc.arc_angle_deg, divisions
        )
    if method not in methods:
        raise InputError(source, f"the {method} method failed on this part")
    for name, arc in methods.items():
        if name != "ours" and abs(arc.arc_angle_deg - ours.arc_angle_deg) > ARC_DISAGREE_DEG:
            warnings.append(
                f"the seed's {name} method gives an arc of {arc.arc_angle_deg:.1f} deg where the "
                f"centreline spans {ours.arc_angle_deg:.1f} deg: its figures do not describe "
                "this part"
            )
    shape = _shape(poly)
    if shape == "s-curve":
        warnings.append(
            "the bends change sign along the wire (a saddle / S-curve): radius_mm and "
            "arc_angle_deg are of the one circle nearest to it and describe no real arc; read "
            "chord_width_mm, height_mm and the bend at each vertex"
        )
    end_px = float(np.max(centre.end_uncertainty_px))
    if end_px > 0.0 and ours.radius_mm > 0.0:
        # one end point moved along the wire by u turns the arc by u / R: each chord's bend
        # by that over the chords
        end_mm = end_px * plane.mm_per_px
        turn_deg = float(np.degrees(end_mm / ours.radius_mm))
        per_chord = turn_deg / divisions if divisions else turn_deg
        if per_chord > END_BEND_DEG:
            warnings.append(
                f"part_end_uncertain: an end of the wire faces its shadow on a light plate and "
                f"its cap's outline could lie up to {end_mm:.2f} mm farther in; the arc angle "
                f"may be up to {turn_deg:.2f} deg and the bend per chord {per_chord:.3f} deg "
                "smaller (the vertex bends are not affected)"
            )
    cut = _ends_at_a_boundary(centre.ends_px, board, plane, image.shape[:2], wire.width_px)
    if cut:
        warnings.append(
            f"the wire ends next to {cut}: it may go on there, hidden (the part is measured "
            "only as far as it is seen)"
        )
    if ours.arc_angle_deg < 30.0:
        warnings.append(
            f"the arc spans only {ours.arc_angle_deg:.1f} deg: its radius is poorly determined"
        )
    if not plane.affine_ok:
        warnings.append(
            f"the board plane is tilted {plane.tilt_deg:.2f} deg (corrected by the homography)"
        )
    vertex_bends = None if vpoly is None else vpoly.bend_deg
    comparison = None
    if design is not None:
        comparison = compare_with_design(
            centreline_mm,
            vertex_bends,
            methods[method],
            design,
            design_source=design_source,
            allow_mirror=allow_mirror,
            reference_mm=reference_mm,
        )
    return PartMeasurement(
        source=source,
        result=methods[method],
        shape=shape,
        divisions_from=divisions_from,
        chords_found=chords,
        methods=methods,
        vertex_bend_deg=vertex_bends,
        vertex_bend_sigma_deg=bend_sigma,
        vertices_mm=None if poly is None else poly.vertices_mm,
        vertices_px=None if poly is None else plane.plane_to_image_px(poly.vertices_mm),
        centreline_mm=centreline_mm,
        centreline_px=centre.points_px,
        wire_width_mm=2.0 * centre.half_width_px * plane.mm_per_px,
        circle=circle,
        plane={
            "tilt_deg": plane.tilt_deg,
            "mm_per_px": plane.mm_per_px,
            "rms_px": plane.rms_px,
            "corner_count": plane.corner_count,
        },
        wire={**wire.to_dict(), **centre.to_dict()},
        lift=lift_info,
        seed_arcs=seed_arcs,
        comparison=comparison,
        warnings=tuple(warnings),
    )
