"""A known limit: the wire's stated diameter on a light sheet of the photo lab."""

from __future__ import annotations

import functools

import numpy as np
import pytest

from cvmeasure.board import CharucoBoardSpec
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import PartOptions, WireOptions

cvmeasure_datasets = pytest.importorskip("cvmeasure_datasets")

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)


@functools.cache
def _photo():
    """R60 120 deg in 10 chords of 2 mm wire on the light sheet, 0.26 mm/px."""
    part = cvmeasure_datasets.arc_part(60.0, 120.0, 10)
    return cvmeasure_datasets.render_part_photo(
        part=part, board=BOARD, sheet="light", seed=1, scale=0.5
    )


@pytest.mark.xfail(
    strict=True,
    reason=(
        "known defect: with --wire-diameter-mm on the photo lab's light sheet (a hard cast "
        "shadow beside the wire) the centreline is lost along two chords and the vertex "
        "bends are off by up to 16 deg (warned: part_centreline_gap, part_s_curve); "
        "without the diameter the same photo measures within 0.05 deg"
    ),
)
def test_a_stated_diameter_on_a_light_sheet_measures_the_arc():
    photo = _photo()
    options = PartOptions(divisions=10, wire=WireOptions(diameter_mm=2.0))
    m = measure_part(photo.bgr, BOARD, photo.camera, options=options)
    true = np.asarray(photo.truth["segment_bend_deg"], dtype=float)
    assert m.vertex_bend_deg is not None
    assert np.max(np.abs(np.abs(m.vertex_bend_deg) - np.abs(true))) < 0.1  # deg


def test_the_same_photo_without_the_diameter_measures_the_arc():
    photo = _photo()
    m = measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=10))
    true = np.asarray(photo.truth["segment_bend_deg"], dtype=float)
    assert np.max(np.abs(np.abs(m.vertex_bend_deg) - np.abs(true))) < 0.1  # deg
