"""Small geometric helpers shared by every stage (angles, circle fits)."""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "wrap_deg",
    "mod_positive",
    "direction_deg",
    "fit_circle_taubin",
    "CircleFit",
    "fit_circle_robust",
    "fit_circles_robust",
    "median_by_partition",
]


def mod_positive(x: NDArray[np.float64], period: float) -> NDArray[np.float64]:
    """``np.mod(x, period)`` for ``period > 0``, the same numbers (up to the sign of a
    zero result, which the callers' ``c - result`` and ``result - c`` make the same
    value) at a fraction of the time: numpy's float remainder is C ``fmod`` plus
    ``period`` when the two differ in sign, and computes the floor quotient it then
    drops; ``fmod`` is exact, so the sum is the same rounding either way."""
    m = np.fmod(x, period)
    return np.where(m < 0.0, m + period, m)


def arclength_mm(points: ArrayLike) -> np.ndarray:
    """Cumulative length along a polyline ((N, 2) points, mm): 0 at the first point,
    (N,)."""
    pts = np.asarray(points, dtype=np.float64)
    return np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))))


def wrap_deg(angle_deg: ArrayLike) -> np.ndarray | float:
    """Wrap angles in degrees to (-180, 180] (spec: signed angles).

    >>> wrap_deg(190.0), wrap_deg(-180.0), wrap_deg(180.0)
    (-170.0, 180.0, 180.0)
    >>> wrap_deg([360.0, -270.0]).tolist()
    [0.0, 90.0]
    """
    a = np.asarray(angle_deg, dtype=np.float64)
    wrapped = 180.0 - mod_positive(180.0 - a, 360.0)
    return float(wrapped) if wrapped.ndim == 0 else wrapped


def direction_deg(from_xy: ArrayLike, to_xy: ArrayLike) -> np.ndarray | float:
    """Direction of the vector from -> to, in degrees, counter-clockwise from +x.

    Works in any right-handed (x, y) frame; for image pixels (y down) negate y
    first to get counter-clockwise-as-seen angles.

    >>> direction_deg((0.0, 0.0), (0.0, 1.0))
    90.0
    >>> direction_deg((1.0, 1.0), (0.0, 1.0))
    180.0
    """
    f = np.asarray(from_xy, dtype=np.float64)
    t = np.asarray(to_xy, dtype=np.float64)
    d = t - f
    return wrap_deg(np.degrees(np.arctan2(d[..., 1], d[..., 0])))


def fit_circle_taubin(points: ArrayLike) -> tuple[np.ndarray, float]:
    """Taubin's algebraic circle fit of points (N, 2), N >= 3; any length unit.

    Returns ``(centre (2,), radius)`` in the points' unit. Unbiased to first
    order (unlike Kasa's fit); the stages use it to start their robust
    geometric fits. Raises ValueError for fewer than 3, non-finite or collinear
    points.

    References: G. Taubin, "Estimation of planar curves, surfaces and nonplanar
    space curves ...", IEEE PAMI 13(11), 1991, doi:10.1109/34.103273.

    >>> t = np.linspace(0.0, np.pi, 7)
    >>> centre, radius = fit_circle_taubin(np.column_stack((3 + 2 * np.cos(t), -1 + 2 * np.sin(t))))
    >>> np.round(centre, 9).tolist(), round(radius, 9)
    ([3.0, -1.0], 2.0)
    """
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2:
        raise ValueError(f"points must have shape (N, 2), got {pts.shape}")
    if len(pts) < 3:
        raise ValueError(f"a circle fit needs at least 3 points, got {len(pts)}")
    if not np.all(np.isfinite(pts)):
        raise ValueError("points must be finite")
    mean = pts.mean(axis=0)
    x, y = (pts - mean).T
    z = x * x + y * y
    zm = z.mean()
    if zm <= 0:
        raise ValueError("points are all the same: no circle")
    z0 = (z - zm) / (2.0 * math.sqrt(zm))
    _, _, vt = np.linalg.svd(np.column_stack((z0, x, y)), full_matrices=False)
    a = vt[-1]
    a0 = a[0] / (2.0 * math.sqrt(zm))
    if abs(a0) < 1e-300 or abs(a0) * math.sqrt(zm) < 1e-12 * math.hypot(a[1], a[2]):
        raise ValueError("points are collinear: no circle")
    a3 = -zm * a0
    cx, cy = -a[1] / (2 * a0), -a[2] / (2 * a0)
    radius = math.sqrt(max(cx * cx + cy * cy - a3 / a0, 0.0))
    return np.array([cx, cy]) + mean, radius


@dataclass(frozen=True)
class CircleFit:
    """A circle fitted to edge points, in the frame of the points.

    Attributes
    ----------
    centre : (x, y).
    radius : float.
    covariance : ndarray (2, 2), the centre's covariance (same units squared).
    rms_residual : float, weighted RMS distance of inliers to the circle.
    radius_sigma : float, one standard uncertainty of the radius (same units).
    n_points, n_inliers : int.
    coverage : float, share of the circle's 10-degree sectors that hold inliers.

    Units are those of the points fitted (px for marker edges, mm for a part's
    centreline); uncertainties are sampling errors of the fit only.
    """

    centre: tuple[float, float]
    radius: float
    covariance: np.ndarray
    rms_residual: float
    n_points: int
    n_inliers: int
    coverage: float
    radius_sigma: float = math.nan

    @property
    def sigma(self) -> float:
        """Standard uncertainty of the centre, RMS over the two axes."""
        return float(math.sqrt(max(0.0, 0.5 * np.trace(self.covariance))))

    def to_dict(self, unit: str) -> dict[str, Any]:
        """JSON form, lengths named with ``unit`` (``"mm"`` -> ``radius_mm`` ...)."""
        return {
            f"centre_{unit}": [self.centre[0], self.centre[1]],
            f"radius_{unit}": self.radius,
            f"radius_sigma_{unit}": self.radius_sigma,
            f"centre_sigma_{unit}": self.sigma,
            f"rms_residual_{unit}": self.rms_residual,
            "n_points": self.n_points,
            "n_inliers": self.n_inliers,
            "coverage": self.coverage,
        }


def _coverage(dx: np.ndarray, dy: np.ndarray) -> float:
    """Share of the 36 10-degree sectors holding a point, from the points' offsets
    ``dx``, ``dy`` from the centre."""
    ang = np.arctan2(dy, dx)
    bins = np.floor((ang + np.pi) / (2 * np.pi) * 36).astype(np.intp) % 36
    return float(np.count_nonzero(np.bincount(bins, minlength=36)) / 36.0)


def median_by_partition(values: np.ndarray) -> float:
    """``np.median`` of a non-empty 1-D float array (the same value), by one partition
    (no sort, no checks: the hot loops' median)."""
    n = values.size
    if n % 2:
        return float(np.partition(values, n // 2)[n // 2])
    part = np.partition(values, (n // 2 - 1, n // 2))
    return float((part[n // 2 - 1] + part[n // 2]) / 2.0)


def _abs_median(values: np.ndarray) -> float:
    """``np.median(np.abs(values))`` of a 1-D array (:func:`median_by_partition`)."""
    return median_by_partition(np.abs(values))


def _solve_sym3(g: list[list[float]]) -> tuple[float, float, float] | None:
    """``x`` with ``a x = b`` for ``g = [a | b]``, ``a`` symmetric 3x3 (Cramer's rule); None when singular.

    ``g``: the rows of a 3x4 or 4x4 matrix as Python lists (``a`` its top left 3x3,
    ``b`` its fourth column). The circle fit's normal equations are 3x3: the explicit
    solution avoids ``np.linalg.solve``'s per-call overhead (several times the arithmetic).
    """
    (a00, a01, a02, b0), (_, a11, a12, b1), (_, _, a22, b2) = g[0], g[1], g[2]
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    if not det or not math.isfinite(det):
        return None
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    return (
        (c00 * b0 + c01 * b1 + c02 * b2) / det,
        (c01 * b0 + c11 * b1 + c12 * b2) / det,
        (c02 * b0 + c12 * b1 + c22 * b2) / det,
    )


def fit_circle_robust(
    points: np.ndarray,
    *,
    init: tuple[float, float, float] | None = None,
    iterations: int = 12,
    tukey_c: float = 4.685,
    min_scale: float = 0.02,
    correlation_factor: float = 1.0,
    stop: float = 1e-5,
) -> CircleFit:
    """Geometric circle fit with Tukey biweights (IRLS Gauss-Newton).

    Parameters
    ----------
    points : ndarray of shape (N, 2), float, edge points (any planar frame).
    init : (cx, cy, r) start; Taubin's fit when None.
    tukey_c : Tukey constant in units of the robust residual scale (1.4826 MAD).
    min_scale : smallest residual scale, in the points' units.
    correlation_factor : variance inflation for correlated neighbouring points
        (1: independent points; marker edge points use 2.5, see
        :data:`cvmeasure.markers.refine.CORRELATION_FACTOR`).
    stop : the iterations end when no step of (cx, cy, r) exceeds this, in the points'
        units (after at least three iterations, which fix the robust scale).

    Returns
    -------
    CircleFit
        The covariance is ``s^2 (J^T W J)^-1 * correlation_factor`` with s the
        weighted residual RMS: sampling error only, not model error.
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] < 3:
        raise ValueError(f"a circle fit needs at least 3 points, got {p.shape[0]}")
    if not np.isfinite(p).all():
        raise ValueError("points must be finite")
    if init is not None:
        cx, cy, r = init
    else:
        (cx, cy), r = fit_circle_taubin(p)
    cx, cy, r = float(cx), float(cy), float(r)
    n = p.shape[0]
    w = np.ones(n)
    scale = 0.0
    # rows (d / dist, 1, residual) of one (4, N) array: its weighted Gram matrix holds
    # J^T W J (top left 3x3) and J^T W res (last column) in one small product
    rows = np.empty((4, n))
    rows[2] = 1.0
    jac_t, res = rows[:3], rows[3]
    pts_t = np.ascontiguousarray(p.T)  # (2, N): x and y rows
    px, py = pts_t
    d = np.empty((2, n))  # (dx, dy) rows, made again in place each iteration
    dist = np.empty(n)
    centre = np.empty((2, 1))
    for it in range(iterations):
        centre[0, 0], centre[1, 0] = cx, cy
        np.subtract(pts_t, centre, out=d)
        np.hypot(d[0], d[1], out=dist)
        np.maximum(dist, 1e-12, out=dist)
        np.subtract(dist, r, out=res)
        if it < 3:  # robust scale from the first iterations, then fixed (stable weights)
            mad = 1.4826 * _abs_median(res)
            scale = max(min_scale, mad) if it > 0 else max(min_scale, mad, 0.05 * r)
        w = np.square(res)  # Tukey's biweight (1 - u^2)^2, u = res / (c scale); 0 for |u| >= 1
        w *= -1.0 / (tukey_c * scale) ** 2
        w += 1.0
        np.maximum(w, 0.0, out=w)
        w *= w
        # Gauss-Newton on J = -[d / dist, 1]: solve (J^T W J) step = -(J^T W res)
        np.divide(d, dist, out=rows[:2])
        gram = ((rows * w) @ rows.T).tolist()
        if gram[2][2] < min(5, n):  # (almost) every weight 0: unweighted
            w = np.ones_like(w)
            gram = (rows @ rows.T).tolist()
        step = _solve_sym3(gram)
        if step is None:
            break
        cx, cy, r = cx + step[0], cy + step[1], r + step[2]
        if it >= 2 and max(abs(step[0]), abs(step[1]), abs(step[2])) < stop:
            break
    return _circle_fit_result(p, pts_t, (cx, cy, r), w, correlation_factor, centre, d, jac_t)


def _circle_fit_result(
    p: np.ndarray,
    pts_t: np.ndarray,
    circle: tuple[float, float, float],
    w: np.ndarray,
    correlation_factor: float,
    centre: np.ndarray,
    d: np.ndarray,
    jac_t: np.ndarray,
) -> CircleFit:
    """The :class:`CircleFit` at the converged circle: residuals, weighted covariance.

    ``centre`` (2, 1), ``d`` (2, N) and ``jac_t`` (3, N) are the fit's work arrays, reused.
    """
    cx, cy, r = circle
    theta = np.array([cx, cy, r])
    centre[0, 0], centre[1, 0] = cx, cy
    np.subtract(pts_t, centre, out=d)
    dist = np.maximum(np.hypot(d[0], d[1]), 1e-12)
    res = dist - r
    inl = w > 0
    n_in = int(np.count_nonzero(inl))
    np.divide(d, dist, out=jac_t[:2])  # the sign of J does not change J^T W J
    jw_t = jac_t * w
    dof = max(1.0, float(w.sum()) - 3.0)
    s2 = float((w * res) @ res / dof)
    try:
        cov = np.linalg.inv(jw_t @ jac_t.T) * s2 * correlation_factor
    except np.linalg.LinAlgError:
        cov = np.full((3, 3), np.inf)
    return CircleFit(
        (float(theta[0]), float(theta[1])),
        float(theta[2]),
        cov[:2, :2].copy(),
        float(math.sqrt(s2)),
        int(p.shape[0]),
        n_in,
        _coverage(d[0, inl], d[1, inl]) if n_in else 0.0,  # d: the points less the centre
        float(math.sqrt(max(cov[2, 2], 0.0))),
    )


def _taubin_batch(x: np.ndarray, y: np.ndarray, valid: np.ndarray) -> list[tuple | None]:
    """:func:`fit_circle_taubin` of each row of ``x``, ``y`` (B, N) where ``valid``: (cx, cy, r) or None.

    One stacked SVD: the padding's rows of the design matrix are zeros, which leave its
    right singular vectors as they are (the same circle up to rounding).
    """
    n = valid.sum(axis=1)
    mx = np.where(valid, x, 0.0).sum(axis=1) / n
    my = np.where(valid, y, 0.0).sum(axis=1) / n
    xc = np.where(valid, x - mx[:, None], 0.0)
    yc = np.where(valid, y - my[:, None], 0.0)
    z = xc * xc + yc * yc
    zm = z.sum(axis=1) / n
    out: list[tuple | None] = [None] * len(n)
    ok = zm > 0
    root = np.sqrt(np.where(ok, zm, 1.0))
    z0 = np.where(valid, (z - zm[:, None]) / (2.0 * root[:, None]), 0.0)
    try:
        _, _, vt = np.linalg.svd(np.stack((z0, xc, yc), axis=2), full_matrices=False)
    except np.linalg.LinAlgError:  # one set's SVD did not converge: each on its own
        for i in range(len(n)):
            with contextlib.suppress(ValueError, np.linalg.LinAlgError):
                (cx, cy), r = fit_circle_taubin(np.column_stack((x[i], y[i]))[valid[i]])
                out[i] = (float(cx), float(cy), float(r))
        return out
    for i in np.flatnonzero(ok):
        a = vt[i, -1]
        zmi, rt = float(zm[i]), float(root[i])
        a0 = a[0] / (2.0 * rt)
        if abs(a0) < 1e-300 or abs(a0) * rt < 1e-12 * math.hypot(a[1], a[2]):
            continue  # collinear
        a3 = -zmi * a0
        cx, cy = -a[1] / (2 * a0), -a[2] / (2 * a0)
        out[i] = (
            float(cx + mx[i]),
            float(cy + my[i]),
            math.sqrt(max(cx * cx + cy * cy - a3 / a0, 0.0)),
        )
    return out


def fit_circles_robust(
    point_sets: list[np.ndarray],
    *,
    inits: list[tuple[float, float, float] | None] | None = None,
    iterations: int = 12,
    tukey_c: float = 4.685,
    min_scale: float = 0.02,
    correlation_factors: list[float] | None = None,
    stop: float = 1e-5,
) -> list[CircleFit | None]:
    """:func:`fit_circle_robust` of several point sets at once (the same fits, vectorised).

    Each set's fit is the one :func:`fit_circle_robust` makes with the same arguments
    (its own start, robust scale, weights and stop), up to rounding: the sets are padded
    to one length with zero-weight points and iterated together, so a few small fits cost
    about what one does (numpy's per-call overhead, not arithmetic, is most of a fit of
    ~100 points). A set with fewer than 3 or non-finite points, or whose Taubin start
    fails (``inits`` None for it), gives None.

    Parameters
    ----------
    point_sets : list of (N_i, 2) arrays.
    inits : per set, (cx, cy, r) or None (Taubin's fit).
    correlation_factors : per set (default 1.0 each).
    iterations, tukey_c, min_scale, stop : as :func:`fit_circle_robust`.
    """
    out: list[CircleFit | None] = [None] * len(point_sets)
    sets = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in point_sets]
    batch = _padded_batch(sets, inits)
    if batch is None:
        return out
    use, counts, valid, px, py, starts = batch
    theta, w = _iterate_circles(
        px, py, valid, counts, np.array(starts, dtype=np.float64),
        iterations=iterations, tukey_c=tukey_c, min_scale=min_scale, stop=stop,
    )  # fmt: skip
    cf = (
        np.ones(len(use))
        if correlation_factors is None
        else np.array([correlation_factors[i] for i in use], dtype=np.float64)
    )
    for i, fit in zip(use, _circle_summaries(px, py, theta, w, counts, cf), strict=True):
        out[i] = fit
    return out


def _padded_batch(
    sets: list[np.ndarray], inits: list[tuple[float, float, float] | None] | None
) -> tuple[list[int], np.ndarray, np.ndarray, np.ndarray, np.ndarray, list] | None:
    """The usable sets padded to one length, with their starts (None when none is usable).

    Returns the sets' indices, point counts, the valid-point mask, x and y (B, N) and
    each set's start (cx, cy, r); a set with fewer than 3 or non-finite points, or whose
    Taubin start fails, is left out.
    """
    use = [i for i, p in enumerate(sets) if p.shape[0] >= 3]
    if not use:
        return None
    n_max = max(sets[i].shape[0] for i in use)
    # padded with each set's first point (finite distances; weight 0 throughout)
    xy = np.empty((len(use), n_max, 2))
    for k, i in enumerate(use):
        n = sets[i].shape[0]
        xy[k, :n] = sets[i]
        xy[k, n:] = sets[i][0]
    finite = np.isfinite(xy).all(axis=(1, 2)).tolist()
    if not all(finite):
        use = [i for i, f in zip(use, finite, strict=True) if f]
        xy = xy[finite]
        if not use:
            return None
    counts = np.array([sets[i].shape[0] for i in use])
    valid = np.arange(n_max)[None, :] < counts[:, None]
    px, py = xy[:, :, 0], xy[:, :, 1]
    starts = [None if inits is None else inits[i] for i in use]
    if any(s is None for s in starts):
        taubin = _taubin_batch(px, py, valid)
        starts = [s if s is not None else taubin[k] for k, s in enumerate(starts)]
    keep = [k for k, s in enumerate(starts) if s is not None]
    if len(keep) < len(use):
        use = [use[k] for k in keep]
        counts, valid, px, py = counts[keep], valid[keep], px[keep], py[keep]
        starts = [starts[k] for k in keep]
        if not use:
            return None
    return use, counts, valid, px, py, starts


def _iterate_circles(
    px: np.ndarray,
    py: np.ndarray,
    valid: np.ndarray,
    counts: np.ndarray,
    theta: np.ndarray,
    *,
    iterations: int,
    tukey_c: float,
    min_scale: float,
    stop: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Tukey-weighted Gauss-Newton of every set at once: circles (B, 3) and last weights."""
    m = theta.shape[0]
    n_max = px.shape[1]
    validf = valid.astype(np.float64)
    w = validf.copy()
    scale = np.zeros(m)
    # every set iterates until all have stopped, but a stopped set's circle, scale and
    # weights no longer change (``active``): each keeps the fit it would have alone
    active = np.ones(m, dtype=bool)
    rows = np.empty((m, 4, n_max))  # rows (d / dist, 1, res), as fit_circle_robust
    rows[:, 2] = 1.0
    rows_t = rows.transpose(0, 2, 1)
    dist = np.empty((m, n_max))
    ar = np.arange(m)
    lo, hi = (counts - 1) // 2, counts // 2
    few = np.minimum(5, counts)
    for it in range(iterations):
        dx = px - theta[:, 0:1]
        dy = py - theta[:, 1:2]
        # sqrt(dx^2 + dy^2), not np.hypot: libm's hypot is ~50x the arithmetic (the
        # same distance to an ulp; no overflow at image or millimetre scales)
        np.multiply(dx, dx, out=dist)
        dist += np.square(dy)
        np.sqrt(dist, out=dist)
        np.maximum(dist, 1e-12, out=dist)
        res = dist - theta[:, 2:3]
        if it < 3:  # robust scale from the first iterations, then fixed (as fit_circle_robust)
            srt = np.sort(np.where(valid, np.abs(res), np.inf), axis=1)
            mad = 1.4826 * ((srt[ar, lo] + srt[ar, hi]) / 2.0)
            new = np.maximum(min_scale, mad)
            if it == 0:
                new = np.maximum(new, 0.05 * theta[:, 2])
            scale = np.where(active, new, scale)
        wn = np.square(res)
        wn *= (-1.0 / np.square(tukey_c * scale))[:, None]
        wn += 1.0
        np.maximum(wn, 0.0, out=wn)
        wn *= wn
        wn *= validf
        np.divide(dx, dist, out=rows[:, 0])
        np.divide(dy, dist, out=rows[:, 1])
        rows[:, 3] = res
        gram = (rows * wn[:, None, :]) @ rows_t
        flat = gram[:, 2, 2] < few
        if flat.any():  # (almost) every weight 0: unweighted
            wn[flat] = validf[flat]
            gram[flat] = (rows[flat] * wn[flat][:, None, :]) @ rows_t[flat]
        w = wn if active.all() else np.where(active[:, None], wn, w)
        # each set's 3x3 solve in Python floats (as fit_circle_robust: the same arithmetic)
        th = theta.tolist()
        for k, g in enumerate(gram.tolist()):
            if not active[k]:
                continue
            step = _solve_sym3(g)
            if step is None:
                active[k] = False
                continue
            th[k] = [th[k][0] + step[0], th[k][1] + step[1], th[k][2] + step[2]]
            if it >= 2 and max(abs(step[0]), abs(step[1]), abs(step[2])) < stop:
                active[k] = False
        theta = np.array(th)
        if not active.any():
            break
    return theta, w


def _circle_summaries(
    px: np.ndarray,
    py: np.ndarray,
    theta: np.ndarray,
    w: np.ndarray,
    counts: np.ndarray,
    cf: np.ndarray,
) -> list[CircleFit]:
    """Each set's :class:`CircleFit` at its final circle, with its last weights."""
    m = theta.shape[0]
    dx = px - theta[:, 0:1]
    dy = py - theta[:, 1:2]
    dist = np.maximum(np.sqrt(np.square(dx) + np.square(dy)), 1e-12)
    res = dist - theta[:, 2:3]
    inl = w > 0
    n_in = inl.sum(axis=1).tolist()  # (np.count_nonzero with an axis is this, slower)
    jac = np.stack((dx / dist, dy / dist, np.ones_like(dist)), axis=1)  # (B, 3, N)
    jtwj = (jac * w[:, None, :]) @ jac.transpose(0, 2, 1)
    dof = np.maximum(1.0, w.sum(axis=1) - 3.0)
    s2 = np.einsum("bn,bn,bn->b", w, res, res) / dof
    inv = np.array([_inverse_sym3(g) for g in jtwj.tolist()])
    cov = inv * (s2 * cf)[:, None, None]
    ang = np.arctan2(dy, dx)
    bins = np.floor((ang + np.pi) / (2 * np.pi) * 36).astype(np.intp) % 36
    bins += 36 * np.arange(m)[:, None]
    sectors = np.bincount(bins[inl], minlength=36 * m).reshape(m, 36)
    coverage = ((sectors > 0).sum(axis=1) / 36.0).tolist()
    # Python floats and ints of each set's numbers in one conversion per array
    th, s2_k, counts_k, r_var = theta.tolist(), s2.tolist(), counts.tolist(), cov[:, 2, 2].tolist()
    return [
        CircleFit(
            (th[k][0], th[k][1]),
            th[k][2],
            cov[k, :2, :2].copy(),
            math.sqrt(s2_k[k]),
            int(counts_k[k]),
            n_in[k],
            coverage[k] if n_in[k] else 0.0,
            math.sqrt(max(r_var[k], 0.0)),
        )
        for k in range(m)
    ]


def _inverse_sym3(a: list[list[float]]) -> list[list[float]]:
    """The inverse of a symmetric 3x3 matrix (rows as lists), by its cofactors; inf where singular."""
    (a00, a01, a02), (_, a11, a12), (_, _, a22) = a
    c00 = a11 * a22 - a12 * a12
    c01 = a02 * a12 - a01 * a22
    c02 = a01 * a12 - a02 * a11
    det = a00 * c00 + a01 * c01 + a02 * c02
    if not det or not math.isfinite(det):
        return [[math.inf] * 3 for _ in range(3)]
    c11 = a00 * a22 - a02 * a02
    c12 = a01 * a02 - a00 * a12
    c22 = a00 * a11 - a01 * a01
    return [
        [c00 / det, c01 / det, c02 / det],
        [c01 / det, c11 / det, c12 / det],
        [c02 / det, c12 / det, c22 / det],
    ]
