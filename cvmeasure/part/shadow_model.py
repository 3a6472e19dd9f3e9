"""The model of a lifted wire's cast shadow: where its outer edges fall for a lamp and a tilt.

Under a distant lamp the axis at height ``H`` shadows at ``p + H s`` (a lamp at a finite
height: ``s`` changes along the part, :meth:`EdgeModel.shadow_vectors`); a cylinder of radius
``r`` casts a band whose outer edge lies ``H (n.s) + r sqrt(1 + (n.s)^2)`` across the
wire. :func:`predict_shadow_edges_mm` gives the edges for a shadow vector and heights,
each crossing followed on the polyline segment it lies on.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.contracts import PlaneModel
from cvmeasure.part.lift import (
    MAX_LIFT_MM,
    points_at_heights_mm,
)
from cvmeasure.part.shadow_edges import ShadowEdges, unit_normals

__all__ = [
    "EdgeModel",
    "edge_model",
    "predict_shadow_edges_mm",
    "predict_edges",
    "forward_steps",
    "rigid_heights",
]


@dataclass(frozen=True)
class EdgeModel:
    """What :func:`predict_shadow_edges_mm` needs that does not change during a fit.

    ``at0_mm`` (M, 2): each centreline point's ray on the plate (height 0), board mm;
    ``per_mm`` (M, 2): its move per mm of height (affine along the ray); the measuring
    lines start at ``edges.axis_mm`` along ``+-edges.normal``.
    """

    at0_mm: np.ndarray
    per_mm: np.ndarray
    edges: ShadowEdges
    radius_mm: float

    def curve(
        self, height_mm: np.ndarray, shadow: np.ndarray, lamp_k: Any = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """The axis (..., M, 2) at its heights (..., M) and the band's outer edge (..., M, 2).

        Leading dimensions run over parameter sets (``shadow`` (..., 2), ``lamp_k`` (...)):
        see :meth:`shadow_vectors`.
        """
        h = height_mm[..., None]
        axis3 = self.at0_mm + h * self.per_mm
        s = self.shadow_vectors(axis3, h, shadow, lamp_k)
        sc = axis3 + h * s
        m = unit_normals(sc)  # the shadow curve's
        ms = np.sum(m * s, axis=-1)
        scale = np.where(ms >= 0, 1.0, -1.0) * self.radius_mm * np.sqrt(1.0 + ms * ms)
        return axis3, sc + scale[..., None] * m

    def shadow_vectors(
        self, axis3: np.ndarray, h: np.ndarray, shadow: np.ndarray, lamp_k: Any = None
    ) -> np.ndarray:
        """Each axis point's shadow vector per mm of height (..., M or 1, 2).

        A distant lamp (``lamp_k`` None or 0): ``shadow`` everywhere. A lamp at height
        ``1 / lamp_k`` (mm) whose shadow vector at the part's middle (``at0_mm``'s mean, on
        the plate) is ``shadow``: a point ``a`` at height ``H`` shadows along
        ``(a - L) / (Lz - H) = (k (a - middle) + shadow) / (1 - k H)``; a desk lamp 150 mm
        up changes it by half across a 100 mm part.
        """
        s = np.asarray(shadow, dtype=np.float64)[..., None, :]
        if lamp_k is None:
            return s
        k = np.asarray(lamp_k, dtype=np.float64)[..., None, None]
        return (k * (axis3 - self.at0_mm.mean(axis=0)) + s) / (1.0 - k * h)

    def crossings(
        self, axis3: np.ndarray, edge: np.ndarray, shadow: np.ndarray, d: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where each measuring line (K) first crosses the polyline ``edge`` (M, 2).

        The line from ``edges.axis_mm`` along ``d`` (K, 2), searched over the segments near
        each sample's own index (a window as long as the shadow's largest displacement).
        Returns the distance along ``d`` (K,) (NaN where none) and the crossed segment's
        first point (K,) (-1 where none).

        The window's segments are grouped in blocks of :data:`CROSSING_BLOCK`; only the
        blocks whose bounding box the line passes through are searched segment by segment
        (a line crosses a segment only inside that segment's block's box): the same
        crossings as searching every segment, at a cost that grows with the window's
        blocks, not its segments (a low lamp's window is hundreds of segments long).
        """
        q = self.edges.axis_mm
        reach = float(np.max(np.hypot(shadow[..., 0], shadow[..., 1])))
        win = 3.0 + (self.radius_mm + 2.0 * MAX_LIFT_MM) * reach
        step = float(np.median(np.hypot(*np.diff(axis3, axis=0).T))) + 1e-9
        kw = int(np.ceil(win / step))
        rows, seg, ca, cb = _window_sign_changes(edge, q, d, self.edges.index, kw)
        along = _along(edge[seg], edge[seg + 1], q[rows], d[rows], ca, cb)
        ahead = along > 0
        rows, seg, along = rows[ahead], seg[ahead], along[ahead]
        # each line's nearest crossing ahead (of equally near ones, the lower segment):
        # rows come sorted, and each row's segments in order
        starts = np.flatnonzero(np.r_[True, rows[1:] != rows[:-1]]) if len(rows) else rows
        nearest = np.repeat(np.minimum.reduceat(along, starts), np.diff(np.r_[starts, len(rows)]))
        at_min = np.flatnonzero(along == nearest)
        first = (
            at_min[np.r_[True, rows[at_min[1:]] != rows[at_min[:-1]]]] if len(at_min) else at_min
        )
        out = np.full(len(q), np.nan)
        out_seg = np.full(len(q), -1)
        out[rows[first]] = along[first]
        out_seg[rows[first]] = seg[first]
        return out, out_seg

    def along_segments(self, edge: np.ndarray, seg: np.ndarray, d: np.ndarray) -> np.ndarray:
        """Distance (..., K) along ``d`` to the lines through the segments ``seg`` (K,) of
        ``edge`` (..., M, 2) (NaN where ``seg`` is -1): the crossing with the segment found
        by :meth:`crossings`, followed as the curve moves (its derivative)."""
        q = self.edges.axis_mm
        j = np.maximum(seg, 0)
        a, b = edge[..., j, :], edge[..., j + 1, :]
        rel_a, rel_b = a - q, b - q
        ca = rel_a[..., 0] * d[:, 1] - rel_a[..., 1] * d[:, 0]
        cb = rel_b[..., 0] * d[:, 1] - rel_b[..., 1] * d[:, 0]
        along = _along(a, b, q, d, ca, np.where(ca != cb, cb, ca + 1.0))
        return np.where(seg >= 0, along, np.nan)


#: Segments per block in :meth:`EdgeModel.crossings`' search (about the square root of a
#: low lamp's window, so the blocks' tests and the searched blocks' segments cost alike).
CROSSING_BLOCK = 16


def _window_sign_changes(
    edge: np.ndarray, q: np.ndarray, d: np.ndarray, index: np.ndarray, kw: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The segments of ``edge`` (M, 2) whose ends lie on opposite sides of (or one on) each
    line from ``q`` (K, 2) along ``d`` (K, 2), among the segments starting within ``kw``
    points before ``index`` (K,) to ``kw - 1`` after it. Returns the lines' rows, the
    segments' first points (sorted by row, then segment) and the ends' cross products.
    """
    m, b = len(edge), CROSSING_BLOCK
    lo = np.maximum(index - kw, 0)
    hi = np.minimum(index + kw - 1, m - 2)
    none = np.zeros(0, dtype=np.intp), np.zeros(0, dtype=np.intp), np.zeros(0), np.zeros(0)
    if m < 2 or len(q) == 0:
        return none
    # each block's bounding box (its B segments' B + 1 points; NaN points ignored)
    n_blocks = (m - 2) // b + 1
    pts = edge[np.minimum(np.arange(n_blocks)[:, None] * b + np.arange(b + 1), m - 1)]
    box_lo, box_hi = np.fmin.reduce(pts, axis=1), np.fmax.reduce(pts, axis=1)
    centre, half = 0.5 * (box_lo + box_hi), 0.5 * (box_hi - box_lo)
    # the blocks of each line's window; the line passes through a box where the box's
    # centre is no farther from it than the box's half extent across it (a margin for
    # rounding: a block too many is only searched)
    first_block, last_block = lo // b, hi // b
    blocks = first_block[:, None] + np.arange(int(np.max(last_block - first_block, initial=0)) + 1)
    in_window = blocks <= last_block[:, None]
    blocks = np.minimum(blocks, n_blocks - 1)
    dx, dy = d[:, :1], d[:, 1:]
    c = centre[blocks]
    dist = np.abs((c[..., 0] - q[:, :1]) * dy - (c[..., 1] - q[:, 1:]) * dx)
    extent = half[blocks, 0] * np.abs(dy) + half[blocks, 1] * np.abs(dx)
    rows, cols = np.nonzero(in_window & (dist <= extent + 1e-6 * (1.0 + extent)))
    if len(rows) == 0:
        return none
    # the searched blocks' segments, as the line's window holds them
    s0 = blocks[rows, cols][:, None] * b + np.arange(b)[None, :]
    valid = (s0 >= lo[rows, None]) & (s0 <= hi[rows, None])
    pt = np.minimum(np.concatenate((s0, s0[:, -1:] + 1), axis=1), m - 1)
    ex, ey = edge[:, 0].take(pt), edge[:, 1].take(pt)
    cross = (ex - q[rows, :1]) * d[rows, 1:] - (ey - q[rows, 1:]) * d[rows, :1]
    cross_a, cross_b = cross[:, :-1], cross[:, 1:]
    r, j = np.nonzero(valid & (cross_a * cross_b <= 0) & (cross_a != cross_b))
    return rows[r], s0[r, j], cross_a[r, j], cross_b[r, j]


def _along(a, b, q, d, cross_a, cross_b):
    """Distance along ``d`` from ``q`` to where the segment ``a``-``b`` (cross products
    ``cross_a``, ``cross_b`` of its ends with the line) meets the line."""
    t = cross_a / (cross_a - cross_b)
    hit = a + t[..., None] * (b - a)
    return np.sum((hit - q) * d, axis=-1)


def edge_model(
    plane: PlaneModel, points_px: np.ndarray, edges: ShadowEdges, radius_mm: float
) -> EdgeModel:
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    at0 = points_at_heights_mm(plane, pts, 0.0)
    at1 = points_at_heights_mm(plane, pts, 1.0)
    return EdgeModel(at0, at1 - at0, edges, radius_mm)


def predict_shadow_edges_mm(
    plane: PlaneModel,
    points_px: np.ndarray,
    edges: ShadowEdges,
    height_mm: np.ndarray,
    shadow: np.ndarray,
    radius_mm: float,
    side: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The model's outer edge offset (K,) along the side ``side`` (K,) (+1 / -1 of normal).

    ``height_mm`` (M,): the axis' height above the plate at every centreline point;
    ``shadow`` (2,): the shadow vector per mm of height. Each axis point on the plane of its
    own height, shadowed to ``p + H s``, the band's outer edge ``r sqrt(1 + (m.s)^2)`` off
    the shadow curve along its own normal ``m``; the offset is where the measuring line
    (from ``edges.axis_mm`` along ``+-edges.normal``) crosses that edge curve. ``side``
    (K,): the side to measure on (default the shadow's, ``sign(n.s)``); NaN where the
    line does not meet the edge.
    """
    model = edge_model(plane, points_px, edges, radius_mm)
    return predict_edges(model, np.asarray(height_mm, dtype=np.float64), shadow, side)[:2]


def predict_edges(
    model: EdgeModel,
    height_mm: np.ndarray,
    shadow: np.ndarray,
    side: np.ndarray | None,
    lamp_k: float | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`predict_shadow_edges_mm` on a prepared model (a lamp at height ``1 / lamp_k``
    mm, see :meth:`EdgeModel.shadow_vectors`); also the crossed segments."""
    shadow = np.asarray(shadow, dtype=np.float64)
    n = model.edges.normal
    if side is None:
        side = np.where(n @ shadow >= 0, 1.0, -1.0)
    axis3, edge = model.curve(height_mm, shadow, lamp_k)
    every = model.shadow_vectors(axis3, height_mm[..., None], shadow, lamp_k)
    along, seg = model.crossings(axis3, edge, every, n * side[:, None])
    return along, side, seg


def forward_steps(x: np.ndarray, rel_step: float) -> np.ndarray:
    """The forward steps scipy's least_squares takes for ``diff_step=rel_step`` (the
    relative step, or sqrt(eps) max(1, |x|) where that vanishes), so a Jacobian supplied
    to it is the one it would have computed."""
    sign = np.where(x >= 0, 1.0, -1.0)
    step = rel_step * sign * np.abs(x)
    fallback = np.sqrt(np.finfo(np.float64).eps) * sign * np.maximum(1.0, np.abs(x))
    return np.where((x + step) - x == 0, fallback, step)


def rigid_heights(plane_mm: np.ndarray, slope: np.ndarray) -> np.ndarray:
    rel = plane_mm @ slope
    return rel - rel.min()
