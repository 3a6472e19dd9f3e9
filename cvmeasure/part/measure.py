"""One photo of a finished part -> its arc quantities, bends and deviation from the design.

Pipeline: the ChArUco board fixes the plane (:func:`cvmeasure.lens.plane.estimate_plane`:
undistorted pixels -> board mm); the wire is segmented beside the board
(:mod:`~cvmeasure.part.segment`); its sub-pixel centreline
(:mod:`~cvmeasure.part.centreline`) is mapped to board mm; then

* ``method="centreline_fit"`` (default): with ``divisions`` N, a polyline of N chords is
  fitted (:func:`~cvmeasure.part.fit.fit_polyline`), its vertex bends are the
  per-segment bends, and the circle through its vertices gives the radius and
  the arc angle; without N, a robust geometric circle fit of the centreline;
* ``"seed_ellipse"`` / ``"seed_sagitta"``: the seed paper's methods on the wire's outline
  (:mod:`~cvmeasure.part.seed_methods`). All three are always computed and
  reported under ``methods``; ``method`` chooses the headline values (older
  names are read too: :func:`cvmeasure.method_names.part_method`).

Sign and frames: positions in the board frame (mm). Signed bends are
counter-clockwise positive in the board frame's (x, y) -- the sense the
renderer's truth uses -- and the centreline is ordered so that the part's net
turn is counter-clockwise (positive bends on an arc); against a design (y up
as drawn) the part is compared as the camera sees it, so ``mirrored`` means
the part lies upside down.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.contracts import PlaneModel
from cvmeasure.design import DesignPath
from cvmeasure.errors import InputError
from cvmeasure.geometry import CircleFit, arclength_mm
from cvmeasure.lens.plane import estimate_plane
from cvmeasure.part.arc import (
    arc_from_points,
    chord_and_height_mm,
    net_turn_deg,
    part_shape,
    polygon_arc,
)
from cvmeasure.part.arc_uncertainty import ArcUncertainty, arc_uncertainty, imprecision_warning
from cvmeasure.part.centreline import Centreline
from cvmeasure.part.checks import (
    END_BEND_DEG,
    arc_consistency_warning,
    chord_length_warning,
    ends_at_a_boundary,
    widen_for_centreline_gaps,
)
from cvmeasure.part.chord_period import chord_spacing_warning, spacing_disagreement_deg
from cvmeasure.part.compare import (
    compare_bends,
    deviation_profile,
    register_to_design,
)
from cvmeasure.part.downsample import auto_downsample, downsample_photo, in_photo_px
from cvmeasure.part.fit import ChordCount, PolylineFit, count_chords, fit_polyline
from cvmeasure.part.lift import LiftEstimate, estimate_lift, lift_bound_mm
from cvmeasure.part.lift_use import (
    LIFT_BEND_DEG,
    LIFT_RADIUS_PCT,
    SHADOW_MAX_2SIGMA_MM,
    ShadowRefusal,
    lift_effects,
    lifted_points_mm,
    moved_lift,
    shadow_lift_scale,
    shadow_unusable,
)
from cvmeasure.part.locate import axis_height_for, measure_centreline_mm, outline_mm
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
from cvmeasure.part.resolution import resolution_warnings
from cvmeasure.part.result import (
    METHODS,
    ArcResult,
    DesignComparison,
    DivisionsSource,
    LiftSource,
    LiftUse,
    Method,
    PartLift,
    PartMeasurement,
    PartWire,
    PlaneSummary,
)
from cvmeasure.part.seed_methods import SeedArc, ellipse_method, sagitta_method
from cvmeasure.part.segment import WireMask
from cvmeasure.part.shadow import estimate_lift_shadow
from cvmeasure.part.vertices import LIT_MIN_LIFT_MM, profile_vertices, vertex_polyline
from cvmeasure.warning import StageWarning
from cvmeasure.wireplan import bent_polygon

__all__ = [
    "Method",
    "METHODS",
    "ArcResult",
    "DesignComparison",
    "PartMeasurement",
    "PartOptions",
    "WireOptions",
    "LiftOptions",
    "measure_part",
    "measure_centreline_mm",
    "compare_with_design",
    "arc_from_points",
    "chord_and_height_mm",
]
# (the result and option types, arc_from_points, chord_and_height_mm and measure_centreline_mm are
# re-exported: this module is where a part measurement is asked for)

#: A seed method's arc angle this far (deg) from the centreline's is warned about.
ARC_DISAGREE_DEG = 10.0


def _edges_lost(wire_diameter_mm: float, radius_mm: float) -> StageWarning:
    """The round wire's silhouette edges were not used: the radius is in doubt by r / R."""
    r = 0.5 * wire_diameter_mm
    pct = 100.0 * r / radius_mm if radius_mm > 0 else float("inf")
    return StageWarning(
        "round_wire_edges_lost",
        "the wire's silhouette edges were not used (not found along the whole wire, not its "
        "width apart, or on a light sheet, where a polished wire's limbs mirror the sheet and "
        "the edges found need not be its silhouette), so the centreline is the profiles' "
        "centre of symmetry, which a side-lit highlight or a shadow can pull off the "
        f"axis by up to the wire's radius ({r:g} mm): the radius may be off by {pct:.1f} % "
        "(more where the pull changes along the wire) and the lift is not read",
    )


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
    d_geo, _ = polygon_arc(verts)  # an S-curve or a straight design has no circle
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
    return DesignComparison(design_source, reg, dev, design_arc, bends, verts)


def measure_part(
    image: np.ndarray,
    board: BoardSpec | None,
    camera: CameraModel | None,
    *,
    options: PartOptions | None = None,
    plane: PlaneModel | None = None,
    design: DesignPath | None = None,
    design_source: str = "design",
    reference_mm: np.ndarray | None = None,
    moved_image: np.ndarray | None = None,
    moved_plane: PlaneModel | None = None,
    source: str = "photo",
) -> PartMeasurement:
    """Measure a finished part in a photo (see the module notes).

    Parameters
    ----------
    image : ndarray (H, W, 3) BGR, uint8 or uint16, at the camera's calibrated size.
    board, camera : the board lying in the part's plane and the calibrated camera; or
        ``plane``, measured elsewhere (``cvmeasure plane``: ``board`` is then only left
        out of the wire search and may be None, ``camera`` is unused).
    options : how to measure (:class:`~cvmeasure.part.options.PartOptions`: the chord
        count, the headline method, the wire stock, the lift); None: the defaults.
        With the wire's diameter, the lift off the plate is read
        (:mod:`cvmeasure.part.lift_use`) from ``moved_image`` or the cast shadow,
        corrected when consistent with the bound, else bounded; reported in ``lift``,
        the sigmas and ``part_lifted``.
    design, design_source : the design wire and its name (compared with, see
        :func:`compare_with_design`).
    reference_mm : (N+1, 2) the polygon bent (design frame, mm; ``WirePlan.vertices_mm``):
        the part is fitted with its N chords, vertices starting where it has them, and
        compared with it. Default: the planner's polygon of ``design`` in N chords.
    moved_image, moved_plane : a second photo of the part slid on the plate, and its
        plane (default: found from ``board``, or ``plane`` when that was given).
    source : the photo's name (in messages and the result).

    Raises InputError (no board, no wire, a part the divisions cannot describe).
    """
    opts = PartOptions() if options is None else options
    if opts.downsample != 1:
        return _measure_downsampled(
            image, board, camera, opts, plane, design, design_source, reference_mm,
            moved_image, moved_plane, source,
        )  # fmt: skip
    wire_opts, lift_opts = opts.wire, opts.lift
    method, divisions, wire_diameter_mm = opts.method, opts.divisions, wire_opts.diameter_mm
    axis_height_mm, end_shape = wire_opts.axis_height_mm, wire_opts.end_shape
    moved_given = plane is not None
    plane, wire, centre, centreline_mm = measure_centreline_mm(
        image, board, camera, axis_height_mm=axis_height_mm, end_shape=end_shape,
        source=source, wire_diameter_mm=wire_diameter_mm, plane=plane,
    )  # fmt: skip
    centre, centreline_mm = _counter_clockwise(centre, centreline_mm)
    warnings = _wire_found_warnings(wire)
    warnings += resolution_warnings(  # a wire too coarse to measure is refused here
        centre.half_width_px, plane.mm_per_px, wire_diameter_mm, wire.sheet, source
    )
    base_mm = axis_height_for(axis_height_mm, wire_diameter_mm)
    lift = _width_lift(plane, centre, wire_diameter_mm, base_mm)
    planned = reference_mm is not None
    if planned:  # the part is fitted with the polygon bent's own chords
        divisions = _planned_divisions(reference_mm, divisions)
    chords, divisions, divisions_from = _chord_count(centreline_mm, divisions, planned, warnings)
    reference_mm, fractions = _bent(centreline_mm, design, divisions, reference_mm)
    ours, circle, poly = _fit_arc(centreline_mm, divisions, source, fractions)
    flat = _Fit(centreline_mm, ours, circle, poly, fractions=fractions)
    reading = _LiftReading()
    if wire_diameter_mm is not None and moved_image is not None:
        reading.moved_info, reading.corrected, moved_warning = moved_lift(
            moved_image, moved_plane if moved_plane is not None else plane if moved_given else None,
            board, camera, plane, centre.points_px, wire_diameter_mm, axis_height_mm, end_shape,
            centre.between_edges,
        )  # fmt: skip
        warnings += [moved_warning] if moved_warning else []
    elif lift_opts.shadow and wire_diameter_mm is not None and centre.between_edges:
        bound_mm = lift_bound_mm(lift, lift_opts.max_lift_mm)
        reading = _shadow_reading(image, plane, centre, wire_diameter_mm, base_mm, bound_mm)
    fit = _with_lift(image, plane, centre, flat, reading, divisions, base_mm, source, warnings)
    if wire_diameter_mm is not None and fit.lift_info is None:
        max_lift_mm = lift_opts.max_lift_mm
        _bound_lift(fit, plane, centre, lift, reading, divisions, base_mm, max_lift_mm, warnings)
    ours, poly, vpoly = fit.ours, fit.poly, fit.vpoly
    if wire_diameter_mm is not None and not centre.between_edges:
        warnings.insert(0, _edges_lost(wire_diameter_mm, ours.radius_mm))
    bend_sigma = _checked_sigma(fit, centre, plane, divisions, warnings)
    methods, seed_arcs = _seed_methods(image, wire, plane, ours, divisions, warnings)
    if method not in methods:
        raise InputError(source, f"the {method} method failed on this part")
    shape = part_shape(poly)
    warnings += _result_warnings(methods, shape, centre, wire, board, plane, image, divisions)
    spacing = chord_spacing_warning(methods[method].segment_bend_deg, divisions, chords.periodic)
    warnings += [spacing] if spacing else []
    comparison = None
    if design is not None:
        comparison = compare_with_design(
            fit.centreline_mm, None if vpoly is None else vpoly.bend_deg, methods[method],
            design, design_source=design_source, allow_mirror=opts.allow_mirror,
            reference_mm=reference_mm,
        )  # fmt: skip
        if fit.poly is not None and divisions:
            differ = chord_length_warning(fit.poly.vertices_mm, comparison.polygon_mm, source)
            warnings += [differ] if differ else []
    uncertainty = None
    if method == "centreline_fit":
        spacing_deg = spacing_disagreement_deg(ours.segment_bend_deg, divisions, chords.periodic)
        uncertainty = _arc_uncertainty(fit, plane, centre, divisions, wire_diameter_mm, spacing_deg)
        # the same tolerances a lift is warned about at: the parts' targets
        imprecise = imprecision_warning(
            uncertainty, ours.radius_mm, radius_pct=LIFT_RADIUS_PCT, bend_deg=LIFT_BEND_DEG
        )
        warnings += [imprecise] if imprecise else []
    return _assemble(
        source, methods[method], shape, divisions_from, chords, methods, fit, bend_sigma,
        plane, centre, wire, seed_arcs, comparison, warnings, base_mm, uncertainty,
    )  # fmt: skip


def _arc_uncertainty(
    fit: _Fit,
    plane: PlaneModel,
    centre: Centreline,
    divisions: int | None,
    wire_diameter_mm: float | None,
    spacing_deg: float,
) -> ArcUncertainty | None:
    """The radius' and bend per chord's standard uncertainties of our fit
    (:func:`cvmeasure.part.arc_uncertainty.arc_uncertainty`)."""
    ours, circle = fit.ours, fit.circle
    wire_radius_mm = (
        wire_diameter_mm / 2.0
        if wire_diameter_mm is not None
        else centre.half_width_px * plane.mm_per_px
    )
    # the even/odd halves' disagreement (model error too) where the camera carries it
    lens = plane.lens_uncertainty_mm()
    lens_mm = lens["cross_validation_mm"]
    lens_mm = lens["sigma_mm"] if lens_mm is None else lens_mm
    lift_r_mm = lift_bend_deg = 0.0
    info = fit.lift_info
    if info is not None and info.used == LiftUse.CORRECTION:
        # the correction's effect is stated at 2 sigma of the lift read: half is one sigma
        lift_r_mm = 0.5 * info.effect_radius_pct / 100.0 * ours.radius_mm
        lift_bend_deg = 0.5 * info.effect_segment_bend_deg
    return arc_uncertainty(
        radius_mm=ours.radius_mm,
        vertices_mm=fit.centreline_mm if fit.poly is None else fit.poly.vertices_mm,
        circle_centre_mm=circle.centre,
        circle_covariance_mm2=circle.covariance,
        circle_radius_sigma_mm=circle.radius_sigma,
        divisions=divisions,
        mm_per_px=plane.mm_per_px,
        wire_radius_mm=wire_radius_mm,
        silhouette=centre.between_edges,
        end_uncertainty_px=centre.end_uncertainty_px,
        lens_sigma_mm=lens_mm,
        lift_radius_sigma_mm=lift_r_mm,
        lift_segment_bend_sigma_deg=lift_bend_deg,
        spacing_disagreement_deg=spacing_deg,
    )


def _checked_sigma(
    fit: _Fit,
    centre: Centreline,
    plane: PlaneModel,
    divisions: int | None,
    warnings: list[StageWarning],
) -> np.ndarray | None:
    """The vertex bends' sigmas, widened where a chord was not seen; the fit's checks warned."""
    poly, bend_sigma = fit.poly, fit.sigma
    if poly is not None and bend_sigma is not None and divisions and divisions > 1:
        bend_sigma, gap_warning = widen_for_centreline_gaps(
            fit.centreline_mm, poly, bend_sigma, 2.0 * centre.half_width_px * plane.mm_per_px
        )
        if gap_warning:
            warnings.append(gap_warning)
    arc_warning = arc_consistency_warning(fit.ours, poly, fit.vpoly, bend_sigma)
    if arc_warning:
        warnings.append(arc_warning)
    return bend_sigma


def _with_lift(
    image: np.ndarray,
    plane: PlaneModel,
    centre: Centreline,
    flat: _Fit,
    reading: _LiftReading,
    divisions: int | None,
    base_mm: float,
    source: str,
    warnings: list[StageWarning],
) -> _Fit:
    """Refitted at the measured lift when one is used, else the part on the plate."""
    if reading.corrected is None:  # on the plate (a lift, if any, bounded after)
        return _flat_fit(image, plane, centre, flat, base_mm)
    fit = _corrected_fit(image, plane, centre, flat, reading, divisions, base_mm, source)
    if fit.warning is not None:
        warnings.append(fit.warning)
    return fit


def _assemble(
    source: str,
    result: ArcResult,
    shape: str,
    divisions_from: DivisionsSource | None,
    chords: ChordCount,
    methods: dict[str, ArcResult],
    fit: _Fit,
    bend_sigma: np.ndarray | None,
    plane: PlaneModel,
    centre: Centreline,
    wire: WireMask,
    seed_arcs: dict[str, SeedArc],
    comparison: DesignComparison | None,
    warnings: list[StageWarning],
    axis_height_mm: float,
    uncertainty: ArcUncertainty | None,
) -> PartMeasurement:
    """The :class:`PartMeasurement` of the steps' results (``axis_height_mm``: where the
    vertices are drawn in the photo, the height the centreline was mapped at)."""
    poly, vpoly = fit.poly, fit.vpoly
    return PartMeasurement(
        source=source,
        result=result,
        shape=shape,
        divisions_from=divisions_from,
        chords_found=chords,
        methods=methods,
        vertex_bend_deg=None if vpoly is None else vpoly.bend_deg,
        vertex_bend_sigma_deg=bend_sigma,
        vertices_mm=None if poly is None else poly.vertices_mm,
        vertices_px=None
        if poly is None
        else plane.plane_to_image_px(poly.vertices_mm, height_mm=axis_height_mm),
        centreline_mm=fit.centreline_mm,
        centreline_px=centre.points_px,
        wire_width_mm=2.0 * centre.half_width_px * plane.mm_per_px,
        circle=fit.circle,
        plane=PlaneSummary.of(plane),
        wire=PartWire.of(wire.to_dict(), centre.to_dict()),
        lift=fit.lift_info,
        seed_arcs=seed_arcs,
        comparison=comparison,
        warnings=tuple(warnings),
        uncertainty=uncertainty,
    )


def _wire_found_warnings(wire: WireMask) -> list[StageWarning]:
    """What the wire search warns about: a longer line passed over."""
    warnings: list[StageWarning] = []
    if wire.passed_over:
        warnings.append(
            StageWarning(
                "part_wire_not_longest",
                f"the longest thin line beside the board was not taken for the wire "
                f"({wire.passed_over[0]}); the wire measured is the line whose profiles are a "
                "round wire's along the longest stretch: check on the overlay that it is the part",
            )
        )
    return warnings


@dataclass
class _Fit:
    """The part's fit at one stage: its centreline (mm), arc, chords and vertex bends."""

    centreline_mm: np.ndarray
    ours: ArcResult
    circle: CircleFit
    poly: PolylineFit | None
    vpoly: PolylineFit | None = None
    sigma: np.ndarray | None = None  # the vertex bends' sigmas, deg
    lift_info: PartLift | None = None
    warning: StageWarning | None = None
    # where the polygon bent has its vertices (shares of its length), None: equal chords
    fractions: np.ndarray | None = None


@dataclass
class _LiftReading:
    """A lift read from a second photo or the shadow, and whether and how it is used."""

    moved_info: dict[str, Any] | None = None
    shadow_info: dict[str, Any] | None = None
    corrected: Any = None  # a lift measured and corrected: the moved photo's or the shadow's
    # an uncertain shadow's lift (2 sigma above SHADOW_MAX_2SIGMA_MM) corrected: read above
    # the bound, it is scaled down to it; its 2 sigma is carried as a bound is (the worst
    # direction), not as the standard tilt error of a well-measured lift
    uncertain: bool = False
    scale: float = 1.0
    refusal: ShadowRefusal | None = None  # why a shadow's lift was not used (or not read)


def _width_lift(
    plane: PlaneModel, centre: Centreline, wire_diameter_mm: float | None, base_mm: float
) -> LiftEstimate | None:
    """The lift estimated from the wire's apparent width (for the bound), where measured."""
    if wire_diameter_mm is None or centre.edge_width_px is None:
        return None
    return estimate_lift(
        plane, centre.points_px, centre.edge_width_px, wire_diameter_mm=wire_diameter_mm,
        axis_height_mm=base_mm,
    )  # fmt: skip


def _planned_divisions(reference_mm: np.ndarray, divisions: int | None) -> int:
    """The chord count of the polygon bent; ValueError when ``divisions`` says another."""
    n = len(np.asarray(reference_mm, dtype=np.float64).reshape(-1, 2)) - 1
    if n < 1:
        raise ValueError("reference_mm must hold at least 2 vertices")
    if divisions is not None and divisions != n:
        raise ValueError(f"divisions {divisions} but the polygon bent has {n} chords")
    return n


def _bent(
    centreline_mm: np.ndarray,
    design: DesignPath | None,
    divisions: int | None,
    reference_mm: np.ndarray | None,
) -> tuple[np.ndarray | None, np.ndarray | None]:
    """The polygon bent (given, or the planner's for a design with drawn corners) and its
    vertex positions in the centreline's order (None: equal chords)."""
    if reference_mm is None and design is not None and divisions and not design.curve_mask.all():
        # a design with drawn corners: the polygon the planner bends in that many chords
        reference_mm = bent_polygon(design, divisions)
    if reference_mm is None:
        return None, None
    return reference_mm, _reference_fractions(centreline_mm, reference_mm)


def _reference_fractions(centreline_mm: np.ndarray, reference_mm: np.ndarray) -> np.ndarray:
    """The polygon bent's vertex positions (shares of its length) in the centreline's order.

    The centreline runs either way along the part; the order whose chord fit leaves the
    smaller residual is the part's (a polygon symmetric end to end gives the same).
    """
    ref = np.asarray(reference_mm, dtype=np.float64).reshape(-1, 2)
    cum = arclength_mm(ref)
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


def _measure_downsampled(
    image: np.ndarray,
    board: BoardSpec | None,
    camera: CameraModel | None,
    opts: PartOptions,
    plane: PlaneModel | None,
    design: DesignPath | None,
    design_source: str,
    reference_mm: np.ndarray | None,
    moved_image: np.ndarray | None,
    moved_plane: PlaneModel | None,
    source: str,
) -> PartMeasurement:
    """:func:`measure_part` on the photo averaged over ``opts.downsample`` pixel blocks
    (None: :func:`~cvmeasure.part.downsample.auto_downsample` on the photo's plane).

    The board plane is found on the photo itself (every corner at full resolution) and
    rescaled; so is the moved photo's. The result's pixel figures are the photo's.
    """
    plane_given = plane is not None
    if plane is None:
        if board is None or camera is None:
            raise ValueError("need a plane, or a board and a camera")
        plane = estimate_plane(image, board, camera, source=source)
    factor = opts.downsample or auto_downsample(plane.mm_per_px, opts.wire.diameter_mm)
    if moved_image is not None and moved_plane is None:
        # as measure_part does: the given plane, else the board's in the moved photo
        moved_plane = (
            plane
            if plane_given
            else estimate_plane(moved_image, board, camera, source="moved photo")
        )
    small, small_plane = image, plane
    small_moved, small_moved_plane = moved_image, moved_plane
    if factor > 1:
        small, small_plane = downsample_photo(image, plane, factor)
        if moved_image is not None:
            small_moved, small_moved_plane = downsample_photo(moved_image, moved_plane, factor)
    m = measure_part(
        small, board, camera, options=replace(opts, downsample=1), plane=small_plane,
        design=design, design_source=design_source, reference_mm=reference_mm,
        moved_image=small_moved, moved_plane=small_moved_plane, source=source,
    )  # fmt: skip
    return in_photo_px(m, factor, plane) if factor > 1 else m


def _counter_clockwise(
    centre: Centreline, centreline_mm: np.ndarray
) -> tuple[Centreline, np.ndarray]:
    """The centreline run so that the part turns counter-clockwise (positive bends on an arc)."""
    if net_turn_deg(centreline_mm) >= 0:
        return centre, centreline_mm
    widths = None if centre.edge_width_px is None else centre.edge_width_px[::-1]
    centre = replace(
        centre,
        points_px=centre.points_px[::-1],
        lit_points_px=None if centre.lit_points_px is None else centre.lit_points_px[::-1],
        ends_px=centre.ends_px[::-1],
        edge_width_px=widths,
        end_uncertainty_px=centre.end_uncertainty_px[::-1],
    )
    return centre, centreline_mm[::-1]


def _chord_count(
    centreline_mm: np.ndarray,
    divisions: int | None,
    planned: bool,
    warnings: list[StageWarning],
) -> tuple[ChordCount, int | None, DivisionsSource | None]:
    """The chord count found in the photo; the one used and where it came from.

    ``planned``: ``divisions`` is the chord count of the polygon bent (the plan's).
    """
    chords = count_chords(centreline_mm)
    given = DivisionsSource.PLAN if planned else DivisionsSource.GIVEN
    divisions_from = given if divisions is not None else None
    what = "the polygon bent has" if planned else "--divisions"
    if divisions is None and chords.divisions is not None:
        divisions, divisions_from = chords.divisions, DivisionsSource.PHOTO
    elif divisions is None:
        warnings.append(
            StageWarning(
                "part_chords_not_found",
                f"no chord count was found in the photo ({chords.reason}): the bend per chord "
                "and the bends at the vertices are not measured, and the radius is the wire's "
                "best circle, which for a part bent in chords lies inside its vertices' circle "
                "(by up to 1 - cos(half the bend per chord): 0.3 % at 9 deg per chord); give "
                "--divisions (or --job) if the part was bent in chords",
            )
        )
    elif divisions is not None and chords.divisions not in (None, divisions):
        warnings.append(
            StageWarning(
                "divisions_mismatch",
                f"{what} {divisions}, but the photo shows {chords.divisions} chords "
                f"({chords.reason}); measured with {divisions}",
            )
        )
    elif divisions is not None and chords.divisions is None:
        warnings.append(
            StageWarning(
                "divisions_not_found",
                f"{what} {divisions}, but no chord vertices were found in the photo "
                f"({chords.reason})",
            )
        )
    return chords, divisions, divisions_from


def _fit_arc(
    centreline_mm: np.ndarray,
    divisions: int | None,
    source: str,
    fractions: np.ndarray | None = None,
) -> tuple[ArcResult, CircleFit, PolylineFit | None]:
    """:func:`arc_from_points`, a part it cannot describe refused naming the photo."""
    try:
        return arc_from_points(centreline_mm, divisions, fractions)
    except ValueError as exc:
        raise InputError(source, f"cannot fit the part ({exc})") from None


def _shadow_reading(
    image: np.ndarray,
    plane: PlaneModel,
    centre: Centreline,
    wire_diameter_mm: float,
    base_mm: float,
    bound_mm: float,
) -> _LiftReading:
    """The lift from the wire's cast shadow, checked against the lift bound before use."""
    shadow = estimate_lift_shadow(
        image, plane, centre.points_px, wire_diameter_mm=wire_diameter_mm,
        axis_height_mm=base_mm,
    )  # fmt: skip
    reading = _LiftReading(shadow_info=shadow.to_dict())
    if shadow.lift is None:
        # not measured: why is named in the bound's warning, if the bound needs one
        reading.refusal = ShadowRefusal(shadow.message, False) if shadow.message else None
        return reading
    # every reading is checked against the lift bound (what the photo says without the
    # shadow); one read above it, within 2 sigma, is corrected at the bound
    reading.refusal = shadow_unusable(shadow.lift, bound_mm)
    if reading.refusal is not None:
        reading.shadow_info["message"] = (
            f"the shadow puts the lift at {shadow.lift.lift_mm:.2f} +- "
            f"{shadow.lift.lift_sigma_mm:.2f} mm: {reading.refusal.message}"
        )
    else:  # corrected; wider than SHADOW_MAX_2SIGMA_MM, its sigma carried as a bound
        reading.corrected = shadow
        reading.uncertain = 2.0 * shadow.lift.lift_sigma_mm > SHADOW_MAX_2SIGMA_MM
        reading.scale = shadow_lift_scale(shadow.lift, bound_mm)
    return reading


def _corrected_fit(
    image: np.ndarray,
    plane: PlaneModel,
    centre: Centreline,
    flat: _Fit,
    reading: _LiftReading,
    divisions: int | None,
    base_mm: float,
    source: str,
) -> _Fit:
    """The part refitted with each point at its measured height, the lift's remaining bound."""
    corrected, scale = reading.corrected, reading.scale
    measured = corrected.lift

    def lifted_mm(points_px: np.ndarray) -> np.ndarray:
        return lifted_points_mm(plane, points_px, base_mm, measured, scale)

    fractions = flat.fractions
    centreline_mm = lifted_mm(centre.points_px)
    ours, circle, poly = _fit_arc(centreline_mm, divisions, source, fractions)
    vpoly = profile_vertices(image, centre, lifted_mm, poly, fractions)
    if vpoly is None:  # no silhouette edges' profile fit: the edges' centres
        vpoly = poly
        if scale * corrected.lift.lift_mm >= LIT_MIN_LIFT_MM:
            vpoly = vertex_polyline(centre.lit_points_px, lifted_mm, divisions, poly, fractions)
    bend_sigma = None if vpoly is None else np.asarray(vpoly.bend_sigma_deg, dtype=float)
    lift_info, extra_sigma, _ = lift_effects(
        plane, centre.points_px, flat.centreline_mm, None, flat.ours, flat.poly, divisions,
        base_mm, 2.0 * corrected.lift.lift_sigma_mm, standard=not reading.uncertain,
        fractions=fractions,
    )  # fmt: skip
    by_shadow = reading.shadow_info is not None
    details = dict(reading.shadow_info if by_shadow else reading.moved_info)
    details.pop("lift_mm", None)
    # lift_mm: the lift corrected with (the reading, or the bound it was read above);
    # read_lift_mm: the shadow's or the two photos' own reading
    lift_info = replace(
        lift_info, used=LiftUse.CORRECTION,
        source=LiftSource.SHADOW if by_shadow else LiftSource.MOVED_PHOTO,
        bound_mm=2.0 * corrected.lift.lift_sigma_mm, lift_mm=scale * corrected.lift.lift_mm,
        lift_sigma_mm=details.pop("lift_sigma_mm", None), read_lift_mm=corrected.lift.lift_mm,
        details=details,
    )  # fmt: skip
    if bend_sigma is not None and extra_sigma is not None:
        bend_sigma = np.hypot(bend_sigma, extra_sigma)
    fit = _Fit(centreline_mm, ours, circle, poly, vpoly, bend_sigma, lift_info, None, fractions)
    if (
        lift_info.effect_radius_pct > LIFT_RADIUS_PCT
        or lift_info.effect_segment_bend_deg > LIFT_BEND_DEG
        or lift_info.effect_bend_deg > LIFT_BEND_DEG
    ):
        corrected_as = "corrected"
        if scale < 1.0:  # read above the bound: corrected at the bound
            corrected_as = (
                f"above the lift bound: corrected at {scale * corrected.lift.lift_mm:.2f} mm"
            )
        fit.warning = StageWarning(
            "part_lifted",
            f"the {'shadow' if by_shadow else 'two photos'} put the lift "
            f"at {corrected.lift.lift_mm:.2f} +- "
            f"{corrected.lift.lift_sigma_mm:.2f} mm ({corrected_as}); its uncertainty (2 "
            f"sigma) would move the radius by up to {lift_info.effect_radius_pct:.2f} %"
            f", the bend per chord by up to {lift_info.effect_segment_bend_deg:.3f} deg "
            f"and a vertex bend by up to {lift_info.effect_bend_deg:.3f} deg",
        )
    return fit


def _flat_fit(
    image: np.ndarray, plane: PlaneModel, centre: Centreline, flat: _Fit, base_mm: float
) -> _Fit:
    """The part on the plate: a round wire's vertex bends from each chord's cross-profile."""
    vpoly = profile_vertices(
        image, centre, lambda q: plane.image_to_plane_mm(q, height_mm=base_mm), flat.poly,
        flat.fractions,
    )  # fmt: skip
    vpoly = flat.poly if vpoly is None else vpoly
    bend_sigma = None if vpoly is None else np.asarray(vpoly.bend_sigma_deg, dtype=float)
    return replace(flat, vpoly=vpoly, sigma=bend_sigma)


def _bound_lift(
    fit: _Fit,
    plane: PlaneModel,
    centre: Centreline,
    lift: LiftEstimate | None,
    reading: _LiftReading,
    divisions: int | None,
    base_mm: float,
    max_lift_mm: float,
    warnings: list[StageWarning],
) -> None:
    """A round wire on the plate may rock: its lift bounded, the bound's effect in the sigmas.

    The bound is the width's estimate where it is good enough, else the largest lift a
    part rocks to; a shadow read but not used is named in the bound's warning.
    """
    lift_info, extra_sigma, lift_warning = lift_effects(
        plane, centre.points_px, fit.centreline_mm, lift, fit.ours, fit.poly, divisions,
        base_mm, max_lift_mm, fractions=fit.fractions,
    )  # fmt: skip
    if fit.sigma is not None and extra_sigma is not None:
        fit.sigma = np.hypot(fit.sigma, extra_sigma)
    refusal = reading.refusal
    if refusal is not None and (lift_warning or refusal.inconsistent):
        # a shadow read but not used: the bound's warning says why (one inconsistent
        # with the bound is warned about whatever the bound's effect: an edge misread)
        lift_warning = StageWarning(
            "part_lifted",
            (lift_warning.message if lift_warning else "the part may not lie flat")
            + f"; the cast shadow was not used: {reading.shadow_info['message']}",
        )
    if lift_warning:
        warnings.append(lift_warning)
    fit.lift_info = replace(lift_info, moved=reading.moved_info, shadow=reading.shadow_info)


def _seed_methods(
    image: np.ndarray,
    wire: WireMask,
    plane: PlaneModel,
    ours: ArcResult,
    divisions: int | None,
    warnings: list[StageWarning],
) -> tuple[dict[str, ArcResult], dict[str, SeedArc]]:
    """The seed paper's ellipse and sagitta methods on the wire's outline, beside ours."""
    methods: dict[str, ArcResult] = {"centreline_fit": ours}
    seed_arcs: dict[str, SeedArc] = {}
    outline = outline_mm(image, wire, plane)
    for name, fn in (("seed_ellipse", ellipse_method), ("seed_sagitta", sagitta_method)):
        try:
            arc = fn(outline)
        except ValueError as exc:
            warnings.append(StageWarning("seed_method_failed", f"the {name} method failed: {exc}"))
            continue
        seed_arcs[name] = arc
        methods[name] = ArcResult(
            name, arc.radius_mm, arc.chord_width_mm, arc.height_mm, arc.arc_angle_deg, divisions
        )
    return methods, seed_arcs


def _result_warnings(
    methods: dict[str, ArcResult],
    shape: str,
    centre: Centreline,
    wire: WireMask,
    board: BoardSpec | None,
    plane: PlaneModel,
    image: np.ndarray,
    divisions: int | None,
) -> list[StageWarning]:
    """What the result's reader must know: seed methods that disagree, an S-curve, uncertain
    or cut ends, a short arc. A tilted board plane is no doubt here: the part is mapped
    through the board's full pose (its tilt in ``plane.tilt_deg``)."""
    ours = methods["centreline_fit"]
    warnings: list[StageWarning] = []
    for name, arc in methods.items():
        if (
            name != "centreline_fit"
            and abs(arc.arc_angle_deg - ours.arc_angle_deg) > ARC_DISAGREE_DEG
        ):
            warnings.append(
                StageWarning(
                    "seed_method_disagrees",
                    f"the {name} method gives an arc of {arc.arc_angle_deg:.1f} deg where "
                    f"the centreline spans {ours.arc_angle_deg:.1f} deg: its figures do not "
                    "describe this part",
                )
            )
    if shape == "s-curve":
        warnings.append(
            StageWarning(
                "part_s_curve",
                "the bends change sign along the wire (a saddle / S-curve): radius_mm and "
                "arc_angle_deg are of the one circle nearest to it and describe no real arc; "
                "read chord_width_mm, height_mm and the bend at each vertex",
            )
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
                StageWarning(
                    "part_end_uncertain",
                    f"an end of the wire faces its shadow on a light plate and "
                    f"its cap's outline could lie up to {end_mm:.2f} mm farther in; the arc angle "
                    f"may be up to {turn_deg:.2f} deg and the bend per chord {per_chord:.3f} deg "
                    "smaller (the vertex bends are not affected)",
                )
            )
    cut = ends_at_a_boundary(centre.ends_px, board, plane, image.shape[:2], wire.width_px)
    if cut:
        warnings.append(
            StageWarning(
                "part_cut_off",
                f"the wire ends next to {cut}: it may go on there, hidden (the part is measured "
                "only as far as it is seen)",
            )
        )
    if ours.arc_angle_deg < 30.0:
        warnings.append(
            StageWarning(
                "arc_too_short",
                f"the arc spans only {ours.arc_angle_deg:.1f} deg: its radius is poorly determined",
            )
        )
    return warnings
