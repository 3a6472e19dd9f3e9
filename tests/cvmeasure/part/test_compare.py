"""Registration of a measured centreline to its design and the deviation figures."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvmeasure.design import bend_angles_deg
from cvmeasure.part.compare import (
    compare_bends,
    deviation_profile,
    point_to_polyline,
    register_to_design,
)


def _rigid(points, angle_deg, shift, *, mirror=False):
    a = math.radians(angle_deg)
    r = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    p = points * np.array([1.0, -1.0]) if mirror else points
    return p @ r.T + np.asarray(shift)


def _saddle_vertices():
    # asymmetric on purpose: a symmetric S maps onto itself reversed
    bends = np.array([5.0] * 4 + [-3.0] * 8)
    heading = np.radians(np.concatenate(([10.0], 10.0 + np.cumsum(bends))))
    steps = 15.0 * np.column_stack((np.cos(heading), np.sin(heading)))
    return np.vstack(([0.0, 0.0], np.cumsum(steps, axis=0))), bends


@pytest.mark.parametrize(
    ("mirror", "reverse"), [(False, False), (True, False), (False, True), (True, True)]
)
def test_registration_undoes_rotation_mirror_and_reversal(mirror, reverse):
    design, bends = _saddle_vertices()
    measured = _rigid(design, 137.0, (300.0, -40.0), mirror=mirror)
    if reverse:
        measured = measured[::-1]
    reg = register_to_design(measured, design)
    assert reg.mirrored == mirror and reg.reversed == reverse
    np.testing.assert_allclose(reg.apply(measured), design[::-1] if reverse else design, atol=1e-6)
    assert reg.rms_mm < 1e-6
    # measured bends in the part's own order and sense come back in the design's
    measured_bends = bend_angles_deg(measured * np.array([1.0, 1.0]))
    cmp = compare_bends(
        measured_bends, design, reg, measured_segment_bend_deg=5.0, design_segment_bend_deg=5.0
    )
    np.testing.assert_allclose(cmp.measured_bend_deg, bends, atol=1e-6)
    assert cmp.max_abs_error_deg < 1e-6


def test_mirror_can_be_forbidden():
    design, _ = _saddle_vertices()
    measured = _rigid(design, 20.0, (5.0, 5.0), mirror=True)
    reg = register_to_design(measured, design, allow_mirror=False)
    assert not reg.mirrored and reg.rms_mm > 0.5


def test_deviation_profile_finds_a_local_bump():
    # design: half circle R100; part: the same with a 0.4 mm outward bump 60 deg from one end
    t = np.radians(np.linspace(180.0, 0.0, 3001))
    bump = 0.4 * np.exp(-0.5 * ((np.degrees(t) - 120.0) / 3.0) ** 2)
    design = np.column_stack((100 * np.cos(t), 100 * np.sin(t)))
    part = np.column_stack(((100 + bump) * np.cos(t), (100 + bump) * np.sin(t)))
    rng = np.random.default_rng(4)
    part = _rigid(part, -30.0, (50.0, 20.0)) + rng.normal(0, 0.002, part.shape)
    reg = register_to_design(part, design)
    dev = deviation_profile(part, design, reg)
    k = int(np.argmax(np.abs(dev.distance_mm)))
    assert dev.max_mm == pytest.approx(0.4, abs=0.05)  # the fit leans into the bump
    # outward is to the left of a clockwise traversal: positive
    assert dev.distance_mm[k] > 0
    assert dev.arc_length_mm[k] == pytest.approx(math.radians(60.0) * 100.0, abs=2.0)
    assert dev.rms_mm < 0.1
    assert dev.arc_length_mm[-1] == pytest.approx(math.pi * 100.0, rel=1e-3)


def test_point_to_polyline_signed_distances():
    poly = np.array([[0.0, 0.0], [10.0, 0.0], [10.0, 10.0]])
    pts = np.array([[5.0, 2.0], [5.0, -3.0], [12.0, 5.0]])
    feet, dist, along = point_to_polyline(pts, poly)
    np.testing.assert_allclose(dist, [2.0, -3.0, -2.0])
    np.testing.assert_allclose(feet, [[5, 0], [5, 0], [10, 5]])
    np.testing.assert_allclose(along, [5.0, 5.0, 15.0])


def test_seed_error_figures_follow_source_code_1():
    design, _ = _saddle_vertices()
    reg = register_to_design(design, design)
    cmp = compare_bends(
        bend_angles_deg(design),
        design,
        reg,
        measured_segment_bend_deg=8.3569032,
        design_segment_bend_deg=9.0,
    )
    assert cmp.seed_absolute_error_deg == pytest.approx(0.6430968)
    assert cmp.seed_relative_error_pct == pytest.approx(7.1455, abs=1e-3)
    with pytest.raises(ValueError, match="measured bends"):
        compare_bends(
            np.zeros(3), design, reg, measured_segment_bend_deg=1, design_segment_bend_deg=1
        )
