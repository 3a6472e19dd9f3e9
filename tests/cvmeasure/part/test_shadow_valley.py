"""Symmetric centres keep off a lifted part's parted shadow on a dark sheet
(cvmeasure/part/centreline.py, ``_sheet_floor``), on the photo lab's ray-traced round
wire (datasets/round_wire.py), half size, development seed 9110.

A bright wire on a dark sheet lifted at one end casts a shadow that parts from it: a dark
valley beside the wire, symmetric too, which the symmetric centres followed for a stretch.
A centre not above the sheet lies on no bright wire: every pass looks for the centres
above it, the first across the whole mask (which holds the shadow too).
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial import cKDTree

import cvmeasure_datasets
from cvmeasure.part.measure import measure_centreline_mm
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.round_wire import render_round_wire

WIRE_MM = 3.0
POSE = Pose(tilt_deg=1.5, tilt_direction_deg=70.0, distance_mm=550.0, offset_mm=(30.0, -20.0))


@pytest.mark.parametrize("lift_mm", [2.0, 3.0])
def test_symmetric_centres_stay_on_a_lifted_wire_beside_its_parted_shadow(lift_mm):
    """Measured on these renders at the plane's true scale (0.157 mm/px; symmetric centres,
    no stated width, lamp at 35 deg elevation): the centres' largest distance from the true
    axis 5.9 px (2 mm lift) and 5.0 px (3 mm), centres along 88 % and 97 % of the wire;
    they reached 27.6 and 29.5 px along the parted shadow when no centre was barred, and
    with centres only dropped after the passes the 3 mm wire was followed along 49 % of it.
    Tolerance: the wire's radius (9.5 px at half size), a centre on the wire; the symmetric
    centre of a side-lit wire leans towards its highlight by up to that (module notes)."""
    camera = cvmeasure_datasets.default_camera().scaled(0.5)
    part = cvmeasure_datasets.arc_part(60.0, 100.0, 7, wire_diameter_mm=WIRE_MM)
    photo = render_round_wire(
        part.placed(35.0, (0.0, 0.0)), camera=camera, pose=POSE, wire_diameter_mm=WIRE_MM,
        lift_mm=lift_mm, lift_direction_deg=35.0, sheet="dark", light_azimuth_deg=215.0,
        light_elev_deg=35.0, seed=9110,
    )  # fmt: skip
    _, _, centre, _ = measure_centreline_mm(photo.bgr, None, None, plane=photo.plane)
    v = photo.vertices_mm
    axis = np.vstack([np.linspace(a, b, 400) for a, b in zip(v[:-1], v[1:], strict=True)])
    rot, t_mm = POSE.extrinsics("board")
    axis_px = camera.project(axis @ rot.T + t_mm)
    off_px, _ = cKDTree(axis_px).query(centre.points_px)
    radius_px = 0.5 * WIRE_MM * camera.fx / POSE.distance_mm
    assert off_px.max() <= radius_px
    # the wire is still followed along most of its length
    assert centre.coverage >= 0.6
