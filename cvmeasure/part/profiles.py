"""Profiles across a wire: sampling along paths and the 1-D analysis of each profile.

Paths are polylines in image pixels; a profile is the image sampled (bilinear) along a
path's normal. From profiles: the centre of symmetry (:func:`symmetric_centres`), the
silhouette edges of a round wire (:func:`silhouette_edges`, :func:`outer_edges`), the
wire's half-width, and the least-cost continuous path through a table of costs.
"""

from __future__ import annotations

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view
from scipy.ndimage import (
    gaussian_filter1d,
    map_coordinates,
    median_filter,
    minimum_filter1d,
    uniform_filter1d,
)

from cvmeasure.geometry import arclength_mm

__all__ = [
    "PROFILE_STEP_PX",
    "CLIPPED_LEVEL",
    "path_length",
    "resample_path",
    "smooth_path",
    "path_normals",
    "sample_image",
    "sample_across",
    "asymmetry_costs",
    "symmetric_centres",
    "silhouette_edges",
    "outer_edges",
    "edge_gradient",
    "majority_filter",
    "peak_offset",
    "asymmetry_ratio",
    "least_cost_path",
    "true_runs",
    "long_runs",
    "despike",
    "side_levels",
    "half_width_px",
    "zero_mean_correlation",
]


PROFILE_STEP_PX = 0.05

#: Grey level (0-255 scale) from which a sample counts as clipped (a saturated highlight).
CLIPPED_LEVEL = 250.0


def path_length(path: np.ndarray) -> float:
    return float(np.sum(np.hypot(*np.diff(path, axis=0).T))) if len(path) > 1 else 0.0


def resample_path(path: np.ndarray, step: float) -> np.ndarray:
    s = arclength_mm(path)
    n = max(2, int(s[-1] / step) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.column_stack((np.interp(t, s, path[:, 0]), np.interp(t, s, path[:, 1])))


def smooth_path(path: np.ndarray, sigma: float) -> np.ndarray:
    if sigma <= 0 or len(path) < 3:
        return path
    return np.column_stack(
        (
            gaussian_filter1d(path[:, 0], sigma, mode="nearest"),
            gaussian_filter1d(path[:, 1], sigma, mode="nearest"),
        )
    )


def path_normals(path: np.ndarray) -> np.ndarray:
    t = np.gradient(path, axis=0)
    t /= np.maximum(np.hypot(t[:, 0], t[:, 1]), 1e-12)[:, None]
    return np.column_stack((-t[:, 1], t[:, 0]))


def sample_across(
    gray: np.ndarray, centres: np.ndarray, normals: np.ndarray, offsets: np.ndarray
) -> np.ndarray:
    """Bilinear profiles (P, S) of ``gray`` at ``centres + offsets * normals`` (x, y, pixels).

    The same samples as :func:`sample_image` on those points, with the coordinates
    written straight into the (2, P, S) array the interpolation reads (no (P, S, 2)
    points array and its copies).
    """
    c = np.asarray(centres, dtype=np.float64)
    nrm = np.asarray(normals, dtype=np.float64)
    off = np.asarray(offsets, dtype=np.float64)
    coords = np.empty((2, len(c), len(off)))
    for axis, k in ((0, 1), (1, 0)):  # row (y) then column (x)
        np.multiply(off[None, :], nrm[:, k, None], out=coords[axis])
        coords[axis] += c[:, k, None]
    return map_coordinates(gray, coords, order=1, mode="nearest")


def sample_image(gray: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``gray`` at points (..., 2) x, y."""
    shape = points.shape[:-1]
    flat = points.reshape(-1, 2)
    vals = map_coordinates(gray, [flat[:, 1], flat[:, 0]], order=1, mode="nearest")
    return vals.reshape(shape)


def symmetric_centres(
    profiles: np.ndarray,
    *,
    rho_px: float,
    search_px: float,
    step_px: float = PROFILE_STEP_PX,
    max_slope_px: float | None = None,
    trim_share: float = 0.0,
    by_variance: bool = True,
    min_level: np.ndarray | None = None,
    valley_reach_px: float | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Shift (P,) about which each profile is most symmetric, and the cost there.

    Parameters
    ----------
    profiles : ndarray (P, S); samples every ``step_px`` along the normal,
        centred on the guess (sample ``S // 2`` is offset 0).
    rho_px : half-window of the symmetry test.
    search_px : largest shift tried either way.
    max_slope_px : with it, the shifts of consecutive profiles (in order along
        the wire) differ by at most this much: the path of least total cost
        through the cost table (dynamic programming), so that isolated false
        minima cannot pull single centres away. Without it, each profile's own
        minimum.
    trim_share : the share of the window's offsets whose asymmetry is largest left out
        of each shift's cost (:func:`asymmetry_costs`); 0 counts them all.
    by_variance : with ``max_slope_px``, the basin is chosen by the asymmetry relative to
        the window's variance (True), else by the asymmetry itself: for a window that spans
        both of the wire's silhouette steps to the sheet, where a window about one flank's
        dark valley holds more variance (the sheet on one side only) and so wins by the
        ratio though less symmetric.
    min_level : ndarray (P,), optional; shifts where the profile lies below it are barred
        (no centre there; the path crosses them only where nothing else is in reach).
    valley_reach_px : with it, shifts where the profile lies below the mean of its levels
        this far either side are barred too: a valley is symmetric but is no crest.

    Returns
    -------
    shift_px : ndarray (P,), NaN where the minimum is at the search boundary.
    cost : ndarray (P,), mean squared asymmetry at the minimum.
    """
    p = np.asarray(profiles, dtype=np.float64)
    mid = p.shape[1] // 2
    ku = max(1, int(round(rho_px / step_px)))
    kc = max(1, int(round(search_px / step_px)))
    if mid - kc - ku < 0 or mid + kc + ku >= p.shape[1]:
        raise ValueError("profiles too short for rho_px + search_px")
    shifts = np.arange(-kc, kc + 1)
    cost = asymmetry_costs(p, mid, kc, ku, trim_share=trim_share)
    rows = np.arange(len(p))
    barred = np.zeros(cost.shape, dtype=bool)
    if min_level is not None:
        barred = p[:, mid + shifts] < np.asarray(min_level, dtype=np.float64)[:, None]
    if valley_reach_px is not None:
        kv = max(1, int(round(valley_reach_px / step_px)))
        below = np.clip(mid + shifts - kv, 0, p.shape[1] - 1)
        above = np.clip(mid + shifts + kv, 0, p.shape[1] - 1)
        barred = barred | (p[:, mid + shifts] < 0.5 * (p[:, below] + p[:, above]))
    if max_slope_px is None:
        k = np.argmin(np.where(barred, np.inf, cost), axis=1)
    else:
        if by_variance:
            # choose the basin by asymmetry relative to the window's variance, so a
            # flat, soft shadow band (symmetric but featureless) loses to the wire
            # running sums as far as the last window reaches (the samples beyond it would
            # change no sum read)
            used = p[:, : mid + kc + ku + 1]
            cs = np.cumsum(np.pad(used, ((0, 0), (1, 0))), axis=1)
            cs2 = np.cumsum(np.pad(used * used, ((0, 0), (1, 0))), axis=1)
            lo, hi = mid + shifts - ku, mid + shifts + ku + 1
            n = 2 * ku + 1
            mean = (cs[:, hi] - cs[:, lo]) / n
            var = np.maximum((cs2[:, hi] - cs2[:, lo]) / n - mean**2, 0.0)
            ratio = cost / (2.0 * var + 1e-6 * (1.0 + float(np.median(var))))
        else:  # the same path search on the asymmetry (scaled to order 1)
            ratio = cost / (1e-6 + float(np.median(cost)))
        # a barred shift costs as much as the row's worst, so the path crosses it only
        # where nothing else is in reach
        ratio = np.where(barred, ratio.max(axis=1, keepdims=True), ratio)
        k = least_cost_path(ratio, max(1, int(np.ceil(max_slope_px / step_px))))
        # then the raw asymmetry's own minimum within a few samples of it
        near = 4
        idx = np.clip(k[:, None] + np.arange(-near, near + 1)[None, :], 0, len(shifts) - 1)
        open_cost = np.where(barred, np.inf, cost)
        k = idx[rows, np.argmin(open_cost[rows[:, None], idx], axis=1)]
    inner = (k > 0) & (k < len(shifts) - 1)
    kk = np.clip(k, 1, len(shifts) - 2)
    # a minimum against a barred shift is the bar's edge, no centre of symmetry (as one
    # at the search's edge)
    inner &= ~(barred[rows, kk - 1] | barred[rows, kk] | barred[rows, kk + 1])
    c0, c1, c2 = cost[rows, kk - 1], cost[rows, kk], cost[rows, kk + 1]
    denom = c0 - 2 * c1 + c2
    frac = np.where(denom > 0, 0.5 * (c0 - c2) / np.where(denom > 0, denom, 1.0), 0.0)
    shift = (shifts[kk] + np.clip(frac, -1, 1)) * step_px
    shift = np.where(inner, shift, np.nan)
    return shift, cost[rows, k]


#: Profiles per block of :func:`asymmetry_costs` (a block's samples and costs stay in cache).
_COST_BLOCK_ROWS = 64


def asymmetry_costs(
    profiles: np.ndarray, mid: int, kc: int, ku: int, *, trim_share: float = 0.0
) -> np.ndarray:
    """Mean squared asymmetry (P, 2 kc + 1) of each profile about samples ``mid - kc .. mid + kc``.

    ``cost[i, j] = mean over u = 1 .. ku of (p[i, c + u] - p[i, c - u]) ** 2``, c = mid - kc + j.
    Summed over ``u`` for every shift at once, a block of profiles at a time: the same
    sums as one shift at a time, but each block's samples are read from cache.

    ``trim_share`` > 0: the mean over the offsets ``u`` (every ``_TRIM_STRIDE`` samples)
    with the smallest terms only, that share of the largest left out: a narrow feature on
    one side of the axis alone (a lamp's glint on one flank of a polished wire) then does
    not pull the centre, which the rest of the window, symmetric, fixes.
    """
    p = np.asarray(profiles, dtype=np.float64)
    n = 2 * kc + 1
    if trim_share > 0.0:
        return _trimmed_costs(p, mid, kc, ku, trim_share)
    cost = np.zeros((len(p), n))
    for r0 in range(0, len(p), _COST_BLOCK_ROWS):
        block = p[r0 : r0 + _COST_BLOCK_ROWS]
        out = cost[r0 : r0 + _COST_BLOCK_ROWS]
        diff = np.empty((len(block), n))
        for u in range(1, ku + 1):
            np.subtract(
                block[:, mid - kc + u : mid + kc + u + 1],
                block[:, mid - kc - u : mid + kc - u + 1],
                diff,
            )
            np.square(diff, diff)
            out += diff
    cost /= ku
    return cost


#: Offsets of the trimmed asymmetry cost, every this many samples (0.2 px): the terms are
#: sorted per shift, and neighbouring samples of a smooth profile repeat each other.
_TRIM_STRIDE = 4


def _trimmed_costs(p: np.ndarray, mid: int, kc: int, ku: int, trim_share: float) -> np.ndarray:
    """:func:`asymmetry_costs` with the ``trim_share`` largest terms of each shift left out."""
    n = 2 * kc + 1
    us = np.arange(ku, 0, -_TRIM_STRIDE)[::-1]
    keep = max(1, int(round((1.0 - trim_share) * len(us))))
    cost = np.zeros((len(p), n))
    for r0 in range(0, len(p), _COST_BLOCK_ROWS):
        block = p[r0 : r0 + _COST_BLOCK_ROWS]
        terms = np.empty((len(us), len(block), n))
        for j, u in enumerate(us):
            np.subtract(
                block[:, mid - kc + u : mid + kc + u + 1],
                block[:, mid - kc - u : mid + kc - u + 1],
                terms[j],
            )
        np.square(terms, terms)
        cost[r0 : r0 + _COST_BLOCK_ROWS] = np.partition(terms, keep - 1, axis=0)[:keep].mean(axis=0)
    return cost


def silhouette_edges(
    profiles: np.ndarray,
    offsets_px: np.ndarray,
    width_px: np.ndarray | float,
    *,
    tolerance: float = 0.05,
    centre_tolerance: np.ndarray | float = 0.2,
) -> tuple[np.ndarray, np.ndarray]:
    """The wire's two silhouette edges on each profile across it, pixels along the normal.

    Parameters
    ----------
    profiles : ndarray (P, S); grey levels at ``offsets_px`` (S,) along each normal.
    width_px : the expected apparent width (scalar or (P,)), pixels.
    tolerance : relative range of widths accepted about ``width_px``.
    centre_tolerance : largest distance of the pair's midpoint from offset 0 (the
        current centre), relative to ``width_px`` (scalar or (P,)).

    Returns
    -------
    left, right : ndarray (P,) each, offsets of the two edges (NaN where no pair of
        gradient peaks has a width within the tolerance), pixels.

    Each edge is a local maximum of the profile's gradient magnitude (smoothed over
    0.5 px), refined by a parabola; of every pair of peaks whose distance is within
    ``tolerance`` of the width and whose midpoint is near the current centre, the one
    with the largest summed gradient wins (a shadow's outer edge paired with a
    highlight's edge can have the wire's width, but not about its centre). Beyond a
    silhouette edge (1.5-3 px out) lies the plate or a shadow, never a highlight: an
    edge with a level there above the plate's by 30 % of the profile's range is not one
    (a dark flat shadow's outer edge and a highlight's edge are the strongest pair a
    width apart on a light sheet when the wire's limb beside the shadow is as dark).
    And one edge of the pair steps up, the other down: the limbs are darker than what
    lies beside them (a light sheet, a shadow) or brighter (a dark sheet).
    """
    p = np.asarray(profiles, dtype=np.float64)
    step = float(offsets_px[1] - offsets_px[0])
    signed = gaussian_filter1d(p, 0.5 / step, axis=1, order=1)
    grad = np.abs(signed)
    n_p = len(p)
    width = np.broadcast_to(np.asarray(width_px, dtype=np.float64), (n_p,))
    reach = np.broadcast_to(np.asarray(centre_tolerance, dtype=np.float64), (n_p,))
    left = np.full(n_p, np.nan)
    right = np.full(n_p, np.nan)
    inner = grad[:, 1:-1]
    is_peak = (inner >= grad[:, :-2]) & (inner > grad[:, 2:])
    is_peak &= inner >= 0.15 * inner.max(axis=1, keepdims=True)
    outer = max(3, p.shape[1] // 10)
    plate = np.median(np.concatenate((p[:, :outer], p[:, -outer:]), axis=1), axis=1)
    bright = plate + 0.3 * (p.max(axis=1) - plate)
    out1, out2 = int(round(1.5 / step)), int(round(3.0 / step))
    last = p.shape[1] - 1
    for i in range(n_p):
        k = np.nonzero(is_peak[i])[0] + 1
        if len(k) < 2:
            continue
        g0, g1, g2 = grad[i, k - 1], grad[i, k], grad[i, k + 1]
        den = g0 - 2 * g1 + g2
        frac = np.where(den < 0, 0.5 * (g0 - g2) / np.where(den < 0, den, -1.0), 0.0)
        pos = offsets_px[k] + np.clip(frac, -0.5, 0.5) * step
        gap = pos[None, :] - pos[:, None]
        score = g1[None, :] + g1[:, None]
        # the level beyond each peak as a left edge (outwards = lower offsets) and a right one
        beyond_l = 0.5 * (p[i, np.clip(k - out1, 0, last)] + p[i, np.clip(k - out2, 0, last)])
        beyond_r = 0.5 * (p[i, np.clip(k + out1, 0, last)] + p[i, np.clip(k + out2, 0, last)])
        ok = np.abs(gap / width[i] - 1.0) <= tolerance
        ok &= (beyond_l <= bright[i])[:, None] & (beyond_r <= bright[i])[None, :]
        # one edge steps into the wire, the other out of it (the limbs darker than all
        # around them, or brighter): a shadow's outer edge and a highlight's far edge
        # step the same way
        sense = np.sign(signed[i, k])
        ok &= (sense[:, None] * sense[None, :]) < 0
        ok &= np.abs(pos[None, :] + pos[:, None]) <= 2.0 * reach[i] * width[i]
        if not ok.any():
            continue
        a, b = np.unravel_index(np.argmax(np.where(ok, score, -np.inf)), gap.shape)
        left[i], right[i] = pos[a], pos[b]
    return left, right


def outer_edges(
    profiles: np.ndarray, offsets_px: np.ndarray, width_px: float
) -> tuple[np.ndarray, np.ndarray]:
    """The wire's silhouette edges found from inside: the last edge before the plate.

    A stretch where the profile is flat (gradient below a threshold over 0.08 wire
    widths, at least 1.5 px) is outside the wire: the plate, or a shadow lying on
    it; inside a round wire the only flat stretch is a highlight's crest (clipped,
    or broad as on the photo lab's 3D wire), known by its level: well above the
    plate (more than 30 % of the profile's range), where no shadow is. Between the flat
    stretches lie the wire, a shadow's penumbra, other lines; the wire is the one
    at least 0.9 widths wide nearest the profile's centre (within 0.7 widths; 1.5
    when the centre lies on a flat stretch, such as a wide shadow) whose
    silhouette edges, the strongest gradients within 2.5 px inside its two
    ends (refined by a parabola), are at most 1.6 widths apart (a penumbra joined
    to it widens it). The stretch itself is wider than the edges' distance by the
    blurred edges' tails, about 2 px whatever the width: 1.7 widths on a 6 px wire.

    Returns left, right offsets (P,) px, NaN where no stretch of the wire's width
    was found.
    """
    p = np.asarray(profiles, dtype=np.float64)
    step = float(offsets_px[1] - offsets_px[0])
    g = np.abs(gaussian_filter1d(p, 0.5 / step, axis=1, order=1)) / step  # grey per px
    n = p.shape[1]
    outer = max(3, n // 10)
    noise = 1.4826 * np.median(
        np.abs(np.concatenate((g[:, :outer], g[:, -outer:]), axis=1)), axis=1
    )
    tau = np.maximum(3.0 * noise, 0.08 * g.max(axis=1))
    # a highlight is flat too, but inside the wire: clipped, or a broad crest well
    # above the plate (a shadow, the only other flat level, is darker than the plate)
    plate = np.median(np.concatenate((p[:, :outer], p[:, -outer:]), axis=1), axis=1)
    above = np.maximum(0.3 * (p.max(axis=1) - plate), np.maximum(3.0 * noise * step, 8.0))
    flat = (g < tau[:, None]) & (p < np.minimum(CLIPPED_LEVEL, (plate + above)[:, None]))
    run = max(2, int(round(max(1.5, 0.08 * width_px) / step)))
    back = int(round(2.5 / step))
    left = np.full(len(p), np.nan)
    right = np.full(len(p), np.nan)
    # covered[i, j]: sample j lies in a flat stretch at least ``run`` samples long
    all_flat = sliding_window_view(flat, run, axis=1).all(axis=2)
    covered = np.zeros_like(flat)
    for k in range(run):
        covered[:, k : k + all_flat.shape[1]] |= all_flat
    for i in range(len(p)):
        # the stretches between flat ones: the wire, a penumbra, a stray line...
        busy = ~covered[i]
        starts, stops = true_runs(busy)
        if len(starts) == 0:
            continue
        width = (stops - starts) * step
        centre = 0.5 * (offsets_px[starts] + offsets_px[np.minimum(stops, n) - 1])
        # a stretch holds the blurred edges' tails too (about 2 px each side, whatever
        # the wire's width): the upper bound is on its edges' distance, below
        fits = width >= 0.9 * width_px
        # a rough centre on a flat stretch (a wide shadow) is off the wire: look farther
        reach = (1.5 if covered[i, n // 2] else 0.7) * width_px
        fits &= (starts > 0) & (stops < n) & (np.abs(centre) <= reach)
        # the one holding the current centre, else the nearest
        for j in np.argsort(np.where(fits, np.abs(centre), np.inf))[: int(fits.sum())]:
            a, b = int(starts[j]), int(stops[j])  # busy samples a .. b - 1
            lo = peak_offset(g[i], a, min(b, a + back), offsets_px)
            hi = peak_offset(g[i], max(a, b - back), b, offsets_px)
            if hi - lo <= 1.6 * width_px:
                left[i], right[i] = lo, hi
                break
    return left, right


def edge_gradient(profiles: np.ndarray, offsets: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """The profiles' gradient magnitude (grey per px, over 0.5 px) at ``edge`` (P,); 0 at NaN.

    ``gaussian_filter1d(profiles, 0.5 px, order=1)`` (mode ``reflect``) evaluated at one
    sample per profile only, with the filter's own operations in its order (its odd
    kernel: the weights times the differences of the samples either side), so the same
    values as filtering every sample and reading one.
    """
    p = np.asarray(profiles, float)
    step = float(offsets[1] - offsets[0])
    sigma = 0.5 / step
    radius = int(4.0 * sigma + 0.5)  # gaussian_filter1d's default truncate
    impulse = np.zeros(2 * radius + 1)
    impulse[radius] = 1.0
    # the correlation weights: the response to a unit sample, read backwards
    weights = gaussian_filter1d(impulse, sigma, order=1)[radius::-1]
    ok = np.isfinite(edge)
    k = np.clip(
        np.round((np.nan_to_num(edge) - offsets[0]) / step).astype(int), 0, len(offsets) - 1
    )
    padded = np.pad(p, ((0, 0), (radius, radius)), mode="symmetric")  # scipy's 'reflect'
    rows = np.arange(len(p))
    at = k + radius
    g = padded[rows, at] * weights[0]
    for j in range(1, radius + 1):
        g += (padded[rows, at + j] - padded[rows, at - j]) * weights[j]
    return np.where(ok, np.abs(g) / step, 0.0)


def majority_filter(labels: np.ndarray, window: int) -> np.ndarray:
    """The most frequent non-negative label (0, 1, 2) in a window along the wire; -1 where none."""
    counts = np.stack(
        [uniform_filter1d((labels == k).astype(float), window, mode="nearest") for k in range(3)]
    )
    out = np.argmax(counts, axis=0)
    return np.where(counts.max(axis=0) > 0, out, -1)


def peak_offset(g: np.ndarray, lo: int, hi: int, offsets: np.ndarray) -> float:
    """Sub-sample position of the maximum of ``g[lo:hi]`` (parabola), in offset units."""
    k = lo + int(np.argmax(g[lo:hi]))
    if 0 < k < len(g) - 1:
        c0, c1, c2 = g[k - 1], g[k], g[k + 1]
        den = c0 - 2 * c1 + c2
        frac = 0.5 * (c0 - c2) / den if den < 0 else 0.0
    else:
        frac = 0.0
    step = offsets[1] - offsets[0]
    return float(offsets[k] + np.clip(frac, -0.5, 0.5) * step)


def asymmetry_ratio(
    profiles: np.ndarray, shift_px: np.ndarray, asym: np.ndarray, rho_px: float
) -> float:
    """Median of (mean squared asymmetry) / (2 x variance in the window) over profiles."""
    if len(profiles) == 0:
        return 1.0
    mid = profiles.shape[1] // 2
    ku = max(1, int(round(rho_px / PROFILE_STEP_PX)))
    centre = mid + np.round(shift_px / PROFILE_STEP_PX).astype(np.int64)
    idx = centre[:, None] + np.arange(-ku, ku + 1)[None, :]
    idx = np.clip(idx, 0, profiles.shape[1] - 1)
    window = np.take_along_axis(profiles, idx, axis=1)
    var = window.var(axis=1)
    return float(np.median(asym / np.maximum(2.0 * var, 1e-9)))


def least_cost_path(cost: np.ndarray, reach: int) -> np.ndarray:
    """Column per row (P,) minimising the summed cost with |k_i - k_(i-1)| <= reach."""
    n_rows, n_cols = cost.shape
    # scale each row to its own range so that no single profile dominates
    lo = cost.min(axis=1, keepdims=True)
    span = np.maximum(cost.max(axis=1, keepdims=True) - lo, 1e-12)
    c = (cost - lo) / span
    # forward: each row's least total through it (a running minimum over the reach, in C);
    # backward: the first column of least total within reach of the next row's choice
    # (the same choice, ties to the lowest column, as keeping each row's argmins)
    totals = np.empty((n_rows, n_cols))
    totals[0] = c[0]
    for i in range(1, n_rows):
        totals[i] = c[i] + minimum_filter1d(
            totals[i - 1], 2 * reach + 1, mode="constant", cval=np.inf
        )
    path = np.empty(n_rows, dtype=np.int64)
    path[-1] = int(np.argmin(totals[-1]))
    for i in range(n_rows - 1, 0, -1):
        lo = max(0, int(path[i]) - reach)
        path[i - 1] = lo + int(np.argmin(totals[i - 1, lo : int(path[i]) + reach + 1]))
    return path


def true_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops (one past the end) of a 1-D boolean ``mask``'s runs of True."""
    change = np.diff(np.concatenate(([False], mask, [False])).astype(np.int8))
    return np.nonzero(change == 1)[0], np.nonzero(change == -1)[0]


def long_runs(mask: np.ndarray, min_length: float) -> np.ndarray:
    """True at the elements of ``mask``'s runs of True at least ``min_length`` long."""
    out = np.zeros(len(mask), dtype=bool)
    for start, stop in zip(*true_runs(mask), strict=True):
        if stop - start >= min_length:
            out[start:stop] = True
    return out


def despike(shift: np.ndarray, window: int) -> np.ndarray:
    """NaN where a shift departs from the running median of its neighbours along the wire.

    A centre moves smoothly along the wire; one that jumps (a false symmetric
    point in a flank, a crossing shadow) is dropped: more than 3 robust sigmas
    (and 0.5 px) from the running median over ``window`` profiles.
    """
    out = shift.copy()
    ok = np.isfinite(shift)
    if ok.sum() < 5:
        return out
    vals = shift[ok]
    med = median_filter(vals, size=max(3, window | 1), mode="nearest")
    res = vals - med
    sigma = 1.4826 * float(np.median(np.abs(res)))
    bad = np.abs(res) > max(3.0 * sigma, 0.5)
    idx = np.nonzero(ok)[0]
    out[idx[bad]] = np.nan
    return out


def zero_mean_correlation(rows: np.ndarray, template: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The correlation (R,) of each of ``rows`` (R, S) with ``template`` (S,), both less
    their means (0 where either is flat), and each row's contrast (R,): its root sum of
    squares about its mean, in the rows' units.

    How like the wire's own cross profile a profile is, whatever the light's level: a
    profile across the axis correlates with its neighbours' at 0.85-0.98, one across the
    sheet's grain by chance at a fraction of the contrast.
    """
    r = np.asarray(rows, dtype=np.float64)
    r = r - r.mean(axis=1, keepdims=True)
    t = np.asarray(template, dtype=np.float64)
    t = t - t.mean()
    norms = np.sqrt(np.sum(r * r, axis=1))
    den = norms * float(np.sqrt(t @ t))
    corr = np.divide(r @ t, den, out=np.zeros(len(r)), where=den > 0)
    return corr, norms


def side_levels(profiles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The sheet's grey level beyond each end of every profile across the wire: the
    medians of its outer tenths (at least 2 samples), left and right, each (P,)."""
    outer = max(2, profiles.shape[1] // 10)
    return np.median(profiles[:, :outer], axis=1), np.median(profiles[:, -outer:], axis=1)


def half_width_px(profiles: np.ndarray, offsets: np.ndarray, guess_px: float) -> np.ndarray:
    """Per profile, the smaller distance from 0 to a flank at half contrast (P,).

    The contrast is taken against the background on the side *farther* in
    level from the wire's extreme (a shadow sits between the two); the
    smaller of the two sides is the one a shadow did not widen.
    """
    p = profiles
    n = p.shape[1]
    bg_l, bg_r = side_levels(p)
    core = np.abs(offsets) <= 1.5 * guess_px
    bg = 0.5 * (bg_l + bg_r)
    dev = p[:, core] - bg[:, None]
    hi = dev.max(axis=1)
    lo = dev.min(axis=1)
    bright = hi >= -lo  # the wire stands out brighter than its background
    extreme = np.where(bright, p[:, core].max(axis=1), p[:, core].min(axis=1))
    ref = np.where(bright, np.minimum(bg_l, bg_r), np.maximum(bg_l, bg_r))
    level = 0.5 * (ref + extreme)
    # past the level towards the extreme; the sign's product is exact, so kept in the
    # profiles' own type (no float64 copy of them)
    past = p - level[:, None]
    past *= np.where(bright, 1.0, -1.0).astype(past.dtype)[:, None]
    above = past > 0
    out = np.full(len(p), np.nan)
    centre = n // 2
    # the first sample past the level from the left end, the last from the right end (every
    # profile at once: the same samples, and the same float32 and float64 operations, as one
    # profile at a time)
    has_left = above[:, :centre].any(axis=1)
    has_right = above[:, centre:].any(axis=1)
    a = np.argmax(above[:, :centre], axis=1)
    b = n - 1 - np.argmax(above[:, centre:][:, ::-1], axis=1)
    rows = np.nonzero(has_left & has_right & (a > 0) & (b < n - 1))[0]
    a, b, lv = a[rows], b[rows], level[rows]
    pa0, pa1 = p[rows, a - 1], p[rows, a]
    pb0, pb1 = p[rows, b], p[rows, b + 1]
    fa = (lv - pa0) / (pa1 - pa0)
    fb = (lv - pb0) / (pb1 - pb0)
    xa = offsets[a - 1] + fa * (offsets[a] - offsets[a - 1])
    xb = offsets[b] + fb * (offsets[b + 1] - offsets[b])
    out[rows] = np.where(xb < -xa, xb, -xa)  # min(-xa, xb), ties and all
    return out
