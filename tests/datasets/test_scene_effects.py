"""Real-scene effects of the photo lab: discs at their heights, a round shiny wire,
camera blur, Bayer, clutter and occlusion, each checked against the render's truth."""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from cvmeasure.kit import default_kit
from cvmeasure_datasets import Lighting, Pose, arc_part, render_bender_photo, render_part_photo
from cvmeasure_datasets.blur import defocus_diameter_px, depth_of_field, motion_kernel
from cvmeasure_datasets.checks import check_disc_centre
from cvmeasure_datasets.effects import EFFECT_NAMES, SceneEffects
from cvmeasure_datasets.parts import lifted_centreline

ROLES = ("origin", "axis", "pin", "wire_a", "wire_b")
TILTED = Pose(tilt_deg=25.0, tilt_direction_deg=200.0, yaw_deg=15.0, distance_mm=550.0)


def test_no_effects_is_the_flat_scene_bit_for_bit():
    kw = dict(pin_angle_deg=30.0, bend_angle_deg=25.0, scale=0.125, seed=5)
    flat = render_bender_photo(**kw)
    same = render_bender_photo(effects=SceneEffects(), **kw)
    assert np.array_equal(flat.bgr, same.bgr)
    assert SceneEffects().flat and not SceneEffects(bayer=True).flat
    assert SceneEffects.only("clutter").names_on() == ["clutter"]
    assert SceneEffects.all_on().names_on() == [
        n for n in EFFECT_NAMES if n not in ("wire_across", "tool_shadow")
    ]
    with pytest.raises(ValueError):
        SceneEffects.only("fog")


def _projected_edge_centre(photo, role: str, radius_mm: float) -> np.ndarray:
    """Centre of an ellipse fitted to the disc's 3D edge put through cv2.projectPoints."""
    m = photo.truth["markers"][role]
    phi = np.linspace(0.0, 2 * np.pi, 720, endpoint=False)
    edge = np.column_stack(
        (
            m["x_mm"] + radius_mm * np.cos(phi),
            m["y_mm"] + radius_mm * np.sin(phi),
            np.full(phi.shape, m["height_mm"]),
        )
    )
    pose = photo.truth["pose"]
    cam = photo.camera
    px, _ = cv2.projectPoints(
        edge, np.array(pose["rvec"]), np.array(pose["tvec_mm"]), cam.camera_matrix, cam.dist_coeffs
    )
    (cx, cy), _, _ = cv2.fitEllipse(px.reshape(-1, 2).astype(np.float32))
    return np.array([cx, cy])


def test_discs_appear_where_their_3d_edge_projects():
    """Each disc, at its kit height, is where cv2.projectPoints puts its 3D edge (< 0.05 px);
    on the plate it would be pixels away."""
    kit = default_kit()
    kw = dict(
        pin_angle_deg=-100.0,
        bend_angle_deg=40.0,
        pose=TILTED,
        lighting=Lighting.clean(blur_px=0.0),
        scale=0.25,
        linear=True,
    )
    photo = render_bender_photo(effects=SceneEffects(marker_heights=True), **kw)
    flat = render_bender_photo(**kw)
    for role in ROLES:
        m = photo.truth["markers"][role]
        assert m["height_mm"] == kit.height_mm(role)
        assert m["centre_3d_mm"] == [m["x_mm"], m["y_mm"], kit.height_mm(role)]
        fitted = np.array(check_disc_centre(photo, role).fitted_centre_px)
        projected = _projected_edge_centre(photo, role, kit.by_role(role).diameter_mm / 2)
        assert np.hypot(*(fitted - projected)) < 0.05, role
        moved = np.hypot(*np.subtract(m["centre_px"], flat.truth["markers"][role]["centre_px"]))
        assert moved > 1.0, role  # the height really moves the disc in this photo
    # plate-plane angles: unchanged by the heights (centres projected along the normal)
    assert photo.truth["pin_angle_deg"] == pytest.approx(flat.truth["pin_angle_deg"], abs=1e-12)
    assert photo.truth["bend_angle_deg"] == pytest.approx(flat.truth["bend_angle_deg"], abs=1e-12)


def test_supports_show_beside_the_ring_off_axis():
    """A printed support under a tall disc shows beside its ring on the side facing the
    image centre (its top, nearer the camera, is magnified outwards); the disc hides the rest."""
    kw = dict(
        pin_angle_deg=60.0,
        bend_angle_deg=20.0,
        pose=Pose(distance_mm=550.0, offset_mm=(60.0, 60.0)),
        lighting=replace(Lighting.clean(), shadow_strength=0.0),
        scale=0.25,
    )
    without = render_bender_photo(effects=SceneEffects(marker_heights=True), **kw)
    with_ = render_bender_photo(effects=SceneEffects(marker_heights=True, supports=True), **kw)
    changed = np.abs(with_.bgr.astype(int) - without.bgr.astype(int)).max(axis=2) > 20
    m = with_.truth["markers"]["pin"]
    cx, cy = m["centre_px"]
    yy, xx = np.mgrid[0 : changed.shape[0], 0 : changed.shape[1]]
    r = np.hypot(xx - cx, yy - cy)
    assert not changed[r < m["ring_r_px"] - 1.0].any()  # the disc and ring on top
    near = changed & (r < m["ring_r_px"] * 1.6)
    for role, other in with_.truth["markers"].items():  # not the neighbours' supports
        if role != "pin":
            ox, oy = other["centre_px"]
            near &= np.hypot(xx - ox, yy - oy) > other["ring_r_px"] * 1.6
    assert near.sum() > 10
    # the visible side faces the principal point
    pp = np.array(with_.camera.principal_point_px)
    side = np.array([xx[near].mean() - cx, yy[near].mean() - cy])
    outwards = np.array([cx, cy]) - pp
    assert side @ outwards / np.linalg.norm(side) / np.linalg.norm(outwards) < -0.9


def _wire_profile(photo, x_mm: float):
    """Green channel across the straight infeed at machine x = x_mm, and the axis' pixel row."""
    geo = photo.truth["geometry"]
    y_axis = geo["wire_centreline_3d_mm"][0][1]
    z = geo["wire_axis_height_mm"]
    pose = photo.truth["pose"]
    cam = photo.camera
    pts = np.array([[x_mm, y_axis, z], [x_mm, y_axis + 1.0, z]])
    px, _ = cv2.projectPoints(
        pts, np.array(pose["rvec"]), np.array(pose["tvec_mm"]), cam.camera_matrix, cam.dist_coeffs
    )
    px = px.reshape(-1, 2)
    col = int(round(px[0, 0]))
    return photo.bgr[:, col, 1].astype(float), px[0, 1], px[1, 1] - px[0, 1]


@pytest.mark.parametrize("azimuth", [90.0, 270.0])
def test_highlight_on_the_side_facing_the_lamp(azimuth):
    light = replace(Lighting.clean(), light_azimuth_deg=azimuth)
    photo = render_bender_photo(
        pin_angle_deg=30.0,
        bend_angle_deg=20.0,
        lighting=light,
        scale=0.5,
        effects=SceneEffects(wire_3d=True),
    )
    profile, row_axis, px_per_mm_y = _wire_profile(photo, -120.0)
    r_px = 1.5 * abs(px_per_mm_y)
    lo, hi = int(row_axis - r_px), int(row_axis + r_px) + 1
    brightest = lo + int(np.argmax(profile[lo:hi]))
    offset_mm = (brightest - row_axis) / px_per_mm_y  # along machine +y
    # the lamp at azimuth 90 lies towards +y: the highlight is on the +y half, and vice versa
    assert np.sign(offset_mm) == np.sign(np.sin(np.radians(azimuth)))
    assert 0.2 < abs(offset_mm) < 1.5
    # the wire's silhouette: 3 mm wide at its axis height (within 0.6 px, blur and grey
    # edges included), against the plate on both sides
    edge = profile[lo - 5 : hi + 5]
    plate = np.median(np.r_[profile[lo - 20 : lo - 8], profile[hi + 8 : hi + 20]])
    assert edge.max() > plate + 40


def test_bayer_changes_pixels_not_centres():
    kw = dict(
        pin_angle_deg=-40.0,
        bend_angle_deg=-30.0,
        lighting=Lighting.clean(blur_px=0.6),
        scale=0.25,
        linear=True,
    )
    plain = render_bender_photo(effects=SceneEffects(marker_heights=True), **kw)
    bayer = render_bender_photo(effects=SceneEffects(marker_heights=True, bayer=True), **kw)
    assert bayer.truth["lighting"]["bayer"] is True
    assert np.abs(plain.bgr.astype(int) - bayer.bgr.astype(int)).max() > 10
    for role in ROLES:
        a = np.array(check_disc_centre(plain, role).fitted_centre_px)
        b = np.array(check_disc_centre(bayer, role).fitted_centre_px)
        # stated tolerance 0.1 px (the edge-aware demosaic moves a disc by <= 0.07 px here)
        assert np.hypot(*(a - b)) < 0.1, role


def test_defocus_follows_the_thin_lens():
    # f = 35 mm at f/4, 7000 px focal length, focus 550 mm: 10 mm nearer gives
    # (7000 / 4) * 35 / 515 * 10 / 540 = 2.2 px of blur circle
    c = defocus_diameter_px(np.array([540.0, 550.0]), 550.0, 7000.0, 35.0, 4.0)
    assert c[0] == pytest.approx(1750.0 * 35.0 / 515.0 * 10.0 / 540.0, rel=1e-12)
    assert c[1] == 0.0
    img = np.zeros((41, 41, 1), dtype=np.float32)
    img[20, 20] = 1.0
    sharp = depth_of_field(img[..., 0:1].repeat(3, axis=2), np.zeros((41, 41)))
    assert np.array_equal(sharp[..., 0], img[..., 0])
    blurred = depth_of_field(img.repeat(3, axis=2), np.full((41, 41), 8.0))[..., 0]
    yy, xx = np.mgrid[0:41, 0:41]
    var = float((blurred * ((xx - 20) ** 2)).sum() / blurred.sum())
    assert var == pytest.approx((8.0 / 4) ** 2, rel=0.02)  # sigma = c / 4 (pillbox moment)
    assert float((blurred * xx).sum() / blurred.sum()) == pytest.approx(20.0, abs=1e-5)


def test_motion_kernel_is_a_centred_line():
    k = motion_kernel(6.0, 30.0)
    assert k.sum() == pytest.approx(1.0, abs=1e-6)
    yy, xx = np.mgrid[0 : k.shape[0], 0 : k.shape[1]]
    c = (k.shape[0] - 1) / 2
    assert (k * xx).sum() == pytest.approx(c, abs=1e-6) and (k * yy).sum() == pytest.approx(
        c, abs=1e-6
    )
    # second moment along the line: uniform over 6 px -> 3 px^2, plus the bilinear
    # splat's own 1/6 px^2
    d = (xx - c) * np.cos(np.radians(30)) + (yy - c) * np.sin(np.radians(30))
    assert (k * d**2).sum() == pytest.approx(3.0 + 1.0 / 6.0, abs=0.1)


def test_depth_of_field_blurs_what_is_out_of_focus():
    kw = dict(
        pin_angle_deg=30.0,
        bend_angle_deg=20.0,
        lighting=Lighting.clean(blur_px=0.0),
        scale=0.25,
        pose=Pose(distance_mm=550.0, offset_mm=(-10.0, 0.0), tilt_deg=20.0),
    )
    fx = SceneEffects(marker_heights=True, depth_of_field=True, f_number=2.8)
    photo = render_bender_photo(effects=fx, **kw)
    dof = photo.truth["depth_of_field"]
    assert dof["blur_diameter_px_max"] > 3.0 * max(dof["blur_diameter_px_min"], 0.3)
    sharp = render_bender_photo(effects=replace(fx, depth_of_field=False), **kw)
    assert np.abs(photo.bgr.astype(int) - sharp.bgr.astype(int)).max() > 20


def test_clutter_keeps_clear_of_markers_and_has_near_colours():
    kit = default_kit()
    photo = render_bender_photo(
        pin_angle_deg=30.0,
        bend_angle_deg=20.0,
        lighting=Lighting.clean(),
        scale=0.25,
        seed=11,
        effects=SceneEffects(clutter=10, textured_background=True),
    )
    strays = photo.truth["stray_objects"]
    assert len(strays) == 10
    near = [o for o in strays if o["near_role"]]
    assert len(near) >= 4
    for o in near:
        ref = np.array(kit.by_role(o["near_role"]).srgb)
        assert np.abs(np.array(o["srgb"]) - ref).max() <= 12
    for o in strays:
        for m in photo.truth["markers"].values():
            d = np.hypot(o["centre_mm"][0] - m["x_mm"], o["centre_mm"][1] - m["y_mm"])
            assert d > m["ring_mm"] / 2 + 8.0
        # diameters differ from the kit's (8-10 mm discs)
        if o["shape"] == "disc":
            assert o["size_mm"][0] < 5.5 or o["size_mm"][0] > 17.5


def test_wire_across_and_tool_shadow_cover_part_of_the_marker():
    kw = dict(
        pin_angle_deg=-60.0, bend_angle_deg=35.0, scale=0.25, lighting=Lighting.clean(), seed=2
    )
    base = SceneEffects(marker_heights=True)
    free = render_bender_photo(effects=base, **kw)
    hidden = render_bender_photo(
        effects=replace(base, wire_across=("wire_b",), tool_shadow=("pin",)), **kw
    )
    diff = np.abs(hidden.bgr.astype(int) - free.bgr.astype(int)).max(axis=2) > 25
    yy, xx = np.mgrid[0 : diff.shape[0], 0 : diff.shape[1]]
    for role in ("wire_b", "pin"):
        m = hidden.truth["markers"][role]
        cx, cy = m["centre_px"]
        ring = np.hypot(xx - cx, yy - cy) < m["ring_r_px"]
        frac = diff[ring].mean()
        assert 0.05 < frac < 0.8, role  # partly, not wholly, covered
    for role in ("origin", "axis", "wire_a"):
        m = hidden.truth["markers"][role]
        ring = np.hypot(xx - m["centre_px"][0], yy - m["centre_px"][1]) < m["ring_r_px"]
        assert not diff[ring].any(), role
    assert hidden.truth["markers"]["wire_b"]["wire_across"] is True
    assert hidden.truth["markers"]["pin"]["tool_shadow"] is True


def test_lifted_part_is_rigid_and_lifts_one_end():
    part = arc_part(80.0, 120.0, 6, wire_diameter_mm=3.0)
    flat = part.placed(30.0, (400.0, 100.0))
    axis3, info = lifted_centreline(flat, 1.5, 3.0)
    heights = -axis3[:, 2]
    assert heights.min() == pytest.approx(1.5, abs=1e-12)
    assert heights.max() == pytest.approx(4.5, abs=1e-12)
    # rigid: every distance between vertices is the flat part's (the design)
    d3 = np.linalg.norm(axis3[:, None] - axis3[None], axis=2)
    d2 = np.linalg.norm(flat[:, None] - flat[None], axis=2)
    assert np.abs(d3 - d2).max() < 1e-9
    assert info["tilt_deg"] == pytest.approx(np.degrees(np.arcsin(3.0 / part.chord_width_mm)))


def _wire_mask_centroid(photo, centre_px, normal_px, half_len=6, half_w=14):
    """Centroid offset (px, along ``normal_px``) of the bright wire pixels near a point."""
    g = photo.bgr[..., 1].astype(float)
    t = np.array([-normal_px[1], normal_px[0]])
    offs = []
    for s in range(-half_len, half_len + 1):
        ws = np.arange(-half_w, half_w + 1)
        pts = np.asarray(centre_px) + s * t + np.outer(ws, normal_px)
        vals = g[np.round(pts[:, 1]).astype(int), np.round(pts[:, 0]).astype(int)]
        mask = vals > 80
        offs.append(ws[mask].mean())
    return float(np.mean(offs))


def test_lifted_part_appears_where_its_3d_axis_projects():
    """The lifted end moves in the photo by what the 3D axis predicts (< 0.2 px)."""
    part = arc_part(80.0, 120.0, 6, wire_diameter_mm=3.0)
    light = replace(Lighting.clean(), shadow_strength=0.0)
    kw = dict(part=part, lighting=light, scale=0.5, seed=4, placement_deg=15.0)
    low = render_part_photo(effects=SceneEffects(wire_3d=True), **kw)
    high = render_part_photo(effects=SceneEffects(wire_3d=True, part_lift_mm=3.0), **kw)
    assert high.truth["lift_mm"] == 3.0
    assert high.truth["segment_bend_deg"] == pytest.approx(low.truth["segment_bend_deg"])
    pose = high.truth["pose"]
    cam = high.camera

    def project(p3):
        px, _ = cv2.projectPoints(
            np.asarray(p3, dtype=np.float64).reshape(-1, 3),
            np.array(pose["rvec"]),
            np.array(pose["tvec_mm"]),
            cam.camera_matrix,
            cam.dist_coeffs,
        )
        return px.reshape(-1, 2)

    a_low = np.array(low.truth["part"]["centreline_3d_mm"])
    a_high = np.array(high.truth["part"]["centreline_3d_mm"])
    mid_low = project((a_low[-2] + a_low[-1]) / 2)[0]
    mid_high = project((a_high[-2] + a_high[-1]) / 2)[0]
    seg = project(a_low[-2:])
    direction = (seg[1] - seg[0]) / np.linalg.norm(seg[1] - seg[0])
    normal = np.array([-direction[1], direction[0]])
    predicted = float((mid_high - mid_low) @ normal)
    assert abs(predicted) > 0.5  # the lift moves the wire in this photo
    c_low = _wire_mask_centroid(low, mid_low, normal)
    c_high = _wire_mask_centroid(high, mid_low, normal)
    assert (c_high - c_low) == pytest.approx(predicted, abs=0.2)


def test_effects_parse_from_text():
    assert SceneEffects.parse("") == SceneEffects()
    assert SceneEffects.parse("all") == SceneEffects.all_on()
    fx = SceneEffects.parse("all,clutter=12,bayer=off,tool_shadow=pin+axis")
    assert fx.clutter == 12 and not fx.bayer and fx.tool_shadow == ("pin", "axis")
    assert SceneEffects.parse("part_lift_mm").part_lift_mm == SceneEffects.all_on().part_lift_mm
    assert SceneEffects.from_dict(fx.to_dict()) == fx
    for bad in ("fog", "clutter=many", "wire_across", "bayer=maybe"):
        with pytest.raises(ValueError):
            SceneEffects.parse(bad)


@pytest.mark.parametrize("azimuth_deg", [90.0, 0.0, 30.0])
def test_a_round_wires_cast_shadow_is_a_cylinders(azimuth_deg):
    """A straight 3 mm wire along x, its axis 4 mm up, under the lab's lamp (49.6 deg up): the
    shadow's edges lie where the light's rays graze the cylinder, ``H (n . s) +- r sqrt(1 +
    (n . s)^2)`` across the axis' shadow (``s`` the shadow vector per mm of height): a band
    r / sin(elevation) wide when the wire runs across the light, r along it. The lab drew
    a capsule of half-width r in both cases."""
    from cvmeasure_datasets.solids import LAMP_ELEVATION_DEG, cast_shadow_sdf, lamp_direction

    r, height = 1.5, 4.0
    lamp = lamp_direction(azimuth_deg, up=-1.0)
    axis = np.array([[-60.0, 0.0, -height], [60.0, 0.0, -height]])
    y = np.linspace(-12.0, 12.0, 24001)
    sdf = cast_shadow_sdf(np.zeros((1, len(y))), y[None, :], axis, r, lamp, r + 5.0)[0]
    inside = y[sdf < 0]
    s = -lamp[:2] / abs(lamp[2])  # shadow shift per mm of height
    ns = s[1]  # the band's normal is y
    half = r * np.hypot(1.0, ns)
    assert inside.min() == pytest.approx(height * ns - half, abs=2e-3)
    assert inside.max() == pytest.approx(height * ns + half, abs=2e-3)
    if azimuth_deg == 90.0:
        assert half == pytest.approx(r / np.sin(np.radians(LAMP_ELEVATION_DEG)), rel=1e-9)
    # the distance is in mm of plane across the band (the soft edge's ramp)
    k = np.searchsorted(y, height * ns + half + 1.0)
    assert sdf[k] == pytest.approx(1.0, abs=2e-3)
