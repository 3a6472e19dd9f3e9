"""A part measured on pixel blocks: the working image's frame and the measurement through it."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.errors import InputError
from cvmeasure.lens.plane import estimate_plane
from cvmeasure.part.compare import point_to_polyline
from cvmeasure.part.downsample import auto_downsample, downsample_photo, photo_px
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import PartOptions, WireOptions

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)


@functools.cache
def _photo():
    # full size, 0.13 mm/px: the 2 mm wire is 15 px wide, 7.7 px over 2 x 2 blocks
    pose = cvmeasure_datasets.Pose(
        tilt_deg=2.5, tilt_direction_deg=40.0, distance_mm=900.0, offset_mm=(280.0, 100.0)
    )
    return cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(60.0, 180.0, 10), board=BOARD, sheet="light",
        pose=pose, seed=3, scale=1.0,
    )  # fmt: skip


@functools.cache
def _plane():
    photo = _photo()
    return estimate_plane(photo.bgr, BOARD, photo.camera, source="part")


def test_working_pixels_see_the_plate_as_the_photo_does():
    photo, plane = _photo(), _plane()
    small, small_plane = downsample_photo(photo.bgr, plane, 2)
    h, w = photo.bgr.shape[:2]
    assert small.shape[:2] == (h // 2, w // 2)
    assert small_plane.mm_per_px == pytest.approx(2 * plane.mm_per_px, rel=1e-12)
    rng = np.random.default_rng(5)
    pts = rng.uniform((0, 0), (w - 1, h - 1), size=(50, 2))
    working = (pts + 0.5) / 2 - 0.5
    np.testing.assert_allclose(photo_px(working, 2), pts, atol=1e-9)
    for height_mm in (0.0, 1.5):  # the board's plane and a wire axis above it
        np.testing.assert_allclose(
            small_plane.image_to_plane_mm(working, height_mm=height_mm),
            plane.image_to_plane_mm(pts, height_mm=height_mm),
            atol=1e-6,
        )
    # the lens' uncertainty on the plate is the photo's, in mm
    assert small_plane.lens_uncertainty_mm() == pytest.approx(plane.lens_uncertainty_mm())


def test_a_block_mean_keeps_a_spot_where_it_lies():
    # every working pixel is one block's mean: a spot's centroid maps back exactly
    yy, xx = np.mgrid[0:241, 0:321].astype(np.float64)  # odd sizes: the last row, column cut
    centre = (101.3, 57.8)
    spot = np.exp(-((xx - centre[0]) ** 2 + (yy - centre[1]) ** 2) / (2 * 4.0**2))
    small, _ = downsample_photo(spot.astype(np.float32), _plane(), 2)
    ys, xs = np.mgrid[0 : small.shape[0], 0 : small.shape[1]]
    found = np.array([(small * xs).sum(), (small * ys).sum()]) / small.sum()
    np.testing.assert_allclose(photo_px(found, 2), centre, atol=1e-3)


def test_part_measured_on_blocks_against_truth():
    photo = _photo()
    truth = photo.truth
    n = truth["divisions"]
    plain = measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=n))
    m = measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=n, downsample=2))
    assert m.downsample == 2 and plain.downsample == 1
    assert m.result.radius_mm == pytest.approx(truth["radius_mm"], rel=0.003)
    assert m.result.segment_bend_deg == pytest.approx(truth["arc_angle_deg"] / n, abs=0.05)
    _, dist, _ = point_to_polyline(m.centreline_mm, np.asarray(truth["part"]["centreline_mm"]))
    assert np.sqrt(np.mean(dist**2)) < 0.05
    # the record's pixels are the photo's: its centreline lies on the one measured there,
    # and its plane is the photo's own
    _, dist_px, _ = point_to_polyline(m.centreline_px, plain.centreline_px)
    assert np.median(dist_px) < 0.5
    assert m.plane == plain.plane
    assert m.wire.width_px == pytest.approx(plain.wire.width_px, rel=0.15)
    # the same radius within the two readings' stated sigmas
    both = np.hypot(m.radius_sigma_mm, plain.radius_sigma_mm)
    assert abs(m.result.radius_mm - plain.result.radius_mm) <= 2 * both


def test_auto_blocks_bring_a_wide_wire_near_twelve_px():
    # a 3 mm wire at 0.13 mm/px is 23 px wide: auto measures it over 2 x 2 blocks
    pose = cvmeasure_datasets.Pose(
        tilt_deg=2.5, tilt_direction_deg=40.0, distance_mm=900.0, offset_mm=(280.0, 100.0)
    )
    photo = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(70.0, 120.0, 8, wire_diameter_mm=3.0), board=BOARD,
        sheet="dark", pose=pose, seed=8, scale=1.0,
    )  # fmt: skip
    truth, n = photo.truth, photo.truth["divisions"]
    opts = PartOptions(divisions=n, wire=WireOptions(diameter_mm=3.0), downsample=None)
    m = measure_part(photo.bgr, BOARD, photo.camera, options=opts)
    assert m.downsample == auto_downsample(m.plane.mm_per_px, 3.0) == 2
    assert m.result.radius_mm == pytest.approx(truth["radius_mm"], rel=0.003)
    assert m.result.segment_bend_deg == pytest.approx(truth["arc_angle_deg"] / n, abs=0.05)
    # without the diameter the profiles' centre of symmetry is measured on the photo itself
    assert auto_downsample(m.plane.mm_per_px, None) == 1


def test_the_default_is_the_photos_own_pixels():
    assert PartOptions().downsample == 1


def test_downsample_must_be_whole_and_positive():
    for bad in (0, -1, 1.5):
        with pytest.raises(ValueError, match="downsample"):
            PartOptions(downsample=bad)


def test_no_board_in_the_photo_is_named_before_any_block_is_averaged():
    blank = np.full((600, 800, 3), 128, np.uint8)
    with pytest.raises(InputError, match="blank"):
        measure_part(
            blank, BOARD, _photo().camera.scaled(800 / _photo().camera.image_size_px[0]),
            options=PartOptions(downsample=2), source="blank",
        )  # fmt: skip
