"""A part's lift from ONE photo: the wire's cast shadow on the plate, fitted globally.

Under a distant lamp a point of the wire's axis at height ``H`` above the plate casts
its shadow at ``p + H s`` (plate, board frame), ``s`` the lamp's horizontal shadow vector
per mm of height (unknown: learnt from the photo). A cylinder of radius ``r`` lying
along a horizontal direction with plate normal ``n`` casts a band whose edges lie at
``H (n.s) +- r sqrt(1 + (n.s)^2)`` across it (the light's ray at distance ``r`` from the
axis); the outer edge, on the side ``n.s > 0``, lies beyond the wire and is seen on
the plate. A rigid part rests on the plate: ``H = r + h(p)``, ``h = a.p + c >= 0`` with
``h = 0`` at its lowest point (``c = -min a.p``). Fitted together over the whole
centreline: ``s`` (2) and ``a`` (2), by least squares on the shadow's outer edge
measured across the wire (on the plate, the photo linearised from sRGB, the edge at
half the shadow's own step: one depth and penumbra fitted over all profiles beyond the
wire's blurred silhouette, so a wire darker or brighter than the shadow does not set
the level). The resting stretch's offset
is ``r (n.s)`` plus the band's half width, which fixes ``s``; the lifted stretch's extra
offset ``h (n.s)`` gives ``a``. The curved part supplies many directions ``n``.

The predicted edge is the exact one of the model: each axis point on the plane of its
own height (the perspective of the lifted end counts), its shadow point, the shadow
curve's own normal and the crossing of the measuring line with that curve (on a bend
the shadow is displaced along the wire too).

Where the shadow is not usable (no dark band beside the wire, the lamp nearly along
the wire everywhere, the edge hidden behind the wire in the oblique view) or the fit's
uncertainty is too large, :func:`estimate_lift_shadow` says so (``message``) and the
caller bounds the lift instead. Frames: board frame (mm), heights towards the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cvmeasure.contracts import PlaneModel
from cvmeasure.part.lift import (
    MAX_LIFT_MM,
    LiftEstimate,
    points_at_heights_mm,
    silhouette_sides,
)

__all__ = [
    "ShadowEdges",
    "ShadowLift",
    "estimate_lift_shadow",
    "measure_shadow_edges",
    "predict_shadow_edges_mm",
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
#: Residuals are clipped at this (mm) when starts of the fit are compared.
SCORE_CLIP_MM = 0.15
#: The model's axis points are this far apart (mm).
MODEL_STEP_MM = 0.25
#: The shadow edges' common bias, mm: on the ray-traced round wires (development seeds,
#: full and half size) the measured edges sat -0.05..+0.05 mm from the true ones on
#: average (negative on light plates, positive on dark ones).
EDGE_BIAS_MM = 0.05
#: An edge is an outlier (a centreline defect, clutter) only beyond this from the fit (mm),
#: however tight the others: several times the edges' bias.
OUTLIER_MM = 0.15
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
#: A first fit lifted by more than this (mm) has its edges measured again beyond the
#: silhouette of the axis at the fitted heights.
REMEASURE_LIFT_MM = 0.25
#: Centreline points this close to either end are left out (the caps' own shadows), mm.
END_MARGIN_MM = 4.0
#: The fit's forward differences: relative step of the parameters (shadow vector, slope).
DIFF_STEP = 1e-5


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


@dataclass(frozen=True)
class ShadowLift:
    """The part's lift from its cast shadow in one photo.

    Attributes
    ----------
    lift : heights along the centreline (0 at the lowest point), slope, lift and its
        standard uncertainty; None when the shadow does not measure it (``message``).
    shadow_mm_per_mm : (sx, sy) the lamp's horizontal shadow vector per mm of height, and
        ``shadow_sigma`` its standard uncertainties.
    lamp_elevation_deg, lamp_azimuth_deg : the lamp's direction from ``s`` (azimuth of
        the direction towards the lamp, board frame).
    residual_rms_mm : rms of the edges' residuals, mm.
    samples : edges used; ``length_mm`` the wire length they span.
    message : '' when measured, else why not.
    """

    lift: LiftEstimate | None
    shadow_mm_per_mm: tuple[float, float]
    shadow_sigma: tuple[float, float]
    lamp_elevation_deg: float
    lamp_azimuth_deg: float
    residual_rms_mm: float
    samples: int
    length_mm: float
    message: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            **(self.lift.to_dict() if self.lift is not None else {"lift_mm": None}),
            "shadow_mm_per_mm": list(self.shadow_mm_per_mm),
            "lamp_elevation_deg": self.lamp_elevation_deg,
            "lamp_azimuth_deg": self.lamp_azimuth_deg,
            "residual_rms_mm": self.residual_rms_mm,
            "samples": self.samples,
            "message": self.message,
        }


def _unit_normals(points_mm: np.ndarray) -> np.ndarray:
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
    import cv2

    from cvmeasure.colorimetry import srgb_decode
    from cvmeasure.part.segment import gray_float

    pts_px = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    axis_all = points_at_heights_mm(plane, pts_px, axis_height_mm)
    s_along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(axis_all, axis=0).T))))
    total = float(s_along[-1])
    marks = np.arange(END_MARGIN_MM, total - END_MARGIN_MM + 1e-9, step_mm)
    if len(marks) == 0:
        marks = np.array([0.5 * total])
    index = np.clip(np.searchsorted(s_along, marks), 0, len(pts_px) - 1)
    normal_all = _unit_normals(axis_all)
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
    lin = srgb_decode(np.clip(gray / top, 0.0, 1.0)).astype(np.float32)
    du = 0.25 * plane.mm_per_px
    u = np.arange(0.0, PROFILE_REACH_MM + 1e-9, du)
    far = u >= PROFILE_REACH_MM - PLATE_STRETCH_MM
    q = np.empty((2, len(index), len(u)))
    for k_side, sign in enumerate((1.0, -1.0)):
        where = axis[:, None, :] + sign * u[None, :, None] * normal[:, None, :]
        px = plane.plane_to_image_px(where.reshape(-1, 2)).astype(np.float32)
        prof = cv2.remap(
            lin, px[:, 0].reshape(len(index), -1), px[:, 1].reshape(len(index), -1),
            cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan,
        ).astype(np.float64)  # fmt: skip
        plate = np.median(prof[:, far], axis=1)
        q[k_side] = prof / np.maximum(plate, 1e-9)[:, None]
    # the wire's own blurred edge reaches this far beyond its silhouette (mm)
    margin = max(WIRE_BLUR_MARGIN_MM, WIRE_BLUR_MARGIN_PX * plane.mm_per_px)
    q = _less_wire_halo(u, q, silhouette.T, margin, far)
    start = silhouette.T + margin
    offsets, contrast, k_w = _fit_ramps(u, q, start, far)
    texture = _texture_edge_errors(u, q, start, far, offsets, contrast, k_w)
    return ShadowEdges(index, axis, normal, offsets.T, silhouette, contrast.T, margin, texture)


#: The sheet's own edge errors (:func:`_texture_edge_errors`) are clipped at this (mm) before
#: they widen the fit's uncertainty: a laid step lost in clutter or in another shadow says
#: no more than a large error. 0.15 mm (the outlier limit) left the textured lab sheets' lifts
#: 4-7 sigma off (dev seeds 2000-2020); 1 mm keeps what a dark textured sheet does (0.2-0.5 mm).
TEXTURE_CLIP_MM = 1.0
#: The texture draws: the synthetic step's gap beyond the silhouette moved by these (mm),
#: each laid on the lit side of its own sample and of the sample mirrored along the wire.
TEXTURE_GAP_SHIFTS_MM = (-0.6, 0.0, 0.6)


def _texture_edge_errors(
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
            e_fit, _, _ = _fit_ramps(u, q_inj, starts, far, min_depth=0.5 * k)
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


def _fit_ramps(
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
        sse = np.einsum("ku,gu->kg", rc.astype(float), pred**2) - 2.0 * (qc * rc) @ pred.T
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
    r = np.clip(0.5 - (u[None, None, :] - cand[..., None]) / w, 0.0, 1.0)  # (K, G, U)
    s_rr = np.einsum("kgu,ku->kg", r * r, m)
    s_r = np.einsum("kgu,ku->kg", r, m)
    s_n = m.sum(axis=1)[:, None]
    s_qr = np.einsum("kgu,ku->kg", r, qm)
    s_q = qm.sum(axis=1)[:, None]
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


@dataclass(frozen=True)
class _EdgeModel:
    """What :func:`predict_shadow_edges_mm` needs that does not change during a fit.

    ``at0_mm`` (M, 2): each centreline point's ray on the plate (height 0), board mm;
    ``per_mm`` (M, 2): its move per mm of height (affine along the ray); the measuring
    lines start at ``edges.axis_mm`` along ``+-edges.normal``.
    """

    at0_mm: np.ndarray
    per_mm: np.ndarray
    edges: ShadowEdges
    radius_mm: float

    def curve(self, height_mm: np.ndarray, shadow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The axis (..., M, 2) at its heights (..., M) and the band's outer edge (..., M, 2).

        Leading dimensions run over parameter sets (``shadow`` (..., 2)).
        """
        h = height_mm[..., None]
        axis3 = self.at0_mm + h * self.per_mm
        sc = axis3 + h * shadow[..., None, :]
        m = _unit_normals(sc)  # the shadow curve's
        ms = m[..., 1] * shadow[..., 1:] + m[..., 0] * shadow[..., :1]
        scale = np.where(ms >= 0, 1.0, -1.0) * self.radius_mm * np.sqrt(1.0 + ms * ms)
        return axis3, sc + scale[..., None] * m

    def crossings(
        self, axis3: np.ndarray, edge: np.ndarray, shadow: np.ndarray, d: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Where each measuring line (K) first crosses the polyline ``edge`` (M, 2).

        The line from ``edges.axis_mm`` along ``d`` (K, 2), searched over the segments near
        each sample's own index (a window as long as the shadow's largest displacement).
        Returns the distance along ``d`` (K,) (NaN where none) and the crossed segment's
        first point (K,) (-1 where none).
        """
        q = self.edges.axis_mm
        win = 3.0 + (self.radius_mm + 2.0 * MAX_LIFT_MM) * float(np.hypot(*shadow))
        step = float(np.median(np.hypot(*np.diff(axis3, axis=0).T))) + 1e-9
        kw = int(np.ceil(win / step))
        p = np.clip(self.edges.index[:, None] + np.arange(-kw, kw + 1)[None, :], 0, len(edge) - 1)
        ex, ey = edge[:, 0].take(p), edge[:, 1].take(p)
        cross = (ex - q[:, :1]) * d[:, 1:] - (ey - q[:, 1:]) * d[:, :1]
        cross_a, cross_b = cross[:, :-1], cross[:, 1:]
        rows, cols = np.nonzero((cross_a * cross_b <= 0) & (cross_a != cross_b))
        ca, cb = cross_a[rows, cols], cross_b[rows, cols]
        seg = p[rows, cols]
        along = _along(edge[seg], edge[p[rows, cols + 1]], q[rows], d[rows], ca, cb)
        ahead = along > 0
        rows, seg, along = rows[ahead], seg[ahead], along[ahead]
        if np.all(rows[1:] > rows[:-1]):  # one crossing per line (rows come sorted)
            first = slice(None)
        else:
            order = np.lexsort((along, rows))
            first = order[np.unique(rows[order], return_index=True)[1]]
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


def _along(a, b, q, d, cross_a, cross_b):
    """Distance along ``d`` from ``q`` to where the segment ``a``-``b`` (cross products
    ``cross_a``, ``cross_b`` of its ends with the line) meets the line."""
    t = cross_a / (cross_a - cross_b)
    hit = a + t[..., None] * (b - a)
    return np.sum((hit - q) * d, axis=-1)


def _edge_model(
    plane: PlaneModel, points_px: np.ndarray, edges: ShadowEdges, radius_mm: float
) -> _EdgeModel:
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    at0 = points_at_heights_mm(plane, pts, 0.0)
    at1 = points_at_heights_mm(plane, pts, 1.0)
    return _EdgeModel(at0, at1 - at0, edges, radius_mm)


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
    model = _edge_model(plane, points_px, edges, radius_mm)
    return _predict(model, np.asarray(height_mm, dtype=np.float64), shadow, side)[:2]


def _predict(
    model: _EdgeModel, height_mm: np.ndarray, shadow: np.ndarray, side: np.ndarray | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """:func:`predict_shadow_edges_mm` on a prepared model; also the crossed segments."""
    shadow = np.asarray(shadow, dtype=np.float64)
    n = model.edges.normal
    if side is None:
        side = np.where(n @ shadow >= 0, 1.0, -1.0)
    axis3, edge = model.curve(height_mm, shadow)
    along, seg = model.crossings(axis3, edge, shadow, n * side[:, None])
    return along, side, seg


def _forward_steps(x: np.ndarray, rel_step: float) -> np.ndarray:
    """The forward steps scipy's least_squares takes for ``diff_step=rel_step`` (the
    relative step, or sqrt(eps) max(1, |x|) where that vanishes), so a Jacobian supplied
    to it is the one it would have computed."""
    sign = np.where(x >= 0, 1.0, -1.0)
    step = rel_step * sign * np.abs(x)
    fallback = np.sqrt(np.finfo(np.float64).eps) * sign * np.maximum(1.0, np.abs(x))
    return np.where((x + step) - x == 0, fallback, step)


def _heights(plane_mm: np.ndarray, slope: np.ndarray) -> np.ndarray:
    rel = plane_mm @ slope
    return rel - rel.min()


def estimate_lift_shadow(
    image: np.ndarray,
    plane: PlaneModel,
    points_px: np.ndarray,
    *,
    wire_diameter_mm: float,
    axis_height_mm: float | None = None,
    edges: ShadowEdges | None = None,
) -> ShadowLift:
    """The part's lift from its cast shadow in one photo (see the module's docstring).

    ``points_px`` (M, 2): the wire's centreline in the photo (silhouette centres), ordered;
    ``axis_height_mm``: the axis' height where the part rests (default the radius). The
    standard uncertainties count one independent edge per wire diameter along the part, or
    the residuals' own correlation along the wire when it says less (a textured plate), plus
    an edge bias (common, and drifting across the plate) no smaller than the edges' rms nor
    than the sheet's own edge errors (a shadow step laid on its bare stretch beside the
    wire and measured), plus those errors taken through the fit; the Jacobian by central differences over physical steps; the lift's sigma is the tilt's
    uncertainty between any two points of the part.
    """
    from scipy.optimize import least_squares

    radius = 0.5 * wire_diameter_mm
    base = radius if axis_height_mm is None else float(axis_height_mm)
    pts_px = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    if edges is None:
        kw = {"wire_diameter_mm": wire_diameter_mm, "axis_height_mm": axis_height_mm}
        edges = measure_shadow_edges(
            image, plane, pts_px, wire_diameter_mm=wire_diameter_mm, axis_height_mm=base
        )
        first = estimate_lift_shadow(image, plane, pts_px, **kw, edges=edges)
        if first.lift is None or first.lift.lift_mm < REMEASURE_LIFT_MM:
            return first
        # the wire's silhouette on the plate from the fitted heights (a lifted end is seen
        # along its ray, so its silhouette reaches farther out on the side facing away from
        # the camera), the edges measured again beyond it, and fitted again
        edges = measure_shadow_edges(
            image, plane, pts_px, wire_diameter_mm=wire_diameter_mm, axis_height_mm=base,
            heights_mm=base + first.lift.height_mm,
        )  # fmt: skip
        return estimate_lift_shadow(image, plane, pts_px, **kw, edges=edges)
    flat_mm = points_at_heights_mm(plane, pts_px, base)
    centred = flat_mm - flat_mm.mean(axis=0)
    nan2 = (float("nan"), float("nan"))
    empty = ShadowLift(None, nan2, nan2, float("nan"), float("nan"), float("nan"), 0, 0.0)
    have = np.isfinite(edges.offset_mm)
    if have.sum() < 20:
        return _with(empty, "no cast shadow beside the wire (plate too dark, or no lamp)")
    full_centred = flat_mm - flat_mm.mean(axis=0)
    # the model runs on the axis every MODEL_STEP_MM (the photo's centres are ~1 px apart)
    along = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(flat_mm, axis=0).T))))
    keep = np.unique(np.searchsorted(along, np.arange(0.0, along[-1], MODEL_STEP_MM)))
    keep = np.unique(np.concatenate((keep[keep < len(pts_px)], [len(pts_px) - 1])))
    edges = replace(edges, index=np.clip(np.searchsorted(keep, edges.index), 0, len(keep) - 1))
    pts_px = pts_px[keep]
    centred = full_centred[keep]

    # each sample's shadow side is where its edge was found (the darker band when both);
    # used where the edge is clear of the wire's silhouette: a fixed set, so the fit cannot
    # drop an awkward edge by moving its prediction behind the wire
    k_side = np.where(
        np.isfinite(edges.offset_mm[:, 0])
        & (~np.isfinite(edges.offset_mm[:, 1]) | (edges.contrast[:, 0] >= edges.contrast[:, 1])),
        0,
        1,
    )
    rows = np.arange(len(k_side))
    meas = edges.offset_mm[rows, k_side]
    clear = np.isfinite(meas) & (meas > edges.silhouette_mm[rows, k_side] + edges.margin_mm)
    side = np.where(k_side == 0, 1.0, -1.0)

    model = _edge_model(plane, pts_px, edges, radius)
    line = edges.normal * side[:, None]
    last: dict[str, np.ndarray] = {}

    def residual(x: np.ndarray, use: np.ndarray) -> np.ndarray:
        h = base + _heights(centred, x[2:] * 1e-2)
        pred, _, seg = _predict(model, h, x[:2], side)
        last.update(x=x.copy(), pred=pred, seg=seg)
        res = np.where(np.isfinite(pred), meas - pred, SCORE_CLIP_MM)
        return np.where(use, res, 0.0)

    def jacobian(x: np.ndarray, use: np.ndarray) -> np.ndarray:
        """``residual``'s forward differences (least_squares' own steps for a relative
        step DIFF_STEP), each crossing followed on the segment it lies on at ``x``."""
        if "x" not in last or not np.array_equal(last["x"], x):
            residual(x, use)
        pred0, seg = last["pred"], last["seg"]
        xs = x + np.diag(_forward_steps(x, DIFF_STEP))
        dx = np.diag(xs) - x
        rel = (xs[:, 2:] * 1e-2) @ centred.T
        _, edge = model.curve(base + (rel - rel.min(axis=1, keepdims=True)), xs[:, :2])
        pred = model.along_segments(edge, seg, line)
        jac = ((meas - pred) - (meas - pred0)) / dx[:, None]
        return np.where(use & np.isfinite(pred0) & np.isfinite(pred), jac, 0.0).T

    def usable(x: np.ndarray) -> np.ndarray:
        return clear.copy()

    # start (flat part, no perspective): the side with the shadow is the sign of n.s and
    # the outer edge u = r (x + sqrt(1 + x^2)), x = |n.s|, so n.s is linear in s
    u0 = meas / radius
    ok0 = clear & (u0 > 1.0)
    if ok0.sum() < 20:
        return _with(empty, "the shadow's edge is nowhere clear of the wire")
    xs = (u0[ok0] ** 2 - 1.0) / (2.0 * u0[ok0]) * side[ok0]
    design = edges.normal[ok0]
    s0 = np.linalg.lstsq(design, xs, rcond=None)[0]
    for _ in range(5):  # a few edges off the shadow (a centreline defect) do not turn it
        r0 = xs - design @ s0
        w = np.abs(r0) < 3.0 * 1.4826 * float(np.median(np.abs(r0))) + 1e-6
        s0 = np.linalg.lstsq(design[w], xs[w], rcond=None)[0]

    def refine(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        use = usable(x)
        for _ in range(3):  # refit: the used edges follow the shadow's side; drop outliers
            if use.sum() < 20:
                break
            fit = least_squares(residual, x, jacobian, args=(use,), loss="soft_l1",
                                f_scale=0.1, x_scale=np.array([0.05, 0.05, 0.1, 0.1]))  # fmt: skip
            x, fitted = fit.x, use
            use = usable(x)
            res = residual(x, use)
            med = float(np.median(res[use])) if use.any() else 0.0
            mad = 1.4826 * float(np.median(np.abs(res[use] - med))) + 1e-6 if use.any() else 1.0
            use &= np.abs(res - med) < max(4.0 * mad, OUTLIER_MM)
            if np.array_equal(use, fitted):  # the same edges: a refit starts at its minimum
                break
        return x, use

    def score(x: np.ndarray) -> float:
        """One objective for every start: clipped squares, an edge not used costs the clip."""
        use = usable(x)
        res = residual(x, use)
        clipped = np.minimum(res**2, SCORE_CLIP_MM**2)
        return float(np.sum(np.where(use, clipped, SCORE_CLIP_MM**2)[have.any(axis=1)]))

    # starts: flat, and lifted by MAX_LIFT_MM towards eight directions (the tilt's fit
    # has local minima where the lamp's length trades against the lift)
    extent = float(np.max(np.ptp(centred, axis=0))) + 1e-9
    starts = [np.array([s0[0], s0[1], 0.0, 0.0])]
    for ang in np.radians(np.arange(0.0, 360.0, 45.0)):
        g = 100.0 * MAX_LIFT_MM / extent
        starts.append(np.array([s0[0], s0[1], g * np.cos(ang), g * np.sin(ang)]))
    best = None
    for x_start in starts:
        x_fit, use_fit = refine(x_start)
        sc = score(x_fit)
        if best is None or sc < best[0]:
            best = (sc, x_fit, use_fit)
    _, x, use = best
    fit = least_squares(residual, x, jacobian, args=(use,),
                        x_scale=np.array([0.05, 0.05, 0.1, 0.1]))  # fmt: skip
    x = fit.x
    res = fit.fun[use]
    n_used = int(use.sum())
    if n_used < 20:
        return _with(empty, "too few shadow edges clear of the wire")
    # the covariance's Jacobian by central differences over physical steps (a lamp's shadow
    # vector by 0.01 mm/mm, the tilt by 0.5 mm/m): the optimiser's own forward differences
    # at 1e-5 can land on a kink of the crossing (a column of zeros, or a jump) and state a
    # sigma of nothing
    steps = np.array([0.01, 0.01, 0.05, 0.05])
    jac = np.column_stack([
        (residual(x + h * e, use) - residual(x - h * e, use))[use] / (2.0 * h)
        for h, e in zip(steps, np.eye(4), strict=True)
    ])  # fmt: skip
    sigma2 = float(np.sum(res**2) / max(n_used - 4, 1))
    along = edges.axis_mm[use]
    length = float(np.sum(np.hypot(*np.diff(along, axis=0).T)))
    n_eff = max(4.0, min(n_used, length / wire_diameter_mm))
    pinv = np.linalg.pinv(jac)
    cov_stat = pinv @ pinv.T * sigma2 * n_used / n_eff
    # the edges' errors are correlated along the wire where a texture (a stain, the grain)
    # moves neighbouring edges alike: their covariance from the residuals' own correlation
    pos = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(along, axis=0).T))))
    cov_corr = _correlated_cov(pinv, res, pos)
    cov_stat = np.maximum(cov_stat, cov_corr) if np.all(np.diag(cov_corr) > 0) else cov_stat
    # the edges' bias: blur, penumbra and tone curve move every edge alike, and the plate's
    # texture and light (vignetting, defocus) drift across it; a texture that scatters the
    # edges by their rms moves them by as much over a stain, so the bias is not known
    # better than that scatter (clean renders: 0.02-0.06 mm, below EDGE_BIAS_MM); nor than
    # the sheet's own share of the edges' errors (a shadow step laid on its bare stretch
    # beside the wire and measured, _texture_edge_errors): the fit absorbs the smooth part
    # of a texture's errors into the lamp and the tilt, so its residuals understate them
    bias = max(EDGE_BIAS_MM, float(np.sqrt(sigma2)), _texture_rms_mm(edges.texture_mm, use))
    half = 0.5 * np.maximum(np.ptp(along, axis=0), 1e-9)
    drift = (along - 0.5 * (along.max(axis=0) + along.min(axis=0))) / half
    cov = cov_stat.copy()
    for pattern in (np.ones(n_used), drift[:, 0], drift[:, 1]):
        shift = pinv @ (bias * pattern)
        cov += np.outer(shift, shift)
    # and those errors themselves, at the wire's own positions, taken through the fit
    cov += _texture_cov(pinv, edges.texture_mm, use)
    slope = x[2:] * 1e-2
    slope_cov = cov[2:, 2:] * 1e-4
    height = _heights(full_centred, slope)
    rel = full_centred @ slope
    span = full_centred[int(np.argmax(rel))] - full_centred[int(np.argmin(rel))]
    lift = LiftEstimate(
        height_mm=height,
        slope=(float(slope[0]), float(slope[1])),
        slope_cov=slope_cov,
        lift_mm=float(height.max()),
        lift_sigma_mm=_height_sigma_mm(full_centred, slope_cov, span),
        samples=n_used,
        width_scale=float("nan"),
    )
    s = x[:2]
    return ShadowLift(
        lift=lift,
        shadow_mm_per_mm=(float(s[0]), float(s[1])),
        shadow_sigma=(float(np.sqrt(cov[0, 0])), float(np.sqrt(cov[1, 1]))),
        lamp_elevation_deg=float(np.degrees(np.arctan2(1.0, np.hypot(*s)))),
        lamp_azimuth_deg=float(np.degrees(np.arctan2(-s[1], -s[0])) % 360.0),
        residual_rms_mm=float(np.sqrt(np.mean(res**2))),
        samples=n_used,
        length_mm=length,
    )


def _texture_cov(pinv: np.ndarray, texture_mm: np.ndarray | None, use: np.ndarray) -> np.ndarray:
    """The parameters' covariance from the sheet's own edge errors (``texture_mm`` (K, D),
    :func:`_texture_edge_errors`) on the used samples: the mean of the D draws' shifts'
    outer products (each draw's errors taken through ``pinv``, clipped at
    :data:`TEXTURE_CLIP_MM`, none where not measured)."""
    p = pinv.shape[0]
    if texture_mm is None:
        return np.zeros((p, p))
    t = texture_mm[use]
    t = np.clip(np.where(np.isfinite(t), t, 0.0), -TEXTURE_CLIP_MM, TEXTURE_CLIP_MM)
    shifts = pinv @ t  # (P, D)
    return shifts @ shifts.T / t.shape[1]


def _texture_rms_mm(texture_mm: np.ndarray | None, use: np.ndarray) -> float:
    """The rms of the sheet's own edge errors on the used samples (clipped as in
    :func:`_texture_cov`), mm; 0 with fewer than 10 measured."""
    if texture_mm is None:
        return 0.0
    t = texture_mm[use]
    t = np.clip(t[np.isfinite(t)], -TEXTURE_CLIP_MM, TEXTURE_CLIP_MM)
    return float(np.sqrt(np.mean(t * t))) if len(t) >= 10 else 0.0


def _height_sigma_mm(points_mm: np.ndarray, slope_cov: np.ndarray, span: np.ndarray) -> float:
    """The lift's standard uncertainty: the largest of the tilt's uncertainty between any
    two points of the part (``points_mm`` (M, 2), ``slope_cov`` (2, 2) per mm^2), at least
    along ``span`` (lowest to highest point). Where the fitted tilt is small its direction is
    not known, so which points are highest is not either: the lift's error is the heights'
    error anywhere on the part, not only between the two points the estimate happens to
    name."""
    sub = points_mm[:: max(1, len(points_mm) // 200)]
    d = sub[:, None, :] - sub[None, :, :]
    q = np.einsum("ijk,kl,ijl->ij", d, slope_cov, d)
    return float(np.sqrt(max(float(q.max()), float(span @ slope_cov @ span), 0.0)))


def _with(base: ShadowLift, message: str) -> ShadowLift:
    return replace(base, message=message)


def _residual_correlation(
    res: np.ndarray, pos_mm: np.ndarray, bin_mm: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """The residuals' autocorrelation against their distance along the wire (bins of ``bin_mm``),
    cut at its first non-positive bin."""
    r = res - res.mean()
    var = float(np.mean(r * r)) + 1e-18
    lag = np.abs(pos_mm[:, None] - pos_mm[None, :])
    b = np.floor(lag / bin_mm + 0.5).astype(int)
    nb = int(min(b.max(), 0.5 * (pos_mm[-1] - pos_mm[0]) / bin_mm)) + 1
    prod = r[:, None] * r[None, :]
    sums = np.bincount(b.ravel(), weights=prod.ravel(), minlength=nb + 1)[:nb]
    counts = np.bincount(b.ravel(), minlength=nb + 1)[:nb]
    rho = sums / np.maximum(counts, 1) / var
    rho[0] = 1.0
    bad = np.nonzero(rho[1:] <= 0.0)[0]
    if len(bad):
        rho[bad[0] + 1 :] = 0.0
    return np.arange(nb) * bin_mm, rho


def _correlated_cov(pinv: np.ndarray, res: np.ndarray, pos_mm: np.ndarray) -> np.ndarray:
    """The parameters' covariance (``pinv`` the Jacobian's pseudo-inverse) with the residuals'
    correlation along the wire (``pos_mm``) counted."""
    lags, rho = _residual_correlation(res, pos_mm)
    var = float(np.mean((res - res.mean()) ** 2))
    c = var * np.interp(np.abs(pos_mm[:, None] - pos_mm[None, :]), lags, rho, right=0.0)
    return pinv @ c @ pinv.T
