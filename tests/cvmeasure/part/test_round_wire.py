"""A round wire lit from the side, ray-traced (tests/cvmeasure/part/round_wire.py): silhouette
centreline, the lift read from the apparent width, and a lifted part never silently wrong."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.errors import InputError
from cvmeasure.part.centreline import measure_centreline
from cvmeasure.part.lift import expected_width_px, points_at_heights_mm
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
from cvmeasure.part.segment import gray_float, segment_wire
from cvmeasure.warning import codes, has_code
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.round_wire import render_round_wire

SCALE = 0.5  # 2304 x 1536 px, 0.157 mm/px at 550 mm: a 3 mm wire is 19 px wide
POSE = Pose(tilt_deg=2.0, tilt_direction_deg=30.0, distance_mm=550.0, offset_mm=(-60.0, 20.0))
WIRE_MM = 3.0


@functools.lru_cache(maxsize=4)
def _photo(sheet: str, lift_mm: float):
    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    part = cvmeasure_datasets.arc_part(50.0, 120.0, 8, wire_diameter_mm=WIRE_MM)
    verts = part.placed(20.0, (0.0, 0.0))
    return render_round_wire(
        verts, camera=camera, pose=POSE, lift_mm=lift_mm, lift_direction_deg=20.0, sheet=sheet
    )


def _offsets_px(photo, points_px: np.ndarray) -> np.ndarray:
    """Distance (px) of each point from the true axis projected into the photo."""
    from scipy.spatial import cKDTree

    rot, t_mm = POSE.extrinsics("board")
    v = photo.vertices_mm
    dense = np.vstack([np.linspace(a, b, 400) for a, b in zip(v[:-1], v[1:], strict=True)])
    axis_px = photo.plane.camera.project(dense @ rot.T + t_mm)
    return cKDTree(axis_px).query(points_px)[0]


def _measured_on_true_plane(photo, divisions: int):
    """``measure_part`` of a lab photo on its true plane, the stated wire, the given count."""
    return measure_part(
        photo.bgr,
        None,
        None,
        plane=photo.plane,
        options=PartOptions(divisions=divisions, wire=WireOptions(diameter_mm=WIRE_MM)),
    )


@pytest.mark.parametrize("sheet", ["light", "dark"])
def test_silhouette_centres_follow_the_axis_not_the_side_lit_highlight(sheet):
    photo = _photo(sheet, 0.0)
    mm_per_px = POSE.distance_mm / photo.plane.camera.fx
    wire = segment_wire(photo.bgr, max_wire_width_px=7 / mm_per_px, min_length_px=15 / mm_per_px)
    gray = gray_float(photo.bgr)
    sym = measure_centreline(gray, wire.path_px, width_guess_px=wire.width_px)
    width_px = WIRE_MM / mm_per_px * POSE.distance_mm / (POSE.distance_mm - WIRE_MM / 2)
    sil = measure_centreline(
        gray, wire.path_px, width_guess_px=wire.width_px, wire_width_px=width_px
    )
    assert sil.centre_from == "silhouette"
    off_sym = _offsets_px(photo, sym.points_px[5:-5])
    off_sil = _offsets_px(photo, sil.points_px[5:-5])
    # the symmetric centre follows the highlight on the lit flank (measured 1.4 px median)
    assert np.median(off_sym) > 1.0
    # between the silhouette edges: 0.14 (light) / 0.22 (dark) px median measured
    assert np.median(off_sil) < 0.3
    assert np.percentile(off_sil, 90) < 0.6
    # the edges' distance is the wire's apparent width within the edges' shading bias
    assert abs(np.nanmedian(sil.edge_width_px) / width_px - 1.0) < 0.05


def test_points_at_their_own_heights_are_the_ray_plane_intersections():
    plane = _photo("light", 0.0).plane
    rng = np.random.default_rng(3)
    px = rng.uniform((200, 200), (2000, 1300), size=(50, 2))
    heights = rng.uniform(0.0, 6.0, 50)
    got = points_at_heights_mm(plane, px, heights)
    for p, h, g in zip(px, heights, got, strict=True):
        np.testing.assert_allclose(g, plane.image_to_plane_mm(p[None], height_mm=h)[0], atol=1e-9)


def test_expected_width_grows_as_the_wire_nears_the_camera():
    plane = _photo("light", 0.0).plane
    pts = np.column_stack((np.linspace(-20, 20, 41), np.zeros(41)))
    w0 = expected_width_px(plane, pts, 1.5, WIRE_MM)
    w3 = expected_width_px(plane, pts, 4.5, WIRE_MM)
    # width ~ f d / D: 3 mm nearer at about 550 mm is 0.55 % wider
    np.testing.assert_allclose(w3 / w0 - 1.0, 3.0 / (550.0 - 4.5), rtol=0.05)
    np.testing.assert_allclose(w0, WIRE_MM * plane.camera.fx / (550.0 - 1.5), rtol=0.02)


@pytest.mark.parametrize(("sheet", "lift_mm"), [("light", 3.0), ("dark", 3.0)])
def test_a_lifted_part_is_refused_warned_about_or_right(sheet, lift_mm):
    photo = _photo(sheet, lift_mm)
    try:
        m = measure_part(
            photo.bgr,
            None,
            None,
            plane=photo.plane,
            options=PartOptions(
                divisions=8, wire=WireOptions(diameter_mm=WIRE_MM), lift=LiftOptions(shadow=False)
            ),
        )
    except InputError:
        return  # a clear refusal
    radius_err_pct = abs(100.0 * (m.result.radius_mm / 50.0 - 1.0))
    bend_err = float(np.max(np.abs(np.abs(m.vertex_bend_deg) - 15.0)))
    warned = has_code(m.warnings, "part_lifted")
    assert m.lift is not None and m.lift.used == "bound"
    assert warned or (radius_err_pct <= 0.3 and bend_err <= 0.03), (m.warnings, radius_err_pct)


def test_the_lift_is_recovered_from_exact_widths():
    """The estimator's geometry alone: widths of a rigidly tilted part, as the camera sees them."""
    from cvmeasure.part.lift import estimate_lift
    from cvmeasure_datasets.round_wire import lifted_vertices

    plane = _photo("light", 0.0).plane
    theta = np.radians(np.linspace(-165.0, -15.0, 300))
    plate = 60.0 * np.column_stack((np.cos(theta), np.sin(theta)))
    axis = lifted_vertices(plate, WIRE_MM / 2, 2.0, 30.0)  # 2 mm lift along 30 deg
    rot, t_mm = POSE.extrinsics("board")
    px = plane.camera.project(axis @ rot.T + t_mm)
    heights = -axis[:, 2]
    seen = points_at_heights_mm(plane, px, heights)
    widths = expected_width_px(plane, seen, heights, WIRE_MM) * 1.02  # a 2 % edge bias
    lift = estimate_lift(plane, px, widths, wire_diameter_mm=WIRE_MM, axis_height_mm=WIRE_MM / 2)
    assert lift is not None
    assert abs(lift.lift_mm - (heights.max() - heights.min())) < 0.05
    np.testing.assert_allclose(lift.height_mm, heights - heights.min(), atol=0.05)
    assert abs(lift.width_scale - 1.02) < 0.002


@pytest.mark.parametrize("lift_mm", [0.0, 2.0])
def test_the_photo_labs_round_wire_is_never_silently_wrong(lift_mm):
    """rend14's 3D part (its own ray tracer): refused, warned about, or within the targets."""
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure_datasets.effects import SceneEffects

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    part = cvmeasure_datasets.arc_part(62.0, 120.0, 8, wire_diameter_mm=WIRE_MM)
    photo = cvmeasure_datasets.render_part_photo(
        part=part,
        board=board,
        sheet="dark",
        seed=1700,
        scale=0.5,
        pose=Pose(
            tilt_deg=2.0, tilt_direction_deg=40.0, distance_mm=900.0, offset_mm=(270.0, 75.0)
        ),
        effects=SceneEffects(wire_3d=True, part_lift_mm=lift_mm),
    )
    try:
        m = measure_part(
            photo.bgr,
            board,
            photo.camera,
            options=PartOptions(divisions=8, wire=WireOptions(diameter_mm=WIRE_MM)),
        )
    except InputError:
        return
    radius_err_pct = abs(100.0 * (m.result.radius_mm / photo.truth["radius_mm"] - 1.0))
    bend_err = abs(float(m.result.segment_bend_deg) - 15.0)
    named = codes(m.warnings) & {"part_lifted", "round_wire_edges_lost"}
    assert named or (radius_err_pct <= 0.3 and bend_err <= 0.03), (m.warnings, radius_err_pct)


def test_the_photo_labs_round_wire_is_followed_between_its_silhouette_edges():
    """rend14's 3D wire at quarter size (3 mm = 6 px, blurred edges, a broad flat
    highlight crest): the centreline is taken between the silhouette edges, not at the
    symmetric centre the highlight pulls (measured: bend error 0.02 vs 0.52 deg)."""
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure_datasets.effects import SceneEffects

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    part = cvmeasure_datasets.arc_part(62.0, 120.0, 8, wire_diameter_mm=WIRE_MM)
    photo = cvmeasure_datasets.render_part_photo(
        part=part,
        board=board,
        sheet="dark",
        seed=1700,
        scale=0.25,
        pose=Pose(
            tilt_deg=2.0, tilt_direction_deg=40.0, distance_mm=900.0, offset_mm=(270.0, 75.0)
        ),
        effects=SceneEffects(wire_3d=True),
    )
    m = measure_part(
        photo.bgr,
        board,
        photo.camera,
        options=PartOptions(divisions=8, wire=WireOptions(diameter_mm=WIRE_MM)),
    )
    assert not has_code(m.warnings, "round_wire_edges_lost"), m.warnings
    # 0.51 mm/px: measured radius 0.20 %, bend 0.021 deg (the symmetric centre: 0.52 deg)
    assert abs(m.result.radius_mm / photo.truth["radius_mm"] - 1.0) < 0.003
    assert abs(float(m.result.segment_bend_deg) - 15.0) < 0.05


def test_a_side_lit_lab_wire_on_the_light_sheet_is_measured_to_its_caps():
    """rend14's 3D wire on the light sheet at half size (3 mm = 11.5 px): a dark wire with a
    soft shadow ramp joined to one side and side-lit caps. Measured: radius 0.030 %, bend
    per chord 0.0095 deg, ends 0.038 / 0.046 mm from the axis' true ends (before the caps'
    silhouettes were used: 0.040 deg, ends 0.8 / 1.3 mm; at full size such photos were
    refused, no silhouette edges found)."""
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure_datasets.effects import SceneEffects

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    bw, bh = board.size_mm
    part = cvmeasure_datasets.arc_part(77.0, 90.0, 8, wire_diameter_mm=WIRE_MM)
    photo = cvmeasure_datasets.render_part_photo(
        part=part,
        board=board,
        sheet="light",
        seed=1701,
        scale=0.5,
        pose=Pose(
            tilt_deg=3.0,
            tilt_direction_deg=195.0,
            distance_mm=900.0,
            offset_mm=((bw + 10.0 + 250.0 - 20.0) / 2 + 10.0, bh / 2),
        ),
        effects=SceneEffects(wire_3d=True),
    )
    m = measure_part(
        photo.bgr,
        board,
        photo.camera,
        options=PartOptions(divisions=8, wire=WireOptions(diameter_mm=WIRE_MM)),
    )
    assert m.wire.centre_from == "silhouette"
    # the targets of issue 14: radius within 0.3 %, bend per chord within 0.03 deg
    assert abs(m.result.radius_mm / photo.truth["radius_mm"] - 1.0) < 0.003
    assert abs(float(m.result.segment_bend_deg) - 90.0 / 8) < 0.03
    # the end points: the caps' centres (the axis' ends) within 0.15 mm
    ends = np.asarray(photo.truth["part"]["centreline_3d_mm"])[[0, -1], :2]
    for end in m.centreline_mm[[0, -1]]:
        assert np.min(np.hypot(*(ends - end).T)) < 0.15


def test_an_end_facing_its_shadow_on_a_light_plate_is_found_at_its_cap():
    """A lifted part's shadow reaches beyond the cap that faces away from the light (light
    sheet, light from azimuth 0) and its far edge steps as strongly as the cap's outline. The
    stretch between the two is darker than the wire's body (the plate in the ambient light
    only), so the cap is the step inside it. Measured: that end 0.25 px from the true axis end
    (taking the outermost strong step: 6.8 px beyond it), the other 0.28 px."""
    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    part = cvmeasure_datasets.arc_part(50.0, 120.0, 8, wire_diameter_mm=WIRE_MM)
    photo = render_round_wire(
        part.placed(20.0, (0.0, 0.0)), camera=camera, pose=POSE, lift_mm=1.5,
        lift_direction_deg=20.0, sheet="light", light_azimuth_deg=0.0, light_elev_deg=50.0,
    )  # fmt: skip
    m = _measured_on_true_plane(photo, divisions=8)
    rot, t_mm = POSE.extrinsics("board")
    true_ends_px = photo.plane.camera.project(photo.vertices_mm[[0, -1]] @ rot.T + t_mm)
    for end in m.centreline_px[[0, -1]]:
        assert float(np.min(np.hypot(*(true_ends_px - end).T))) < 1.0
    assert not has_code(m.warnings, "part_end_uncertain"), m.warnings


def test_a_chord_whose_shadow_joins_its_silhouette_keeps_its_centres():
    """A development part (light sheet, lamp at 55 deg elevation; not the benchmark's seeds):
    along the chord running 28 deg from the light's azimuth (its shadow almost under it) no
    clean edge pair is found. Where pairs cover most of the wire the gaps were left open and
    that chord had no centre: its line came from the centres at the gap's ends, the bends at
    its vertices 0.29 and 0.31 deg off (4-5 sigma) with no warning. Gaps as long as three
    widths are now filled by one edge: measured every vertex within 0.074 deg."""
    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    part = cvmeasure_datasets.arc_part(60.68332962534025, 120.0, 10, wire_diameter_mm=WIRE_MM)
    pose = Pose(
        tilt_deg=0.4108767137116258, tilt_direction_deg=134.80330300438374, distance_mm=550.0,
        offset_mm=(46.079114818845596, 14.475134270695456),
    )  # fmt: skip
    photo = render_round_wire(
        part.placed(301.94041691724664, (0.0, 0.0)), camera=camera, pose=pose, sheet="light",
        lift_direction_deg=301.94041691724664, light_azimuth_deg=348.2205802124632,
        light_elev_deg=54.97370483416649, seed=9103,
    )  # fmt: skip
    m = _measured_on_true_plane(photo, divisions=10)
    err = np.asarray(m.vertex_bend_deg) - 12.0
    assert np.max(np.abs(err)) < 0.12, err
    assert not has_code(m.warnings, "part_centreline_gap"), m.warnings


def test_an_end_whose_cap_meets_its_shadow_without_a_step_is_stated_uncertain():
    """A development part (R46 120 deg N6, light sheet, lamp at 61 deg elevation from
    azimuth 202, lifted 1.5 mm; not the benchmark's seeds): at the end facing away from the
    light the cap's dark limb meets the cast shadow at about the shadow's own level, with no
    rising step between them, so the only step out of the dark is the shadow's far edge. The
    end point is taken there, 9.3 px (1.5 mm) beyond the true axis end: +0.16 deg per chord.
    Before, that end said nothing (uncertainty 0, no warning). The stretch inside the taken
    step is as dark as cast shadow over more than a half-width (a cap's own dark limb lies
    within one): its length is the end's uncertainty (15.6 px) and the part is warned."""
    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    part = cvmeasure_datasets.arc_part(46.295, 120.0, 6, wire_diameter_mm=WIRE_MM)
    pose = Pose(
        tilt_deg=1.765, tilt_direction_deg=348.0, distance_mm=550.0, offset_mm=(-40.55, 6.83)
    )
    photo = render_round_wire(
        part.placed(337.71, (0.0, 0.0)), camera=camera, pose=pose, lift_mm=1.5,
        lift_direction_deg=337.71, sheet="light", light_azimuth_deg=201.93,
        light_elev_deg=61.40, seed=9101,
    )  # fmt: skip
    m = _measured_on_true_plane(photo, divisions=6)
    rot, t_mm = pose.extrinsics("board")
    true_ends_px = photo.plane.camera.project(photo.vertices_mm[[0, -1]] @ rot.T + t_mm)
    off = [float(np.min(np.hypot(*(true_ends_px - e).T))) for e in m.centreline_px[[0, -1]]]
    u = np.asarray(m.wire.end_uncertainty_px)
    assert max(off) > 5.0, off  # the end is still taken at the shadow's edge: stated, not fixed
    # each end's stated uncertainty covers its distance from the truth
    assert np.all(np.asarray(off) <= u + 1.0), (off, u)
    assert has_code(m.warnings, "part_end_uncertain"), m.warnings


@pytest.mark.parametrize("noise", [0.0, 1.5])
def test_a_dark_sheets_vertex_bends_are_off_by_the_noise_not_by_the_shading(noise):
    """A development part (dark sheet, lamp at 61 deg elevation, lying flat; the geometry of
    ``benchmarks.parts._round_cases(6, 9102)[4]`` with another render seed: not the
    benchmark's). The edge midpoints sit off the axis by an amount that changes from chord to
    chord (a parallel shift: no bend turns); what the shading leaves in the bends is small:
    without noise every vertex within 0.020 deg measured. With the renderer's noise (1.5
    grey levels) 0.062 deg, within 1.5 stated sigma: the stated sigma (the centres' scatter
    about each chord's line) carries it (docs/part-measurement.md)."""
    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    part = cvmeasure_datasets.arc_part(48.04144415576658, 90.0, 6, wire_diameter_mm=WIRE_MM)
    pose = Pose(
        tilt_deg=2.3048734346727957, tilt_direction_deg=247.1602727148274, distance_mm=550.0,
        offset_mm=(44.297707893477224, 1.8459737807449415),
    )  # fmt: skip
    photo = render_round_wire(
        part.placed(266.4285730641856, (0.0, 0.0)), camera=camera, pose=pose, sheet="dark",
        light_azimuth_deg=45.64317745039895, light_elev_deg=60.54944243400179, seed=9105,
        noise=noise,
    )  # fmt: skip
    m = measure_part(
        photo.bgr,
        None,
        None,
        plane=photo.plane,
        options=PartOptions(
            divisions=6, wire=WireOptions(diameter_mm=WIRE_MM), lift=LiftOptions(max_lift_mm=0.0)
        ),
    )
    err = np.asarray(m.vertex_bend_deg) - 15.0
    if noise == 0.0:
        assert np.max(np.abs(err)) < 0.03, err
    assert np.max(np.abs(err) / np.asarray(m.vertex_bend_sigma_deg)) < 2.5, err


def test_a_cap_ringed_by_its_dark_limb_is_measured_to_its_outline():
    """On a mid-tone sheet the lit steel's crest is lighter and its rim darker than the
    plate: along the axis the cap falls from its crest into a dark limb, then rises to the
    plate at its outline. The fall is the strongest step but lies inside the cap; the end
    is the rise out of the limb (before: the cap's centre read 4.1 px short, 0.65 mm)."""
    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    part = cvmeasure_datasets.arc_part(50.0, 120.0, 8, wire_diameter_mm=WIRE_MM)
    photo = render_round_wire(
        part.placed(20.0, (0.0, 0.0)), camera=camera, pose=POSE, sheet="grey",
        light_azimuth_deg=30.0, light_elev_deg=50.0,
    )  # fmt: skip
    mm_per_px = POSE.distance_mm / camera.fx
    wire = segment_wire(photo.bgr, max_wire_width_px=7 / mm_per_px, min_length_px=15 / mm_per_px)
    width_px = WIRE_MM / mm_per_px * POSE.distance_mm / (POSE.distance_mm - WIRE_MM / 2)
    c = measure_centreline(
        gray_float(photo.bgr), wire.path_px, width_guess_px=wire.width_px, wire_width_px=width_px
    )
    assert c.centre_from == "silhouette"
    rot, t_mm = POSE.extrinsics("board")
    v = photo.vertices_mm
    end, inner = camera.project(v[[-1, -2]] @ rot.T + t_mm)  # the end lit from behind
    out = (end - inner) / np.hypot(*(end - inner))
    got = c.ends_px[int(np.argmin(np.hypot(*(c.ends_px - end).T)))]
    # along the axis: measured 0.23 px (a 19 px wide wire); across it the end lies on the
    # line through the last centres, extrapolated (2.8 px off here): not asserted
    assert abs(float((got - end) @ out)) < 1.0


@pytest.mark.parametrize("beyond_hw", [1.2, 1.6])
def test_a_fleck_on_the_light_sheet_beyond_a_cap_is_not_its_outline(beyond_hw):
    """A lab part (R45 125 deg N7, 3 mm wire, light sheet) with a narrow dark fleck across the
    axis on the sheet 1.2 or 1.6 half-widths beyond each cap's outline, as a grainy white
    sheet has: the fleck's far side rises to the plate as strongly as the cap's outline and
    lies within two half-widths of it. Taken for the outline it put one end 12.9 / 16.9 px
    (2.2 / 2.9 mm) out and the radius 0.54 / 0.78 % and the bend per chord 0.28 / 0.35 deg
    off with only part_lifted (whose stated effect is smaller); a step with bare plate
    inside it is not the outline. Measured: ends 0.26 / 0.05 px from the true axis ends,
    radius 0.13 %, bend per chord 0.023 deg."""
    import cv2

    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    pose = Pose(tilt_deg=2.0, tilt_direction_deg=30.0, distance_mm=550.0, offset_mm=(-60.0, 20.0))
    part = cvmeasure_datasets.arc_part(45.0, 125.0, 7, wire_diameter_mm=WIRE_MM)
    photo = render_round_wire(
        part.placed(200.0, (0.0, 0.0)), camera=camera, pose=pose, sheet="light",
        light_azimuth_deg=10.0, seed=1,
    )  # fmt: skip
    rot, t_mm = pose.extrinsics("board")
    ends_px = camera.project(photo.vertices_mm @ rot.T + t_mm)
    hw_px = 0.5 * WIRE_MM * camera.fx / pose.distance_mm
    fleck = np.zeros(photo.bgr.shape[:2], np.float32)
    for end, inner in ((ends_px[0], ends_px[1]), (ends_px[-1], ends_px[-2])):
        out = (end - inner) / np.linalg.norm(end - inner)
        across = np.array([-out[1], out[0]])
        c = end + (1.0 + beyond_hw) * hw_px * out
        a, b = (np.round(16 * (c + s * 0.6 * hw_px * across)).astype(int) for s in (-1, 1))
        cv2.line(fleck, tuple(a), tuple(b), 1.0, 2, cv2.LINE_AA, 4)
    fleck = cv2.GaussianBlur(fleck, (0, 0), 0.7)
    bgr = np.clip(photo.bgr - 40.0 * (fleck / fleck.max())[..., None], 0, 255).astype(np.uint8)
    m = measure_part(
        bgr,
        None,
        None,
        plane=photo.plane,
        options=PartOptions(
            divisions=7, wire=WireOptions(diameter_mm=WIRE_MM), lift=LiftOptions(shadow=False)
        ),
    )
    for end in m.centreline_px[[0, -1]]:
        assert float(np.min(np.hypot(*(ends_px[[0, -1]] - end).T))) < 1.0
    assert abs(m.result.radius_mm / 45.0 - 1.0) < 0.003
    assert abs(float(m.result.segment_bend_deg) - 125.0 / 7) < 0.03


def test_a_grey_sheets_centreline_pulled_by_the_shadow_gives_no_false_chord_count():
    """The photo lab's grey sheet at 0.28 mm/px (3 mm wire, lamp at 22 deg): the wire's
    edges are lost and the centre of symmetry runs along the wire's shadow side, stepping
    1.8 mm across the wire where the shadow leaves it. Vertex by vertex that step and
    drift read as 4 chords of 8 (bends 7.7-20.6 deg, RMS 0.155 mm about them against the
    centreline's noise of 0.025 mm) and the bend per chord came out 15.6 deg for 7.6
    (+8.0 deg) with no warning on it. The chord count found must be the wire's, or none."""
    radius_mm, arc_deg, n = 77.25058611414653, 61.185581930981265, 8
    camera = cvmeasure_datasets.default_camera().scaled(0.28)
    part = cvmeasure_datasets.arc_part(radius_mm, arc_deg, n, wire_diameter_mm=WIRE_MM)
    photo = render_round_wire(
        part.placed(34.769890854444014, (0.0, 0.0)), camera=camera,
        pose=Pose(tilt_deg=1.0, tilt_direction_deg=30.0, distance_mm=550.0, offset_mm=(0.0, 0.0)),
        sheet="grey", light_azimuth_deg=198.51711274050695, light_elev_deg=22.0,
        wire_diameter_mm=WIRE_MM, seed=7,
    )  # fmt: skip
    try:
        m = measure_part(
            photo.bgr, None, None, plane=photo.plane,
            options=PartOptions(wire=WireOptions(diameter_mm=WIRE_MM)),
        )  # fmt: skip
    except InputError:
        return  # a clear refusal
    if m.result.divisions is None:
        assert m.result.segment_bend_deg is None
        assert has_code(m.warnings, "part_chords_not_found"), m.warnings
        return
    assert m.result.divisions == n, m.warnings
    assert abs(m.result.segment_bend_deg - arc_deg / n) < 0.1


def test_the_vertices_are_drawn_where_the_photo_shows_the_axis():
    """``vertices_px`` are the vertices at the wire axis' height (the height the centreline was
    mapped at), not on the plate: 1.5 mm nearer the camera moves them by about height /
    distance of their offset from the camera's foot point (0.9 px here)."""
    photo = _photo("dark", 0.0)
    m = _measured_on_true_plane(photo, divisions=8)
    back = photo.plane.image_to_plane_mm(m.vertices_px, height_mm=WIRE_MM / 2)
    np.testing.assert_allclose(back, m.vertices_mm, atol=1e-6)
    rot, t_mm = POSE.extrinsics("board")
    true_px = photo.plane.camera.project(np.asarray(photo.vertices_mm) @ rot.T + t_mm)
    off = np.linalg.norm(m.vertices_px[:, None] - true_px[None], axis=2).min(axis=1)
    # measured 0.56 px median (the vertices' own error); drawn on the plate: 0.92 px
    assert np.median(off) < 0.7
