"""G-code generation: bend lists under the seed's rules, compensation, TinyG lines."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvmeasure.design import arc_points_mm, bend_angles_deg
from cvmeasure.driver.protocol import parse_block, track_positions
from cvmeasure.errors import InputError
from cvmeasure.gcode import (
    MachineLayout,
    bend_list,
    design_job,
    gcode_lines,
    pin_commands,
)
from cvmeasure.sim import pin_command_for_angle, simulate


def half_circle(chords: int = 20, radius_mm: float = 100.0) -> np.ndarray:
    return arc_points_mm((0.0, 0.0), radius_mm, 90.0, 180.0, chords=chords)


def saddle() -> np.ndarray:
    """A zig-zag whose bends change sign (like the seed's saddle)."""
    return np.array([[0, 0], [20, 0], [40, 10], [60, 0], [80, 10], [100, 10.0]])


def test_half_circle_bend_list_matches_geometry():
    bl = bend_list(half_circle(), source="half.svg")
    chord = 2 * 100.0 * math.sin(math.radians(4.5))
    assert len(bl.steps) == 20
    np.testing.assert_allclose([s.feed_mm for s in bl.steps], chord, atol=1e-9)
    # the design turns +9 deg (CCW) at each vertex; the machine bends the fed leg -9 deg
    np.testing.assert_allclose(bl.bends_deg, -9.0, atol=1e-9)
    assert bl.steps[-1].bend_deg == 0.0
    assert bl.total_feed_mm == pytest.approx(20 * chord, abs=1e-9)


def test_collinear_vertices_are_merged():
    bl = bend_list(np.array([[0, 0], [10, 0], [20, 0], [20, 30.0]]))
    assert [s.feed_mm for s in bl.steps] == pytest.approx([20.0, 30.0])
    assert bl.bends_deg.tolist() == pytest.approx([-90.0])


def test_setback_shortens_feeds_around_a_corner():
    r = 3.0
    bl = bend_list(np.array([[0, 0], [50, 0], [50, 50.0]]), bend_radius_mm=r)
    corr = r * (math.pi / 4 - math.tan(math.pi / 4))
    assert [s.feed_mm for s in bl.steps] == pytest.approx([50 + corr, 50 + corr], abs=1e-12)


def test_default_compensation_is_the_simulation_inverse():
    bl = bend_list(saddle())
    pins = pin_commands(bl)
    np.testing.assert_allclose(pins, pin_command_for_angle(bl.bends_deg), atol=1e-9)
    final = simulate(np.array(pins)).unloaded_bend_deg
    np.testing.assert_allclose(final, bl.bends_deg, atol=1e-6)


class _Table:
    """A stand-in calibration: pin = 1.5 * target (any object with compensate())."""

    def compensate(self, target_final_deg: float) -> float:
        if abs(target_final_deg) > 40:
            raise ValueError("outside the calibrated range 0..40 deg")
        return 1.5 * target_final_deg


def test_calibration_object_is_used_and_its_range_enforced():
    bl = bend_list(np.array([[0, 0], [20, 0], [40, 5], [60, 0.0]]))
    assert pin_commands(bl, _Table()) == pytest.approx(tuple(1.5 * b for b in bl.bends_deg))
    with pytest.raises(InputError, match=r"bend 1 of -90.00 deg cannot be made.*calibrated"):
        pin_commands(bend_list(np.array([[0, 0], [20, 0], [20, 20.0]]), source="l.svg"), _Table())


def test_gcode_lines_follow_the_tinyg_rules():
    job = design_job(saddle(), source="designs/saddle.svg")
    lines = job.lines
    assert lines[0].startswith("N1 G21 G90")
    numbers = [parse_block(t).line_number for t in lines]
    assert numbers == list(range(1, len(lines) + 1))
    assert not any(c in t for t in lines for c in "!~%$?\r\t")
    blocks = [parse_block(t) for t in lines]
    for b in blocks:
        if "y" in b.axes:
            assert b.distance_mode == "relative" and b.feed == 3000.0
        if "x" in b.axes and b.motion == 1:
            assert b.distance_mode == "absolute"
    # the total relative feed is the wire length
    pos = track_positions(blocks)
    assert pos[-1]["y"] == pytest.approx(job.bends.total_feed_mm, abs=5e-3)
    # every bend goes to its pin command and back home, ducking when the sign changes
    bends_x = [b.axes["x"] for b in blocks if "x" in b.axes and b.motion == 1 and b.feed]
    np.testing.assert_allclose(bends_x, job.pin_deg, atol=5e-4)
    signs = np.sign(job.bends.bends_deg)
    changes = int(np.sum(signs[1:] != signs[:-1]))
    assert sum(1 for b in blocks if b.axes.get("z") == 180.0) == changes
    assert lines[-1] == f"N{len(lines)} (end)"


def test_layout_homes_per_side_and_pin_limit():
    bl = bend_list(saddle())
    pins = pin_commands(bl)
    lay = MachineLayout(home_ccw_deg=-10.0, home_cw_deg=10.0)
    lines = gcode_lines(bl, pins, layout=lay)
    blocks = [parse_block(t) for t in lines]
    xs = [b.axes["x"] for b in blocks if "x" in b.axes and b.feed]
    np.testing.assert_allclose(xs, [p + (10.0 if p < 0 else -10.0) for p in pins], atol=5e-4)
    with pytest.raises(InputError, match="beyond the machine's 20 deg"):
        gcode_lines(bl, pins, layout=MachineLayout(max_pin_deg=20.0))


def test_shape_rules_are_named():
    with pytest.raises(InputError, match="closed shape"):
        bend_list(np.array([[0, 0], [30, 0], [30, 30], [0, 0.0]]), source="sq.svg")
    with pytest.raises(InputError, match="closed shape"):
        bend_list(np.array([[0, 0], [30, 0], [30, 30.0]]), closed=True)
    with pytest.raises(InputError, match=r"sq.svg: segment 2 .* 8.00 mm long; .* 12 mm"):
        bend_list(np.array([[0, 0], [30, 0], [30, 8], [60, 8.0]]), source="sq.svg")
    with pytest.raises(InputError, match=r"bend at vertex 1 .* 150.0 deg; .* at most 135"):
        bend_list(np.array([[0, 0], [30, 0], [30 - 30 * math.cos(math.radians(30)), 15.0]]))
    with pytest.raises(InputError, match="fewer than 2 points"):
        bend_list(np.zeros((1, 2)))


def test_unreachable_bend_for_the_simulation_is_input_error():
    pts = np.array(
        [[0, 0], [30, 0], [30 - 30 * math.cos(math.radians(0.3)), 30 * math.sin(math.radians(0.3))]]
    )
    assert abs(bend_angles_deg(pts)[0]) > 179.5
    with pytest.raises(InputError, match="cannot be made"):
        design_job(pts, max_bend_deg=180.0)
