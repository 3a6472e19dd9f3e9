"""Finding the kit's markers on a reduced copy of the photo.

The photo is subsampled (every ``step``-th pixel, so a reduced pixel (i, j) is
exactly the full-resolution pixel (i * step, j * step)), white-balanced, and
every pixel labelled with its nearest marker colour (:mod:`.colour`). Each
role's pixels form connected regions; a region is a candidate disc when it is
compact and round and surrounded by the white ring. A whole disc's circle
comes from its moments; a partly hidden one's from a robust circle fit to the
region's outline (Hough circles on its mask as the fallback). All coordinates returned are
full-resolution image pixels.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from cvmeasure.geometry import fit_circle_robust
from cvmeasure.kit import ROLES, MarkerKit
from cvmeasure.markers.colour import (
    CLIPPED_WHITE_FRACTION,
    ColourModel,
    WhiteEstimate,
    classify_bgr8,
    estimate_white,
)

__all__ = [
    "MarkerCandidate",
    "MarkerSearch",
    "search_step",
    "find_markers",
]

#: The reduced copy holds at most this many pixels.
SEARCH_MAX_PIXELS = 160_000
#: Smallest region (reduced pixels) that can be a marker disc.
MIN_AREA_PX = 10


@dataclass(frozen=True)
class MarkerCandidate:
    """One disc-shaped region of a role's colour, in full-resolution pixels.

    ``fill`` is area / bounding-box area (pi/4 for a whole disc); ``ring_fraction``
    the share of bright (white-ring) pixels just outside it.
    """

    role: str
    centre_px: tuple[float, float]
    radius_px: float
    area_px: float
    fill: float
    ring_fraction: float

    @property
    def score(self) -> float:
        return self.area_px * (0.25 + self.ring_fraction)

    def to_dict(self) -> dict[str, Any]:
        return {
            "role": self.role,
            "x_px": round(self.centre_px[0], 3),
            "y_px": round(self.centre_px[1], 3),
            "r_px": round(self.radius_px, 3),
            "fill": round(self.fill, 3),
            "ring_fraction": round(self.ring_fraction, 3),
        }


@dataclass(frozen=True)
class MarkerSearch:
    """What the search found: one candidate per role, or the reason there is none."""

    found: dict[str, MarkerCandidate]
    failures: dict[str, str]
    white: WhiteEstimate
    step: int
    others: dict[str, tuple[MarkerCandidate, ...]] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return not self.failures


def search_step(shape: tuple[int, ...], max_pixels: int = SEARCH_MAX_PIXELS) -> int:
    """Subsampling step so that the reduced copy has at most ``max_pixels`` pixels."""
    h, w = shape[:2]
    return max(1, math.ceil(math.sqrt(h * w / max_pixels)))


def _ring_fraction(bright: np.ndarray, cx: float, cy: float, r: float, ring_ratio: float) -> float:
    """Share of bright pixels in the annulus between the disc and the ring's outer edge."""
    h, w = bright.shape
    outer = max(r * ring_ratio, r + 1.5)
    inner = r + max(0.6, 0.25 * (outer - r))
    x0, x1 = max(0, int(cx - outer - 1)), min(w, int(cx + outer + 2))
    y0, y1 = max(0, int(cy - outer - 1)), min(h, int(cy + outer + 2))
    if x1 <= x0 or y1 <= y0:
        return 0.0
    # broadcast rows x columns (np.mgrid's full grids cost more than the annulus test)
    d = np.hypot(np.arange(x0, x1)[None, :] - cx, np.arange(y0, y1)[:, None] - cy)
    ann = (d >= inner) & (d <= outer)
    n = int(np.count_nonzero(ann))
    if not n:
        return 0.0
    # the share as float32 (the mean of a float32 0/1 image, as before: the same value)
    return float(np.float32(np.count_nonzero(bright[y0:y1, x0:x1][ann])) / np.float32(n))


def _partial_circle(
    mask: np.ndarray, x: int, y: int, w: int, h: int
) -> tuple[float, float, float] | None:
    """Circle of a partly hidden region (reduced pixels), or None.

    A robust (Tukey) circle fit to the region's outline: the visible arc is the
    majority, the occluder's edge the outliers. Hough circles on the region's
    mask are the fallback when that fit fails.
    """
    crop = np.ascontiguousarray(mask[y : y + h, x : x + w])
    contours, _ = cv2.findContours(crop, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    if contours:
        pts = max(contours, key=len).reshape(-1, 2).astype(np.float64) + (x, y)
        if len(pts) >= 8:
            try:
                fit = fit_circle_robust(pts, tukey_c=3.0, min_scale=0.5)
            except (ValueError, np.linalg.LinAlgError):
                fit = None
            if fit is not None and fit.coverage >= 0.4 and fit.radius < 1.5 * max(w, h):
                return fit.centre[0], fit.centre[1], fit.radius + 0.5
    pad = max(w, h)
    H, W = mask.shape
    x0, y0 = max(0, x - pad), max(0, y - pad)
    x1, y1 = min(W, x + w + pad), min(H, y + h + pad)
    img = cv2.GaussianBlur((mask[y0:y1, x0:x1] * 255).astype(np.uint8), (0, 0), 1.0)
    r_max = max(w, h)
    circles = cv2.HoughCircles(
        img,
        cv2.HOUGH_GRADIENT,
        dp=1,
        minDist=max(2 * r_max, 4),
        param1=100,
        param2=max(4, int(0.8 * r_max)),
        minRadius=max(2, int(0.4 * r_max)),
        maxRadius=int(1.3 * r_max) + 1,
    )
    if circles is None:
        return None
    cx, cy, r = (float(v) for v in circles[0, 0])
    return cx + x0, cy + y0, r


def _role_boxes(labels: np.ndarray, n_roles: int) -> list[tuple[int, int, int, int, int]]:
    """Per role index, the bounding box of its pixels in ``labels`` and their count:
    ``(x, y, w, h, n)`` (``cv2.boundingRect`` of its mask; all 0 without pixels).

    From one pass over the image (the few labelled pixels' positions), not one per role.
    """
    flat = np.flatnonzero(labels >= 0)
    ks = labels.ravel()[flat]
    ys, xs = np.divmod(flat, labels.shape[1])
    out = []
    for k in range(n_roles):
        sel = ks == k
        n = int(np.count_nonzero(sel))
        if not n:
            out.append((0, 0, 0, 0, 0))
            continue
        y, x = ys[sel], xs[sel]
        x0, y0 = int(x.min()), int(y[0])  # positions in row-major order: y[0] is the least
        out.append((x0, y0, int(x.max()) - x0 + 1, int(y[-1]) - y0 + 1, n))
    return out


def _candidates(
    role: str,
    labels: np.ndarray,
    k: int,
    box: tuple[int, int, int, int, int],
    bright: np.ndarray,
    ring_ratio: float,
    step: int,
) -> tuple[list[MarkerCandidate], str]:
    """Round, ring-surrounded regions of one role's pixels (``labels == k``, inside
    ``box``: :func:`_role_boxes`); the reason when there are none."""
    bx, by, bw, bh, n_pixels = box
    found: list[MarkerCandidate] = []
    largest = 0
    n, stats, centroids = 0, np.zeros((0, 5), int), np.zeros((0, 2))
    mask = None  # the role's whole mask, made only for a partly hidden disc
    if bw > 0 and bh > 0:
        crop = (labels[by : by + bh, bx : bx + bw] == k).view(np.uint8)  # 0/1 bytes
        ltype = cv2.CV_16U if crop.size < 131_000 else cv2.CV_32S
        n, _, stats, centroids = cv2.connectedComponentsWithStats(crop, connectivity=8, ltype=ltype)
        stats = stats.astype(np.int64)
        stats[:, 0] += bx
        stats[:, 1] += by
        centroids = centroids + (bx, by)
    if n > 1:
        largest = int(stats[1:, 4].max())
    for i in np.flatnonzero(stats[:, 4] >= MIN_AREA_PX):
        if i == 0:
            continue  # the background
        x, y, w, h, area = (int(v) for v in stats[i])
        fill = area / float(w * h)
        aspect = w / float(h)
        if not (0.3 <= fill <= 0.97 and 0.4 <= aspect <= 2.5):
            continue
        cx, cy = (float(v) for v in centroids[i])
        r = math.sqrt(area / math.pi)
        if (fill < 0.68 or not 0.75 <= aspect <= 1.33) and max(w, h) >= 12:
            # large enough for its outline to tell the hidden part from the visible arc;
            # smaller regions keep their moments (the refinement walks to the true circle)
            if mask is None:
                mask = (labels == k).view(np.uint8)
            circle = _partial_circle(mask, x, y, w, h)
            if circle is None:
                continue
            cx, cy, r = circle
        ring = _ring_fraction(bright, cx, cy, r, ring_ratio)
        if ring < 0.2:
            continue
        found.append(
            MarkerCandidate(
                role,
                (cx * step, cy * step),
                r * step,
                area * step * step,
                fill,
                ring,
            )
        )
    if found:
        return sorted(found, key=lambda c: -c.score), ""
    if n_pixels == 0:
        return [], "no pixels of its colour in the photo"
    return [], (
        f"no round disc of its colour on a white ring (largest region {largest * step * step} px)"
    )


def find_markers(
    bgr8: np.ndarray,
    kit: MarkerKit,
    model: ColourModel,
    *,
    max_pixels: int = SEARCH_MAX_PIXELS,
    white: WhiteEstimate | None = None,
) -> MarkerSearch:
    """Find each role's disc on a reduced copy of the photo.

    Parameters
    ----------
    bgr8 : ndarray of shape (H, W, 3), uint8, the full-resolution photo.
    kit : the marker kit (sizes: ring to disc ratio).
    model : the colour model (see :func:`cvmeasure.markers.colour.kit_colour_model`).
    max_pixels : size of the reduced copy.
    white : the photo's white; estimated from the brightest pixels when None (and,
        when that misses a marker on a photo whose whites are clipped, estimated
        again from its unclipped neutral pixels: ``estimate_white(recover_clipped=True)``).

    Returns
    -------
    MarkerSearch
        ``found[role]`` in full-resolution pixels, or ``failures[role]`` saying why.
        A role with two similar discs is ambiguous (a failure naming both).
    """
    step = search_step(bgr8.shape, max_pixels)
    small = np.ascontiguousarray(bgr8[::step, ::step])
    luma = cv2.cvtColor(small, cv2.COLOR_BGR2GRAY)  # the white's and the rings' grey
    # its b, g, r planes, split once for the white and the colour classes
    channels = tuple(cv2.split(small))
    if white is not None:
        return _search(small, luma, channels, kit, model, white, step)
    white = estimate_white(small, gray=luma, channels=channels)
    search = _search(small, luma, channels, kit, model, white, step)
    if search.failures and search.white.clipped_fraction > CLIPPED_WHITE_FRACTION:
        white = estimate_white(small, recover_clipped=True, gray=luma, channels=channels)
        retry = _search(small, luma, channels, kit, model, white, step)
        if len(retry.failures) < len(search.failures):
            return retry
    return search


def _search(
    small: np.ndarray,
    luma: np.ndarray,
    channels: tuple[np.ndarray, ...],
    kit: MarkerKit,
    model: ColourModel,
    white: WhiteEstimate,
    step: int,
) -> MarkerSearch:
    """:func:`find_markers` on the reduced copy ``small`` (its grey ``luma``, its b, g, r
    ``channels``) with a given white."""
    labels = classify_bgr8(small, model, white, channels)
    white_luma = 0.114 * white.srgb8[2] + 0.587 * white.srgb8[1] + 0.299 * white.srgb8[0]
    # luma >= 0.72 white_luma for 8-bit luma, as an integer comparison (not a float64
    # copy of the image): the smallest whole level at or above the threshold
    level = max(0, math.ceil(0.72 * white_luma))
    bright = luma >= level if level <= 255 else np.zeros(luma.shape, dtype=bool)

    per_role: dict[str, list[MarkerCandidate]] = {}
    failures: dict[str, str] = {}
    boxes = _role_boxes(labels, len(model.roles))
    for k, role in enumerate(model.roles):
        marker = kit.by_role(role)
        ratio = marker.ring_mm / marker.diameter_mm
        cands, reason = _candidates(role, labels, k, boxes[k], bright, ratio, step)
        per_role[role] = cands
        if not cands:
            failures[role] = reason
    for role in ROLES:
        if role not in model.roles:
            failures[role] = "the colour model has no entry for this role"

    # scale consistency: every disc should show about the same px per mm
    scales = [c[0].radius_px / (kit.by_role(r).diameter_mm / 2) for r, c in per_role.items() if c]
    px_per_mm = float(np.median(scales)) if scales else 0.0
    found: dict[str, MarkerCandidate] = {}
    others: dict[str, tuple[MarkerCandidate, ...]] = {}
    for role, cands in per_role.items():
        if not cands:
            continue
        half_d = kit.by_role(role).diameter_mm / 2
        if px_per_mm > 0:
            plausible = [c for c in cands if 0.6 <= c.radius_px / half_d / px_per_mm <= 1.6]
            cands = plausible or cands
        best = cands[0]
        rivals = [c for c in cands[1:] if c.score > 0.5 * best.score]
        if rivals:
            where = ", ".join(
                f"({c.centre_px[0]:.0f}, {c.centre_px[1]:.0f})" for c in [best, *rivals]
            )
            near = all(
                math.dist(c.centre_px, best.centre_px) < 2.0 * max(c.radius_px, best.radius_px)
                for c in rivals
            )
            failures[role] = (
                f"ambiguous: {1 + len(rivals)} pieces of its colour side by side at {where} "
                "(one disc cut by something across it?)"
                if near
                else f"ambiguous: {1 + len(rivals)} discs of its colour at {where}"
            )
            continue
        found[role] = best
        others[role] = tuple(cands[1:])
    return MarkerSearch(found, failures, white, step, others)
