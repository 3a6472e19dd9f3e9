"""The part's stated radius and bend-per-chord uncertainties: what each term propagates, and
the errors on ray-traced round wires within two of them."""

from __future__ import annotations

import functools
import math

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.part.arc import polygon_arc
from cvmeasure.part.arc_uncertainty import (
    END_ALONG_PX,
    SILHOUETTE_OFFSET_PX,
    arc_uncertainty,
    imprecision_warning,
)
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
from cvmeasure.part.profiles import resample_path
from cvmeasure.warning import has_code
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.round_wire import render_round_wire

R_MM, ARC_DEG, N = 50.0, 120.0, 8


def _arc_vertices(radius_mm: float = R_MM) -> np.ndarray:
    phi = np.radians(-90.0 - ARC_DEG / 2 + np.linspace(0.0, ARC_DEG, N + 1))
    return radius_mm * np.column_stack((np.cos(phi), np.sin(phi)))


def _uncertainty(v: np.ndarray, **kw):
    geo, circle = polygon_arc(v)
    args = dict(
        radius_mm=geo.radius_mm, vertices_mm=v, circle_centre_mm=circle.centre,
        circle_covariance_mm2=circle.covariance, circle_radius_sigma_mm=circle.radius_sigma,
        divisions=N, mm_per_px=0.2, wire_radius_mm=1.5, silhouette=True,
        end_uncertainty_px=[0.0, 0.0], lens_sigma_mm=None,
    )  # fmt: skip
    args.update(kw)
    return arc_uncertainty(**args)


def test_each_common_term_is_what_moving_the_vertices_alike_does_to_the_fit():
    v = _arc_vertices()
    base, _ = polygon_arc(v)
    u = _uncertainty(v)
    # a common radial offset of the silhouette's sigma moves the fitted radius by as much
    d_mm = SILHOUETTE_OFFSET_PX * 0.2
    moved, _ = polygon_arc(_arc_vertices(R_MM + d_mm))
    assert moved.radius_mm - base.radius_mm == pytest.approx(u.offset_radius_mm, rel=1e-6)
    # an end moved along its chord by the end sigma (the other end likewise: the two in
    # quadrature) turns the refitted circle's sweep and moves its radius by the ends' terms
    along_mm = END_ALONG_PX * 0.2
    d_arc, d_r = [], []
    for end, nb in ((0, 1), (-1, -2)):
        slid = v.copy()
        step = v[end] - v[nb]
        slid[end] = v[end] + along_mm * step / np.hypot(*step)
        got, _ = polygon_arc(slid)
        d_arc.append(got.arc_angle_deg - base.arc_angle_deg)
        d_r.append(got.radius_mm - base.radius_mm)
    assert math.hypot(*d_arc) == pytest.approx(u.ends_arc_deg, rel=0.02)
    assert math.hypot(*d_r) == pytest.approx(u.ends_radius_mm, rel=0.02)
    # about u / R of each end's sweep: the refitted centre takes up a little of it
    turn_deg = math.degrees(along_mm / R_MM)
    assert 0.6 * turn_deg < abs(d_arc[0]) < turn_deg
    assert u.segment_bend_sigma_deg == pytest.approx(u.arc_angle_sigma_deg / N)
    # the lens' position sigma at both ends, over the chord: a scale, on the radius only
    lens = _uncertainty(v, lens_sigma_mm=0.05)
    chord_mm = float(np.hypot(*(v[-1] - v[0])))
    assert lens.scale_radius_mm == pytest.approx(R_MM * math.sqrt(2.0) * 0.05 / chord_mm)
    assert lens.arc_angle_sigma_deg == pytest.approx(u.arc_angle_sigma_deg)
    # the symmetric centre's offset is a share of the wire's radius, wider than the edges'
    assert _uncertainty(v, silhouette=False).offset_radius_mm > u.offset_radius_mm
    # a spacing that disagrees with the ends by D per chord: the bend per chord uncertain
    # by D, the radius by the same share of the arc
    spaced = _uncertainty(v, spacing_disagreement_deg=0.1)
    assert spaced.spacing_arc_deg == pytest.approx(0.1 * N)
    assert spaced.spacing_radius_mm == pytest.approx(R_MM * 0.1 * N / ARC_DEG, rel=1e-6)
    assert spaced.segment_bend_sigma_deg > 0.1
    # an end facing its shadow widens the arc's sigma by its one-sided range
    assert _uncertainty(v, end_uncertainty_px=[5.0, 0.0]).ends_arc_deg > u.ends_arc_deg


@pytest.mark.parametrize("divisions", [6, 13])
def test_without_a_chord_count_the_radius_sigma_reaches_the_vertices_circle(divisions):
    # a part bent in chords, its count not found: the radius is the centreline's best
    # circle, inside the vertices' circle by about 2/3 of the sagitta; the stated 2 sigma
    # must reach the vertices' circle (the radius asked for)
    phi = np.radians(-90.0 - ARC_DEG / 2 + np.linspace(0.0, ARC_DEG, divisions + 1))
    v = R_MM * np.column_stack((np.cos(phi), np.sin(phi)))
    line = resample_path(v, 0.1)  # every 0.1 mm along the chords: a centreline without noise
    geo, circle = polygon_arc(line)
    sagitta_mm = R_MM * (1.0 - math.cos(math.radians(ARC_DEG / divisions / 2)))
    low_mm = R_MM - geo.radius_mm
    assert 0.5 * sagitta_mm < low_mm < 0.8 * sagitta_mm  # 2/3 of it, the arc's ends aside
    u = _uncertainty(line, divisions=None)
    assert u.chords_radius_mm > 0.0
    assert low_mm <= 2.0 * u.radius_sigma_mm <= 1.6 * low_mm  # reached, not far beyond
    # with the count, the chords are fitted: no such term
    assert _uncertainty(v, divisions=divisions).chords_radius_mm == 0.0


def test_a_smooth_arcs_unseen_chords_term_is_its_noise():
    # a smooth arc (no chords) with centreline noise 0.05 mm: the term is the bound sqrt(5)
    # times the noise, halved
    rng = np.random.default_rng(3)
    phi = np.radians(np.linspace(-150.0, -30.0, 1200))
    line = R_MM * np.column_stack((np.cos(phi), np.sin(phi)))
    line += rng.normal(0.0, 0.05, line.shape)  # 0.05 mm rms on each axis, so radially too
    u = _uncertainty(line, divisions=None)
    assert u.chords_radius_mm == pytest.approx(0.5 * math.sqrt(5.0) * 0.05, rel=0.1)


def test_a_straight_wire_has_no_radius_uncertainty():
    line = np.column_stack((np.linspace(0.0, 80.0, N + 1), np.zeros(N + 1)))
    geo, circle = polygon_arc(line)
    assert not math.isfinite(geo.radius_mm)
    got = arc_uncertainty(
        radius_mm=geo.radius_mm, vertices_mm=line, circle_centre_mm=circle.centre,
        circle_covariance_mm2=circle.covariance, circle_radius_sigma_mm=circle.radius_sigma,
        divisions=N, mm_per_px=0.2, wire_radius_mm=1.5, silhouette=True,
        end_uncertainty_px=[0.0, 0.0], lens_sigma_mm=None,
    )  # fmt: skip
    assert got is None


@functools.lru_cache(maxsize=8)
def _measured(sheet: str, seed: int, light_azimuth_deg: float):
    camera = cvmeasure_datasets.default_camera().scaled(0.5)
    pose = Pose(tilt_deg=2.0, tilt_direction_deg=30.0, distance_mm=550.0, offset_mm=(-60.0, 20.0))
    part = cvmeasure_datasets.arc_part(R_MM, ARC_DEG, N, wire_diameter_mm=3.0)
    photo = render_round_wire(
        part.placed(20.0, (0.0, 0.0)), camera=camera, pose=pose, sheet=sheet, seed=seed,
        light_azimuth_deg=light_azimuth_deg,
    )  # fmt: skip
    opts = PartOptions(
        divisions=N, wire=WireOptions(diameter_mm=3.0), lift=LiftOptions(shadow=False)
    )
    return measure_part(photo.bgr, None, None, plane=photo.plane, options=opts)


@pytest.mark.parametrize(
    ("sheet", "seed", "light_azimuth_deg"),
    [("dark", 0, 30.0), ("dark", 5, 150.0), ("light", 3, 30.0)],
)
def test_the_radius_and_bend_per_chord_lie_within_two_stated_sigmas(sheet, seed, light_azimuth_deg):
    m = _measured(sheet, seed, light_azimuth_deg)
    d = m.to_dict()
    assert d["radius_sigma_mm"] == m.radius_sigma_mm and m.radius_sigma_mm is not None
    assert d["segment_bend_sigma_deg"] == m.segment_bend_sigma_deg
    # the stated sigma holds what the circle's sampling sigma leaves out: at least it
    assert m.radius_sigma_mm >= m.circle.radius_sigma
    assert abs(m.result.radius_mm - R_MM) <= 2.0 * m.radius_sigma_mm
    assert abs(m.result.segment_bend_deg - ARC_DEG / N) <= 2.0 * m.segment_bend_sigma_deg
    # and not so wide that it says nothing against the 0.3 % / 0.03 deg targets (measured at
    # the lab's 0.157 mm/px: radius sigma 0.14-0.25 %, bend per chord 0.029-0.043 deg; the
    # widest where the vertices' spacing disagrees with the ends, part_chord_spacing)
    assert m.radius_sigma_mm < 0.003 * R_MM
    assert m.segment_bend_sigma_deg < 0.05
    # part_imprecise exactly where a stated 2 sigma is wider than those targets
    wide = 2.0 * m.radius_sigma_mm > 0.003 * m.result.radius_mm or (
        2.0 * m.segment_bend_sigma_deg > 0.03
    )
    assert has_code(m.warnings, "part_imprecise") == wide


def test_imprecision_is_warned_about_the_quantities_wider_than_the_tolerances():
    """Tolerances 1 % above and below an arc's stated 2 sigmas: warned about exactly
    the quantity whose 2 sigma is wider, with its figure."""
    offset_only = _uncertainty(_arc_vertices(), silhouette=True)
    radius_pct = 200.0 * offset_only.radius_sigma_mm / R_MM
    bend_2sigma = 2.0 * offset_only.segment_bend_sigma_deg
    assert (
        imprecision_warning(
            offset_only, R_MM, radius_pct=radius_pct * 1.01, bend_deg=bend_2sigma * 1.01
        )
        is None
    )
    w = imprecision_warning(offset_only, R_MM, radius_pct=radius_pct * 0.99, bend_deg=1.0)
    assert w is not None and w.code == "part_imprecise"
    assert "radius" in w.message and "bend per chord" not in w.message
    assert f"{radius_pct:.2f} %" in w.message
    w = imprecision_warning(offset_only, R_MM, radius_pct=5.0, bend_deg=bend_2sigma * 0.99)
    assert w is not None and "bend per chord" in w.message and "radius" not in w.message
