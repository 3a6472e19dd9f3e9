"""A centreline stretch off the wire (on its shadow) moves the chords' vertices but not
the vertex bends: the arc through the vertices must then be warned about
(:func:`cvmeasure.part.checks.arc_consistency_warning`, ``part_arc_inconsistent``)."""

from __future__ import annotations

import numpy as np

import cvmeasure_datasets
from cvmeasure.part.arc import arc_from_points
from cvmeasure.part.checks import arc_consistency_warning
from cvmeasure.part.fit import fit_polyline

# dev part B4: R 52.5 mm, 70 deg in 6 chords of 10.7 mm; the last chord's centres ran
# 2.3 mm off the axis along the wire's shadow after a 3 mm gap
RADIUS_MM, ARC_DEG, DIVISIONS = 52.5, 70.0, 6
STEP_MM = 0.09
EDGE_SIGMA_MM = 0.015
SHADOW_MM, GAP_MM = 2.3, 3.0


def _centres(rng: np.random.Generator, on_shadow: bool) -> np.ndarray:
    verts = cvmeasure_datasets.arc_part(RADIUS_MM, ARC_DEG, DIVISIONS).vertices_mm
    out = []
    for k, (a, b) in enumerate(zip(verts[:-1], verts[1:], strict=True)):
        chord = float(np.hypot(*(b - a)))
        e = (b - a) / chord
        n = np.array([-e[1], e[0]])  # towards the circle's centre (the arc turns left)
        t = np.arange(0.0, chord, STEP_MM)
        off = rng.normal(0.0, EDGE_SIGMA_MM, len(t))
        if on_shadow and k == DIVISIONS - 1:  # towards the centre, after a gap
            keep = t > GAP_MM
            t, off = t[keep], off[keep] + SHADOW_MM
        out.append(a + t[:, None] * e + off[:, None] * n)
    return np.vstack(out)


def _measure(on_shadow: bool, seed: int):
    rng = np.random.default_rng(seed)
    seen = _centres(rng, on_shadow)
    ours, _, poly = arc_from_points(seen, DIVISIONS)
    # the vertex bends as the chords' cross-profiles read them on the wire itself
    vpoly = fit_polyline(_centres(rng, False), DIVISIONS)
    sigma = np.full(DIVISIONS - 1, 0.02)
    return ours, poly, vpoly, arc_consistency_warning(ours, poly, vpoly, sigma)


def test_a_chord_on_the_shadow_makes_the_arc_disagree_with_the_bends_and_is_warned():
    for seed in (1401, 1402, 1403):
        ours, _, vpoly, warning = _measure(True, seed)
        # the failure: the radius far off while every vertex bend is right
        assert abs(ours.radius_mm / RADIUS_MM - 1.0) > 0.05
        assert np.max(np.abs(vpoly.bend_deg - ARC_DEG / DIVISIONS)) < 0.1
        assert warning is not None and warning.code == "part_arc_inconsistent"


def test_a_clean_arc_is_not_warned():
    for seed in (1411, 1412, 1413):
        ours, _, _, warning = _measure(False, seed)
        assert abs(ours.radius_mm / RADIUS_MM - 1.0) < 0.005
        assert warning is None
