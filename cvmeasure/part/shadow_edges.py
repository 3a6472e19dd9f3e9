"""The outer edges of a wire's cast shadow on the plate, measured in the photo.

Beside each stretch of the wire, the profile across it on the plate is read in linear
light (the wire's blurred silhouette and halo left out); one shadow depth and penumbra
are fitted over all profiles and each edge taken at half the shadow's own step. The
sheet's own texture is measured beside the wire too: the fitted step laid on bare
sheet and measured the same way gives the edges' texture errors.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from cvmeasure.colorimetry import srgb_decode
from cvmeasure.contracts import PlaneModel
from cvmeasure.geometry import arclength_mm
from cvmeasure.part.lift import (
    points_at_heights_mm,
    silhouette_sides,
)
from cvmeasure.part.segment import gray_float

__all__ = [
    "PROFILE_REACH_MM",
    "PLATE_STRETCH_MM",
    "MIN_SHADOW_CONTRAST",
    "MIN_GAP_MM",
    "WIRE_BLUR_MARGIN_MM",
    "WIRE_BLUR_MARGIN_PX",
    "RAMP_WINDOW_MM",
    "ROUNDS",
    "LOCAL_OUT_MM",
    "END_MARGIN_MM",
    "ShadowEdges",
    "unit_normals",
    "measure_shadow_edges",
    "TEXTURE_CLIP_MM",
    "TEXTURE_GAP_SHIFTS_MM",
    "texture_edge_errors",
    "fit_ramps",
]


#: Profiles across the wire reach this far from its axis on each side (mm).
PROFILE_REACH_MM = 11.0

#: The plate's level is the median of the profile's last stretch this long (mm).
PLATE_STRETCH_MM = 1.5

#: A shadow darker than the plate by less than this fraction of the plate's light is none
#: (a cast shadow keeps only the ambient light; 0.25 leaves room for a bright room).
MIN_SHADOW_CONTRAST = 0.25

#: A measured edge is used where the model puts it this far beyond the wire's silhouette
#: on the plate (mm): nearer, the silhouette's own step joins it.
MIN_GAP_MM = 0.35

#: The wire's own blurred silhouette reaches this far beyond it on the plate: the larger of
#: a length (mm) and a number of photo pixels. Only beyond it is the plate's profile the
#: shadow's (the wire, darker than a shadow, would set the step's level there).
WIRE_BLUR_MARGIN_MM = 0.35

WIRE_BLUR_MARGIN_PX = 2.5

#: From the second round of the ramps' fit on, each profile is fitted only from this far
#: inside its ramp (mm) outward: nearer the wire its halo, not the shadow, sets the level
#: (dark lab sheets, plain: the common depth 0.23-0.25 for the lab's 0.35, edges +0.25 mm
#: outside the true ones; with it 0.30-0.33, +0.10..+0.13 mm).
RAMP_WINDOW_MM = 0.5

#: Rounds of the ramps' alternating fit (edges, then the common depth and penumbra).
ROUNDS = 6

#: Each edge is finally refitted with its own sheet levels inside and outside the step
#: (:func:`_refine_local_levels`), from RAMP_WINDOW_MM inside the ramp to this far beyond
#: it (mm): the sheet's local albedo, not the far plate's, sets the half step.
LOCAL_OUT_MM = 1.5

#: Centreline points this close to either end are left out (the caps' own shadows), mm.
END_MARGIN_MM = 4.0


@dataclass(frozen=True)
class ShadowEdges:
    """The cast shadow's outer edge measured across the wire, per sampled axis point.

    Attributes
    ----------
    index : (K,) index into the centreline points of each sample.
    axis_mm : (K, 2) axis point at the resting height on the plate, board mm.
    normal : (K, 2) unit plate normal of the axis (left of travel).
    offset_mm : (K, 2) the outer edge's distance along ``+normal`` / ``-normal`` (both
        >= 0), NaN where that side has no shadow edge.
    silhouette_mm : (K, 2) where the plate starts to be seen beyond the wire on each side
        (the silhouette generators' rays on the plate), mm along ``+-normal``.
    contrast : (K, 2) (plate - shadow) / plate, linear light.
    texture_mm : (K, D) the sheet's own contribution to each sample's edge, D draws (mm):
        a shadow step like the fitted one (depth, penumbra, gap beyond the silhouette)
        laid on the bare sheet beside the wire (the profile's lit side) and measured
        the same way, less where it was laid; NaN where not measured.
    """

    index: np.ndarray
    axis_mm: np.ndarray
    normal: np.ndarray
    offset_mm: np.ndarray
    silhouette_mm: np.ndarray
    contrast: np.ndarray
    margin_mm: float = MIN_GAP_MM
    texture_mm: np.ndarray | None = None


def unit_normals(points_mm: np.ndarray) -> np.ndarray:
    """Unit normals (..., M, 2), left of travel, of polylines (..., M, 2) (M >= 2).

    The tangent is ``np.gradient``'s (central differences, one-sided at the ends), written
    out: the shadow fit calls this on every step, where np.gradient's and norm's per-call
    overhead is most of the cost.
    """
    t = np.empty_like(points_mm, dtype=np.float64)
    t[..., 1:-1, :] = (points_mm[..., 2:, :] - points_mm[..., :-2, :]) / 2.0
    t[..., 0, :] = points_mm[..., 1, :] - points_mm[..., 0, :]
    t[..., -1, :] = points_mm[..., -1, :] - points_mm[..., -2, :]
    t /= np.maximum(np.sqrt(t[..., 0] * t[..., 0] + t[..., 1] * t[..., 1]), 1e-12)[..., None]
    return np.stack((-t[..., 1], t[..., 0]), axis=-1)


def _silhouette_on_plate_mm(
    plane: PlaneModel,
    axis_mm: np.ndarray,
    normal: np.ndarray,
    height_mm: Any,
    radius_mm: float,
    axis_at_height_mm: np.ndarray | None = None,
) -> np.ndarray:
    """(K, 2): how far along +-normal from ``axis_mm`` the wire hides the plate (its
    silhouette's rays). ``height_mm`` (scalar or (K,)): the axis' height; the axis itself
    at ``axis_at_height_mm`` (K, 2) when given (a lifted point seen along its ray), else at
    ``axis_mm``."""
    centre = plane.camera_centre_mm
    h = np.broadcast_to(np.asarray(height_mm, dtype=np.float64), (len(axis_mm),))
    at = axis_mm if axis_at_height_mm is None else axis_at_height_mm
    xyz = np.column_stack((at, -h))
    tangent = np.column_stack((normal[:, 1], -normal[:, 0], np.zeros(len(normal))))
    side = silhouette_sides(plane, xyz, tangent)
    out = np.empty((len(axis_mm), 2))
    for k, sign in enumerate((1.0, -1.0)):
        limb = xyz + sign * radius_mm * side
        # the camera's ray through the limb, on to the plate (z = 0)
        ray = limb - centre
        t = -centre[2] / ray[:, 2]
        ground = centre[:2] + t[:, None] * ray[:, :2]
        if axis_at_height_mm is None:
            out[:, k] = np.abs(np.einsum("ij,ij->i", ground - axis_mm, normal))
        else:  # the generator on the +normal side is the one farther along +normal
            along = np.einsum("ij,ij->i", ground - axis_mm, normal)
            out[:, k] = along
    if axis_at_height_mm is not None:
        out = np.column_stack((np.maximum(out.max(axis=1), 0.0), np.maximum(-out.min(axis=1), 0.0)))
    return out


def _sample_box(px: np.ndarray, shape: tuple[int, ...]) -> tuple[int, int, int, int]:
    """Pixel box (x0, y0, x1, y1) holding every pixel bilinear samples at ``px`` (N, 2) read.

    Clipped to the image (where it is, samples beyond it read the border as before); the
    whole image when no sample is finite.
    """
    h, w = shape[:2]
    ok = np.all(np.isfinite(px), axis=1)
    if not ok.any():
        return 0, 0, w, h
    lo = np.floor(px[ok].min(axis=0)).astype(np.int64) - 1
    hi = np.floor(px[ok].max(axis=0)).astype(np.int64) + 3
    x0, y0 = int(np.clip(lo[0], 0, w)), int(np.clip(lo[1], 0, h))
    x1, y1 = int(np.clip(hi[0], 0, w)), int(np.clip(hi[1], 0, h))
    if x1 - x0 < 1 or y1 - y0 < 1:
        return 0, 0, w, h
    return x0, y0, x1, y1


def measure_shadow_edges(
    image: np.ndarray,
    plane: PlaneModel,
    points_px: np.ndarray,
    *,
    wire_diameter_mm: float,
    axis_height_mm: float,
    step_mm: float = 0.5,
    heights_mm: np.ndarray | None = None,
) -> ShadowEdges:
    """The cast shadow's outer edge across the wire (both sides), every ``step_mm`` along it.

    ``points_px`` (M, 2): the wire's centreline (silhouette centres), ordered. Profiles are
    sampled on the plate (height 0, where the shadow lies) along the axis' plate normal,
    in linear light (the photo decoded from sRGB). On each side the plate's level is the
    median of the profile's far end, the shadow's the darkest beyond the silhouette; the
    edge is the outermost crossing of their mean, linearly interpolated.
    """
    pts_px = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    axis_all = points_at_heights_mm(plane, pts_px, axis_height_mm)
    s_along = arclength_mm(axis_all)
    total = float(s_along[-1])
    marks = np.arange(END_MARGIN_MM, total - END_MARGIN_MM + 1e-9, step_mm)
    if len(marks) == 0:
        marks = np.array([0.5 * total])
    index = np.clip(np.searchsorted(s_along, marks), 0, len(pts_px) - 1)
    normal_all = unit_normals(axis_all)
    # smooth the normals over ~3 mm: pixel noise of the centre turns them
    k = max(1, int(round(3.0 / max(total / max(len(pts_px) - 1, 1), 1e-6))))
    kernel = np.ones(2 * k + 1) / (2 * k + 1)
    padded = np.pad(normal_all, ((k, k), (0, 0)), mode="edge")
    smooth = np.column_stack([np.convolve(padded[:, j], kernel, mode="valid") for j in (0, 1)])
    smooth /= np.maximum(np.linalg.norm(smooth, axis=1), 1e-12)[:, None]
    axis = axis_all[index]
    normal = smooth[index]
    radius = 0.5 * wire_diameter_mm
    if heights_mm is None:
        silhouette = _silhouette_on_plate_mm(plane, axis, normal, axis_height_mm, radius)
    else:  # a lifted axis point is seen along its ray: its silhouette from there
        h = np.asarray(heights_mm, dtype=np.float64)[index]
        at_h = points_at_heights_mm(plane, pts_px[index], h)
        silhouette = _silhouette_on_plate_mm(plane, axis, normal, h, radius, at_h)
    gray = gray_float(image)
    top = 255.0 if gray.max() > 1.5 else 1.0
    du = 0.25 * plane.mm_per_px
    u = np.arange(0.0, PROFILE_REACH_MM + 1e-9, du)
    far = u >= PROFILE_REACH_MM - PLATE_STRETCH_MM
    q = np.empty((2, len(index), len(u)))
    sides = []
    for sign in (1.0, -1.0):
        where = axis[:, None, :] + sign * u[None, :, None] * normal[:, None, :]
        sides.append(plane.plane_to_image_px(where.reshape(-1, 2)).astype(np.float32))
    # linear light only in the box the profiles read (the whole photo's was most of the
    # time and memory); shifted by whole pixels, the samples are the same
    x0, y0, x1, y1 = _sample_box(np.vstack(sides), gray.shape)
    lin = srgb_decode(np.clip(gray[y0:y1, x0:x1] / top, 0.0, 1.0)).astype(np.float32)
    for k_side, px in enumerate(sides):
        prof = cv2.remap(
            lin, (px[:, 0] - x0).reshape(len(index), -1), (px[:, 1] - y0).reshape(len(index), -1),
            cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan,
        ).astype(np.float64)  # fmt: skip
        plate = np.median(prof[:, far], axis=1)
        q[k_side] = prof / np.maximum(plate, 1e-9)[:, None]
    # the wire's own blurred edge reaches this far beyond its silhouette (mm)
    margin = max(WIRE_BLUR_MARGIN_MM, WIRE_BLUR_MARGIN_PX * plane.mm_per_px)
    q = _less_wire_halo(u, q, silhouette.T, margin, far)
    start = silhouette.T + margin
    offsets, contrast, k_w = fit_ramps(u, q, start, far)
    texture = texture_edge_errors(u, q, start, far, offsets, contrast, k_w)
    return ShadowEdges(index, axis, normal, offsets.T, silhouette, contrast.T, margin, texture)


#: The sheet's own edge errors (:func:`texture_edge_errors`) are clipped at this (mm) before
#: they widen the fit's uncertainty: a laid step lost in clutter or in another shadow says
#: no more than a large error. Clipped at the outlier limit (0.15 mm) the textured sheets'
#: lifts were stated far too precisely; 1 mm keeps what a dark textured sheet does (0.2-0.5 mm).
TEXTURE_CLIP_MM = 1.0

#: The texture draws: the synthetic step's gap beyond the silhouette moved by these (mm),
#: each laid on the lit side of its own sample and of the sample mirrored along the wire.
TEXTURE_GAP_SHIFTS_MM = (-0.6, 0.0, 0.6)


def texture_edge_errors(
    u: np.ndarray,
    q: np.ndarray,
    start_mm: np.ndarray,
    far: np.ndarray,
    offsets: np.ndarray,
    contrast: np.ndarray,
    k_w: tuple[float, float] | None,
) -> np.ndarray | None:
    """(K, D): the edge errors the sheet itself makes, from its bare stretch beside the wire.

    Each sample's lit side (the side without the shadow's edge) is bare sheet (less the
    wire's halo) beyond ``start_mm``: the fitted shadow step (depth and penumbra ``k_w``) is
    laid on it at the shadow side's gap beyond the silhouette (moved by
    :data:`TEXTURE_GAP_SHIFTS_MM`; once with the sample's own lit profile, once with the
    profile of the sample mirrored along the wire), all are measured by the same fit (its
    own depth and penumbra) and the measured edges less the laid ones are returned: the
    texture's and light's share of the edges' errors, at the wire's own positions. None
    when there is no shadow."""
    if k_w is None:
        return None
    k, w = k_w
    n = offsets.shape[1]
    have = np.isfinite(offsets)
    shadow_side = np.where(have[0] & (~have[1] | (contrast[0] >= contrast[1])), 0, 1)
    rows = np.arange(n)
    gap = offsets[shadow_side, rows] - start_mm[shadow_side, rows]
    if not np.isfinite(gap).any():
        return None
    gap = np.where(np.isfinite(gap), gap, np.nanmedian(gap))
    draws = []
    for pair in (rows, rows[::-1]):
        lit = 1 - shadow_side[pair]
        q_lit = q[lit, pair]  # (K, U)
        start_lit = start_mm[lit, pair]
        for shift in TEXTURE_GAP_SHIFTS_MM:
            e_syn = start_lit + np.maximum(gap + shift, 0.5 * w)
            ramp = np.clip(0.5 - (u[None, :] - e_syn[:, None]) / w, 0.0, 1.0)
            q_inj = np.full((2, *q_lit.shape), np.nan)
            q_inj[0] = q_lit * (1.0 - k * ramp)
            starts = np.stack((start_lit, np.full(n, np.inf)))
            e_fit, _, _ = fit_ramps(u, q_inj, starts, far, min_depth=0.5 * k)
            draws.append(e_fit[0] - e_syn)
    return np.column_stack(draws)


def _less_wire_halo(
    u: np.ndarray, q: np.ndarray, silhouette_mm: np.ndarray, margin_mm: float, far: np.ndarray
) -> np.ndarray:
    """The profiles ``q`` (2, K, U) less the wire's own light spread onto the plate.

    The wire's image leaks beyond its silhouette (blur, demosaic, JPEG ringing): on a dark
    plate a bright wire lifts the plate's level for a millimetre or so, on a light plate a
    dark wire lowers it, and either moves the shadow's step that starts there. The leak is
    measured on the profiles with no shadow (the wire's lit sides: nothing darker than the
    plate by ``MIN_SHADOW_CONTRAST / 2`` beyond ``margin_mm``), as the median excess over
    the plate against the distance from the silhouette, and taken off every profile.
    """
    v = u[None, None, :] - silhouette_mm[..., None]  # mm beyond the silhouette
    region = (v > margin_mm) & ~far[None, None, :] & np.isfinite(q)
    low = np.where(region, q, np.inf).min(axis=2)
    lit = np.isfinite(low) & (low > 1.0 - 0.5 * MIN_SHADOW_CONTRAST)
    if lit.sum() < 10:
        return q
    step = float(u[1] - u[0])
    bins = np.arange(0.0, float(u[~far][-1]), step)
    vals = _interp_rows(bins, v[lit], q[lit] - 1.0)  # (lit profiles, bins)
    # the median over the profiles with a value at each bin (0 where none has one)
    leak = np.zeros(len(bins))
    some = np.isfinite(vals).any(axis=0)
    leak[some] = np.nanmedian(vals[:, some], axis=0)
    leak[bins > float(u[~far][-1]) - 1.0] = 0.0
    return q - np.interp(v, bins, leak, left=0.0, right=0.0)


def _interp_rows(x: np.ndarray, xp: np.ndarray, fp: np.ndarray) -> np.ndarray:
    """``np.interp(x, xp[i], fp[i])`` for every row ``i`` at once: (N, X) from ``x`` (X,)
    and ``xp``, ``fp`` (N, P), each ``xp`` row increasing. As np.interp: the end values
    outside ``xp``, NaN where a bracketing value is NaN."""
    n, p = xp.shape
    j = np.empty((n, len(x)), dtype=np.intp)
    for i in range(n):  # one searchsorted per row (not per point)
        j[i] = np.searchsorted(xp[i], x, side="right") - 1
    jc = np.clip(j, 0, p - 2)
    rows = np.arange(n)[:, None]
    x0, x1 = xp[rows, jc], xp[rows, jc + 1]
    f0, f1 = fp[rows, jc], fp[rows, jc + 1]
    out = (f1 - f0) / (x1 - x0) * (x[None, :] - x0) + f0
    out = np.where(j < 0, fp[:, :1], out)
    return np.where(j >= p - 1, fp[:, -1:], out)


def fit_ramps(
    u: np.ndarray,
    q: np.ndarray,
    start_mm: np.ndarray,
    far: np.ndarray,
    min_depth: float = MIN_SHADOW_CONTRAST,
    window_mm: float = RAMP_WINDOW_MM,
) -> tuple[np.ndarray, np.ndarray, tuple[float, float] | None]:
    """The shadow's outer edge on every profile, with ONE depth and penumbra for all.

    ``q`` (2, K, U): profiles across the wire (both sides) in linear light over the plate's
    level; ``start_mm`` (2, K): where the plate is clear of the wire's own (blurred)
    silhouette. A distant lamp over one plate casts a shadow of one depth ``k`` (the lamp's
    share of the plate's light) and, the wire near the plate, one penumbra ``w``: each
    profile beyond ``start_mm`` is ``1 - k ramp((e - u) / w)`` with its own edge ``e`` (the
    half level of the shadow's step, not of the darker wire's). ``k``, ``w`` and the edges
    are fitted by alternating least squares (:data:`ROUNDS`), each profile from the second
    round on only from ``window_mm`` inside its ramp outward, and its edge finally refitted
    with its own sheet levels (:data:`LOCAL_OUT_MM`). Returns the edges (2, K), NaN where the profile
    has no shadow edge beyond ``start_mm``, each profile's depth (2, K) and the fitted
    ``(k, w)`` (None when no profile is darker than ``min_depth``).
    """
    region = (u[None, None, :] > start_mm[..., None]) & ~far[None, None, :]
    region &= np.isfinite(q)
    qz = np.where(region, q, 1.0)
    depth = np.where(region.any(axis=2), 1.0 - np.min(np.where(region, q, np.inf), axis=2), 0.0)
    depth = np.where(np.isfinite(depth), depth, 0.0)
    cand = depth >= min_depth
    edges = np.full(depth.shape, np.nan)
    if cand.sum() < 10:
        return edges, depth, None
    k = float(np.median(depth[cand]))
    w = 1.0
    du = float(u[1] - u[0])
    grid = u[::2]

    qc, rc_all = qz[cand], region[cand]
    rc = rc_all
    for it in range(ROUNDS):
        # each edge on a grid, then a parabola through the best three
        ramp = np.clip(0.5 - (u[None, :] - grid[:, None]) / w, 0.0, 1.0)  # (G, U)
        pred = 1.0 - k * ramp
        sse = rc.astype(float) @ (pred**2).T - 2.0 * (qc * rc) @ pred.T
        g = np.clip(np.argmin(sse, axis=1), 1, len(grid) - 2)
        rows = np.arange(len(g))
        y0, y1, y2 = sse[rows, g - 1], sse[rows, g], sse[rows, g + 1]
        den = y0 - 2.0 * y1 + y2
        shift = np.where(den > 0, 0.5 * (y0 - y2) / np.where(den > 0, den, 1.0), 0.0)
        e = grid[g] + np.clip(shift, -1.0, 1.0) * (grid[1] - grid[0])
        # then the common depth and penumbra
        best = None
        for ww in w * np.array([0.7, 0.85, 1.0, 1.2, 1.4]):
            ramp_e = np.clip(0.5 - (u[None, :] - e[:, None]) / ww, 0.0, 1.0)
            a = np.sum(rc * ramp_e * ramp_e)
            kk = float(np.sum(rc * ramp_e * (1.0 - qc)) / max(a, 1e-12))
            r = np.sum(rc * (qc - 1.0 + kk * ramp_e) ** 2)
            if best is None or r < best[0]:
                best = (r, kk, ww)
        _, k, w = best
        w = max(w, 2.0 * du)
        if it >= 1:
            # from the second round on, each profile only about its own edge: the plate
            # beyond it and the shadow's plateau up to window_mm inside its ramp (nearer the
            # wire its halo, not the shadow, sets the level)
            rc = rc_all & (u[None, :] > (e - 0.5 * w - window_mm)[:, None])
    e = _refine_local_levels(u, qc, rc_all, e, k, w, window_mm, LOCAL_OUT_MM)
    # an edge counts where its ramp's outer half lies in the region and the profile is dark
    # inside it: its step measured, not the wire's
    start = start_mm[cand]
    ok = (e > start) & (e < u[~far][-1] - 0.5 * w)
    inner = rc & (u[None, :] < e[:, None]) & (u[None, :] > start[:, None])
    dark_in = np.where(inner.any(axis=1), np.sum(np.where(inner, qc, 0.0), axis=1)
                       / np.maximum(inner.sum(axis=1), 1), 1.0)  # fmt: skip
    ok &= dark_in < 1.0 - 0.25 * k
    out = np.where(ok, e, np.nan)
    edges[cand] = out
    return edges, depth, (k, w)


def _refine_local_levels(
    u: np.ndarray,
    q: np.ndarray,
    region: np.ndarray,
    e: np.ndarray,
    k: float,
    w: float,
    inside_mm: float,
    outside_mm: float,
    reach_mm: float = 0.6,
) -> np.ndarray:
    """Each edge ``e`` (K,) refitted against the sheet's own level just outside it.

    The profile ``q`` (K, U) about its edge (from ``inside_mm`` inside the ramp to
    ``outside_mm`` beyond it) is ``b (1 - k ramp)`` with the common depth ``k`` and
    penumbra ``w`` and the level ``b`` free per profile: the shadow is a ratio of the sheet
    it falls on, so the sheet's local albedo (a stain, the grain's slow swell, the light's
    falloff) does not move the half step as it does against the far plate's level. The
    edge is searched within ``reach_mm`` of ``e`` (kept where at least 8 samples lie in the
    window, else the common edge stays). (Both levels free, the shadow's too,
    scattered the edges on plain lab sheets: a flat part corrected to a 1 mm lift.)"""
    du = float(u[1] - u[0])
    offs = np.arange(-reach_mm, reach_mm + 0.5 * du, du)
    m = (region & (u[None, :] > (e - 0.5 * w - inside_mm)[:, None])
         & (u[None, :] < (e + 0.5 * w + outside_mm)[:, None])).astype(float)  # fmt: skip
    qm = np.where(m > 0, q, 0.0)
    cand = e[:, None] + offs[None, :]  # (K, G)
    s_n = m.sum(axis=1)[:, None]
    s_q = qm.sum(axis=1)[:, None]
    # the sums run over each profile's window only (from its first sample in it to its
    # last): elsewhere its weight is 0, and a fine photo's profiles are far longer
    used = m > 0
    first = np.argmax(used, axis=1)
    span = np.where(used.any(axis=1), len(u) - np.argmax(used[:, ::-1], axis=1) - first, 0)
    at = np.minimum(first[:, None] + np.arange(max(int(span.max(initial=0)), 1)), len(u) - 1)
    inside_window = np.arange(at.shape[1])[None, :] < span[:, None]
    rows_k = np.arange(len(e))[:, None]
    m_w = np.where(inside_window, m[rows_k, at], 0.0)
    qm_w = np.where(inside_window, qm[rows_k, at], 0.0)
    r = np.clip(0.5 - (u[at][:, None, :] - cand[..., None]) / w, 0.0, 1.0)  # (K, G, window)
    s_rr = np.einsum("kgu,ku->kg", r * r, m_w)
    s_r = np.einsum("kgu,ku->kg", r, m_w)
    s_qr = np.einsum("kgu,ku->kg", r, qm_w)
    # q = b (1 - k r): the sheet's level b just outside the shadow free, the shadow's depth
    # the common one (the ratio of shadowed to bare sheet)
    s_mm = s_n - 2.0 * k * s_r + k * k * s_rr
    s_qm = s_q - k * s_qr
    ok_det = s_mm > 1e-9
    s_mm = np.where(ok_det, s_mm, 1.0)
    sse = np.where(ok_det, -(s_qm**2) / s_mm, 1e30)  # less the constant sum q^2
    g = np.clip(np.argmin(sse, axis=1), 1, len(offs) - 2)
    rows = np.arange(len(e))
    y0, y1, y2 = sse[rows, g - 1], sse[rows, g], sse[rows, g + 1]
    den = y0 - 2.0 * y1 + y2
    shift = np.where(den > 0, 0.5 * (y0 - y2) / np.where(den > 0, den, 1.0), 0.0)
    e_new = cand[rows, g] + np.clip(shift, -1.0, 1.0) * du
    keep = ok_det[rows, g] & (m.sum(axis=1) >= 8)
    return np.where(keep, e_new, e)
