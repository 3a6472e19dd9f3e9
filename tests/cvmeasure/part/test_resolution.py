"""The wire's resolution check: rendered part photos at low and normal resolution."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.errors import InputError
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import PartOptions
from cvmeasure.part.resolution import (
    MIN_PX_PER_RADIUS,
    WARN_PX_PER_RADIUS,
    resolution_warning,
    wire_resolution,
)
from cvmeasure.warning import has_code

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
CODE = "part_low_resolution"


@functools.cache
def _photo(sheet: str, scale: float):
    """R60 120 deg in 10 chords of 2 mm wire from 900 mm (0.129 mm/px at scale 1)."""
    return cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(60.0, 120.0, 10), board=BOARD, sheet=sheet, seed=1,
        scale=scale,
    )  # fmt: skip


def _bend_errors(photo, m) -> np.ndarray:
    """Measured - true vertex bends (deg); the truth's direction of travel is arbitrary."""
    true = np.asarray(photo.truth["segment_bend_deg"], dtype=float)
    e1, e2 = m.vertex_bend_deg - true, m.vertex_bend_deg + true[::-1]
    return e1 if np.max(np.abs(e1)) <= np.max(np.abs(e2)) else e2


def _measure(photo):
    return measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=10))


def test_thresholds():
    # the apparent half-width over the plane's scale; the stated wire's figure named beside it
    low = resolution_warning(wire_resolution(2.0, 0.43, 2.0), "p.jpg")
    assert low is not None and low.code == CODE and low.subject == "p.jpg"
    assert "2.0 px per wire radius" in low.message and "2.3 px per radius" in low.message
    assert resolution_warning(wire_resolution(WARN_PX_PER_RADIUS, 0.3), "p.jpg") is None
    with pytest.raises(InputError, match="p.jpg: .*move the camera closer"):
        resolution_warning(wire_resolution(0.9 * MIN_PX_PER_RADIUS, 0.5), "p.jpg")
    with pytest.raises(InputError):
        resolution_warning(wire_resolution(float("nan"), 0.5), "p.jpg")


def test_low_resolution_light_sheet_is_warned():
    # 0.64 mm/px: about 1.6 px per wire radius; the centreline follows the shadow along a
    # stretch and vertex bends are off by degrees, beyond their sigmas
    photo = _photo("light", 0.2)
    m = _measure(photo)
    assert has_code(m.warnings, CODE)
    err = _bend_errors(photo, m)
    assert np.max(np.abs(err) / m.vertex_bend_sigma_deg) > 3.0  # what the warning is for


def test_low_resolution_dark_sheet_is_warned():
    m = _measure(_photo("dark", 0.3))  # about 1.9 px per (apparent) wire radius
    assert has_code(m.warnings, CODE)


@pytest.mark.parametrize("sheet", ["dark", "light"])
def test_normal_resolution_not_warned_and_sigma_covers(sheet):
    photo = _photo(sheet, 0.5)  # 0.26 mm/px: 3-4 px per apparent wire radius
    m = _measure(photo)
    assert not has_code(m.warnings, CODE)
    err = _bend_errors(photo, m)
    assert np.all(np.abs(err) <= 3.0 * m.vertex_bend_sigma_deg), (err, m.vertex_bend_sigma_deg)
