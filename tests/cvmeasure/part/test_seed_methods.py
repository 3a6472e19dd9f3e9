"""The seed paper's methods: Source code 1 on its published numbers, the robust
circle-ellipse intersection, and its ellipse and sagitta arc methods."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvmeasure.design import arc_points_mm
from cvmeasure.part.seed_methods import (
    SEED_HALF_CIRCLE,
    SEED_SADDLE,
    circle_ellipse_intersections,
    ellipse_method,
    sagitta_method,
    seed_bending_angle,
    trig_quadratic_roots,
)

# The seed's Part III, 8: (relative %, absolute deg) of its three bending experiments,
# printed to two decimals (some rounded, some cut), so compared within 0.01.
PUBLISHED_HALF_CIRCLE = [(7.14, 0.64), (14.21, 1.28), (0.63, 0.05)]
PUBLISHED_SADDLE = [(45.68, 1.59), (29.11, 1.01), (2.37, 0.08)]


@pytest.mark.parametrize(
    ("inputs", "published", "design_bend"),
    [(SEED_HALF_CIRCLE, PUBLISHED_HALF_CIRCLE, 9.0), (SEED_SADDLE, PUBLISHED_SADDLE, 3.48)],
)
def test_source_code_1_reproduces_the_published_errors(inputs, published, design_bend):
    table = seed_bending_angle(**inputs)
    assert table.bend_angle_deg[0] == pytest.approx(design_bend, abs=0.005)
    for k, (rel_pct, abs_deg) in enumerate(published, start=1):
        assert abs(table.relative_error_pct[k]) == pytest.approx(rel_pct, abs=0.01)
        assert abs(table.absolute_error_deg[k]) == pytest.approx(abs_deg, abs=0.01)
    assert table.absolute_error_deg[0] == 0.0


def _ellipse_points(centre, semi, angle_deg, t):
    ca, sa = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    return np.column_stack(
        (
            centre[0] + semi[0] * np.cos(t) * ca - semi[1] * np.sin(t) * sa,
            centre[1] + semi[0] * np.cos(t) * sa + semi[1] * np.sin(t) * ca,
        )
    )


def _brute_force_count(cc, r, ec, semi, ang):
    t = np.linspace(0, 2 * np.pi, 200_001)
    pts = _ellipse_points(ec, semi, ang, t)
    f = np.hypot(pts[:, 0] - cc[0], pts[:, 1] - cc[1]) - r
    return int(np.sum(np.sign(f[:-1]) != np.sign(f[1:])))


def test_intersections_find_every_root_on_random_pairs():
    rng = np.random.default_rng(2026)
    counts = {0: 0, 2: 0, 4: 0}
    for _ in range(300):
        ec = rng.uniform(-5, 5, 2)
        semi = (rng.uniform(1, 6), rng.uniform(0.3, 6))
        ang = rng.uniform(-180, 180)
        if rng.random() < 0.5:  # anywhere
            cc = ec + rng.uniform(-6, 6, 2)
            r = rng.uniform(0.5, 8)
        else:  # near-concentric: mostly 4 intersections
            cc = ec + rng.uniform(-0.3, 0.3, 2)
            r = rng.uniform(min(semi), max(semi))
        pts = circle_ellipse_intersections(cc, r, ec, semi, ang)
        expected = _brute_force_count(cc, r, ec, semi, ang)
        assert len(pts) == expected
        counts[expected] = counts.get(expected, 0) + 1
        # every returned point is on both curves
        np.testing.assert_allclose(np.hypot(*(pts - cc).T), r, atol=1e-8)
        ca, sa = math.cos(math.radians(ang)), math.sin(math.radians(ang))
        u = (pts[:, 0] - ec[0]) * ca + (pts[:, 1] - ec[1]) * sa
        v = -(pts[:, 0] - ec[0]) * sa + (pts[:, 1] - ec[1]) * ca
        np.testing.assert_allclose((u / semi[0]) ** 2 + (v / semi[1]) ** 2, 1.0, atol=1e-8)
    assert counts[4] >= 5 and counts[2] >= 50 and counts[0] >= 1  # all cases exercised


def test_intersections_with_a_root_at_the_parametrisation_seam_and_tangency():
    # the circle point at t = pi lies on the ellipse (u = tan(t/2) is infinite there)
    pts = circle_ellipse_intersections((3.0, 0.0), 1.0, (0.0, 0.0), (2.0, 1.0), 0.0)
    assert any(np.allclose(p, [2.0, 0.0], atol=1e-7) for p in pts)
    # tangent: a circle inscribed at the ends of the major axis touches at 2 points
    pts = circle_ellipse_intersections((0.0, 0.0), 2.0, (0.0, 0.0), (2.0, 0.5), 0.0)
    assert len(pts) == 2
    np.testing.assert_allclose(np.sort(pts[:, 0]), [-2.0, 2.0], atol=1e-7)


def test_trig_quadratic_roots_of_a_known_polynomial():
    # cos(2t) = 0 -> t = pi/4 + k pi/2
    roots = trig_quadratic_roots((0.0, 0.0, 0.0, 1.0, 0.0))
    np.testing.assert_allclose(roots, np.pi / 4 + np.arange(4) * np.pi / 2, atol=1e-12)
    with pytest.raises(ValueError, match="identically zero"):
        trig_quadratic_roots((0.0, 0.0, 0.0, 0.0, 0.0))


def _wire_outline(radius, arc_deg, wire_d=3.0, n=600):
    """Both flanks of a wire bent on a circular arc (the seed's contour), mm."""
    start = 90 + arc_deg / 2
    outer = arc_points_mm((0, 0), radius + wire_d / 2, start, -arc_deg, chords=n)
    inner = arc_points_mm((0, 0), radius - wire_d / 2, start, -arc_deg, chords=n)
    return np.vstack((outer, inner[::-1]))


@pytest.mark.parametrize("arc_deg", [90.0, 120.0, 150.0])
def test_ellipse_method_on_a_clean_arc_outline(arc_deg):
    r = 60.0
    res = ellipse_method(_wire_outline(r, arc_deg))
    assert res.intersections >= 2 or res.intersections == 0
    # its end points are where the outer flank meets the enclosing circle
    outer_r = r + 1.5
    np.testing.assert_allclose(np.hypot(*res.end_points_mm.T), outer_r, rtol=0.02)
    # the hull is the outer flank: the radius comes out near the outer radius
    assert res.radius_mm == pytest.approx(outer_r, rel=0.03)
    assert res.arc_angle_deg == pytest.approx(arc_deg, abs=6.0)


def test_sagitta_method_includes_the_wire_thickness():
    r, arc = 60.0, 120.0
    res = sagitta_method(_wire_outline(r, arc))
    half = math.radians(arc / 2)
    # rectangle: width = outer chord, height = outer sagitta + wire diameter - ...
    d_expected = 2 * (r + 1.5) * math.sin(half)
    h_expected = (r + 1.5) - (r - 1.5) * math.cos(half)
    assert res.chord_width_mm == pytest.approx(d_expected, abs=1e-3)
    assert res.height_mm == pytest.approx(h_expected, abs=1e-3)
    assert res.radius_mm == pytest.approx(d_expected**2 / (8 * h_expected) + h_expected / 2)
