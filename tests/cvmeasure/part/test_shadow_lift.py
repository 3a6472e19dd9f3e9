"""One-photo lift from the cast shadow (cvmeasure/part/shadow.py) on the independent
ray-traced generator (datasets/round_wire.py), half size, development seeds 9102-9105
(not the benchmark's). The lamp's direction is not given to the fit."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.part.measure import measure_centreline_mm
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
from cvmeasure.part.shadow import estimate_lift_shadow
from cvmeasure.warning import has_code
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.round_wire import render_round_wire

WIRE_MM = 3.0
#: The photo lab's board in its part scenes (real_scenes' part rows).
LAB_BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
POSE = Pose(tilt_deg=1.5, tilt_direction_deg=70.0, distance_mm=550.0, offset_mm=(30.0, -20.0))


@functools.cache
def _photo(sheet: str, lift_mm: float, elev_deg: float, az_deg: float, seed: int):
    """The render and its centreline, made once per session (read-only: tests share them)."""
    part = cvmeasure_datasets.arc_part(60.0, 100.0, 7, wire_diameter_mm=WIRE_MM)
    verts = part.placed(35.0, (0.0, 0.0))
    pose = POSE
    camera = cvmeasure_datasets.default_camera().scaled(0.5)
    photo = render_round_wire(
        verts, camera=camera, pose=pose, wire_diameter_mm=WIRE_MM, lift_mm=lift_mm,
        lift_direction_deg=35.0, sheet=sheet, light_azimuth_deg=az_deg,
        light_elev_deg=elev_deg, seed=seed,
    )  # fmt: skip
    _, _, centre, _ = measure_centreline_mm(
        photo.bgr, None, None, wire_diameter_mm=WIRE_MM, plane=photo.plane
    )
    photo.bgr.setflags(write=False)
    centre.points_px.setflags(write=False)
    return photo, centre


@functools.cache
def _dark_lifted_plane():
    """The plane of :func:`_photo`'s dark-plate part lifted 3 mm (seed 9104) as a user
    measures it: a board photo from the same pose (made once per session)."""
    from benchmarks._calibrated import plane_for_pose

    photo, _ = _photo("dark", 3.0, 55.0, 300.0, 9104)
    return plane_for_pose(POSE, photo.plane.camera, scale=0.5, seed=9104, frame="board")


@pytest.mark.parametrize(
    ("sheet", "lift_mm", "elev_deg", "az_deg", "seed"),
    [
        ("dark", 0.0, 45.0, 65.0, 9102),
        ("light", 1.5, 50.0, 230.0, 9105),
        ("dark", 3.0, 55.0, 300.0, 9104),
    ],  # fmt: skip
)
def test_the_shadow_gives_the_lift_and_the_lamp(sheet, lift_mm, elev_deg, az_deg, seed):
    """Measured on these renders: lift 0.25 +- 0.22 (flat), 1.46 +- 0.09 (1.5), 2.86 +- 0.19
    (3) mm; lamp elevation within 1.3 deg, azimuth within 0.4 deg. Tolerances: lift 0.3 mm
    (the edges' sheet-dependent bias, +-0.05 mm, and the lamp's length trading against the
    lift) or two stated sigmas where those are wider (the 3 mm render read 2.58 +- 0.32 mm
    after the first pass of the pair search looked a width from the mask's path, part14u:
    the centreline moved by under 0.1 px at 7 of 656 points), lamp 3 deg."""
    photo, centre = _photo(sheet, lift_mm, elev_deg, az_deg, seed)
    fit = estimate_lift_shadow(photo.bgr, photo.plane, centre.points_px, wire_diameter_mm=WIRE_MM)
    assert fit.lift is not None, fit.message
    assert abs(fit.lift.lift_mm - lift_mm) <= max(0.3, 2.0 * fit.lift.lift_sigma_mm)
    assert fit.lamp_elevation_deg == pytest.approx(elev_deg, abs=3.0)
    diff = (fit.lamp_azimuth_deg - az_deg + 180.0) % 360.0 - 180.0
    assert abs(diff) < 3.0
    assert np.all(fit.lift.height_mm >= 0.0) and fit.lift.height_mm.min() == 0.0


def test_a_lamp_overhead_gives_no_shadow_lift():
    """Lamp at 89 deg: the shadow hides under the wire; no lift, and a message why."""
    photo, centre = _photo("light", 1.5, 89.0, 0.0, 9103)
    fit = estimate_lift_shadow(photo.bgr, photo.plane, centre.points_px, wire_diameter_mm=WIRE_MM)
    assert fit.lift is None and fit.message


def test_cli_part_shadow_lift(tmp_path, capsys):
    """``cvmeasure part PHOTO --plane P --shadow-lift`` on the dark-plate render lifted 3 mm
    (seed 9104, half size, the plane measured from a board photo of the same pose):
    measured lift 2.91 mm (corrected, source "shadow"), radius +0.05 %; the same without
    the option (the default); with ``--no-shadow-lift`` the lift is only bounded (source
    "width", part_lifted warned). Tolerances: lift 0.3 mm (as above), radius issue 14's
    0.3 %; the option needs the wire's diameter and is not given with its negation."""
    import json

    import cv2

    from cvmeasure.camera_model import save_camera
    from cvmeasure.cli import main

    photo, _ = _photo("dark", 3.0, 55.0, 300.0, 9104)
    path, camera, plane = tmp_path / "part.png", tmp_path / "camera.json", tmp_path / "plane.json"
    cv2.imwrite(str(path), photo.bgr)
    save_camera(camera, photo.plane.camera)
    # the plate's plane as a user measures it: a board photo from the same pose
    _dark_lifted_plane().save(plane)
    base = ["part", str(path), "--plane", str(plane), "--camera", str(camera), "--divisions", "7"]
    argv = [*base, "--wire-diameter-mm", "3"]
    assert main([*argv, "--shadow-lift", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["lift"]["used"] == "correction" and out["lift"]["source"] == "shadow"
    assert out["lift"]["lift_mm"] == pytest.approx(3.0, abs=0.3)
    assert abs(100.0 * (out["radius_mm"] / 60.0 - 1.0)) < 0.3
    lift_flag = out["lift"]["lift_mm"]
    assert main([*argv, "--json"]) == 0  # the default: the same correction
    out = json.loads(capsys.readouterr().out)
    assert out["lift"]["source"] == "shadow" and out["lift"]["lift_mm"] == lift_flag
    assert main([*argv, "--no-shadow-lift", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["lift"]["used"] == "bound" and out["lift"]["source"] == "width"
    assert any(w["code"] == "part_lifted" for w in out["warnings"])
    assert main([*argv, "--shadow-lift"]) == 0
    assert "from the cast shadow" in capsys.readouterr().out
    assert main([*base, "--shadow-lift"]) == 2
    assert "--shadow-lift" in capsys.readouterr().err
    with pytest.raises(SystemExit):  # argparse: not both
        main([*argv, "--shadow-lift", "--no-shadow-lift"])
    assert "--no-shadow-lift" in capsys.readouterr().err


@functools.cache
def _lab_render(seed: int, i: int, effects):
    """The photo lab's part scene (real_scenes' part rows' recipe at a development seed,
    not the benchmark's 1400), half size, with ``effects``: lamp 49.6 deg up, shadow 35 %
    of the light; a dark sheet for even ``i``, a light one for odd. Made once per session,
    its image read-only (tests share it)."""
    bw, bh = LAB_BOARD.size_mm
    rng = np.random.default_rng([seed, 77, i])
    part = cvmeasure_datasets.arc_part(
        float(rng.uniform(45.0, 85.0)), float(rng.choice([90.0, 120.0, 150.0])),
        int(rng.integers(6, 10)), wire_diameter_mm=WIRE_MM,
    )  # fmt: skip
    pose = Pose(
        tilt_deg=float(rng.uniform(0.0, 4.0)), tilt_direction_deg=float(rng.uniform(0.0, 360.0)),
        distance_mm=900.0, offset_mm=((bw + 10.0 + 250.0 - 20.0) / 2 + 10.0, bh / 2),
    )  # fmt: skip
    photo = cvmeasure_datasets.render_part_photo(
        part=part, board=LAB_BOARD, sheet="dark" if i % 2 == 0 else "light", pose=pose,
        seed=seed + 300 + i, scale=0.5, effects=effects,
    )  # fmt: skip
    photo.bgr.setflags(write=False)
    return photo


def _lab_photo(seed: int, i: int, lift_mm: float):
    """:func:`_lab_render` with the 3D wire lifted ``lift_mm``, and its centreline."""
    from cvmeasure_datasets.effects import SceneEffects

    photo = _lab_render(seed, i, SceneEffects(wire_3d=True, part_lift_mm=lift_mm))
    plane, _, centre, _ = measure_centreline_mm(
        photo.bgr, LAB_BOARD, photo.camera, wire_diameter_mm=WIRE_MM
    )
    return photo, plane, centre


@pytest.mark.parametrize(("seed", "i"), [(2100, 0), (2100, 1)])
def test_the_photo_labs_flat_part_reads_no_lift_from_its_shadow(seed, i):
    """The lab's shadow takes 35 % of the plate's light; its wire is darker than a light
    sheet and 14x brighter than a dark one. The edge at half of the darkest level's step
    was the wire's: a flat part read 5.8 +- 1.8 mm (light) and 1.8 +- 0.9 mm (dark). The
    edge at half the shadow's own step (one depth and penumbra for all profiles): 0.16 +-
    0.13 (light) and 0.10 +- 0.34 mm (dark) measured with the benchmark's calibrated lens;
    with each edge fitted against the sheet just outside it (part14m) 0.13 +- 0.31 and
    0.18 +- 0.42. Asserted: within 2 sigma of 0 (+ 0.1 mm) and the lamp within 5 deg."""
    photo, plane, centre = _lab_photo(seed, i, 0.0)
    fit = estimate_lift_shadow(photo.bgr, plane, centre.points_px, wire_diameter_mm=WIRE_MM)
    assert fit.lift is not None, fit.message
    assert fit.lift.lift_mm < 2.0 * fit.lift.lift_sigma_mm + 0.1
    assert fit.lamp_elevation_deg == pytest.approx(49.6, abs=5.0)
    az = photo.truth["lighting"]["light_azimuth_deg"]
    assert abs((fit.lamp_azimuth_deg - az + 180.0) % 360.0 - 180.0) < 5.0


def test_the_photo_labs_lifted_part_is_corrected_from_its_shadow():
    """The lab's part lifted 2 mm at one end, light sheet (dev seed 2101): the shadow reads
    1.51 +- 0.27 mm (measured; 1.8 sigma low) and the corrected radius is -0.044 %; since
    part14m 2.27 +- 0.15 mm (1.8 sigma high), +0.032 %.
    Asserted: corrected, the lift within 2 sigma + 0.1 mm of 2, the radius within issue
    14's 0.3 %."""
    from cvmeasure.part.measure import measure_part

    photo, _, _ = _lab_photo(2101, 1, 2.0)
    m = measure_part(
        photo.bgr,
        LAB_BOARD,
        photo.camera,
        options=PartOptions(
            divisions=photo.truth["divisions"],
            wire=WireOptions(diameter_mm=WIRE_MM),
            lift=LiftOptions(shadow=True),
        ),
    )
    assert m.lift is not None and m.lift.used == "correction", m.lift
    assert abs(m.lift.lift_mm - 2.0) < 2.0 * m.lift.lift_sigma_mm + 0.1
    assert abs(100.0 * (m.result.radius_mm / photo.truth["radius_mm"] - 1.0)) < 0.3


def test_residuals_correlated_along_the_wire_widen_the_covariance():
    """Residuals that move together over ~10 mm (a stain) carry less information than as
    many independent ones: the correlated covariance is larger than the independent one by
    about the number of edges per correlation length; white residuals give the same."""
    from cvmeasure.part.shadow import _correlated_cov, _residual_correlation

    rng = np.random.default_rng(3)
    pos = np.arange(0.0, 150.0, 0.5)
    jac = np.column_stack((np.ones_like(pos), (pos - pos.mean()) / 75.0))
    pinv = np.linalg.pinv(jac)
    white = rng.normal(0.0, 0.1, len(pos))
    lags, rho = _residual_correlation(white, pos)
    assert abs(rho[2]) < 0.2
    cov_w = _correlated_cov(pinv, white, pos)
    ratio_w = np.diag(cov_w) / np.diag(pinv @ pinv.T * np.var(white))
    assert np.all((ratio_w > 0.5) & (ratio_w < 2.0))
    # an AR(1) texture, correlation length 10 mm (20 edges)
    phi = np.exp(-0.5 / 10.0)
    red = np.zeros(len(pos))
    for i in range(1, len(pos)):
        red[i] = phi * red[i - 1] + rng.normal(0.0, 0.1 * np.sqrt(1 - phi**2))
    _, rho = _residual_correlation(red, pos)
    assert rho[2] > 0.5
    cov_r = _correlated_cov(pinv, red, pos)
    ratio_r = np.diag(cov_r) / np.diag(pinv @ pinv.T * np.var(red))
    assert np.all(ratio_r > 8.0)


def test_a_textured_lab_sheet_is_not_corrected_silently_wrong():
    """The lab's part with all effects (textured light sheet, depth of field, Bayer; dev seed
    2000, half size), lying flat. Its edges scatter 0.12 mm about the fit (0.02-0.06 on clean
    renders) and the lamp comes out 17 deg off. Before (the optimiser's forward-difference
    Jacobian for the covariance, a fixed 0.05 mm bias, the sigma between the two points the
    fit names highest and lowest): 2.18 +- 0.33 mm, corrected (6.6 sigma). Measured now:
    2.18 +- 0.83 mm, bounded (part14m: 3.00 +- 1.43, bounded). Asserted: not corrected unless within 2 sigma of the truth."""
    from dataclasses import replace

    from cvmeasure.part.measure import measure_part
    from cvmeasure_datasets.effects import SceneEffects

    photo = _lab_render(2000, 1, replace(SceneEffects.all_on(), part_lift_mm=0.0))  # light
    m = measure_part(
        photo.bgr,
        LAB_BOARD,
        photo.camera,
        options=PartOptions(
            divisions=photo.truth["divisions"],
            wire=WireOptions(diameter_mm=WIRE_MM),
            lift=LiftOptions(shadow=True),
        ),
    )
    assert m.lift is not None
    if m.lift.used == "correction":
        assert abs(m.lift.lift_mm) < 2.0 * m.lift.lift_sigma_mm
    else:
        assert m.lift.shadow["lift_mm"] is None or m.lift.shadow["lift_sigma_mm"] > 0.5


def test_a_dark_textured_lab_sheet_widens_the_shadow_lift():
    """The lab's part lifted 3 mm on a dark textured sheet, all effects, half size: the
    sheet's texture moves the shadow's edges (its laid steps' errors are about 0.5 mm rms
    on this sheet), so the lift's sigma must count them. Without them the lift read 5.92 +-
    0.41 mm and was corrected, 7 sigma off. Asserted: the sigma at least the sheet's
    0.5 mm edge errors, the truth within 2 sigma, and no correction unless within 3 sigma
    (issue 14: no corrected fit beyond 3 sigma)."""
    from dataclasses import replace

    from cvmeasure_datasets.effects import SceneEffects

    photo = _lab_render(2002, 0, replace(SceneEffects.all_on(), part_lift_mm=3.0))  # dark
    plane, _, centre, _ = measure_centreline_mm(
        photo.bgr, LAB_BOARD, photo.camera, wire_diameter_mm=WIRE_MM
    )
    fit = estimate_lift_shadow(photo.bgr, plane, centre.points_px, wire_diameter_mm=WIRE_MM)
    assert fit.lift is not None, fit.message
    assert fit.lift.lift_sigma_mm >= 0.5  # mm: the sheet's own edge errors
    assert abs(fit.lift.lift_mm - 3.0) < 2.0 * fit.lift.lift_sigma_mm
    if 2.0 * fit.lift.lift_sigma_mm <= 1.0:
        assert abs(fit.lift.lift_mm - 3.0) < 3.0 * fit.lift.lift_sigma_mm


def test_the_sheets_own_edge_errors_come_from_its_bare_side():
    """:func:`texture_edge_errors` on synthetic profiles: a shadow step (depth 0.35,
    penumbra 1 mm) on one side of each profile, the other side bare. Measured: a plain
    sheet (noise 0.005) 0.003 mm rms of laid-step errors, a sheet with stains along the
    profile (a +-10 % sinusoid, 3 mm period) 0.15 mm. Asserted: below 0.02 mm, and 0.05 mm
    or more."""
    from cvmeasure.part.shadow_edges import fit_ramps, texture_edge_errors

    rng = np.random.default_rng(11)
    u = np.arange(0.0, 11.0 + 1e-9, 0.05)
    far = u >= 9.5
    n = 120
    start = np.full((2, n), 2.0)
    edge_true = 4.0 + 0.5 * np.sin(np.arange(n) / 9.0)
    for stain, low, high in ((0.0, 0.0, 0.02), (0.10, 0.05, 1.0)):
        q = 1.0 + rng.normal(0.0, 0.005, (2, n, len(u)))
        phase = rng.uniform(0.0, 2.0 * np.pi, (2, n, 1))
        q *= 1.0 + stain * np.sin(2.0 * np.pi * u[None, None, :] / 3.0 + phase)
        q[0] *= 1.0 - 0.35 * np.clip(0.5 - (u[None, :] - edge_true[:, None]) / 1.0, 0.0, 1.0)
        offsets, contrast, k_w = fit_ramps(u, q, start, far)
        assert k_w is not None and np.isfinite(offsets[0]).all()
        tex = texture_edge_errors(u, q, start, far, offsets, contrast, k_w)
        rms = float(np.sqrt(np.nanmean(tex**2)))
        assert low <= rms < high, (stain, rms)


def _true_edge_residuals_mm(photo, plane, centre) -> tuple[np.ndarray, np.ndarray]:
    """The measured shadow edges less the true ones (the render's lamp and axis heights
    through :func:`predict_shadow_edges_mm`), and each edge's gap beyond the silhouette."""
    from cvmeasure.part.lift import points_at_heights_mm
    from cvmeasure.part.shadow_edges import measure_shadow_edges
    from cvmeasure.part.shadow_model import predict_shadow_edges_mm
    from cvmeasure_datasets.solids import lamp_direction

    lamp = lamp_direction(photo.truth["lighting"]["light_azimuth_deg"], up=-1.0)
    s_true = -lamp[:2] / abs(lamp[2])
    axis3 = np.array(photo.truth["part"]["centreline_3d_mm"])
    pts = centre.points_px
    flat = points_at_heights_mm(plane, pts, 0.5 * WIRE_MM)
    nearest = np.argmin(np.linalg.norm(flat[:, None, :] - axis3[None, :, :2], axis=2), axis=1)
    heights = -axis3[nearest, 2]
    edges = measure_shadow_edges(
        photo.bgr, plane, pts, wire_diameter_mm=WIRE_MM, axis_height_mm=0.5 * WIRE_MM,
        heights_mm=heights,
    )  # fmt: skip
    have = np.isfinite(edges.offset_mm)
    k = np.where(have[:, 0] & (~have[:, 1] | (edges.contrast[:, 0] >= edges.contrast[:, 1])), 0, 1)
    rows = np.arange(len(k))
    meas = edges.offset_mm[rows, k]
    side = np.where(k == 0, 1.0, -1.0)
    pred, _ = predict_shadow_edges_mm(plane, pts, edges, heights, s_true, 0.5 * WIRE_MM, side)
    res = meas - pred
    ok = np.isfinite(res) & (np.abs(res) < 1.0)
    return res[ok], (meas - edges.silhouette_mm[rows, k])[ok]


def test_a_dark_textured_sheets_shadow_edges_sit_on_the_true_ones():
    """The lab's part lifted 2.5 mm on a dark textured sheet, all effects (dev seed 2009,
    half size), against the render's truth (the edges measured beyond the silhouette of
    the axis at its true heights, as the fit's second pass does at the fitted ones). The
    common depth had been fitted over the whole profile, where the wire's halo lifts the
    shadow near the wire, and the plate's level taken far out, where the sheet's albedo
    differs: +0.33 mm outside the true edges on average. Each profile fitted about its
    edge, against the sheet's own level just outside it: +0.051 mm median (measured).
    Asserted: within 0.12 mm."""
    from dataclasses import replace

    from cvmeasure_datasets.effects import SceneEffects

    photo = _lab_render(2009, 0, replace(SceneEffects.all_on(), part_lift_mm=2.5))  # dark
    plane, _, centre, _ = measure_centreline_mm(
        photo.bgr, LAB_BOARD, photo.camera, wire_diameter_mm=WIRE_MM
    )
    res, _ = _true_edge_residuals_mm(photo, plane, centre)
    assert len(res) > 100
    assert abs(float(np.median(res))) < 0.12, float(np.median(res))


def test_a_stray_discs_outline_is_not_taken_for_the_wire():
    """The lab's part lifted 1 mm on a light textured cluttered sheet (dev seed 2004, half
    size): a large stray disc's outline has a longer skeleton (143 px at the mask's scale)
    than the 90 mm wire (128 px), and was taken for it ("no wire found"). The wire is now
    the component whose filled mask has the longest path: the centreline lies 0.14 mm from
    the truth's axis at most (on the plate, at the resting height), 98.6 mm long for 98.4
    (measured). Asserted: within 0.5 mm, and at least 80 % of the part's length."""
    from dataclasses import replace

    from cvmeasure_datasets.effects import SceneEffects

    photo = _lab_render(2004, 1, replace(SceneEffects.all_on(), part_lift_mm=1.0))  # light
    _, _, _, centre_mm = measure_centreline_mm(
        photo.bgr, LAB_BOARD, photo.camera, wire_diameter_mm=WIRE_MM
    )
    truth = np.array(photo.truth["part"]["projected_centreline_mm"])
    fine = np.concatenate([
        a + np.linspace(0.0, 1.0, 50)[:, None] * (b - a)
        for a, b in zip(truth[:-1], truth[1:], strict=True)
    ])  # fmt: skip
    dist = np.min(np.linalg.norm(centre_mm[:, None, :] - fine[None, :, :], axis=2), axis=1)
    assert float(np.max(dist)) < 0.5, float(np.max(dist))
    length = float(np.sum(np.hypot(*np.diff(centre_mm, axis=0).T)))
    assert length > 0.8 * float(np.sum(np.hypot(*np.diff(truth, axis=0).T)))


def test_an_uncertain_shadow_lift_is_corrected_with_its_sigma_carried():
    """The lab's part lifted 3 mm on a dark textured sheet, all effects (dev seed 2002, half
    size). The shadow reads 3.50 +- 0.72 mm: 2 sigma is above SHADOW_MAX_2SIGMA_MM, so
    before part14p the part was measured flat and only its lift bounded (radius -0.437 %,
    bound effect 0.78 %). Measured now: corrected with the shadow's lift, its 2 sigma
    carried into the stated effects: radius +0.034 % (effect 0.42 %), bend per chord
    -0.0097 deg (effect 0.084). Asserted: corrected from the shadow and warned
    part_lifted; the lift within 2 sigma of 3 mm; the radius within issue 14's 0.3 % and
    within its stated effect, the bend per chord within its stated effect."""
    from dataclasses import replace

    from cvmeasure.part.lift_use import SHADOW_MAX_2SIGMA_MM
    from cvmeasure.part.measure import measure_part
    from cvmeasure_datasets.effects import SceneEffects

    photo = _lab_render(2002, 0, replace(SceneEffects.all_on(), part_lift_mm=3.0))  # dark
    n = photo.truth["divisions"]
    m = measure_part(
        photo.bgr,
        LAB_BOARD,
        photo.camera,
        options=PartOptions(divisions=n, wire=WireOptions(diameter_mm=WIRE_MM)),
    )
    assert m.lift is not None and m.lift.used == "correction", m.lift
    assert m.lift.source == "shadow"
    assert 2.0 * m.lift.lift_sigma_mm > SHADOW_MAX_2SIGMA_MM  # the case this is about
    assert abs(m.lift.lift_mm - 3.0) < 2.0 * m.lift.lift_sigma_mm
    assert has_code(m.warnings, "part_lifted")
    radius_err = 100.0 * (m.result.radius_mm / photo.truth["radius_mm"] - 1.0)
    assert abs(radius_err) < min(0.3, m.lift.effect_radius_pct)
    bend_err = m.result.segment_bend_deg - photo.truth["arc_angle_deg"] / n
    assert abs(bend_err) < m.lift.effect_segment_bend_deg


@pytest.mark.parametrize(
    ("lift_mm", "sigma_mm", "bound_mm", "usable"),
    [
        (2.2, 0.8, 3.0, True),  # informative: 2 sigma 1.6 mm < the 3 mm bound
        (6.39, 1.20, 3.0, False),  # a gross miss of a 3 mm lift: 2.0 sigma above the bound
        (7.75, 6.15, 3.0, False),  # 2 sigma wider than the bound: tells nothing more
        (3.00, 1.43, 3.0, False),  # 2 sigma 2.9 mm: over SHADOW_WIDE_MAX_2SIGMA_MM
        (1.0, 0.99, 3.0, True),
        (0.5, 0.7, 1.2, False),  # the width's bound is tighter than the shadow's 2 sigma
        # confident readings (2 sigma <= SHADOW_MAX_2SIGMA_MM) are checked too (part14r)
        (7.42, 0.29, 3.0, False),  # a 3 mm lift read at full size: 15 sigma above the bound
        (2.9, 0.2, 3.0, True),
        (3.3, 0.2, 3.0, True),  # above the bound within 2 sigma: corrected at the bound
        (0.3, 0.4, 0.2, True),  # a confident reading is not refused for being wider
    ],
)
def test_which_uncertain_shadow_lifts_are_corrected(lift_mm, sigma_mm, bound_mm, usable):
    """An uncertain shadow lift is used only when its 2 sigma is at most 2 mm and below the
    bound otherwise used, and it is within 2 sigma of that bound (dev reads of part14j/m,
    and the flat dev-seed-2000 part on a textured light sheet that read 3.00 +- 1.43 mm)."""
    from cvmeasure.part.lift import LiftEstimate
    from cvmeasure.part.lift_use import SHADOW_WIDE_MAX_2SIGMA_MM, shadow_unusable

    est = LiftEstimate(np.zeros(3), (0.0, 0.0), np.eye(2), lift_mm, sigma_mm, 3, 1.0)
    refusal = shadow_unusable(est, bound_mm)
    assert (refusal is None) is usable
    # inconsistent (more than 2 sigma above the bound) where a reading not too uncertain is
    if refusal is not None:
        two_sigma = 2.0 * sigma_mm
        inconsistent = two_sigma <= SHADOW_WIDE_MAX_2SIGMA_MM and lift_mm - two_sigma > bound_mm
        assert refusal.inconsistent is inconsistent, refusal


@pytest.mark.parametrize(
    ("lift_mm", "bound_mm", "used_mm"),
    [(2.5, 3.0, 2.5), (3.0, 3.0, 3.0), (4.2, 3.5, 3.5), (0.0, 3.0, 0.0)],
)
def test_an_uncertain_shadow_lift_read_above_the_bound_is_corrected_at_the_bound(
    lift_mm, bound_mm, used_mm
):
    """The lift corrected with is the shadow's, or the bound where the shadow reads above it
    (a reading within 2 sigma of the bound; shadow_unusable rejects one farther above)."""
    from cvmeasure.part.lift import LiftEstimate
    from cvmeasure.part.lift_use import shadow_lift_scale

    est = LiftEstimate(np.zeros(3), (0.0, 0.0), np.eye(2), lift_mm, 0.8, 3, 1.0)
    assert shadow_lift_scale(est, bound_mm) * lift_mm == pytest.approx(used_mm, abs=1e-9)


def _faked_shadow(shadow, lift_mm: float, sigma_mm: float):
    """``shadow`` (a ShadowLift) with its lift's heights and slope scaled to ``lift_mm`` and
    its sigma set to ``sigma_mm`` (a shadow edge taken for another, made to order)."""
    from dataclasses import replace

    k = lift_mm / shadow.lift.lift_mm
    lift = replace(
        shadow.lift, height_mm=k * shadow.lift.height_mm, lift_mm=lift_mm,
        slope=(k * shadow.lift.slope[0], k * shadow.lift.slope[1]), lift_sigma_mm=sigma_mm,
    )  # fmt: skip
    return replace(shadow, lift=lift)


@pytest.fixture(scope="module")
def dark_lifted_photo():
    """:func:`_photo`'s dark-plate part lifted 3 mm (seed 9104) and the plate's plane as a
    user measures it (a board photo from the same pose)."""
    return _photo("dark", 3.0, 55.0, 300.0, 9104)[0], _dark_lifted_plane()


@pytest.mark.parametrize(
    ("lift_mm", "sigma_mm", "used"),
    [(7.42, 0.29, "bound"), (None, None, "correction"), (3.3, 0.2, "correction")],
)
def test_a_confident_shadow_lift_inconsistent_with_the_bound_is_not_used(
    monkeypatch, dark_lifted_photo, lift_mm, sigma_mm, used
):
    """The dark-plate render lifted 3 mm (seed 9104, half size), its shadow read as the
    full-size R46 dev part's once was: 7.42 +- 0.29 mm for 3 (2 sigma under
    SHADOW_MAX_2SIGMA_MM, so before part14r it was corrected with that reading: that
    part's vertex bends came out 0.15-0.20 deg off, 4.7-5.6 sigma, unwarned). Asserted:
    not corrected, the lift bounded (source "width", bound 3 mm) and a part_lifted warning
    that says the shadow was not used and why. The shadow's own reading (2.9 mm, as in
    test_cli_part_shadow_lift) is still corrected: lift within 0.3 mm, radius within issue 14's 0.3 %.
    Read 3.3 +- 0.2 mm (above the 3 mm bound within 2 sigma) it is corrected at the bound:
    ``lift_mm`` says 3.0, ``read_lift_mm`` the reading."""
    import cvmeasure.part.measure as measure

    photo, plane = dark_lifted_photo
    real = measure.estimate_lift_shadow
    if lift_mm is not None:
        monkeypatch.setattr(
            measure, "estimate_lift_shadow",
            lambda *a, **k: _faked_shadow(real(*a, **k), lift_mm, sigma_mm),
        )  # fmt: skip
    m = measure.measure_part(
        photo.bgr,
        None,
        None,
        plane=plane,
        options=PartOptions(divisions=7, wire=WireOptions(diameter_mm=WIRE_MM)),
    )
    assert m.lift is not None and m.lift.used == used, m.lift
    lifted = [str(w) for w in m.warnings if w.code == "part_lifted"]
    if used == "bound":
        assert m.lift.source == "width" and m.lift.bound_mm == pytest.approx(3.0)
        assert m.lift.shadow["lift_mm"] == pytest.approx(7.42)
        assert len(lifted) == 1 and "shadow was not used" in lifted[0]
        assert "inconsistent" in lifted[0]
    else:
        assert m.lift.source == "shadow"
        assert m.lift.lift_mm == pytest.approx(3.0, abs=0.3)
        if lift_mm is not None:  # read above the bound: the lift used is the bound
            assert m.lift.lift_mm == pytest.approx(3.0)
            assert m.lift.read_lift_mm == pytest.approx(lift_mm)
        else:
            assert m.lift.read_lift_mm == m.lift.lift_mm
        assert abs(100.0 * (m.result.radius_mm / 60.0 - 1.0)) < 0.3
