"""Sub-pixel marker centres: edge points on the disc's boundary and a robust circle fit.

Around each detected disc (full resolution, a small region only) the image, in
linear light, is scaled to 1 on the disc and 0 on its white ring (its luminance
by default; or its green channel, or the projection on the disc-to-ring colour
difference: :data:`EDGE_MODE`).
Its 0.5 crossings, sampled along rays from the approximate centre with linear
interpolation, are sub-pixel edge points; a geometric circle fit with Tukey weights
(iteratively reweighted Gauss-Newton, Taubin's algebraic fit to start) gives
the centre, its covariance and the residuals. Edge points hidden by another
marker or the wire are down-weighted to zero by the robust loss.

References
----------
G. Taubin, "Estimation of planar curves, surfaces and nonplanar space curves",
IEEE TPAMI 13(11), 1991, doi:10.1109/34.103273.
N. Chernov, C. Lesort, "Least squares fitting of circles", J. Math. Imaging
Vision 23, 2005, doi:10.1007/s10851-005-0482-8.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import cv2
import numpy as np

from cvmeasure.colorimetry import SRGB8_TO_LINEAR, srgb_decode, srgb_encode_floats
from cvmeasure.geometry import median_by_partition

__all__ = [
    "EdgePoints",
    "disc_edge_points",
    "channel_shifts_px",
    "CORRELATION_FACTOR",
    "RAY_SPACING_PX",
    "FIT_STOP_PX",
    "ray_correlation_factor",
    "edge_ray_count",
    "CENTRE_FLOOR_PX",
    "EDGE_MODE",
    "EDGE_MODES",
    "MIN_STEP_SHARE",
]

#: Variance inflation for neighbouring edge points that share noise (blur, JPEG
#: blocks), for rays 1 px of circumference apart: the effective number of independent
#: points is N / CORRELATION_FACTOR. Calibrated on rendered photos (benchmarks/markers.py).
CORRELATION_FACTOR = 2.5
#: Arc length between neighbouring edge rays (px of circumference). Neighbouring rays
#: read overlapping pixels (bilinear samples of a blurred image), so rays closer than
#: the noise's correlation length add little: CORRELATION_FACTOR is per ray at 1 px and
#: scaled to the rays' actual spacing (:func:`ray_correlation_factor`).
RAY_SPACING_PX = 2.0
#: The edge fits stop when no step of the centre or radius exceeds this (px): a
#: thousandth of a pixel, far under a centre's uncertainty (about 0.005 px).
FIT_STOP_PX = 1e-3
#: Fewest rays round a disc (small discs: rays closer than RAY_SPACING_PX apart; with
#: fewer, the planes path and the full decode disagreed by 0.006 deg on 0.3-scale renders).
MIN_RAYS = 96


def edge_ray_count(radius_px: float) -> int:
    """Rays of :func:`disc_edge_points` round a disc of ``radius_px``: one per
    :data:`RAY_SPACING_PX` of circumference, :data:`MIN_RAYS` to 1440."""
    return min(max(round(2 * math.pi * radius_px / RAY_SPACING_PX), MIN_RAYS), 1440)


def ray_correlation_factor(radius_px: float) -> float:
    """Variance inflation of the circle fit of a disc's edge rays (``radius_px``):
    :data:`CORRELATION_FACTOR` scaled to the rays' actual spacing (px of circumference)."""
    spacing_px = 2 * math.pi * max(radius_px, 1e-9) / edge_ray_count(radius_px)
    return max(1.0, CORRELATION_FACTOR / spacing_px)


#: Standard uncertainty floor of a centre (px, per axis): what the residuals cannot
#: see (colour fringes, print tolerance, JPEG chroma subsampling).
CENTRE_FLOOR_PX = 0.003
#: Which image the edge is found in: "luma" (linear luminance Y, the default: the
#: component JPEG keeps at full resolution, so chroma subsampling does not blur or
#: bias it; p95 angle error 0.0022 deg vs 0.006 deg for "colour" on full-size
#: renders), "green" (the green channel alone: immune to lateral chromatic
#: aberration, which magnifies red and blue; the best choice for a lens with strong
#: lateral colour), "colour" (projection on the disc-to-ring colour difference,
#: all channels) or "shade" (the ring's colour with the disc's colour projected out:
#: every shade of the disc's colour reads as the disc, see :data:`SHADE_EDGES`).
#: "luma", "green" and "shade" fall back to "colour" for a disc whose step in that
#: image is less than MIN_STEP_SHARE of its colour difference.
EDGE_MODE = "luma"
EDGE_MODES: tuple[str, ...] = ("luma", "green", "colour", "shade")
#: Why "shade" edges for raised caps: a cap's coloured top stands on its white ring by
#: a step whose wall, darker or lighter than the top, is seen on the side facing the
#: camera's foot point, just outside the top's edge. In luminance (or one channel) the
#: wall counts as disc by ``(ring - wall) / (ring - disc)``: near 1 for a dark disc,
#: up to 1.8 for a light one (the orange pin), so each disc's centre moves towards the
#: foot point by its own share of the wall (Mitsuba renders: the pin 0.1 px, 0.04 deg
#: of pin angle). Projected orthogonally to the disc's colour, every shade of that
#: colour reads 0 (the disc) and the ring its own light: the wall counts exactly once
#: for every disc, a common scale about the foot point that leaves the angles alone,
#: and a shadow on the ring moves the edge as much as in luminance for a dark disc, half
#: as much for a light one.
SHADE_EDGES = "shade"
MIN_STEP_SHARE = 0.25
#: Ring levels round a disc (each ray's, smoothed over neighbours) spread by more than
#: this share of the disc-to-ring step: uneven light (a shadow across the marker). The
#: edge is then found half-way between each ray's own disc and ring levels, and rays
#: whose own step is under :data:`MIN_LOCAL_STEP` of it (covered) are dropped.
UNEVEN_RING_SPREAD = 0.2
MIN_LOCAL_STEP = 0.35
LEVEL_RATIO_TOLERANCE = 0.15


def _linear_roi(raw: np.ndarray) -> np.ndarray:
    """A region in linear light (float32, 0..1): a blurred edge crosses half-way at the edge."""
    if raw.dtype == np.uint8:
        return cv2.LUT(raw, SRGB8_TO_LINEAR)
    top = float(np.iinfo(raw.dtype).max)
    return srgb_decode(raw.astype(np.float32) / top).astype(np.float32)


@dataclass(frozen=True)
class EdgePoints:
    """Sub-pixel points on one disc's boundary (full-resolution image pixels).

    ``disc_bgr`` / ``ring_bgr`` are the median colours inside the disc and on its
    white ring; ``contrast`` their distance (0..255 units); ``clipped_fraction``
    the share of ring pixels with a saturated channel; ``ring_spread`` how much the
    ring's level varies round the disc (5-95 % range, share of the disc-to-ring step;
    0 for even light, :data:`UNEVEN_RING_SPREAD` and more: a shadow across it),
    computed when first read from ``ring_samples`` (per ray, its samples on the ring,
    1 on the disc and 0 on the ring): only the refinement's settled pass needs it.
    """

    points_px: np.ndarray
    disc_bgr: tuple[float, float, float]
    ring_bgr: tuple[float, float, float]
    contrast: float
    clipped_fraction: float
    ring_samples: np.ndarray | None = field(default=None, repr=False, compare=False)

    @functools.cached_property
    def ring_spread(self) -> float:
        """5-95 % range of the rays' ring levels (median of each ray's ring samples)."""
        if self.ring_samples is None:
            return 0.0
        ring = np.sort(_row_medians(self.ring_samples))
        return _sorted_percentile(ring, 95.0) - _sorted_percentile(ring, 5.0)


def _encode8(linear: np.ndarray) -> tuple[float, float, float]:
    """8-bit sRGB (0..255, float) of three linear values (:func:`srgb_encode_floats`)."""
    r, g, b = (255.0 * e for e in srgb_encode_floats(linear.tolist()))
    return r, g, b


def _row_medians(a: np.ndarray) -> np.ndarray:
    """``np.median(a, axis=1)`` of a small 2-D array, from one sort (no NaN checks)."""
    srt = np.sort(a, axis=1)
    n = srt.shape[1]
    if n % 2:
        return srt[:, n // 2]
    return (srt[:, n // 2 - 1] + srt[:, n // 2]) / 2


def _sorted_percentile(srt: np.ndarray, q: float) -> float:
    """The ``q`` % percentile of sorted values, linear between neighbours (numpy's default)."""
    if len(srt) == 1:
        return float(srt[0])
    h = (len(srt) - 1) * q / 100.0
    i = min(int(h), len(srt) - 2)
    return float(srt[i] + (h - i) * (float(srt[i + 1]) - float(srt[i])))


@functools.lru_cache(maxsize=64)
def _unit_rays(n_rays: int) -> tuple[np.ndarray, np.ndarray]:
    """``(cos, sin)`` of ``n_rays`` evenly spaced ray directions, each (n_rays, 1)."""
    phi = np.arange(n_rays) * (2 * math.pi / n_rays)
    cos, sin = np.cos(phi)[:, None], np.sin(phi)[:, None]
    cos.flags.writeable = sin.flags.writeable = False
    return cos, sin


def _ray_maps(
    x_px: float, y_px: float, radius_px: float, band: float, step_px: float, n_rays: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Samples along ``n_rays`` rays from ``(x_px, y_px)`` (pixels of the region read) at
    radii ``(1 - band) r .. (1 + band) r`` every ``step_px``: ``radii`` (K,) and the
    ``cv2.remap`` maps ``map_x``, ``map_y`` (n_rays, K) float32 (float64 sums rounded once:
    summed in place, then cast; a casting ``np.add`` into float32 buffers its scalar)."""
    radii = np.arange((1 - band) * radius_px, (1 + band) * radius_px + step_px, step_px)
    cos, sin = _unit_rays(n_rays)
    map_x = radii * cos
    map_x += x_px
    map_y = radii * sin
    map_y += y_px
    return radii, map_x.astype(np.float32), map_y.astype(np.float32)


def _median_levels(
    raw: np.ndarray, lut: np.ndarray, mask: np.ndarray, n: int
) -> tuple[np.ndarray, int]:
    """Per channel, the median of ``lut[raw]`` over ``mask`` (uint8 data; ``n`` pixels in it),
    and how many channel values there are at 254 or 255 (summed over the channels).

    From each channel's histogram (the lookup table is increasing): the same value as
    ``np.median(lut[raw][mask], axis=0)``, float32, without sorting the pixels.
    """
    lo, hi = (n - 1) // 2, n // 2
    levels: list[int] = []  # per channel, the levels of its lo-th and hi-th pixel
    n_top = 0
    for c in range(3):
        cum = cv2.calcHist([raw], [c], mask, [256], [0, 256]).cumsum()
        levels.extend(cum.searchsorted((lo, hi), side="right").tolist())
        n_top += n - int(cum[253])  # the pixels above level 253
    v = lut[levels]
    return (v[0::2] + v[1::2]) * np.float32(0.5), n_top


def _box(dy2: np.ndarray, dx2: np.ndarray, r2: float) -> tuple[slice, slice]:
    """Rows and columns of a region holding every pixel with ``dy2 + dx2 < r2`` (a disc's box)."""
    rows = np.nonzero(dy2 < r2)[0]
    cols = np.nonzero(dx2 < r2)[0]
    if not len(rows) or not len(cols):
        return slice(0, 0), slice(0, 0)
    return slice(int(rows[0]), int(rows[-1]) + 1), slice(int(cols[0]), int(cols[-1]) + 1)


def _disc_and_ring_levels(
    bgr: np.ndarray,
    centre_px: tuple[float, float],
    radius_px: float,
    ring_ratio: float,
    band: float,
) -> tuple[tuple[int, int], np.ndarray, np.ndarray, np.ndarray, float] | None:
    """The region about a disc in linear light and the disc's and ring's median colours.

    Returns the region's top-left corner (px), the region (linear), the disc's and the
    ring's median linear colours and the share of ring pixels clipped at full scale;
    None when the region or its masks are too small.
    """
    h, w = bgr.shape[:2]
    cx, cy = centre_px
    half = int(math.ceil(radius_px * max(ring_ratio, 1.0 + band) * 1.05 + 4))
    x0, x1 = max(0, int(cx) - half), min(w, int(cx) + half + 1)
    y0, y1 = max(0, int(cy) - half), min(h, int(cy) + half + 1)
    if x1 - x0 < 5 or y1 - y0 < 5:
        return None
    top = 255.0 if bgr.dtype == np.uint8 else float(np.iinfo(bgr.dtype).max)
    raw = bgr[y0:y1, x0:x1]
    roi = _linear_roi(raw)
    # squared distances from the centre: the masks without a square root per pixel
    dy2 = (np.arange(y0, y1, dtype=np.float64) - cy) ** 2
    dx2 = (np.arange(x0, x1, dtype=np.float64) - cx) ** 2
    outer_r = radius_px * ring_ratio
    gap = outer_r - radius_px
    # each mask made on its bounding box only, which holds every pixel of it (the inner
    # disc's box is ~1/7 of the region)
    in_box = _box(dy2, dx2, (0.6 * radius_px) ** 2)
    ring_box = _box(dy2, dx2, (outer_r - 0.15 * gap) ** 2)
    inner = dy2[in_box[0], None] + dx2[None, in_box[1]] < (0.6 * radius_px) ** 2
    d2 = dy2[ring_box[0], None] + dx2[None, ring_box[1]]
    ring = (d2 > (radius_px + 0.3 * gap) ** 2) & (d2 < (outer_r - 0.15 * gap) ** 2)
    n_inner, n_ring = np.count_nonzero(inner), np.count_nonzero(ring)
    if n_inner < 3 or n_ring < 3:
        return None
    if raw.dtype == np.uint8:
        disc_c, _ = _median_levels(raw[in_box], SRGB8_TO_LINEAR, inner.view(np.uint8), n_inner)
        ring8 = ring.view(np.uint8)
        ring_c, ring_top = _median_levels(raw[ring_box], SRGB8_TO_LINEAR, ring8, n_ring)
        n_clipped = 0  # the ring's histograms hold no value at 254 or 255: none clipped
        if ring_top:
            # ring pixels with a channel at 254 or 255: not in range 0..253 on every channel
            below = cv2.inRange(raw[ring_box], (0, 0, 0), (253, 253, 253))
            n_clipped = n_ring - cv2.countNonZero(cv2.bitwise_and(below, ring8))
    else:
        disc_c = np.median(roi[in_box][inner], axis=0)
        ring_c = np.median(roi[ring_box][ring], axis=0)
        n_clipped = np.count_nonzero((raw[ring_box].max(axis=2) >= top - 1) & ring)
    clipped_fraction = n_clipped / n_ring
    return (x0, y0), roi, disc_c, ring_c, clipped_fraction


def disc_edge_points(
    bgr: np.ndarray,
    centre_px: tuple[float, float],
    radius_px: float,
    ring_ratio: float,
    *,
    blur_px: float = 0.8,
    band: float = 0.3,
    step_px: float = 0.25,
    edge: str | None = None,
    local_levels: bool = False,
) -> EdgePoints:
    """Edge points of a disc on its white ring, from a small region of the full photo.

    The region, in linear light, is scaled to 1 on the disc and 0 on the ring (its
    luminance, green channel, or projection on the disc-to-ring colour axis:
    :data:`EDGE_MODE`),
    blurred, and sampled along rays from the approximate centre
    (one ray per pixel of circumference, bilinear samples every ``step_px``);
    on each ray the 0.5 crossing nearest the approximate radius, linearly
    interpolated, is an edge point.

    Parameters
    ----------
    bgr : ndarray (H, W, 3), uint8 or uint16, the full-resolution photo.
    centre_px, radius_px : the disc's approximate circle (full-resolution pixels).
    ring_ratio : ring outer diameter / disc diameter (kit).
    blur_px : Gaussian blur (px) of the scalar image.
    band : search the edge within ``(1 +- band) * radius``.
    step_px : sample spacing along each ray (px).
    edge : "luma", "green" or "colour" (default :data:`EDGE_MODE`).
    local_levels : where the ring's level varies round the disc (``ring_spread`` at or
        above :data:`UNEVEN_RING_SPREAD`: a shadow across it), find each ray's edge
        half-way between its own disc and ring levels and drop the rays whose levels
        are not one light's (see :func:`_local_levels`). Needs a good circle to start
        (its ring samples must fall on the ring): the refinement's last pass.
    """

    cx, cy = centre_px
    levels = _disc_and_ring_levels(bgr, centre_px, radius_px, ring_ratio, band)
    if levels is None:
        return _NO_EDGE
    (x0, y0), roi, disc_c, ring_c, clipped_fraction = levels
    axis = disc_c - ring_c
    norm2 = float(axis @ axis)
    disc_t, ring_t = _encode8(disc_c), _encode8(ring_c)
    contrast = math.dist(disc_t, ring_t)
    if norm2 <= 0:
        return EdgePoints(np.zeros((0, 2)), disc_t, ring_t, 0.0, clipped_fraction)
    mode = edge or EDGE_MODE
    shade = None
    if mode not in EDGE_MODES:
        raise ValueError(f"unknown edge mode {mode!r}; valid: {EDGE_MODES}")
    # s = (value - ring) / (disc - ring) of one projection of the colour (a weighted sum
    # of the channels: one cv2.transform); its offset ring / (disc - ring) makes
    # s + offset proportional to the light
    if mode == "green" and abs(float(axis[1])) >= MIN_STEP_SHARE * math.sqrt(norm2):
        # the green channel alone: lateral chromatic aberration moves red and blue edges
        weights = np.array([0.0, 1.0, 0.0])
    elif mode == "luma" and abs(float(axis @ _LUMA_BGR)) >= MIN_STEP_SHARE * math.sqrt(norm2):
        weights = _LUMA_BGR.astype(np.float64)
    elif mode == "shade" and (shade := _shade_weights(disc_c, ring_c, norm2)) is not None:
        weights = shade
    else:
        weights = axis.astype(np.float64)
    n_rays = edge_ray_count(radius_px)
    radii, map_x, map_y = _ray_maps(cx - x0, cy - y0, radius_px, band, step_px, n_rays)
    v, offset = _ray_values(roi, weights, axis, ring_c, blur_px, map_x, map_y)
    inside = v > -0.5  # not off the photo (and not far darker than the disc)
    # the ring's samples, for ring_spread (read only on the refinement's settled pass)
    # the samples at radii >= (1 + band / 2) r: the last ones (radii increase), a view
    k_outer = int(radii.searchsorted((1 + band / 2) * radius_px, side="left"))
    n_disc = np.count_nonzero(radii <= (1 - band / 2) * radius_px)
    ring_samples = v[:, k_outer:] if min(len(v) // 4, n_disc, len(radii) - k_outer) >= 2 else None
    if local_levels:
        check = None
        luma_step = abs(float(axis @ _LUMA_BGR))
        if weights is shade and luma_step >= MIN_STEP_SHARE * math.sqrt(norm2):
            # every shade of the disc reads 1 here, so whether a ray's disc and ring share
            # one light (a shadow, not a cover) is read in luminance, where the disc's
            # level follows the light
            check = _ray_values(roi, _LUMA_BGR.astype(np.float64), axis, ring_c, blur_px,
                                map_x, map_y)  # fmt: skip
        v = _local_levels(v, radii, radius_px, band, offset, check)
    rows, r_best = _nearest_crossings(v, inside, radii, radius_px, step_px)
    cos, sin = _unit_rays(n_rays)
    points = np.empty((len(rows), 2))  # (x, y) columns, without np.column_stack's checks
    points[:, 0] = cx + r_best * cos[rows, 0]
    points[:, 1] = cy + r_best * sin[rows, 0]
    return EdgePoints(points, disc_t, ring_t, contrast, clipped_fraction, ring_samples)


def _ray_values(
    roi: np.ndarray,
    weights: np.ndarray,
    axis: np.ndarray,
    ring_c: np.ndarray,
    blur_px: float,
    map_x: np.ndarray,
    map_y: np.ndarray,
) -> tuple[np.ndarray, float]:
    """The region weighted by ``weights`` (linear BGR), scaled to 1 on the disc and 0 on
    the ring (``axis`` = disc - ring), blurred and sampled along the rays (-1 off the
    region), and its offset ``ring . weights / step``: ``v + offset`` is proportional to
    the light."""
    step_level = float(axis.astype(np.float64) @ weights)
    offset = float(ring_c.astype(np.float64) @ weights) / step_level
    m = np.concatenate((weights / step_level, [-offset]))[None, :]  # (np.append, fewer steps)
    s = cv2.transform(roi, m)
    if blur_px > 0:
        s = cv2.GaussianBlur(s, (0, 0), blur_px)
    v = cv2.remap(s, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=-1)
    return v, offset


def _shade_weights(disc_c: np.ndarray, ring_c: np.ndarray, norm2: float) -> np.ndarray | None:
    """Channel weights (linear BGR) of "shade" edges: the ring's colour with the disc's
    projected out, so that any shade of the disc's colour weighs 0; None where the
    disc-to-ring step they leave is under :data:`MIN_STEP_SHARE` of the colour difference
    (a disc near the ring's hue: grey)."""
    disc = disc_c.astype(np.float64)
    ring = ring_c.astype(np.float64)
    d2 = float(disc @ disc)
    weights = ring - (float(ring @ disc) / d2) * disc if d2 > 0 else ring
    # the step (ring - disc) . weights = ring . weights against the weights' own size
    if float(ring @ weights) < MIN_STEP_SHARE * math.sqrt(norm2 * float(weights @ weights)):
        return None
    return weights


#: No edge found (a region too small, or no disc or ring pixels in it).
_NO_EDGE = EdgePoints(np.zeros((0, 2)), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0)
_NO_EDGE.points_px.flags.writeable = False

#: Linear luminance Y of a linear BGR pixel (Rec. 709 weights, blue first).
_LUMA_BGR = np.array([0.0722, 0.7152, 0.2126], dtype=np.float32)


def _nearest_crossings(
    v: np.ndarray, inside: np.ndarray, radii: np.ndarray, radius_px: float, step_px: float
) -> tuple[np.ndarray, np.ndarray]:
    """Per ray (rows of ``v``), the 0.5 crossing radius nearest ``radius_px``: ``(rows, radii)``.

    A crossing lies between two neighbouring samples both ``inside``, linearly
    interpolated; rays without one are left out. Only the crossings are interpolated
    (a few per ray), not every sample; of two crossings equally near, the inner one.
    """
    above = v >= 0.5
    cross = above[:, :-1] ^ above[:, 1:]
    cross &= inside[:, :-1]
    cross &= inside[:, 1:]
    # row-major flat indices split into (ray, sample): 2-3x faster than a 2-D np.nonzero
    rows, cols = np.divmod(np.flatnonzero(cross), cross.shape[1])
    if not len(rows):
        return rows, np.zeros(0)
    va, vb = v[rows, cols], v[rows, cols + 1]
    r_cross = radii[cols] + ((0.5 - va) / (vb - va)) * step_px
    if len(rows) > 1 and not (rows[1:] > rows[:-1]).all():
        # rays with more than one crossing: the nearest the radius (lexsort is stable)
        order = np.lexsort((np.abs(r_cross - radius_px), rows))
        pick = order[np.flatnonzero(np.diff(rows[order], prepend=-1))]
        rows, r_cross = rows[pick], r_cross[pick]
    return rows, r_cross


def _local_levels(
    v: np.ndarray,
    radii: np.ndarray,
    radius_px: float,
    band: float,
    offset: float,
    check: tuple[np.ndarray, float] | None = None,
) -> np.ndarray:
    """Rays (rows of ``v``, 1 on the disc, 0 on the ring) rescaled to their own levels if uneven.

    Each ray's disc level is the median of its samples inside ``(1 - band / 2) r``,
    its ring level outside ``(1 + band / 2) r``. ``v + offset`` is proportional to the
    light (linear data), so a shadow scales both levels alike: their ratio is the
    same on every ray. When the ring levels spread by :data:`UNEVEN_RING_SPREAD` or
    more, each ray is rescaled to 0 at its ring and 1 at its disc, and a ray is
    dropped (set to -1: no edge on it) where its disc level is off the one its ring's
    light predicts by more than :data:`LEVEL_RATIO_TOLERANCE` of the step (a shadow's
    edge between its disc and ring parts),
    either part is not flat (a shadow's edge across it) or its step is under
    :data:`MIN_LOCAL_STEP`. Returns ``v`` (unchanged for even light).
    """
    inner = radii <= (1 - band / 2) * radius_px
    outer = radii >= (1 + band / 2) * radius_px
    if inner.sum() < 2 or outer.sum() < 2 or len(v) < 8:
        return v
    disc = np.median(v[:, inner], axis=1)
    ring = np.median(v[:, outer], axis=1)
    spread = float(np.percentile(ring, 95) - np.percentile(ring, 5))
    if spread < UNEVEN_RING_SPREAD:
        return v
    step = disc - ring
    flat = (np.ptp(v[:, inner], axis=1) < 0.3 * np.abs(step)) & (
        np.ptp(v[:, outer], axis=1) < 0.3 * np.abs(step)
    )
    ok = (np.abs(step) >= MIN_LOCAL_STEP) & flat & _one_light(v, inner, outer, offset, check)
    out = np.full_like(v, -1.0)
    out[ok] = (v[ok] - ring[ok, None]) / step[ok, None]
    return out


def _one_light(
    v: np.ndarray,
    inner: np.ndarray,
    outer: np.ndarray,
    offset: float,
    check: tuple[np.ndarray, float] | None,
) -> np.ndarray:
    """Rays whose disc level is the one their ring's light predicts, within
    :data:`LEVEL_RATIO_TOLERANCE` of the step (a shadow, not a cover), read in ``v`` or,
    given, in ``check`` (another weighting's rays and offset)."""
    if check is not None:
        v, offset = check
    disc = np.median(v[:, inner], axis=1)
    ring = np.median(v[:, outer], axis=1)
    # the light on each ray from its ring level; the disc level that light predicts
    light = (ring + offset) / offset if offset != 0 else np.ones_like(ring)
    disc_pred = light * (1.0 + offset) - offset
    return np.abs(disc - disc_pred) < LEVEL_RATIO_TOLERANCE * np.abs(disc_pred - ring)


def _ray_crossings(
    v: np.ndarray, radii: np.ndarray, radius_px: float, step_px: float
) -> np.ndarray:
    """Per ray (last axis: samples), the 0.5 crossing radius nearest ``radius_px``; NaN if none."""
    flat = v.reshape(-1, v.shape[-1])
    rows, r_best = _nearest_crossings(flat, flat > -0.5, radii, radius_px, step_px)
    out = np.full(flat.shape[0], np.nan)
    out[rows] = r_best
    return out.reshape(v.shape[:-1])


def channel_shifts_px(
    bgr: np.ndarray,
    centre_px: tuple[float, float],
    radius_px: float,
    disc_bgr: tuple[float, float, float],
    ring_bgr: tuple[float, float, float],
    *,
    n_rays: int = 64,
    band: float = 0.2,
    step_px: float = 0.25,
    blur_px: float = 0.8,
) -> dict[str, tuple[float, float]]:
    """Shift of the red and blue edges of a disc relative to its green edge (image px).

    A cheap probe for lateral chromatic aberration, on the small region around an
    already fitted circle: each channel, in linear light, is scaled to 1 on the
    disc and 0 on the ring, its 0.5 crossings found on ``n_rays`` rays, and the
    per-ray radius differences to green fitted as ``dx cos + dy sin + dr``.

    Parameters
    ----------
    bgr : ndarray (H, W, 3), uint8 or uint16, the full-resolution photo.
    centre_px, radius_px : the disc's fitted circle (image px).
    disc_bgr, ring_bgr : the disc's and ring's colours, 8-bit sRGB (:class:`EdgePoints`).

    Returns
    -------
    dict
        ``{"red": (dx, dy), "blue": (dx, dy)}`` in px, x right, y down; a channel
        whose disc-to-ring step is under :data:`MIN_STEP_SHARE` of the colour
        difference (or green's is) is left out.
    """
    disc = srgb_decode(np.asarray(disc_bgr, dtype=np.float64) / 255.0)
    ring = srgb_decode(np.asarray(ring_bgr, dtype=np.float64) / 255.0)
    axis = disc - ring
    norm = float(np.linalg.norm(axis))
    use = np.abs(axis) >= MIN_STEP_SHARE * norm
    if norm <= 0 or not use[1] or not (use[0] or use[2]):
        return {}
    h, w = bgr.shape[:2]
    cx, cy = centre_px
    half = int(math.ceil(radius_px * (1 + band) + 3 + 2 * blur_px))
    x0, x1 = max(0, int(cx) - half), min(w, int(cx) + half + 1)
    y0, y1 = max(0, int(cy) - half), min(h, int(cy) + half + 1)
    if x1 - x0 < 5 or y1 - y0 < 5:
        return {}
    radii, map_x, map_y = _ray_maps(cx - x0, cy - y0, radius_px, band, step_px, n_rays)
    cos_c, sin_c = _unit_rays(n_rays)  # (n_rays, 1)
    cos, sin = cos_c[:, 0], sin_c[:, 0]
    roi = _linear_roi(bgr[y0:y1, x0:x1])
    if blur_px > 0:
        roi = cv2.GaussianBlur(roi, (0, 0), blur_px)
    v = cv2.remap(roi, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
    v = (v - ring.astype(np.float32)) / np.where(use, axis, 1.0).astype(np.float32)
    r_edge = _ray_crossings(np.moveaxis(v, 2, 0), radii, radius_px, step_px)  # (3, n_rays)
    basis = np.stack((cos, sin, np.ones(n_rays)))
    out: dict[str, tuple[float, float]] = {}
    for name, c in (("blue", 0), ("red", 2)):
        if not use[c]:
            continue
        d = r_edge[c] - r_edge[1]
        ok = np.isfinite(d)
        if ok.sum() < 0.75 * n_rays:
            continue
        med = median_by_partition(d[ok])
        ok &= np.abs(d - med) < 0.5  # rays crossing the wire or a neighbour
        a = basis[:, ok]
        try:
            sol = np.linalg.solve(a @ a.T, a @ d[ok])
        except np.linalg.LinAlgError:
            continue
        out[name] = (float(sol[0]), float(sol[1]))
    return out
