"""The wire's sub-pixel centreline: symmetric-profile centres across the wire.

A round wire's brightness across it is symmetric about its axis (shading,
specular crest and dark flanks alike), while what lies *beside* it is not: a
cast shadow darkens one side only, which is why a threshold or edge midpoint
is pulled towards the shadow on a light sheet. So each centre is the point
about which the profile across the wire, *within* the wire, is most symmetric:
the shift ``c`` minimising ``sum_u (I(c + u) - I(c - u))^2`` over
``|u| <= rho``, ``rho`` a little less than the wire's half-width, on
profiles sampled every 0.05 px along the normals (bilinear), refined by a
parabola through the cost minimum. Four passes: normals from the skeleton
with a window of most of the wire's rough width (a small window finds false
centres in each dark flank: a local valley is symmetric too), then normals from
the centres found with the window set from the half-width measured about
them; centres that jump from the running median along the wire are dropped.

Each end of the wire is found the same way along the axis: the wire's end is
taken as a hemispherical cap (as a cut end rounded by handling, and as the
renderer draws it), so the brightness beyond the end point along the axis
repeats the half-profile across the wire; the end point is where the axial
profile best matches the mean cross half-profile.

With the wire's expected width in pixels (from its diameter through the
calibrated plane, :func:`cvmeasure.part.measure.measure_centreline_mm`), the
centres are instead taken between the wire's two **silhouette edges**
(:func:`silhouette_edges`): the symmetry above holds only for light from
straight above; a light from one side puts the specular highlight on the lit
flank and the symmetric centre follows it (1.4-2.9 px off the axis on a
ray-traced 19 px wire lit from 50 deg elevation). A silhouette edge is a peak of
the profile's gradient; per profile, the pair of peaks whose distance is within
8 % of the expected width, that step one up and one down, with no highlight
beyond either, and whose summed strength is largest is the wire (the highlight's
own edges are closer together, the shadow's outer edge farther out). The end
points are the caps' silhouettes on the axis less the half-width. The edges' distance is the wire's apparent width, which
:mod:`cvmeasure.part.lift` reads as the wire's distance from the camera.

Frames: input and output in image pixels (OpenCV: x right, y down, pixel
centres at integers). :mod:`cvmeasure.part.measure` maps them to board mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from cvmeasure.part.fit import PolylineFit, fit_polyline

__all__ = [
    "Centreline",
    "EndShape",
    "chord_profile_centres",
    "profile_polyline",
    "measure_centreline",
    "silhouette_edges",
    "symmetric_centres",
]

_STEP_PX = 0.05
#: How far the first pass of the pair search looks from the mask's path for the pair's
#: midpoint, in wire widths (:func:`_silhouette_centres`).
FIRST_PASS_REACH = 1.0
#: An end whose outward axis is within 60 deg of the shadow's direction faces away from
#: the light (:func:`_end_point`).
INTO_SHADOW_COS = 0.5
#: Least strength of a step inside the taken cap edge (share of the strongest) that can be
#: the cap's silhouette where a cast shadow reaches past the cap (:func:`_cap_edge`).
SHADOW_STEP_SHARE = 0.25
#: A stretch along the axis whose darkening below the plate exceeds this many times the
#: wire body's is cast shadow (measured: shadows 1.9-2.4, caps' own stretches <= 0.9).
SHADOW_DARKER = 1.25
#: Smallest half-window of the symmetry test (px): below it a dark flank's own
#: valley is symmetric enough to pass for a centre.
_MIN_RHO_PX = 1.5

EndShape = Literal["round", "flat"]
#: Least length of the silhouette centreline, as a share of the symmetric one's.
SILHOUETTE_MIN_SHARE = 0.95
#: Remaining asymmetry (see :attr:`Centreline.asymmetry`) above which the symmetric
#: centres are not a wire's (rendered wires lit from above give 0.001-0.08).
SYMMETRIC_WIRE_MAX = 0.12
#: Least length of the silhouette centreline, as a share of the mask path's, when the
#: symmetric centres are not a wire's (the path runs on a little into a joined shadow).
SILHOUETTE_MIN_SHARE_OF_PATH = 0.85
#: Relative range of the silhouette edges' distance about the expected width.
PAIR_TOLERANCE = 0.08
#: Share of profiles with a clean edge pair from which the gaps are left open.
PAIRS_ONLY_SHARE = 0.6
#: A gap in the clean pairs at least this many wire widths long is filled by one edge
#: even where pairs cover most of the wire (a chord without a centre has no line).
LONG_GAP_WIDTHS = 3.0
#: Grey level (0-255 scale) from which a sample counts as clipped (a saturated highlight).
_CLIPPED = 250.0


@dataclass(frozen=True)
class Centreline:
    """A wire centreline in image pixels.

    Attributes
    ----------
    points_px : ndarray (M, 2); ordered centres from one end point to the
        other, both end points included (x, y), pixels.
    half_width_px : the wire's apparent half-width (flank at half contrast), pixels.
    rho_px : the half-window the symmetric centres used, pixels.
    ends_px : ndarray (2, 2); the two end points (also ``points_px[0]``, ``[-1]``).
    rejected : profiles dropped in the last pass (no symmetric centre near the guess).
    coverage : the share of the last pass's profiles that had a symmetric
        centre: near 1 along a wire, lower along other thin structures.
    asymmetry : median over the profiles of the remaining asymmetry at the centre
        relative to the profile's own variance in the window (0 perfectly
        symmetric, about 1 for no symmetry at all).
    centre_from : ``"symmetry"``, ``"silhouette"`` (between the two silhouette edges),
        or ``"symmetry (...)"`` when silhouette edges were asked for but did not follow
        the whole wire.
    edge_width_px : with silhouette edges, ndarray (M,): the distance between the
        two edges at each point (NaN at the end points), pixels; else None.
    lit_points_px : with silhouette edges and the shadow's side seen, ndarray (M, 2): the
        same centres with each pair's midpoint replaced by the lit side's edge moved by
        half the wire's width (:func:`_silhouette_centres`); for the bend at each vertex,
        which the shadow side's edge bends on a lifted part. Else None.
    end_uncertainty_px : (2,) how far inside each end point a weaker step could be the
        cap's silhouette instead (pixels, along the axis; 0 where none): at an end facing
        away from the light on a light sheet, where the shadow's far edge and the cap's
        silhouette both step the same way (:func:`_cap_edge`).
    """

    points_px: np.ndarray
    half_width_px: float
    rho_px: float
    ends_px: np.ndarray
    rejected: int
    coverage: float = 1.0
    asymmetry: float = 0.0
    centre_from: str = "symmetry"
    edge_width_px: np.ndarray | None = None
    end_uncertainty_px: np.ndarray = field(default_factory=lambda: np.zeros(2))
    lit_points_px: np.ndarray | None = None

    def to_dict(self) -> dict[str, Any]:
        widths = self.edge_width_px
        return {
            "centre_from": self.centre_from,
            "edge_width_px": (
                None
                if widths is None or not np.isfinite(widths).any()
                else float(np.nanmedian(widths))
            ),
            "points": len(self.points_px),
            "half_width_px": self.half_width_px,
            "rho_px": self.rho_px,
            "ends_px": self.ends_px.tolist(),
            "rejected": self.rejected,
            "coverage": self.coverage,
            "asymmetry": self.asymmetry,
            "end_uncertainty_px": [float(v) for v in self.end_uncertainty_px],
        }


def _length(path: np.ndarray) -> float:
    return float(np.sum(np.hypot(*np.diff(path, axis=0).T))) if len(path) > 1 else 0.0


def _resample(path: np.ndarray, step: float) -> np.ndarray:
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(path, axis=0).T))))
    n = max(2, int(s[-1] / step) + 1)
    t = np.linspace(0.0, s[-1], n)
    return np.column_stack((np.interp(t, s, path[:, 0]), np.interp(t, s, path[:, 1])))


def _smooth(path: np.ndarray, sigma: float) -> np.ndarray:
    from scipy.ndimage import gaussian_filter1d

    if sigma <= 0 or len(path) < 3:
        return path
    return np.column_stack(
        (
            gaussian_filter1d(path[:, 0], sigma, mode="nearest"),
            gaussian_filter1d(path[:, 1], sigma, mode="nearest"),
        )
    )


def _normals(path: np.ndarray) -> np.ndarray:
    t = np.gradient(path, axis=0)
    t /= np.maximum(np.hypot(t[:, 0], t[:, 1]), 1e-12)[:, None]
    return np.column_stack((-t[:, 1], t[:, 0]))


def _sample(gray: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Bilinear samples of ``gray`` at points (..., 2) x, y."""
    from scipy.ndimage import map_coordinates

    shape = points.shape[:-1]
    flat = points.reshape(-1, 2)
    vals = map_coordinates(gray, [flat[:, 1], flat[:, 0]], order=1, mode="nearest")
    return vals.reshape(shape)


def symmetric_centres(
    profiles: np.ndarray,
    *,
    rho_px: float,
    search_px: float,
    step_px: float = _STEP_PX,
    max_slope_px: float | None = None,
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
    cost = np.empty((len(p), len(shifts)))
    u = np.arange(1, ku + 1)
    for j, c in enumerate(shifts):
        a = p[:, mid + c + u]
        b = p[:, mid + c - u]
        cost[:, j] = np.mean((a - b) ** 2, axis=1)
    rows = np.arange(len(p))
    if max_slope_px is None:
        k = np.argmin(cost, axis=1)
    else:
        # choose the basin by asymmetry relative to the window's variance, so a
        # flat, soft shadow band (symmetric but featureless) loses to the wire
        cs = np.cumsum(np.pad(p, ((0, 0), (1, 0))), axis=1)
        cs2 = np.cumsum(np.pad(p * p, ((0, 0), (1, 0))), axis=1)
        lo, hi = mid + shifts - ku, mid + shifts + ku + 1
        n = 2 * ku + 1
        mean = (cs[:, hi] - cs[:, lo]) / n
        var = np.maximum((cs2[:, hi] - cs2[:, lo]) / n - mean**2, 0.0)
        ratio = cost / (2.0 * var + 1e-6 * (1.0 + float(np.median(var))))
        k = _least_cost_path(ratio, max(1, int(np.ceil(max_slope_px / step_px))))
        # then the raw asymmetry's own minimum within a few samples of it
        near = 4
        idx = np.clip(k[:, None] + np.arange(-near, near + 1)[None, :], 0, len(shifts) - 1)
        k = idx[rows, np.argmin(cost[rows[:, None], idx], axis=1)]
    inner = (k > 0) & (k < len(shifts) - 1)
    kk = np.clip(k, 1, len(shifts) - 2)
    c0, c1, c2 = cost[rows, kk - 1], cost[rows, kk], cost[rows, kk + 1]
    denom = c0 - 2 * c1 + c2
    frac = np.where(denom > 0, 0.5 * (c0 - c2) / np.where(denom > 0, denom, 1.0), 0.0)
    shift = (shifts[kk] + np.clip(frac, -1, 1)) * step_px
    shift = np.where(inner, shift, np.nan)
    return shift, cost[rows, k]


def silhouette_edges(
    profiles: np.ndarray,
    offsets_px: np.ndarray,
    width_px: np.ndarray | float,
    *,
    tolerance: float = 0.05,
    centre_tolerance: float = 0.2,
) -> tuple[np.ndarray, np.ndarray]:
    """The wire's two silhouette edges on each profile across it, pixels along the normal.

    Parameters
    ----------
    profiles : ndarray (P, S); grey levels at ``offsets_px`` (S,) along each normal.
    width_px : the expected apparent width (scalar or (P,)), pixels.
    tolerance : relative range of widths accepted about ``width_px``.
    centre_tolerance : largest distance of the pair's midpoint from offset 0 (the
        current centre), relative to ``width_px``.

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
    from scipy.ndimage import gaussian_filter1d

    p = np.asarray(profiles, dtype=np.float64)
    step = float(offsets_px[1] - offsets_px[0])
    signed = gaussian_filter1d(p, 0.5 / step, axis=1, order=1)
    grad = np.abs(signed)
    n_p = len(p)
    width = np.broadcast_to(np.asarray(width_px, dtype=np.float64), (n_p,))
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
        ok &= np.abs(pos[None, :] + pos[:, None]) <= 2.0 * centre_tolerance * width[i]
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
    from scipy.ndimage import gaussian_filter1d

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
    flat = (g < tau[:, None]) & (p < np.minimum(_CLIPPED, (plate + above)[:, None]))
    run = max(2, int(round(max(1.5, 0.08 * width_px) / step)))
    back = int(round(2.5 / step))
    left = np.full(len(p), np.nan)
    right = np.full(len(p), np.nan)
    from numpy.lib.stride_tricks import sliding_window_view

    # covered[i, j]: sample j lies in a flat stretch at least ``run`` samples long
    all_flat = sliding_window_view(flat, run, axis=1).all(axis=2)
    covered = np.zeros_like(flat)
    for k in range(run):
        covered[:, k : k + all_flat.shape[1]] |= all_flat
    for i in range(len(p)):
        # the stretches between flat ones: the wire, a penumbra, a stray line...
        busy = ~covered[i]
        starts, stops = _true_runs(busy)
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
            lo = _peak(g[i], a, min(b, a + back), offsets_px)
            hi = _peak(g[i], max(a, b - back), b, offsets_px)
            if hi - lo <= 1.6 * width_px:
                left[i], right[i] = lo, hi
                break
    return left, right


def _edge_gradient(profiles: np.ndarray, offsets: np.ndarray, edge: np.ndarray) -> np.ndarray:
    """The profiles' gradient magnitude (grey per px, over 0.5 px) at ``edge`` (P,); 0 at NaN."""
    from scipy.ndimage import gaussian_filter1d

    step = float(offsets[1] - offsets[0])
    g = np.abs(gaussian_filter1d(np.asarray(profiles, float), 0.5 / step, axis=1, order=1)) / step
    ok = np.isfinite(edge)
    k = np.clip(
        np.round((np.nan_to_num(edge) - offsets[0]) / step).astype(int), 0, len(offsets) - 1
    )
    return np.where(ok, g[np.arange(len(g)), k], 0.0)


def _majority(labels: np.ndarray, window: int) -> np.ndarray:
    """The most frequent non-negative label (0, 1, 2) in a window along the wire; -1 where none."""
    from scipy.ndimage import uniform_filter1d

    counts = np.stack(
        [uniform_filter1d((labels == k).astype(float), window, mode="nearest") for k in range(3)]
    )
    out = np.argmax(counts, axis=0)
    return np.where(counts.max(axis=0) > 0, out, -1)


def _peak(g: np.ndarray, lo: int, hi: int, offsets: np.ndarray) -> float:
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


def _asymmetry_ratio(
    profiles: np.ndarray, shift_px: np.ndarray, asym: np.ndarray, rho_px: float
) -> float:
    """Median of (mean squared asymmetry) / (2 x variance in the window) over profiles."""
    if len(profiles) == 0:
        return 1.0
    mid = profiles.shape[1] // 2
    ku = max(1, int(round(rho_px / _STEP_PX)))
    centre = mid + np.round(shift_px / _STEP_PX).astype(np.int64)
    idx = centre[:, None] + np.arange(-ku, ku + 1)[None, :]
    idx = np.clip(idx, 0, profiles.shape[1] - 1)
    window = np.take_along_axis(profiles, idx, axis=1)
    var = window.var(axis=1)
    return float(np.median(asym / np.maximum(2.0 * var, 1e-9)))


def _least_cost_path(cost: np.ndarray, reach: int) -> np.ndarray:
    """Column per row (P,) minimising the summed cost with |k_i - k_(i-1)| <= reach."""
    from numpy.lib.stride_tricks import sliding_window_view

    n_rows, n_cols = cost.shape
    # scale each row to its own range so that no single profile dominates
    lo = cost.min(axis=1, keepdims=True)
    span = np.maximum(cost.max(axis=1, keepdims=True) - lo, 1e-12)
    c = (cost - lo) / span
    back = np.empty((n_rows, n_cols), dtype=np.int64)
    total = c[0].copy()
    cols = np.arange(n_cols)
    for i in range(1, n_rows):
        win = sliding_window_view(np.pad(total, reach, constant_values=np.inf), 2 * reach + 1)
        j = np.argmin(win, axis=1)
        back[i] = cols + j - reach
        total = c[i] + win[cols, j]
    path = np.empty(n_rows, dtype=np.int64)
    path[-1] = int(np.argmin(total))
    for i in range(n_rows - 1, 0, -1):
        path[i - 1] = back[i, path[i]]
    return path


def _true_runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Starts and stops (one past the end) of a 1-D boolean ``mask``'s runs of True."""
    change = np.diff(np.concatenate(([False], mask, [False])).astype(np.int8))
    return np.nonzero(change == 1)[0], np.nonzero(change == -1)[0]


def _long_runs(mask: np.ndarray, min_length: float) -> np.ndarray:
    """True at the elements of ``mask``'s runs of True at least ``min_length`` long."""
    out = np.zeros(len(mask), dtype=bool)
    for start, stop in zip(*_true_runs(mask), strict=True):
        if stop - start >= min_length:
            out[start:stop] = True
    return out


def _despike(shift: np.ndarray, window: int) -> np.ndarray:
    """NaN where a shift departs from the running median of its neighbours along the wire.

    A centre moves smoothly along the wire; one that jumps (a false symmetric
    point in a flank, a crossing shadow) is dropped: more than 3 robust sigmas
    (and 0.5 px) from the running median over ``window`` profiles.
    """
    from scipy.ndimage import median_filter

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


def _half_width(profiles: np.ndarray, offsets: np.ndarray, guess_px: float) -> np.ndarray:
    """Per profile, the smaller distance from 0 to a flank at half contrast (P,).

    The contrast is taken against the background on the side *farther* in
    level from the wire's extreme (a shadow sits between the two); the
    smaller of the two sides is the one a shadow did not widen.
    """
    p = profiles
    n = p.shape[1]
    outer = max(2, n // 10)
    bg_l = np.median(p[:, :outer], axis=1)
    bg_r = np.median(p[:, -outer:], axis=1)
    core = np.abs(offsets) <= 1.5 * guess_px
    bg = 0.5 * (bg_l + bg_r)
    dev = p[:, core] - bg[:, None]
    hi = dev.max(axis=1)
    lo = dev.min(axis=1)
    bright = hi >= -lo  # the wire stands out brighter than its background
    extreme = np.where(bright, p[:, core].max(axis=1), p[:, core].min(axis=1))
    ref = np.where(bright, np.minimum(bg_l, bg_r), np.maximum(bg_l, bg_r))
    level = 0.5 * (ref + extreme)
    sign = np.where(bright, 1.0, -1.0)
    above = (p - level[:, None]) * sign[:, None] > 0
    out = np.full(len(p), np.nan)
    centre = n // 2
    for i in range(len(p)):
        row = above[i]
        left = np.nonzero(row[:centre])[0]
        right = np.nonzero(row[centre:])[0]
        if len(left) == 0 or len(right) == 0:
            continue
        a = left[0]
        b = centre + right[-1]
        if a == 0 or b == n - 1:
            continue
        fa = (level[i] - p[i, a - 1]) / (p[i, a] - p[i, a - 1])
        fb = (level[i] - p[i, b]) / (p[i, b + 1] - p[i, b])
        xa = offsets[a - 1] + fa * (offsets[a] - offsets[a - 1])
        xb = offsets[b] + fb * (offsets[b + 1] - offsets[b])
        out[i] = min(-xa, xb)
    return out


def measure_centreline(
    gray: np.ndarray,
    path_px: np.ndarray,
    *,
    width_guess_px: float,
    step_px: float = 1.0,
    end_shape: EndShape = "round",
    wire_width_px: float | None = None,
) -> Centreline:
    """Sub-pixel centreline of the wire along a rough path.

    Parameters
    ----------
    gray : ndarray (H, W), float; the photo's grey levels.
    path_px : ndarray (M, 2); an ordered rough centre path (the mask's
        skeleton), end to end, pixels.
    width_guess_px : the wire's rough width (from the mask), pixels.
    step_px : spacing of the centres along the wire, pixels.
    end_shape : ``"round"`` (hemispherical caps, matched to the cross profile)
        or ``"flat"`` (square-cut: the end face is where the brightness along
        the axis falls half-way from the wire's crest to the background).
    wire_width_px : the wire's expected apparent width (its diameter seen from the
        camera), pixels. With it the centres lie between the two silhouette edges
        (see the module notes); without it, at the profiles' centre of symmetry.

    Raises
    ------
    ValueError
        When too few profiles give a centre (no wire along the path).
    """
    if end_shape not in ("round", "flat"):
        raise ValueError(f"end_shape must be 'round' or 'flat', got {end_shape!r}")
    g = np.asarray(gray, dtype=np.float32)
    hw0 = max(1.0, 0.5 * width_guess_px)
    path = _resample(np.asarray(path_px, dtype=np.float64), step_px)
    path = _smooth(path, max(2.0, 2.0 * hw0) / step_px)
    reach = 3.0 * hw0 + 4.0
    if wire_width_px is not None:
        reach = max(reach, 1.25 * wire_width_px + 5.0)
    offsets = np.arange(-round(reach / _STEP_PX), round(reach / _STEP_PX) + 1) * _STEP_PX

    def profiles_at(centres: np.ndarray, normals: np.ndarray) -> np.ndarray:
        pts = centres[:, None, :] + offsets[None, :, None] * normals[:, None, :]
        return _sample(g, pts)

    normals = _normals(path)
    prof = profiles_at(path, normals)
    centres = path
    # the rough path can sit off the axis (a shadow joined to the mask), which
    # inflates half-widths measured from it: centre with a small window first
    hws = _half_width(prof, offsets, hw0)
    rough = float(np.nanmedian(hws)) if np.isfinite(hws).any() else hw0
    # a window of most of the wire: a small one finds false centres in each
    # dark flank (a local valley is symmetric too)
    rho = max(0.85 * rough, _MIN_RHO_PX)
    search = min(1.0 * rough + 1.0, reach - rho - 0.5)
    rejected = 0
    window = int(round(6.0 * hw0 / step_px))
    for final in (False, False, True):
        shift, _ = symmetric_centres(prof, rho_px=rho, search_px=search, max_slope_px=0.4 * step_px)
        shift = _despike(shift, window)
        ok = np.isfinite(shift)
        rejected = int((~ok).sum())
        if ok.sum() < 5:
            raise ValueError("no symmetric wire profile along the path")
        centres = _resample((centres + shift[:, None] * normals)[ok], step_px)
        # normals from the centres found, smoothed along the wire
        smooth = _smooth(centres, max(2.0, 2.0 * rough) / step_px)
        normals = _normals(smooth)
        prof = profiles_at(centres, normals)
        if not final:
            hws = _half_width(prof, offsets, rough)
            rough = float(np.nanmedian(hws)) if np.isfinite(hws).any() else rough
            rho = max(0.6 * rough, min(0.85 * rough, rough - 0.8), _MIN_RHO_PX)
            search = min(0.5 * rough + 1.0, reach - rho - 0.5)
    half_width = rough
    shift, asym = symmetric_centres(prof, rho_px=rho, search_px=search, max_slope_px=0.4 * step_px)
    shift = _despike(shift, window)
    ok = np.isfinite(shift)
    rejected = int((~ok).sum())
    coverage = float(ok.mean())
    symmetry = _asymmetry_ratio(prof[ok], shift[ok], asym[ok], rho)
    centres = (centres + shift[:, None] * normals)[ok]
    if len(centres) < 5:
        raise ValueError("no symmetric wire profile along the path")
    prof_ok = prof[ok]
    centre_from = "symmetry"
    widths = None
    shadow = None
    lit = None
    if wire_width_px is not None:
        # from the mask's path, not the symmetric centres: those may have lost a
        # stretch of the wire (a clipped highlight), which could not come back
        try:
            found = _silhouette_centres(
                profiles_at, path, offsets, float(wire_width_px), step_px, rough, window
            )
        except ValueError:
            found = None
        # the silhouette edges must follow the wire as far as its symmetric centres do;
        # where they lose a stretch at an end the part would be cut short: keep the
        # symmetric centres and say so (centre_from)
        # unless those are no wire's (a side-lit wire far from symmetric, a shadow joined
        # to it: they wander off along the shadow), then most of the mask's own path
        reach_px = (
            SILHOUETTE_MIN_SHARE * _length(centres)
            if symmetry <= SYMMETRIC_WIRE_MAX
            else SILHOUETTE_MIN_SHARE_OF_PATH * _length(path)
        )
        if found is not None and _length(found[0]) >= reach_px:
            centres, prof_ok, widths, coverage, shadow, lit = found
            centre_from = "silhouette"
            if np.isfinite(widths).any():
                half_width = 0.5 * float(np.nanmedian(widths))
        else:
            centre_from = "symmetry (no silhouette edges along the whole wire)"
    # between silhouette edges the end is found from the cap's silhouette too
    at_edges = centre_from == "silhouette"
    found_ends = [
        _end_point(
            g, centres, prof_ok, offsets, rho, half_width,
            head=head, shape=end_shape, silhouette=at_edges, shadow=shadow,
        )
        for head in (True, False)
    ]  # fmt: skip
    ends = np.vstack([e[0] for e in found_ends])
    end_uncertainty = np.array([e[1] for e in found_ends])
    # trim centres that lie beyond the end points (skeleton overshoot)
    keep = np.ones(len(centres), dtype=bool)
    k = min(5, len(centres) - 1)
    near = max(k, int(round(4.0 * half_width / step_px)))  # only the last few centres
    for end, inward, idx in (
        (ends[0], centres[k] - centres[0], np.arange(min(near, len(centres)))),
        (
            ends[1],
            centres[-1 - k] - centres[-1],
            np.arange(max(0, len(centres) - near), len(centres)),
        ),
    ):
        inward = inward / max(np.hypot(*inward), 1e-12)
        keep[idx] &= ((centres[idx] - end) @ inward) >= 0.5 * half_width
    inner = centres[keep]
    lit_points = None if lit is None else np.vstack((ends[:1], lit[keep], ends[1:]))
    edge_width = None
    if widths is not None:
        edge_width = np.concatenate(([np.nan], widths[keep], [np.nan]))
    return Centreline(
        points_px=np.vstack((ends[:1], inner, ends[1:])),
        half_width_px=half_width,
        rho_px=rho,
        ends_px=ends,
        rejected=rejected,
        coverage=coverage,
        asymmetry=symmetry,
        centre_from=centre_from,
        edge_width_px=edge_width,
        end_uncertainty_px=end_uncertainty,
        lit_points_px=lit_points,
    )


def _shadow_side(
    profiles: np.ndarray,
    normals: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    offsets: np.ndarray,
) -> np.ndarray | None:
    """The image direction (2,) in which the wire's shadow lies, or None when none is seen.

    Beside an edge, a flat stretch darker than the plate farther out on the same side
    is the shadow; the direction that has most of these sides' outward normals on
    its side (the middle of the best ones) is the way the light casts.
    """
    n = profiles.shape[1]
    outer = max(3, n // 12)
    votes = []
    for side, edge in ((-1.0, left), (1.0, right)):
        ok = np.isfinite(edge)
        k = np.clip(np.searchsorted(offsets, edge[ok] + side * 2.0), 0, n - 1)
        k2 = np.clip(np.searchsorted(offsets, edge[ok] + side * 4.0), 0, n - 1)
        rows = np.nonzero(ok)[0]
        near = 0.5 * (profiles[rows, k] + profiles[rows, k2])
        far = np.median(profiles[rows, -outer:] if side > 0 else profiles[rows, :outer], axis=1)
        dark = near < far - 0.15 * np.maximum(far, 10.0)
        votes.append(side * normals[rows[dark]])
    v = np.vstack(votes)
    if len(v) < 10:
        return None
    # the direction that puts the most votes on its side; of a tie, the middle
    angles = np.radians(np.arange(0.0, 360.0, 1.0))
    dirs = np.column_stack((np.cos(angles), np.sin(angles)))
    agree = ((v @ dirs.T) > 0).mean(axis=0)
    if agree.max() < 0.8:
        return None
    best = np.nonzero(agree >= agree.max() - 1e-9)[0]
    mean = dirs[best].sum(axis=0)
    return mean / max(float(np.hypot(*mean)), 1e-12)


def _silhouette_centres(
    profiles_at: Any,
    centres: np.ndarray,
    offsets: np.ndarray,
    width_px: float,
    step_px: float,
    smooth_px: float,
    window: int,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray | None, np.ndarray | None]:
    """Centres between the silhouette edges (:func:`outer_edges`), from rough ``centres``.

    The edges are the strongest gradient pair a width apart (within 8 %, or 0.5 px;
    :func:`silhouette_edges`), else those found from inside (:func:`outer_edges`);
    where they are a width apart the centre is their midpoint. Where such pairs cover
    most of the wire (``PAIRS_ONLY_SHARE``) the other profiles are left out. Where they are not, a shadow's penumbra joins the silhouette on the
    shadow side (its flat stretch too narrow to be seen), or a false flat stretch
    cut the wire, so the centre is one edge moved by half the width (the median
    width of the clean pairs): the lit side's, where the shadow's side is known
    (:func:`_shadow_side`, from the whole wire) and the wire runs across the light;
    else the sharper one. One rule holds along two widths of wire (the majority):
    an edge's shading
    bias is alike along a straight chord: a parallel shift, which leaves its
    direction, and so the bends, unchanged; a chord measured partly by pairs and
    partly by one edge would not be.

    But not along a lifted part: there the shadow parts from the wire as it rises, and
    the shadow side's edge shifts with the gap (0.4 px at half size over two chords of a
    dev part lifted 3 mm, lit at 50 deg elevation), which bends the pairs' midpoints at
    the vertices (0.05-0.13 deg at full size on dev parts R 42-50 mm, 120 deg, N 7). So
    the lit centres are returned too: where the shadow's side is known, each pair's
    midpoint replaced by the lit side's edge moved by half the median width (the same
    rule along two widths of wire); noisier by up to sqrt(2), free of the shadow.

    Returns the centres, their profiles, the edge widths (px, NaN where only one
    edge was used), the share of profiles with a centre, the image direction in
    which the wire's shadow lies (:func:`_shadow_side`, last pass; None when none is seen)
    and the lit centres (None when the shadow's side is not seen).
    """
    coverage = 1.0
    widths = np.zeros(0)
    lit = None
    # the edges' distance is the width within 5 %, or half a pixel on a thin wire (a
    # blurred 6 px wire's limbs read 4-5 % wide)
    tol = max(PAIR_TOLERANCE, 0.5 / width_px)
    for n_pass, final in enumerate((False, False, True)):
        normals = _normals(_smooth(centres, max(2.0, smooth_px) / step_px))
        prof = profiles_at(centres, normals)
        # the mask's path can lie half a width off the axis or more (a shadow joined to the
        # mask, wider where a lifted end's shadow parts from the wire): the first pass looks
        # for the pair's midpoint within a width of it (FIRST_PASS_REACH). Within half a
        # width, the shadow's own band (as wide as the wire, the wire's edge on one side) was
        # the only pair in reach beside a dark sheet's shadow, and the wire's pair, whose
        # summed gradient is the larger (the plate's edge to the lit wire against the
        # shadow's soft outer edge), was not searched (issue 14: dev B4's last 12 mm on the
        # shadow, A6's last 10 mm without pairs)
        near = FIRST_PASS_REACH if n_pass == 0 else 0.2
        # the strongest pair of gradient peaks a width apart about the centre; where there
        # is none (a penumbra joined to one side blurs its edge), the edges found from
        # inside (:func:`outer_edges`). Not the other way round: on a light sheet a dark
        # wire's gently shaded body is flat to that test and a soft shadow ramp joins one
        # side, so a shadow's outer edge and the highlight's can pass for the wire there
        left, right = silhouette_edges(
            prof, offsets, width_px, tolerance=tol, centre_tolerance=near
        )
        width = right - left
        pair = np.abs(width / width_px - 1.0) <= tol
        left2, right2 = outer_edges(prof[~pair], offsets, width_px)
        fill = np.nonzero(~pair)[0]
        left[fill], right[fill] = left2, right2
        width = right - left
        pair = np.abs(width / width_px - 1.0) <= tol
        w_eff = float(np.median(width[pair])) if pair.sum() >= 10 else width_px
        shift = np.where(pair, 0.5 * (left + right), np.nan)
        from_left = left + 0.5 * w_eff
        from_right = right - 0.5 * w_eff
        # the sharper edge (a penumbra joined to the silhouette softens it), unless
        # the shadow says; an edge that would move the centre far does not count
        sharp_l, sharp_r = _edge_gradient(prof, offsets, left), _edge_gradient(prof, offsets, right)
        near_l = np.abs(np.nan_to_num(from_left, nan=np.inf)) <= 0.25 * width_px
        near_r = np.abs(np.nan_to_num(from_right, nan=np.inf)) <= 0.25 * width_px
        use_left = near_l & (~near_r | (sharp_l >= sharp_r))
        shadow = _shadow_side(prof, normals, left, right, offsets)
        if shadow is not None:
            towards = normals @ shadow  # > 0: the shadow lies on the + (right) side
            use_left = np.where(np.abs(towards) > 0.05, towards > 0, use_left)
        # one rule along a stretch of wire (the majority over two widths), so that a
        # chord is not measured partly by pairs and partly by one edge
        rule = np.where(pair, 0, np.where(use_left & near_l, 1, np.where(near_r, 2, -1)))
        rule = _majority(rule, max(3, int(round(2.0 * width_px / step_px))))
        shift = np.where(
            (rule == 0) & pair,
            0.5 * (left + right),
            np.where(
                (rule == 1) & near_l, from_left, np.where((rule == 2) & near_r, from_right, np.nan)
            ),
        )
        if pair.mean() >= PAIRS_ONLY_SHARE:
            # clean pairs along most of the wire: the gaps are left open (the fits need no
            # centre there) rather than filled by one edge, which a shadow's or a
            # highlight's edge can stand in for over a stretch (4 px off on a lab render);
            # but not a gap as long as a chord (no clean pair along a chord near the light's
            # azimuth on a light sheet): without centres its line came from the centres
            # bracketing the gap, a vertex bend 0.6-1.4 deg off on dev parts
            long_gap = _long_runs(~pair, LONG_GAP_WIDTHS * width_px / step_px)
            shift = np.where(pair, 0.5 * (left + right), np.where(long_gap, shift, np.nan))
        shift = _despike(shift, window)
        ok = np.isfinite(shift)
        coverage = float(ok.mean())
        if ok.sum() < 5:
            raise ValueError("no silhouette edges of the wire's width along the path")
        if final and shadow is not None:
            # the lit side's edge moved by half the width, where a pair's midpoint is used
            lit_rule = np.where(np.abs(towards) > 0.05, np.where(towards > 0, 1, 2), 0)
            lit_rule = _majority(lit_rule, max(3, int(round(2.0 * width_px / step_px))))
            lit_edge = np.where(
                lit_rule == 1, from_left, np.where(lit_rule == 2, from_right, np.nan)
            )
            # every centre (not only the pairs' midpoints: a chord would mix the two)
            swap = np.isfinite(lit_edge) & (np.abs(lit_edge) <= 0.25 * width_px)
            delta = np.where(swap & np.isfinite(shift), lit_edge - shift, 0.0)
            lit = (centres + (shift + delta)[:, None] * normals)[ok]
        centres = (centres + shift[:, None] * normals)[ok]
        widths = np.where(pair, width, np.nan)[ok]
        if not final:
            centres = _resample(centres, step_px)
    # a short run of centres cut off from the rest by a gap at either end (false edges
    # beside a cap's highlight: 3 px off the axis on a lab render) is not the wire's
    gap = np.nonzero(np.hypot(*np.diff(centres, axis=0).T) > 3.0 * step_px)[0]
    lo = int(gap[0]) + 1 if len(gap) and _length(centres[: gap[0] + 1]) < width_px else 0
    hi = int(gap[-1]) + 1 if len(gap) and _length(centres[gap[-1] + 1 :]) < width_px else None
    if len(centres[lo:hi]) >= 5:
        centres, widths = centres[lo:hi], widths[lo:hi]
        lit = None if lit is None else lit[lo:hi]
    # the last profiles, re-centred on the edges' midpoints (for the end points)
    normals = _normals(_smooth(centres, max(2.0, smooth_px) / step_px))
    return centres, profiles_at(centres, normals), widths, coverage, shadow, lit


def _end_point(
    gray: np.ndarray,
    centres: np.ndarray,
    profiles: np.ndarray,
    offsets: np.ndarray,
    rho: float,
    half_width: float,
    *,
    head: bool,
    shape: EndShape = "round",
    silhouette: bool = False,
    shadow: np.ndarray | None = None,
) -> tuple[np.ndarray, float]:
    """The end point of the wire's axis at one end, pixels, and its uncertainty (px).

    Round ends: the centre of the hemispherical cap. Flat ends: the end face,
    where the brightness along the axis crosses half-way from the crest (the
    median on the axis inside the wire) to the background beyond.

    With ``silhouette`` (centres between the silhouette edges, ``half_width`` half
    the edges' distance), a round end is the cap's silhouette on the axis
    (:func:`_cap_edge`) moved back by the half-width: the cap's outline is the
    same limb as the wire's sides, so the edges' shading bias cancels. The
    brightness along the axis of a side-lit cap (a specular spot, a lit or a
    dark face) does not repeat the profile across the wire, which the match
    below assumes (it stopped 30 px short on the photo lab's 23 px wire).

    ``shadow``: the image direction in which the wire's shadow lies, when seen. An end
    whose axis points into it (within 60 deg) faces away from the light and the shadow of
    a lifted end can reach beyond its cap: the returned uncertainty says how far inside
    the cap's silhouette could lie (:func:`_cap_edge`; 0 elsewhere).

    The axis near the end is a robust line through the centres 1.5 to 4.5
    half-widths from the last one (the last centres can be pulled by the
    cap's shadow); the cap is searched along that line.
    """
    from cvmeasure.part.fit import _fit_line

    pts = centres if head else centres[::-1]
    prof = profiles if head else profiles[::-1]
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))))
    sel = (s >= 1.5 * half_width) & (s <= 4.5 * half_width + 1.0)
    if sel.sum() < 5:
        sel = np.zeros(len(pts), dtype=bool)
        sel[: min(len(pts), 10)] = True
    p0, d, _ = _fit_line(pts[sel])
    if d @ (pts[0] - pts[sel][-1]) < 0:
        d = -d  # outward
    first = pts[sel][0]
    start = p0 + ((first - p0) @ d) * d
    # mean cross half-profile in the window, symmetrised, on the flank
    # u in [0.35, 0.9] half-widths: inside the wire (no shadow), away from the
    # narrow specular crest (whose sampled height differs between a ridge and a cap)
    mid = len(offsets) // 2
    k0 = int(round(0.35 * half_width / _STEP_PX))
    k1 = max(k0 + 2, int(round(max(rho, 0.9 * half_width) / _STEP_PX)))
    block = prof[sel]
    right = block[:, mid + k0 : mid + k1 + 1]
    left = block[:, mid - k1 : mid - k0 + 1][:, ::-1]
    template = np.median(0.5 * (right + left), axis=0)
    if shape == "flat":
        return _flat_end(gray, start, d, block, half_width), 0.0
    if silhouette:
        into_shadow = shadow is not None and float(d @ shadow) >= INTO_SHADOW_COS
        found = _cap_edge(gray, start, d, block, half_width, facing_shadow=into_shadow)
        if found is not None:
            edge, spread = found
            return start + (edge - half_width) * d, spread
    search = np.arange(
        -round((1.0 * half_width) / _STEP_PX), round((8.0 * half_width + 4.0) / _STEP_PX) + 1
    )
    search = search * _STEP_PX
    u = np.arange(k0, k1 + 1) * _STEP_PX
    samples = _sample(gray, start[None, None, :] + (search[:, None, None] + u[None, :, None]) * d)
    costs = np.mean((samples - template[None, :]) ** 2, axis=1)
    k = int(np.argmin(costs))
    if 0 < k < len(costs) - 1:
        c0, c1, c2 = costs[k - 1], costs[k], costs[k + 1]
        den = c0 - 2 * c1 + c2
        frac = 0.5 * (c0 - c2) / den if den > 0 else 0.0
        best = float(search[k] + np.clip(frac, -1, 1) * _STEP_PX)
    else:
        best = float(search[k])
    return start + best * d, 0.0


def _cap_edge(
    gray: np.ndarray,
    start: np.ndarray,
    d: np.ndarray,
    block: np.ndarray,
    half_width: float,
    *,
    facing_shadow: bool = False,
) -> tuple[float, float] | None:
    """Distance (px) from ``start`` along ``d`` to a round end's silhouette, None if none,
    and how far inside it a weaker step could be the silhouette instead (px, else 0).

    The silhouette is where the brightness along the axis steps from the wire's towards
    the background's (the profiles' ``block`` across the wire near the end give both
    levels): a peak of that signed gradient (over 0.5 px, refined by a parabola). Of the
    peaks at least half as strong as the strongest, the outermost within two
    half-widths beyond the strongest: a specular spot on the cap has edges of its own
    inside the cap, a shadow's penumbra beyond it is soft, and another object farther
    away is not taken. At an end facing away from the light (``facing_shadow``) on a
    plate brighter than the wire, the shadow's far edge steps like the silhouette and as
    strongly, and may be the outermost peak (13.5 px beyond the cap at a 1.5 mm lift):
    there the uncertainty is how far inside the taken peak the innermost one at least a
    quarter as strong lies (within two half-widths), else 0. Taking the innermost strong
    peak instead was measured wrong as often (a lab render's cap: 0.10 deg per chord).
    """
    from scipy.ndimage import gaussian_filter1d

    mid = block.shape[1] // 2
    k_in = max(1, int(round(0.8 * half_width / _STEP_PX)))
    wire = float(np.median(block[:, mid - k_in : mid + k_in + 1]))
    outer = max(2, block.shape[1] // 10)
    background = float(np.median(np.concatenate((block[:, :outer], block[:, -outer:]), axis=1)))
    sign = 1.0 if wire > background else -1.0
    t = np.arange(0, round((8.0 * half_width + 4.0) / _STEP_PX) + 1) * _STEP_PX
    axial = _sample(gray, start[None, :] + t[:, None] * d[None, :])
    grad = -sign * gaussian_filter1d(axial, 0.5 / _STEP_PX, order=1)
    inner = grad[1:-1]
    peaks = np.nonzero((inner >= grad[:-2]) & (inner > grad[2:]) & (inner > 0))[0] + 1
    if len(peaks) == 0:
        return None
    strong = peaks[grad[peaks] >= 0.5 * grad[peaks].max()]
    first = strong[np.argmax(grad[strong])]
    k = int(strong[t[strong] <= t[first] + 2.0 * half_width].max())
    spread = 0.0
    # the shadow's far edge steps like the silhouette, and as strongly, only where the plate
    # is brighter than the wire (a light sheet); on a dark one it is faint beside the wire's
    if facing_shadow and sign < 0:
        weak = peaks[grad[peaks] >= SHADOW_STEP_SHARE * grad[peaks].max()]
        # walk in over cast shadow: a stretch inside the taken step darker than the wire's
        # body is plate lit by the ambient light only, not the lamp-lit wire or its cap
        while True:
            inside = weak[(t[weak] < t[k]) & (t[weak] >= t[k] - 2.0 * half_width)]
            if len(inside) == 0:
                break
            j = int(inside.max())
            level = _stretch_level(gray, start, d, t[j], t[k], half_width)
            if background - level <= SHADOW_DARKER * (background - wire):
                break
            k = j
        near = weak[(t[weak] <= t[k]) & (t[weak] >= t[k] - 2.0 * half_width)]
        spread = float(t[k] - t[near].min())
        # the cap's own outline against the shadow may give no rising step at all (its dark
        # limb meets the shadow at about the shadow's level): a stretch inside the taken
        # step as dark as cast shadow and longer than a half-width (a cap's own dark limb
        # lies within one half-width of its outline) has the silhouette somewhere in it
        dark = axial < background - SHADOW_DARKER * (background - wire)
        j = k - 1
        while j >= 0 and dark[j]:
            j -= 1
        run = float(t[k] - t[j + 1]) if j + 1 < k else 0.0
        if run > half_width:
            spread = max(spread, run)
    g0, g1, g2 = grad[k - 1], grad[k], grad[k + 1]
    den = g0 - 2 * g1 + g2
    frac = 0.5 * (g0 - g2) / den if den < 0 else 0.0
    return float(t[k] + np.clip(frac, -0.5, 0.5) * _STEP_PX), spread


def _stretch_level(
    gray: np.ndarray, start: np.ndarray, d: np.ndarray, t0: float, t1: float, half_width: float
) -> float:
    """Mean grey level of the stretch of the axis ``start + t d`` between two steps at ``t0``
    and ``t1`` (px; 1.5 px kept clear of each), within a quarter half-width across it."""
    lo, hi = t0 + 1.5, t1 - 1.5
    ts = np.arange(lo, hi + 1e-9, 0.5) if hi > lo else np.array([0.5 * (t0 + t1)])
    us = np.arange(-0.25 * half_width, 0.25 * half_width + 1e-9, 0.5)
    normal = np.array([-d[1], d[0]])
    pts = start[None, None, :] + ts[:, None, None] * d + us[None, :, None] * normal
    return float(np.mean(_sample(gray, pts)))


def _flat_end(
    gray: np.ndarray, start: np.ndarray, d: np.ndarray, block: np.ndarray, half_width: float
) -> np.ndarray:
    """The end face of a square-cut wire along the axis ``start + t d``, pixels."""
    mid = block.shape[1] // 2
    crest = float(np.median(block[:, mid]))
    outer = max(2, block.shape[1] // 10)
    background = float(np.median(np.concatenate((block[:, :outer], block[:, -outer:]), axis=1)))
    level = 0.5 * (crest + background)
    t = np.arange(-round(half_width / _STEP_PX), round((8.0 * half_width + 4.0) / _STEP_PX) + 1)
    t = t * _STEP_PX
    axial = _sample(gray, start[None, :] + t[:, None] * d[None, :])
    sign = 1.0 if crest > background else -1.0
    inside = (axial - level) * sign > 0
    k0 = int(np.argmax(inside))  # first sample inside the wire
    beyond = np.nonzero(~inside[k0:])[0]
    if not inside.any() or len(beyond) == 0:
        return start
    k = k0 + int(beyond[0])  # first sample past the end face
    a, b = axial[k - 1], axial[k]
    frac = (level - a) / (b - a) if b != a else 0.5
    return start + (t[k - 1] + frac * (t[k] - t[k - 1])) * d


#: Profile sampling step across the wire for the chord template fit (px).
TEMPLATE_STEP_PX = 0.25


def chord_profile_centres(
    gray: np.ndarray,
    points_px: np.ndarray,
    chords: list[tuple[int, int]],
    *,
    width_px: float,
    margin_px: float = 2.5,
    iterations: int = 4,
    side: Literal["lit", "both"] = "lit",
) -> np.ndarray:
    """Centres re-measured by aligning each station's whole cross-profile with its chord's.

    Along a straight chord the wire's cross-profile (lit flank, highlight, shaded body) is
    the same at every station up to a shift across it: the chord is fitted as
    ``I(t, u) = T(u - c(t))``, ``T`` the chord's own mean profile (nonparametric, re-made
    from the aligned profiles at each iteration) and ``c(t)`` each station's shift, by
    Gauss-Newton on ``T'`` over ``|u| <= width_px / 2 + margin_px`` (the silhouette and what
    lies inside it, not the cast shadow beyond). Every pixel whose grey level changes with
    a shift counts, weighted by ``T'^2``, not two edge points. With ``side="lit"`` the
    flank on the shadow's side (the side beside which the profile is darker, relative to
    the plate farther out) is left out from ``margin_px`` inside the silhouette: its edge
    moves with the shadow's gap on a lifted part (``"both"`` keeps it).

    ``points_px`` (M, 2) are ordered centres (pixels); ``chords`` index ranges ``[a, b)``
    of them, one per chord (its corners left out by the caller). Returns (M, 2): the
    re-measured centres (NaN off the chords and where a profile leaves the image). A
    chord's constant offset is arbitrary (about its input centres' mean): its direction
    is what the fit measures.
    """
    g = np.asarray(gray, dtype=np.float32)
    pts = np.asarray(points_px, dtype=np.float64)
    out = np.full_like(pts, np.nan)
    hw = 0.5 * float(width_px)
    # the plate beyond the shadow's side: a shadow about as wide as the wire, and a margin
    reach = hw + margin_px + 2.0 * width_px / 3.0 + 2.0
    u = np.arange(-round(reach / TEMPLATE_STEP_PX), round(reach / TEMPLATE_STEP_PX) + 1)
    u = u * TEMPLATE_STEP_PX
    h, w = g.shape
    far = max(3, int(round(2.0 / TEMPLATE_STEP_PX)))  # the outer 2 px of each side: plate
    beside = (np.abs(u) > hw + 1.5) & (np.abs(u) < hw + margin_px + 2.0)
    for a, b in chords:
        p = pts[a:b]
        if len(p) < 8:
            continue
        mean = p.mean(axis=0)
        _, _, vt = np.linalg.svd(p - mean, full_matrices=False)
        d = vt[0]
        n = np.array([-d[1], d[0]])
        t = (p - mean) @ d
        c = (p - mean) @ n  # each station's offset across, from the input centres
        base = mean + t[:, None] * d
        grid = base[:, None, :] + (c[:, None] + u[None, :])[:, :, None] * n
        inside = np.all((grid >= 0) & (grid <= np.array([w - 1, h - 1])), axis=(1, 2))
        if inside.sum() < 8:
            continue
        # sampled once; the shifted profiles are interpolated from these
        prof = _sample(g, grid)
        shift = np.zeros(len(p))
        weight = (np.abs(u) <= hw + margin_px).astype(float)
        for it in range(iterations):
            aligned = np.array(
                [np.interp(u, u - s, row) for row, s in zip(prof, shift, strict=True)]
            )
            template = aligned[inside].mean(axis=0)
            if it == 0 and side == "lit":
                dark = [
                    float(np.mean(template[beside & (sign * u > 0)]) - np.mean(template[sl]))
                    for sign, sl in ((-1.0, slice(0, far)), (1.0, slice(-far, None)))
                ]
                shadow_sign = -1.0 if dark[0] < dark[1] else 1.0
                weight = weight * (shadow_sign * u <= hw - margin_px)
            slope = np.gradient(template, TEMPLATE_STEP_PX) * weight
            denom = float(slope @ slope)
            if denom <= 0.0:
                break
            # aligned(u) = T(u + shift - c_true) ~ T(u) + (shift - c_true) T'(u)
            step = -((aligned - template) @ slope) / denom
            shift = shift + np.clip(step, -1.0, 1.0)
        sel = np.arange(a, b)[inside]
        out[sel] = (base + (c + shift)[:, None] * n)[inside]
    return out


def profile_polyline(
    gray: np.ndarray,
    points_px: np.ndarray,
    to_mm: Any,
    chords_from: PolylineFit,
    *,
    width_px: float,
    corner_margin: float = 0.12,
    fractions: np.ndarray | None = None,
) -> PolylineFit | None:
    """The polyline of the vertex bends: each chord's centres from its whole cross-profile.

    ``points_px`` (M, 2) the ordered centres (pixels), ``to_mm`` their map to the part's
    plane (mm), ``chords_from`` a polyline already fitted to them (its vertices split the
    centres into chords; each chord's inner ``1 - 2 corner_margin`` is re-measured by
    :func:`chord_profile_centres`, lit side). The re-measured centres (the others kept)
    are fitted by :func:`cvmeasure.part.fit.fit_polyline`, so each direction's sigma
    comes from their own scatter about the chord, with its correlation
    (:func:`cvmeasure.part.fit._correlation_factor`). ``fractions``: the polygon bent's
    vertex positions (:func:`cvmeasure.part.fit.fit_polyline`). None when the fit fails.
    """
    divisions = chords_from.divisions
    pts_mm = to_mm(points_px)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(pts_mm, axis=0).T))))
    vs = np.array([s[int(np.argmin(np.hypot(*(pts_mm - v).T)))] for v in chords_from.vertices_mm])
    vs[0], vs[-1] = 0.0, s[-1]
    chords = []
    for i in range(divisions):
        lo, hi = vs[i], vs[i + 1]
        m = corner_margin * (hi - lo)
        lo, hi = lo + (m if i > 0 else 0.0), hi - (m if i < divisions - 1 else 0.0)
        idx = np.nonzero((s >= lo) & (s <= hi))[0]
        if len(idx):
            chords.append((int(idx[0]), int(idx[-1]) + 1))
    new = chord_profile_centres(gray, points_px, chords, width_px=width_px, side="lit")
    keep = np.isfinite(new[:, 0])
    new[~keep] = np.asarray(points_px, dtype=np.float64)[~keep]
    try:
        return fit_polyline(to_mm(new), divisions, fractions=fractions)
    except ValueError:
        return None
