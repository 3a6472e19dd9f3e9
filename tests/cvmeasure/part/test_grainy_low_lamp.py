"""A rough steel wire on a grainy white sheet under a lamp 8 deg above it (the photo lab's
round wire): its profiles are not symmetric (one flank lit) and single profiles have the
silhouette edges a width apart along under half of it, so the edges are looked for on
profiles averaged along the wire (:data:`cvmeasure.part.centreline.EDGE_AVERAGE_WIDTHS`)."""

from __future__ import annotations

import functools

import pytest

import cvmeasure_datasets
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
from cvmeasure.warning import has_code
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.round_wire import render_round_wire

WIRE_MM = 3.0
RADIUS_MM, ARC_DEG, CHORDS = 82.86, 122.7, 16
# 1152 x 768 px, 0.29 mm/px at 500 mm: a 3 mm wire is about 10.5 px wide
POSE = Pose(tilt_deg=2.0, tilt_direction_deg=30.0, distance_mm=500.0, offset_mm=(-60.0, 20.0))
#: Warnings that cover a bend per chord off target (as benchmarks.mitsuba_parts scores them).
BEND_COVERED = ("part_s_curve", "part_centreline_gap", "part_chord_spacing", "part_cut_off")


@functools.lru_cache(maxsize=4)
def _measured(seed: int):
    camera = cvmeasure_datasets.default_camera().scaled(0.25)
    part = cvmeasure_datasets.arc_part(RADIUS_MM, ARC_DEG, CHORDS, wire_diameter_mm=WIRE_MM)
    # a lit room (ambient twice the lamp's full light) and the lamp 8 deg up: a faint long
    # shadow; rough steel (a weak broad highlight); sheet grain of 20 grey levels per pixel
    photo = render_round_wire(
        part.placed(20.0, (0.0, 0.0)),
        camera=camera,
        pose=POSE,
        sheet="light",
        light_elev_deg=8.0,
        light_azimuth_deg=150.0,
        light_size_deg=20.0,
        ambient=2.0,
        specular=0.3,
        shininess=10.0,
        noise=20.0,
        seed=seed,
    )
    return measure_part(
        photo.bgr,
        None,
        None,
        plane=photo.plane,
        options=PartOptions(wire=WireOptions(diameter_mm=WIRE_MM), lift=LiftOptions(shadow=False)),
    )


@pytest.mark.parametrize("seed", [0, 3])
def test_a_grainy_sheet_under_a_low_lamp_is_measured_on_target(seed):
    # before the averaged profiles: refused, "looks like a round wire along only 43 % / 46 %"
    m = _measured(seed)
    assert m.wire.centre_from == "silhouette"
    assert m.result.divisions == CHORDS
    # measured: radius -0.17 % / -0.12 %, bend per chord 0.008 / 0.018 deg
    assert abs(m.result.radius_mm / RADIUS_MM - 1.0) < 0.003
    assert abs(m.result.segment_bend_deg - ARC_DEG / CHORDS) < 0.03


@pytest.mark.parametrize("seed", [1, 2])
def test_a_grainy_sheet_under_a_low_lamp_is_on_target_or_warned(seed):
    # before: refused (46 %); measured: radius +0.04 % / -0.03 %, bend per chord +0.037 /
    # +0.004 deg (seed 1: one end's chord not traced, 15 chords of 11.1 mm found, warned by
    # part_chord_spacing)
    m = _measured(seed)
    assert abs(m.result.radius_mm / RADIUS_MM - 1.0) < 0.003
    bend_err = abs(m.result.segment_bend_deg - ARC_DEG / CHORDS)
    assert bend_err < 0.03 or any(has_code(m.warnings, c) for c in BEND_COVERED)
