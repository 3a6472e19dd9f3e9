"""The cast-shadow fit's parts (cvmeasure/part/shadow.py) without a photo: the model's edge
on a straight wire against its closed form, and the Jacobian's forward steps against
least_squares' own."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

import cvmeasure_datasets
from cvmeasure.part.lift import points_at_heights_mm
from cvmeasure.part.shadow_edges import ShadowEdges
from cvmeasure.part.shadow_model import forward_steps, predict_shadow_edges_mm
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.round_wire import true_plane


@pytest.mark.parametrize(
    ("height_mm", "shadow"), [(1.5, (0.6, -0.5)), (4.5, (-0.3, 0.9)), (2.0, (0.0, 1.2))]
)
def test_a_straight_wires_outer_edge_is_the_closed_form(height_mm, shadow):
    """A straight wire at height H, lamp s, normal n: the band's outer edge lies
    H (n.s) + r sqrt(1 + (n.s)^2) from the axis (exact for the model, perspective
    included). Asserted to 1e-9 mm on every sample, on the side sign(n.s)."""
    plane = true_plane(
        cvmeasure_datasets.default_camera().scaled(0.5),
        Pose(tilt_deg=2.0, tilt_direction_deg=40.0, distance_mm=550.0, offset_mm=(30.0, -20.0)),
    )
    radius = 1.5
    direction = np.array([np.cos(0.4), np.sin(0.4)])
    axis_mm = np.array([10.0, -5.0]) + np.arange(-40.0, 40.0, 0.25)[:, None] * direction
    heights = np.full(len(axis_mm), height_mm)
    # the photo's pixels of the axis at its height (z = -H towards the camera)
    xyz = np.column_stack((axis_mm, -heights))
    px = plane.plane_to_image_px(xyz)
    back = points_at_heights_mm(plane, px, heights)
    assert np.abs(back - axis_mm).max() < 1e-6
    index = np.arange(20, len(axis_mm) - 20, 2)
    normal = np.tile([-direction[1], direction[0]], (len(index), 1))
    nan = np.full((len(index), 2), np.nan)
    edges = ShadowEdges(index, axis_mm[index], normal, nan, nan, nan)
    s = np.asarray(shadow)
    pred, side = predict_shadow_edges_mm(plane, px, edges, heights, s, radius)
    ns = float(normal[0] @ s)
    assert np.all(side == (1.0 if ns >= 0 else -1.0))
    expected = height_mm * abs(ns) + radius * np.sqrt(1.0 + ns * ns)
    assert np.abs(pred - expected).max() < 1e-9


def test_the_fits_forward_steps_are_least_squares_own():
    """The shadow fit supplies least_squares a forward-difference Jacobian with its
    ``diff_step`` rule (relative, or sqrt(eps) max(1, |x|) where that vanishes): the same
    matrix as least_squares computes itself (one evaluation, x unchanged), on a
    nonlinear function where the step shows."""

    def f(x):
        return np.array([x[0] ** 2 + x[1], np.sin(x[2]) * x[3] ** 2, x[0] * x[3] ** 3])

    for x0 in (np.array([0.0, -0.37, 2.5, 1e-7]), np.array([-3.0, 0.2, -1e-12, 250.0])):
        ref = least_squares(f, x0, diff_step=1e-5, max_nfev=1)
        assert np.array_equal(ref.x, x0)
        xs = x0 + np.diag(forward_steps(x0, 1e-5))
        jac = np.column_stack([(f(xi) - f(x0)) / (xi[i] - x0[i]) for i, xi in enumerate(xs)])
        assert np.allclose(jac, ref.jac, rtol=1e-12, atol=0.0)


def _arc_edges(lamp_mm: tuple[float, float, float] | None, shadow: np.ndarray):
    """A flat 2 mm wire on an R 60 mm, 120 deg arc and its shadow's outer edges, exact for a
    point lamp at ``lamp_mm`` (board mm, height towards the camera; each sample shadowed by
    its own vector) or, with None, the distant lamp ``shadow``."""
    plane = true_plane(
        cvmeasure_datasets.default_camera().scaled(0.5),
        Pose(tilt_deg=1.5, tilt_direction_deg=40.0, distance_mm=650.0, offset_mm=(30.0, -20.0)),
    )
    radius = 1.0
    t = np.radians(np.arange(-60.0, 60.0, 0.05))
    axis_mm = np.column_stack((60.0 * np.cos(t), 60.0 * np.sin(t)))
    heights = np.full(len(axis_mm), radius)
    px = plane.plane_to_image_px(np.column_stack((axis_mm, -heights)))
    index = np.arange(10, len(axis_mm) - 10, 5)
    normal = np.column_stack((-np.cos(t[index]), -np.sin(t[index])))  # left of travel
    nan = np.full((len(index), 2), np.nan)
    edges = ShadowEdges(index, axis_mm[index], normal, nan, nan, nan)
    pred = np.empty(len(index))
    side = np.empty(len(index))
    for k, i in enumerate(index):
        s = shadow
        if lamp_mm is not None:
            s = (axis_mm[i] - np.asarray(lamp_mm[:2])) / (lamp_mm[2] - radius)
        p, sd = predict_shadow_edges_mm(plane, px, edges, heights, s, radius)
        pred[k], side[k] = p[k], sd[k]
    offset = np.where(side[:, None] == np.array([1.0, -1.0]), pred[:, None], np.nan)
    silhouette = np.full((len(index), 2), radius)
    contrast = np.where(np.isfinite(offset), 0.5, np.nan)
    return plane, px, ShadowEdges(index, axis_mm[index], normal, offset, silhouette, contrast)


def test_a_lamp_near_the_part_reads_a_flat_part_flat():
    """A desk lamp 150 mm up and 250 mm from a flat part's middle: its shadow vector changes
    by half across the part, which one distant lamp's model took for a tilt (0.44 +- 0.19 mm
    here; a flat part read 0.9-2.0 mm lifted on Mitsuba renders). Exact edges of that lamp:
    the fit with the lamp's height reads the part flat (measured 0.001 +- 0.27 mm) and the
    lamp's height. The distant lamp with the vector at the part's middle: flat too.
    Asserted: lift under 0.05 mm, lamp height within 10 %, distant lamp over 1 m."""
    from cvmeasure.part.shadow import estimate_lift_shadow

    lamp = (60.0 + 160.0, 200.0, 150.0)
    s_mid = (np.array([60.0, 0.0]) - np.array(lamp[:2])) / (lamp[2] - 1.0)
    plane, px, edges = _arc_edges(None, s_mid)
    far = estimate_lift_shadow(None, plane, px, wire_diameter_mm=2.0, edges=edges)
    assert far.lift is not None, far.message
    assert far.lift.lift_mm < 0.05 and far.lamp_height_mm > 1000.0
    plane, px, edges = _arc_edges(lamp, s_mid)
    near = estimate_lift_shadow(None, plane, px, wire_diameter_mm=2.0, edges=edges)
    assert near.lift is not None, near.message
    assert near.lift.lift_mm < 0.05
    assert near.lamp_height_mm == pytest.approx(150.0, rel=0.1)


def _crossings_every_segment(model, axis3, edge, shadow, d):
    """The crossings searched over every segment of each line's window (the reference)."""
    from cvmeasure.part.lift import MAX_LIFT_MM
    from cvmeasure.part.shadow_model import _along

    q = model.edges.axis_mm
    reach = float(np.max(np.hypot(shadow[..., 0], shadow[..., 1])))
    win = 3.0 + (model.radius_mm + 2.0 * MAX_LIFT_MM) * reach
    step = float(np.median(np.hypot(*np.diff(axis3, axis=0).T))) + 1e-9
    kw = int(np.ceil(win / step))
    p = np.clip(model.edges.index[:, None] + np.arange(-kw, kw + 1)[None, :], 0, len(edge) - 1)
    cross = (edge[:, 0].take(p) - q[:, :1]) * d[:, 1:] - (edge[:, 1].take(p) - q[:, 1:]) * d[:, :1]
    ca, cb = cross[:, :-1], cross[:, 1:]
    rows, cols = np.nonzero((ca * cb <= 0) & (ca != cb))
    seg = p[rows, cols]
    along = _along(edge[seg], edge[seg + 1], q[rows], d[rows], ca[rows, cols], cb[rows, cols])
    out, out_seg = np.full(len(q), np.nan), np.full(len(q), -1)
    for k in np.unique(rows[along > 0]):
        here = (rows == k) & (along > 0)
        j = np.flatnonzero(here)[np.argmin(along[here])]
        out[k], out_seg[k] = along[j], seg[j]
    return out, out_seg


@pytest.mark.parametrize("lamp_k", [None, 4e-3])
@pytest.mark.parametrize("shadow", [(0.4, -0.3), (2.5, 1.5)])
def test_the_blocked_crossing_search_finds_every_segments_crossing(shadow, lamp_k):
    """A bent wire (a U: each measuring line meets the edge curve several times, a low
    lamp's window spans both legs), lifted at one end: the blocked search's crossings are
    the ones a search over every segment of the window finds, bit for bit."""
    from cvmeasure.part.shadow_model import EdgeModel, predict_edges

    t = np.linspace(0.0, np.pi, 700)
    leg = np.linspace(0.0, 30.0, 120)[1:]
    path = np.concatenate((
        np.column_stack((-20.0 + 0.0 * leg[::-1], 30.0 - leg[::-1])),
        np.column_stack((-20.0 * np.cos(t), -20.0 * np.sin(t))),
        np.column_stack((20.0 + 0.0 * leg, -leg + 0.0 * leg)),
    ))  # fmt: skip
    path = path[np.r_[True, np.hypot(*np.diff(path, axis=0).T) > 1e-9]]
    rng = np.random.default_rng(3)
    index = np.sort(rng.choice(len(path), 400, replace=False))
    normal = np.column_stack((-np.gradient(path[:, 1]), np.gradient(path[:, 0])))
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    edges = ShadowEdges(
        index, path[index] + rng.normal(0.0, 0.05, (400, 2)), normal[index],
        np.full((400, 2), np.nan), np.zeros((400, 2)), np.zeros((400, 2)),
    )  # fmt: skip
    model = EdgeModel(path, np.zeros_like(path) + (0.01, -0.02), edges, 1.5)
    height = 1.5 + 3.0 * (path[:, 0] - path[:, 0].min()) / np.ptp(path[:, 0])
    s = np.array(shadow)
    axis3, edge = model.curve(height, s, lamp_k)
    every = model.shadow_vectors(axis3, height[:, None], s, lamp_k)
    found = 0
    for side in (1.0, -1.0):
        d = normal[index] * side
        got = model.crossings(axis3, edge, every, d)
        want = _crossings_every_segment(model, axis3, edge, every, d)
        found += np.isfinite(want[0]).sum()
        np.testing.assert_array_equal(got[1], want[1])
        np.testing.assert_array_equal(got[0], want[0])
    assert found > 350
    pred = predict_edges(model, height, s, None, lamp_k)
    assert np.isfinite(pred[0]).sum() > 300
