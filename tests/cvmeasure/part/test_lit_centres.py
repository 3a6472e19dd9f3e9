"""A lifted round wire's shadow parts from it as it rises: the lit side's centres keep the
chords straight where the silhouette edges' midpoints bend (the vertex bends)."""

from __future__ import annotations

import functools

import numpy as np

import cvmeasure_datasets
from cvmeasure.part.measure import measure_centreline_mm
from cvmeasure.part.options import PartOptions, WireOptions
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.round_wire import render_round_wire

SCALE = 0.5  # 0.157 mm/px at 550 mm: the 3 mm wire is 19 px wide
# a dev part like the ones whose vertex bends were off: R 46 mm, 120 deg, 7 chords, dark
# sheet, lifted 3 mm, lit at 50 deg elevation (not a benchmark case)
POSE = Pose(tilt_deg=2.55, tilt_direction_deg=236.3, distance_mm=550.0, offset_mm=(44.4, 27.4))
DIVISIONS = 7


@functools.lru_cache(maxsize=1)
def _photo():
    camera = cvmeasure_datasets.default_camera().scaled(SCALE)
    part = cvmeasure_datasets.arc_part(46.0, 120.0, DIVISIONS, wire_diameter_mm=3.0)
    verts = part.placed(219.6, (0.0, 0.0))
    return render_round_wire(
        verts, camera=camera, pose=POSE, wire_diameter_mm=3.0, lift_mm=3.0,
        lift_direction_deg=219.6, sheet="dark", light_azimuth_deg=172.0, light_elev_deg=49.8,
        seed=5001,
    )  # fmt: skip


def _chord_direction_errors_deg(photo, points_px: np.ndarray) -> np.ndarray:
    """Each chord's direction in the photo (a line through the centres along its middle 70 %)
    minus the true axis' projected chord direction, degrees."""
    rot, t_mm = POSE.extrinsics("board")
    v_px = photo.plane.camera.project(photo.vertices_mm @ rot.T + t_mm)
    out = []
    for a, b in zip(v_px[:-1], v_px[1:], strict=True):
        length = float(np.hypot(*(b - a)))
        e = (b - a) / length
        along = (points_px - a) @ e
        across = (points_px - a) @ np.array([-e[1], e[0]])
        sel = (along > 0.15 * length) & (along < 0.85 * length) & (np.abs(across) < 10.0)
        out.append(np.degrees(np.polyfit(along[sel], across[sel], 1)[0]))
    return np.array(out)


def test_lit_centres_keep_a_lifted_parts_chords_straight():
    photo = _photo()
    _, _, centre, _ = measure_centreline_mm(
        photo.bgr, None, None, wire_diameter_mm=3.0, plane=photo.plane
    )
    assert centre.centre_from == "silhouette" and centre.lit_points_px is not None
    assert centre.lit_points_px.shape == centre.points_px.shape
    pairs = _chord_direction_errors_deg(photo, centre.points_px)
    lit = _chord_direction_errors_deg(photo, centre.lit_points_px)
    # the vertex bends are the differences of neighbouring chords' directions (measured with
    # the plane's true scale: pairs 0.057 0.032 -0.071 -0.021 0.103 -0.039 0.102 deg, lit
    # 0.032 0.013 -0.063 0.041 0.027 0.033 0.054; with the scale misstated 0.1 mm/px for
    # 0.156 the pairs' sixth chord turned -0.25 deg and the lit last chord 0.36)
    bend_pairs = np.abs(np.diff(pairs))
    bend_lit = np.abs(np.diff(lit))
    assert bend_pairs.max() < 0.2  # measured 0.14
    assert bend_lit.max() < 0.15  # measured 0.10 (half size: noise of 0.05-0.1 deg)


def test_lifted_parts_vertex_bends_hold_their_sigma():
    """measure_part on the same photo (the shadow's lift, corrected): each chord's direction
    from its whole cross-profile, lit side (:func:`cvmeasure.part.chord_profiles.profile_polyline`),
    against the true bend (the rigid part's own, 120 / 7 deg at every vertex)."""
    from cvmeasure.part.measure import measure_part

    photo = _photo()
    m = measure_part(
        photo.bgr,
        None,
        None,
        plane=photo.plane,
        options=PartOptions(divisions=DIVISIONS, wire=WireOptions(diameter_mm=3.0)),
    )
    assert m.lift.used == "correction" and m.lift.lift_mm >= 2.0  # measured 2.78 +- 0.21
    err = np.asarray(m.vertex_bend_deg) - 120.0 / DIVISIONS
    sigma = np.asarray(m.vertex_bend_sigma_deg)
    # measured: -0.009 0.002 0.003 0.002 0.046 -0.028 deg at sigmas 0.012-0.018 (part14s; the
    # edges' combination before: -0.037 -0.023 0.021 0.052 -0.013 0.182 at 0.044-0.078). The
    # fifth vertex is at 3.8 sigma: the lifted end's chords carry a bias the sampling sigma
    # does not see (half size: a 19 px wire); the others within 2.5 sigma
    assert np.sum(np.abs(err) >= 2.5 * sigma) <= 1, (err, sigma)
    assert np.abs(err).max() < 0.07
    assert np.abs(err[:-2]).max() < 0.02
