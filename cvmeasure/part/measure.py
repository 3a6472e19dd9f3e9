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

from dataclasses import replace

import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.camera import CameraModel
from cvmeasure.contracts import PlaneModel
from cvmeasure.design import DesignPath
from cvmeasure.errors import InputError
from cvmeasure.geometry import fit_circle_robust
from cvmeasure.part.arc import arc_from_points, chord_and_height_mm, net_turn_deg, part_shape
from cvmeasure.part.checks import (
    END_BEND_DEG,
    arc_consistency_warning,
    ends_at_a_boundary,
    widen_for_centreline_gaps,
)
from cvmeasure.part.compare import (
    compare_bends,
    deviation_profile,
    register_to_design,
)
from cvmeasure.part.ends import EndShape
from cvmeasure.part.fit import (
    arc_geometry,
    count_chords,
)
from cvmeasure.part.lift import (
    MAX_LIFT_MM,
    estimate_lift,
    lift_bound_mm,
)
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
from cvmeasure.part.result import METHODS, ArcResult, DesignComparison, Method, PartMeasurement
from cvmeasure.part.seed_methods import SeedArc, ellipse_method, sagitta_method
from cvmeasure.part.shadow import estimate_lift_shadow
from cvmeasure.part.vertices import LIT_MIN_LIFT_MM, profile_vertices, vertex_polyline
from cvmeasure.warning import StageWarning

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
# (the result types, arc_from_points, chord_and_height_mm and measure_centreline_mm are
# re-exported: this module is where a part measurement is asked for)

#: A seed method's arc angle this far (deg) from the centreline's is warned about.
ARC_DISAGREE_DEG = 10.0


def compare_with_design(
    centreline_mm: np.ndarray,
    vertex_bend_deg: np.ndarray | None,
    result: ArcResult,
    design: DesignPath,
    *,
    design_source: str = "design",
    allow_mirror: bool = True,
) -> DesignComparison:
    """Register a board-frame centreline to a design and compare (see the module notes).

    With divisions N the reference is the design divided into N equal chords
    (the polygon the machine is asked to bend), otherwise the design curve.
    ``allow_mirror=False`` refuses the mirror image (the part lies as it left the
    machine): a design symmetric end to end is then matched vertex for vertex.
    """
    seen = np.asarray(centreline_mm, dtype=np.float64) * np.array([1.0, -1.0])
    n = result.divisions
    # with N chords the shape meant is the design divided into N equal chords
    verts = design.chords(n) if n else design.points_mm
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
        (:func:`shadow_unusable`; its 2 sigma then carried as a bound, in any direction,
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
    if net_turn_deg(centreline_mm) < 0:  # run so that the part turns counter-clockwise
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
    warnings: list[StageWarning] = []
    if wire_diameter_mm is not None and centre.centre_from != "silhouette":
        warnings.append(
            StageWarning(
                "round_wire_edges_lost",
                "the wire's silhouette edges were not found along the whole wire, so the "
                "centreline is the profiles' centre of symmetry, which a side-lit highlight or "
                "a shadow can pull off the axis; the lift was not bounded",
            )
        )
    base_mm = axis_height_for(axis_height_mm, wire_diameter_mm)
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
    divisions_from = "--divisions" if divisions is not None else None
    if divisions is None and chords.divisions is not None:
        divisions, divisions_from = chords.divisions, "photo"
    elif divisions is not None and chords.divisions not in (None, divisions):
        warnings.append(
            StageWarning(
                "divisions_mismatch",
                f"--divisions {divisions}, but the photo shows {chords.divisions} chords "
                f"({chords.reason}); measured with {divisions}",
            )
        )
    elif divisions is not None and chords.divisions is None:
        warnings.append(
            StageWarning(
                "divisions_not_found",
                f"--divisions {divisions}, but no chord vertices were found in the photo "
                f"({chords.reason})",
            )
        )
    flat_mm = centreline_mm
    try:
        ours, circle, poly = arc_from_points(centreline_mm, divisions)
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
        moved_info, corrected, moved_warning = moved_lift(
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
            refusal = shadow_unusable(shadow.lift, bound_mm)
            if refusal is not None:
                shadow_info["message"] = (
                    f"the shadow puts the lift at {shadow.lift.lift_mm:.2f} +- "
                    f"{shadow.lift.lift_sigma_mm:.2f} mm: {refusal.message}"
                )
            else:  # corrected; wider than SHADOW_MAX_2SIGMA_MM, its sigma carried as a bound
                corrected = shadow
                uncertain = 2.0 * shadow.lift.lift_sigma_mm > SHADOW_MAX_2SIGMA_MM
                scale = shadow_lift_scale(shadow.lift, bound_mm)
    if corrected is not None:
        flat = (ours, poly)
        measured = corrected.lift

        def lifted_mm(points_px: np.ndarray) -> np.ndarray:
            return lifted_points_mm(plane, points_px, base_mm, measured, scale)

        centreline_mm = lifted_mm(centre.points_px)
        try:
            ours, circle, poly = arc_from_points(centreline_mm, divisions)
        except ValueError as exc:
            raise InputError(source, f"cannot fit the part ({exc})") from None
        vpoly = profile_vertices(image, centre, lifted_mm, poly)
        if vpoly is None:  # no silhouette edges' profile fit: the edges' centres
            vpoly = poly
            if scale * corrected.lift.lift_mm >= LIT_MIN_LIFT_MM:
                vpoly = vertex_polyline(centre.lit_points_px, lifted_mm, divisions, poly)
        bend_sigma = None if vpoly is None else np.asarray(vpoly.bend_sigma_deg, dtype=float)
        lift_info, extra_sigma, _ = lift_effects(
            plane, centre.points_px, flat_mm, None, flat[0], flat[1], divisions, base_mm,
            2.0 * corrected.lift.lift_sigma_mm, standard=not uncertain,
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
                StageWarning(
                    "part_lifted",
                    f"the {'shadow' if by_shadow else 'two photos'} put the lift "
                    f"at {corrected.lift.lift_mm:.2f} +- "
                    f"{corrected.lift.lift_sigma_mm:.2f} mm ({corrected_as}); its uncertainty (2 "
                    f"sigma) would move the radius by up to {lift_info['effect_radius_pct']:.2f} %"
                    f", the bend per chord by up to {lift_info['effect_segment_bend_deg']:.3f} deg "
                    f"and a vertex bend by up to {lift_info['effect_bend_deg']:.3f} deg",
                )
            )
    else:  # measured on the plate (a lift, if any, bounded below), not re-fitted lifted
        # a round wire's vertex bends from each chord's whole cross-profile (part14s)
        vpoly = profile_vertices(
            image, centre, lambda q: plane.image_to_plane_mm(q, height_mm=base_mm), poly
        )
        vpoly = poly if vpoly is None else vpoly
        bend_sigma = None if vpoly is None else np.asarray(vpoly.bend_sigma_deg, dtype=float)
    if wire_diameter_mm is not None and lift_info is None:
        # a round wire on the plate may rock: its lift is bounded (the width's estimate
        # where it is good enough, else the largest lift a part rocks to)
        lift_info, extra_sigma, lift_warning = lift_effects(
            plane, centre.points_px, centreline_mm, lift, ours, poly, divisions, base_mm,
            max_lift_mm,
        )  # fmt: skip
        if bend_sigma is not None and extra_sigma is not None:
            bend_sigma = np.hypot(bend_sigma, extra_sigma)
        if refusal is not None and (lift_warning or refusal.inconsistent):
            # a shadow read but not used: the bound's warning says why (one inconsistent
            # with the bound is warned about whatever the bound's effect: an edge misread)
            lift_warning = StageWarning(
                "part_lifted",
                (lift_warning.message if lift_warning else "the part may not lie flat")
                + f"; the cast shadow was not used: {shadow_info['message']}",
            )
        if lift_warning:
            warnings.append(lift_warning)
        if moved_info is not None:
            lift_info = {**lift_info, "moved": moved_info}
        if shadow_info is not None:
            lift_info = {**lift_info, "shadow": shadow_info}
    if poly is not None and bend_sigma is not None and divisions and divisions > 1:
        bend_sigma, gap_warning = widen_for_centreline_gaps(
            centreline_mm, poly, bend_sigma, 2.0 * centre.half_width_px * plane.mm_per_px
        )
        if gap_warning:
            warnings.append(gap_warning)
    arc_warning = arc_consistency_warning(ours, poly, vpoly, bend_sigma)
    if arc_warning:
        warnings.append(arc_warning)
    methods: dict[str, ArcResult] = {"ours": ours}
    seed_arcs: dict[str, SeedArc] = {}
    outline = outline_mm(image, wire, plane)
    for name, fn in (("ellipse", ellipse_method), ("sagitta", sagitta_method)):
        try:
            arc = fn(outline)
        except ValueError as exc:
            warnings.append(
                StageWarning("seed_method_failed", f"the seed's {name} method failed: {exc}")
            )
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
                StageWarning(
                    "seed_method_disagrees",
                    f"the seed's {name} method gives an arc of {arc.arc_angle_deg:.1f} deg where "
                    f"the centreline spans {ours.arc_angle_deg:.1f} deg: its figures do not "
                    "describe this part",
                )
            )
    shape = part_shape(poly)
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
    if not plane.affine_ok:
        warnings.append(
            StageWarning(
                "plane_tilted",
                f"the board plane is tilted {plane.tilt_deg:.2f} deg (corrected by the homography)",
            )
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
