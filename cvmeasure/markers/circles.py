"""Sub-pixel circles of the found discs (image px) and their centres' covariance.

:func:`refine_candidates` re-extracts each disc's edge points around its refined
circle until it stops moving; :func:`split_half_cov` is what fits to halves of an
edge disagree on (the systematic part a cover or a shadow's edge leaves).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from cvmeasure.geometry import CircleFit, fit_circle_robust, fit_circles_robust
from cvmeasure.markers.detect import MarkerCandidate
from cvmeasure.markers.refine import (
    FIT_STOP_PX,
    UNEVEN_RING_SPREAD,
    disc_edge_points,
    edge_ray_count,
    ray_correlation_factor,
)

__all__ = [
    "MIN_EDGE_POINTS",
    "edge_mode_cov",
    "refine_candidate",
    "refine_candidates",
    "split_half_cov",
]

#: Fewest edge points a disc needs for a centre.
MIN_EDGE_POINTS = 12


def refine_candidate(
    bgr: np.ndarray, cand: MarkerCandidate, ring_ratio: float, *, edge: str | None = None
) -> tuple[CircleFit, Any] | str:
    """Sub-pixel circle of one found disc (image px) and its edge points, or why there is none.

    Edge points are re-extracted around the refined circle until it stops moving
    (at most three passes); where its ring is unevenly lit (a shadow across the
    marker), a last pass takes each ray's edge against that ray's own levels.
    """
    return refine_candidates(bgr, [cand], [ring_ratio], edge=edge)[0]


def refine_candidates(
    bgr: np.ndarray,
    cands: list[MarkerCandidate],
    ring_ratios: list[float],
    *,
    edge: str | None = None,
) -> list[tuple[CircleFit, Any] | str]:
    """:func:`refine_candidate` of several discs, their passes' circles fitted together.

    Each disc's passes, circles and result are those :func:`refine_candidate` gives it
    alone (:func:`cvmeasure.geometry.fit_circles_robust`: the same fits, one call per
    pass for all the discs still refining).
    """
    n = len(cands)
    centres = [c.centre_px for c in cands]
    radii = [c.radius_px for c in cands]
    fits: list[CircleFit | None] = [None] * n
    local = [False] * n  # the last pass, when the ring is unevenly lit: each ray's own levels
    passes = [0] * n
    results: list[tuple[CircleFit, Any] | str | None] = [None] * n
    pending = list(range(n))
    while pending:
        todo, edges_of = [], {}
        for i in pending:
            edges = disc_edge_points(
                bgr, centres[i], radii[i], ring_ratios[i], edge=edge, local_levels=local[i]
            )
            n_points = edges.points_px.shape[0]
            if local[i] and n_points < max(MIN_EDGE_POINTS, 0.3 * edge_ray_count(radii[i])):
                results[i] = (
                    "too little of its edge is clear of the shadow or cover across it "
                    f"({n_points} edge points)"
                )
            elif n_points < MIN_EDGE_POINTS:
                results[i] = f"no clear edge around it (contrast {edges.contrast:.0f}/255)"
            else:
                todo.append(i)
                edges_of[i] = edges
        got = fit_circles_robust(
            [edges_of[i].points_px for i in todo],
            inits=[
                None if (f := fits[i]) is None else (f.centre[0], f.centre[1], f.radius)
                for i in todo
            ],
            correlation_factors=[ray_correlation_factor(radii[i]) for i in todo],
            stop=FIT_STOP_PX,
        )
        pending = []
        for i, fit in zip(todo, got, strict=True):
            if fit is None:
                results[i] = "its edge points do not form a circle"
                continue
            moved = math.hypot(fit.centre[0] - centres[i][0], fit.centre[1] - centres[i][1])
            if not (0.5 * cands[i].radius_px < fit.radius < 1.6 * cands[i].radius_px):
                results[i] = (
                    f"its edge is not a circle of the expected size (r {fit.radius:.1f} px)"
                )
                continue
            fits[i], centres[i], radii[i] = fit, fit.centre, fit.radius
            passes[i] += 1
            if local[i]:
                results[i] = (fit, edges_of[i])
                continue
            if moved < 0.05 * radii[i] or passes[i] >= 3:
                if edges_of[i].ring_spread < UNEVEN_RING_SPREAD:
                    results[i] = (fit, edges_of[i])
                    continue
                local[i] = True  # settled on a circle: its ring samples now fall on the ring
            pending.append(i)
    return results  # type: ignore[return-value]


def split_half_cov(
    points: np.ndarray, fit: CircleFit, *, correlation_factor: float = 1.0
) -> np.ndarray:
    """Centre covariance from how fits to halves of the edge disagree with the whole,
    beyond what their sampling explains (units of ``points``, squared).

    The inlier edge points are split in two halves round the centre, four ways (the
    split line every 45 deg); each half's circle, fitted with the radius free,
    differs from the whole's centre by ``d``. Under sampling error alone ``d d^T``
    averages ``C_half - C_whole`` (the whole nests the half); what is left of the mean
    of ``d d^T - (C_half - C_whole)`` over the eight halves (negative eigenvalues
    clipped) is the systematic part a cover or a shadow's edge leaves: about zero for a
    whole, clean edge, which the sampling covariance already holds. Fit it where the
    disc is a circle (on the plate, on a plane pose): the halves of a tilted view's
    ellipse disagree by its shape alone. ``correlation_factor`` as for the whole's fit.
    """
    pts = np.asarray(points, dtype=np.float64)
    c = np.asarray(fit.centre)
    off = pts - c
    resid = np.abs(np.hypot(off[:, 0], off[:, 1]) - fit.radius)
    keep = resid < 3.0 * max(fit.rms_residual, 0.0025 * fit.radius)
    pts, off = pts[keep], off[keep]
    theta = np.arctan2(off[:, 1], off[:, 0])
    whole = np.asarray(fit.covariance)
    acc, n = np.zeros((2, 2)), 0
    for split in np.radians([0.0, 45.0, 90.0, 135.0]):
        side = np.mod(theta - split, 2 * math.pi) < math.pi
        for half in (side, ~side):
            if half.sum() < MIN_EDGE_POINTS:
                continue
            try:
                part = fit_circle_robust(
                    pts[half],
                    init=(c[0], c[1], fit.radius),
                    stop=FIT_STOP_PX,
                    correlation_factor=correlation_factor,
                )
            except (ValueError, np.linalg.LinAlgError):
                continue
            d = np.asarray(part.centre) - c
            acc += np.outer(d, d) - (np.asarray(part.covariance) - whole)
            n += 1
    if not n:
        return np.zeros((2, 2))
    vals, vecs = np.linalg.eigh(0.5 * (acc + acc.T) / n)
    return (vecs * np.maximum(vals, 0.0)) @ vecs.T  # np.clip(vals, 0, None) is this call


def edge_mode_cov(
    points: np.ndarray,
    fit: CircleFit,
    *,
    correlation_factor: float = 1.0,
    wall_towards: np.ndarray | None = None,
) -> np.ndarray:
    """Centre covariance from how the circle of the same disc's edge read another way
    (``points``: another channel weighting of the same photo) disagrees with ``fit``,
    beyond that circle's sampling (units of ``points``, squared).

    Demosaicing, blur, JPEG and shading move a disc's edge differently in each
    channel weighting, and each weighting's centre by a few hundredths of a pixel
    that the residuals round a circle cannot see: the difference ``d`` between the
    two centres samples that bias. Two readings biased alike but independently
    differ by twice a reading's bias variance, plus their sampling: the term is half
    of ``d d^T`` less the other circle's sampling covariance (the two readings'
    noise is shared in part; the other, a single channel, is the noisier), negative
    eigenvalues clipped; zeros when the points form no circle.

    ``wall_towards`` (a point in the units of ``points``: the camera's foot point on the
    plate) is for "shade" edges of faces raised on their rings, read against luminance:
    luminance counts the step's wall, seen on the side of the foot point, by each disc's
    own share, shade edges by one share for every disc (a common scale that leaves the
    angles alone; :data:`cvmeasure.markers.refine.SHADE_EDGES`). The component of ``d``
    towards that point is then the other reading's wall, not this reading's bias (on the
    Mitsuba renders it was 2-5 times the rest, the same sign on every disc, and taking it
    stated the angles' sigma about twice their errors); only the perpendicular component
    samples the bias, taken alike in both directions.
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.shape[0] < MIN_EDGE_POINTS:
        return np.zeros((2, 2))
    try:
        other = fit_circle_robust(
            pts,
            init=(fit.centre[0], fit.centre[1], fit.radius),
            stop=FIT_STOP_PX,
            correlation_factor=correlation_factor,
        )
    except (ValueError, np.linalg.LinAlgError):
        return np.zeros((2, 2))
    d = np.asarray(other.centre) - np.asarray(fit.centre)
    if wall_towards is not None:
        radial = np.asarray(wall_towards, dtype=np.float64)[:2] - np.asarray(fit.centre)
        norm = float(np.hypot(*radial))
        if norm > 0.0:
            across = np.array([-radial[1], radial[0]]) / norm
            var = 0.5 * (float(d @ across) ** 2 - float(across @ other.covariance @ across))
            return np.eye(2) * max(var, 0.0)
    acc = 0.5 * (np.outer(d, d) - np.asarray(other.covariance))
    vals, vecs = np.linalg.eigh(0.5 * (acc + acc.T))
    return (vecs * np.maximum(vals, 0.0)) @ vecs.T  # np.clip(vals, 0, None) is this call
