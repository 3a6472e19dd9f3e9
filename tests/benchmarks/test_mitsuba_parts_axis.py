"""The Mitsuba part benchmark's axis scoring: where a centreline lies against the axis the
renderer draws, projected into the photo (geometry only: no render, no Mitsuba needed)."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.heldout.mitsuba_scenes import PartScene
from benchmarks.mitsuba_parts import _axis_px, axis_errors_px, part_rig


def _outward(axis: np.ndarray) -> np.ndarray:
    """Unit normals (M, 2) of a projected arc pointing away from its concave side."""
    d = np.gradient(axis, axis=0)
    n = np.column_stack((-d[:, 1], d[:, 0])) / np.hypot(*d.T)[:, None]
    chord_mid = 0.5 * (axis[0] + axis[-1])  # on the concave side of an arc under 180 deg
    return n * np.sign(((axis - chord_mid) * n).sum(axis=1))[:, None]


def test_axis_errors_read_a_known_offset_and_a_short_end() -> None:
    rig = part_rig(1800, 1200)
    scene = PartScene(
        radius_mm=70.0, arc_angle_deg=110.0, wire_diameter_mm=2.0, yaw_deg=20.0, rig=rig,
        chords=9, lift_mm=1.5,
    )  # fmt: skip
    axis = _axis_px(scene, rig)
    exact = axis_errors_px(scene, rig, axis)
    assert exact["offset_px"] == pytest.approx(0.0, abs=1e-6)
    assert exact["ends_along_px"] == pytest.approx([0.0, 0.0], abs=1e-6)
    # every centre 1.5 px outside the arc, read back in either order
    moved = axis + 1.5 * _outward(axis)
    for line in (moved, moved[::-1]):
        got = axis_errors_px(scene, rig, line)
        assert got["offset_px"] == pytest.approx(1.5, abs=0.02)
    # the far end cut 30 px short, the near one carried 12 px past its end
    step = np.hypot(*np.diff(axis, axis=0).T)
    kept = axis[np.r_[0.0, np.cumsum(step)] <= step.sum() - 30.0]
    u = (axis[0] - axis[1]) / np.hypot(*(axis[0] - axis[1]))
    got = axis_errors_px(scene, rig, np.vstack((axis[0] + 12.0 * u, kept)))
    assert got["ends_along_px"] == pytest.approx([12.0, -30.0], abs=0.5)
    assert max(got["ends_across_px"]) < 0.5
