"""The chord count of arcs whose vertices hide in the centreline's noise (synthetic truth)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvmeasure.part.arc import arc_from_points
from cvmeasure.part.chord_period import (
    centreline_noise_mm,
    chord_spacing_warning,
    periodic_chords,
)
from cvmeasure.part.fit import count_chords


def _noisy(pts: np.ndarray, noise_mm: float, rng: np.random.Generator) -> np.ndarray:
    """Noise across the wire, correlated over 3 centres as a photo's centres are."""
    d = np.gradient(pts, axis=0)
    normal = np.column_stack((-d[:, 1], d[:, 0])) / np.hypot(*d.T)[:, None]
    w = np.convolve(rng.standard_normal(len(pts) + 4), np.ones(3) / math.sqrt(3), "valid")
    return pts + (noise_mm * w[: len(pts)])[:, None] * normal


def _chords(radius_mm: float, arc_deg: float, n: int, noise_mm: float, seed: int) -> np.ndarray:
    """Centres every 0.3 mm along ``n`` equal chords, vertices on the circle."""
    rng = np.random.default_rng(seed)
    th = np.radians(np.linspace(0.0, arc_deg, n + 1)) + rng.uniform(0.0, 2 * math.pi)
    v = radius_mm * np.column_stack((np.cos(th), np.sin(th)))
    k = int(np.hypot(*(v[1] - v[0])) / 0.3)
    t = np.linspace(0.0, 1.0, k, endpoint=False)[:, None]
    pts = np.vstack([a + t * (b - a) for a, b in zip(v[:-1], v[1:], strict=True)] + [v[-1:]])
    return _noisy(pts, noise_mm, rng)


def _smooth(radius_mm: float, arc_deg: float, noise_mm: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    phi = np.linspace(0.0, math.radians(arc_deg), int(radius_mm * math.radians(arc_deg) / 0.3))
    return _noisy(radius_mm * np.column_stack((np.cos(phi), np.sin(phi))), noise_mm, rng)


# sagittas 0.15-0.9 mm: chords of 10-11 mm at R 80-85 leave 0.16-0.18 mm, 3-8 times the noise
@pytest.mark.parametrize("noise_mm", [0.02, 0.04, 0.06])
@pytest.mark.parametrize(
    ("radius_mm", "arc_deg", "n"),
    [(80, 90, 12), (85, 120, 16), (45, 70, 6), (70, 100, 3), (85, 180, 24)],
)
def test_the_chord_count_below_the_vertices_noise_is_the_true_one(radius_mm, arc_deg, n, noise_mm):
    for seed in (1, 2):
        pts = _chords(radius_mm, arc_deg, n, noise_mm, seed)
        found = count_chords(pts)
        assert found.divisions == n, found.reason
        assert found.periodic is not None
        assert found.periodic.noise_mm == pytest.approx(noise_mm, rel=0.35)


@pytest.mark.parametrize("noise_mm", [0.02, 0.06])
@pytest.mark.parametrize(("radius_mm", "arc_deg"), [(80, 90), (45, 70), (60, 150)])
def test_a_smooth_arc_has_no_count_and_says_why(radius_mm, arc_deg, noise_mm):
    for seed in range(3):
        found = count_chords(_smooth(radius_mm, arc_deg, noise_mm, seed))
        assert found.divisions is None, found.reason
        assert found.periodic is not None and found.periodic.significance < found.periodic.threshold


def test_a_count_not_clearly_better_than_its_neighbour_is_withheld():
    # 12 chords at R 80 under 0.4 mm of noise: the scallop (0.17 mm) is not resolved
    found = periodic_chords(_chords(80, 90, 12, 0.4, 3))
    assert found is not None and found.divisions is None
    assert found.significance < found.threshold or found.margin < 2 * math.log(100)


def test_the_noise_at_scales_below_a_chord_ignores_the_vertices():
    rng = np.random.default_rng(4)
    pts = _chords(50, 120, 6, 0.0, 4)  # sagitta 1.3 mm: the vertices' kinks are strong
    pts = pts + rng.normal(0.0, 0.03, pts.shape)
    assert centreline_noise_mm(pts) == pytest.approx(0.03, rel=0.2)


@pytest.mark.parametrize("cut_mm", [0.0, 3.0])
def test_an_end_cut_short_is_told_by_the_vertices_spacing(cut_mm):
    pts = _chords(80, 90, 12, 0.04, 5)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(pts, axis=0).T))]
    pts = pts[s >= cut_mm]  # the first end hidden (a shadow, the board's edge)
    found = count_chords(pts)
    assert found.divisions == 12 and found.periodic is not None
    # the vertices' spacing gives the bend per chord whatever the ends: 7.5 deg
    assert found.periodic.chord_angle_deg == pytest.approx(
        7.5, abs=3 * found.periodic.chord_angle_sigma_deg
    )
    arc_over_n = arc_from_points(pts, 12)[0].segment_bend_deg
    warning = chord_spacing_warning(arc_over_n, 12, found.periodic)
    assert abs(arc_over_n - 7.5) > 0.1 if cut_mm else abs(arc_over_n - 7.5) < 0.03
    assert (warning is not None) == bool(cut_mm)
    assert warning is None or warning.code == "part_chord_spacing"


def test_a_count_whose_chords_fall_in_a_gap_is_placed_across_it():
    """Two chords of eight lost from the centreline (a shadow, a glare): the scallop still shows
    eight equal chords; the missing ones are placed on the line across the gap (their
    directions unmeasured, which the part's warnings say), the other vertices' bends within
    0.05 deg of the truth (centres' noise 0.01 mm; measured 0.036)."""
    radius_mm, arc_deg, chords = 60.0, 100.0, 8
    ang = np.radians(np.linspace(-arc_deg / 2, arc_deg / 2, chords + 1))
    v = np.c_[radius_mm * np.cos(ang), radius_mm * np.sin(ang)]
    pts = np.vstack(
        [np.linspace(a, b, 120, endpoint=False) for a, b in zip(v[:-1], v[1:], strict=True)]
        + [v[-1:]]
    )
    pts = pts + np.random.default_rng(0).normal(0.0, 0.01, pts.shape)
    one_lost = count_chords(np.r_[pts[:370], pts[510:]])
    assert one_lost.divisions == chords  # a gap within one chord's reach: still placed
    two_lost = count_chords(np.r_[pts[:220], pts[500:]])
    assert two_lost.divisions == chords
    # chords 2-4 lie (partly) in the gap: the bends at vertices 1-4 touch them
    bend = arc_deg / chords
    assert np.abs(np.abs(two_lost.turn_deg[4:]) - bend).max() < 0.05
    assert abs(abs(two_lost.turn_deg[0]) - bend) < 0.05
