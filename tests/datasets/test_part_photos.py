"""Finished parts: design geometry and the rendered wire on its sheet."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.board import CharucoBoardSpec
from cvmeasure_datasets import Lighting, arc_part, polyline_part, render_part_photo, saddle_part
from cvmeasure_datasets.optics import project_frame_points


@pytest.mark.parametrize(
    ("radius", "angle", "n"), [(45.0, 70.0, 5), (85.0, 180.0, 12), (100.0, 120.0, 7)]
)
def test_arc_part_geometry(radius, angle, n):
    part = arc_part(radius, angle, n)
    v = part.vertices_mm
    assert len(v) == n + 1 and part.divisions == n
    assert np.allclose(np.hypot(v[:, 0], v[:, 1]), radius)
    chords = np.linalg.norm(np.diff(v, axis=0), axis=1)
    assert np.allclose(chords, 2 * radius * np.sin(np.radians(angle / n / 2)))
    assert np.allclose(part.segment_bend_deg, angle / n)
    assert part.chord_width_mm == pytest.approx(2 * radius * np.sin(np.radians(angle / 2)))
    half = angle / 2 / n * (n % 2)  # odd n: no vertex at the arc's middle
    assert part.height_mm == pytest.approx(
        radius * (np.cos(np.radians(half)) - np.cos(np.radians(angle / 2)))
    )
    with pytest.raises(ValueError):
        arc_part(-1.0, angle, n)


def test_saddle_has_equal_chords_and_changing_bend_sign():
    part = saddle_part(200.0, 20.0, 13)
    chords = np.linalg.norm(np.diff(part.vertices_mm, axis=0), axis=1)
    assert len(chords) == 13 and np.ptp(chords) < 1e-6
    assert part.chord_width_mm == pytest.approx(200.0)
    assert 19.0 < part.height_mm <= 20.0
    bends = part.segment_bend_deg
    assert bends[0] > 0 and bends[len(bends) // 2] < 0 and bends[-1] > 0
    first = np.diff(part.vertices_mm[:2], axis=0)[0]
    # mirror-symmetric: the last chord falls as steeply as the first rises
    assert bends.sum() == pytest.approx(-2 * np.degrees(np.arctan2(first[1], first[0])))
    assert np.isnan(part.radius_mm)


def test_rendered_wire_lies_on_the_truth_centreline():
    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    part = arc_part(70.0, 120.0, 8)
    photo = render_part_photo(
        part=part, board=board, sheet="dark", lighting=Lighting.clean(), seed=3, scale=0.25
    )
    t = photo.truth
    assert t["radius_mm"] == 70.0 and t["divisions"] == 8 and t["arc_angle_deg"] == 120.0
    assert np.allclose(t["segment_bend_deg"], 15.0)
    centreline = np.asarray(t["part"]["centreline_mm"])
    # placed rigidly: same chords and bends as the design
    assert np.allclose(np.linalg.norm(np.diff(centreline, axis=0), axis=1), part.chord_mm)
    # the whole part sits on the sheet, right of the board
    assert centreline[:, 0].min() > board.size_mm[0] + 10
    rot = np.asarray(t["pose"]["R_cam_frame"])
    tvec = np.asarray(t["pose"]["tvec_mm"])
    # sample the photo along the centreline (mid-chords) and 6 mm beside it
    mids = (centreline[:-1] + centreline[1:]) / 2
    d = np.diff(centreline, axis=0)
    normal = np.column_stack((-d[:, 1], d[:, 0])) / np.linalg.norm(d, axis=1)[:, None]
    on = project_frame_points(photo.camera, rot, tvec, mids)
    off = project_frame_points(photo.camera, rot, tvec, mids + 6.0 * normal)
    gray = photo.bgr.mean(axis=2)
    bright = gray[np.round(on[:, 1]).astype(int), np.round(on[:, 0]).astype(int)]
    dark = gray[np.round(off[:, 1]).astype(int), np.round(off[:, 0]).astype(int)]
    assert bright.min() > 150 and dark.max() < 60
    # the board's corners are in view
    assert all(t["corners_in_image"]) and len(t["corners_px"]) == board.corner_count


def test_light_sheet_and_polyline_parts():
    photo = render_part_photo(
        part=np.array([[0, 0], [40, 0], [60, 30]]), sheet="light", scale=0.125
    )
    assert photo.truth["sheet"] == "light" and photo.truth["part"]["kind"] == "polyline"
    assert photo.truth["segment_bend_deg"] == pytest.approx([np.degrees(np.arctan2(30, 20))])
    assert polyline_part([[0, 0], [1, 0]]).divisions == 1
    with pytest.raises(ValueError):
        render_part_photo(part=arc_part(50, 90, 4), sheet="grey", scale=0.125)  # type: ignore[arg-type]
