"""A part's lift from ONE photo: the wire's cast shadow on the plate, fitted globally.

Under a distant lamp a point of the wire's axis at height ``H`` above the plate casts
its shadow at ``p + H s`` (plate, board frame), ``s`` the lamp's horizontal shadow vector
per mm of height (unknown: learnt from the photo). A cylinder of radius ``r`` lying
along a horizontal direction with plate normal ``n`` casts a band whose edges lie at
``H (n.s) +- r sqrt(1 + (n.s)^2)`` across it (the light's ray at distance ``r`` from the
axis); the outer edge, on the side ``n.s > 0``, lies beyond the wire and is seen on
the plate. A rigid part rests on the plate: ``H = r + h(p)``, ``h = a.p + c >= 0`` with
``h = 0`` at its lowest point (``c = -min a.p``). Fitted together over the whole
centreline: ``s`` (2), ``a`` (2) and the lamp's inverse height (a desk lamp near the part
shadows along a vector that changes across it, which a distant lamp's ``s`` would take for
a tilt; :meth:`~cvmeasure.part.shadow_model.EdgeModel.shadow_vectors`), by least squares
on the shadow's outer edge measured across the wire (on the plate, the photo linearised from sRGB, the edge at
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
from scipy.optimize import least_squares

from cvmeasure.contracts import PlaneModel
from cvmeasure.geometry import arclength_mm
from cvmeasure.part.lift import (
    MAX_LIFT_MM,
    LiftEstimate,
    points_at_heights_mm,
)
from cvmeasure.part.shadow_edges import TEXTURE_CLIP_MM, ShadowEdges, measure_shadow_edges
from cvmeasure.part.shadow_model import edge_model, forward_steps, predict_edges, rigid_heights

__all__ = ["ShadowLift", "estimate_lift_shadow"]

#: Residuals are clipped at this (mm) when starts of the fit are compared.
SCORE_CLIP_MM = 0.15

#: The model's axis points are this far apart (mm).
MODEL_STEP_MM = 0.25

#: The shadow edges' common bias, mm: on the ray-traced round wires (full and half size)
#: the measured edges sat -0.05..+0.05 mm from the true ones on
#: average (negative on light plates, positive on dark ones).
EDGE_BIAS_MM = 0.05

#: An edge is an outlier (a centreline defect, clutter) only beyond this from the fit (mm),
#: however tight the others: several times the edges' bias.
OUTLIER_MM = 0.15

#: A first fit lifted by more than this (mm) has its edges measured again beyond the
#: silhouette of the axis at the fitted heights.
REMEASURE_LIFT_MM = 0.25

#: The shadow model is refused where its edges' residuals, averaged over two wire diameters
#: (the edges' noise averaged out), keep more than this rms (mm): twice the edges' known
#: bias. On the project's own renders (light, dark, noisy sheets; flat and lifted 1.5-3 mm)
#: the averaged residuals were 0.010-0.049 mm; on Mitsuba 3 renders under a 60 mm sphere
#: lamp 150 mm up or 55 mm up and 500 mm away (a penumbra as long as the shadow), beside a
#: large ceiling light, 0.11-0.29 mm with the lamp's height fitted, where flat parts had
#: read 0.9-2.0 mm lifted.
MISFIT_MM = 2.0 * EDGE_BIAS_MM

#: The fit's parameters: the shadow vector at the part's middle (2), the tilt (2, in
#: 1e-2 mm/mm) and the lamp's inverse height (in LAMP_K_UNIT per mm: 1 is a lamp 1 m up,
#: 0 a distant one); their typical scales.
LAMP_K_UNIT = 1e-3
X_SCALE = np.array([0.05, 0.05, 0.1, 0.1, 1.0])

#: The lamp is taken no lower than this (mm) above the plate.
MIN_LAMP_HEIGHT_MM = 20.0

#: The fit's forward differences: relative step of the parameters (shadow vector, slope).
DIFF_STEP = 1e-5


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
    lamp_height_mm : the lamp's height above the plate (inf: a distant lamp).
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
    lamp_height_mm: float = float("inf")

    def to_dict(self) -> dict[str, Any]:
        return {
            **(self.lift.to_dict() if self.lift is not None else {"lift_mm": None}),
            "shadow_mm_per_mm": list(self.shadow_mm_per_mm),
            "lamp_elevation_deg": self.lamp_elevation_deg,
            "lamp_azimuth_deg": self.lamp_azimuth_deg,
            "residual_rms_mm": self.residual_rms_mm,
            "samples": self.samples,
            "lamp_height_mm": self.lamp_height_mm if np.isfinite(self.lamp_height_mm) else None,
            "message": self.message,
        }


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
    radius = 0.5 * wire_diameter_mm
    base = radius if axis_height_mm is None else float(axis_height_mm)
    pts_px = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    if edges is not None:
        return _fit_shadow(plane, pts_px, edges, wire_diameter_mm, base)
    edges = measure_shadow_edges(
        image, plane, pts_px, wire_diameter_mm=wire_diameter_mm, axis_height_mm=base
    )
    first = _fit_shadow(plane, pts_px, edges, wire_diameter_mm, base)
    if first.lift is None or first.lift.lift_mm < REMEASURE_LIFT_MM:
        return first
    # the wire's silhouette on the plate from the fitted heights (a lifted end is seen
    # along its ray, so its silhouette reaches farther out on the side facing away from
    # the camera), the edges measured again beyond it, and fitted again
    edges = measure_shadow_edges(
        image, plane, pts_px, wire_diameter_mm=wire_diameter_mm, axis_height_mm=base,
        heights_mm=base + first.lift.height_mm,
    )  # fmt: skip
    return _fit_shadow(plane, pts_px, edges, wire_diameter_mm, base)


def _fit_shadow(
    plane: PlaneModel, pts_px: np.ndarray, edges: ShadowEdges, wire_diameter_mm: float, base: float
) -> ShadowLift:
    """The shadow model fitted to measured edges (:func:`estimate_lift_shadow`'s fit)."""
    radius = 0.5 * wire_diameter_mm
    flat_mm = points_at_heights_mm(plane, pts_px, base)
    nan2 = (float("nan"), float("nan"))
    empty = ShadowLift(None, nan2, nan2, float("nan"), float("nan"), float("nan"), 0, 0.0)
    have = np.isfinite(edges.offset_mm)
    if have.sum() < 20:
        return _with(empty, "no cast shadow beside the wire (plate too dark, or no lamp)")
    full_centred = flat_mm - flat_mm.mean(axis=0)
    keep = _model_samples(flat_mm)
    edges = replace(edges, index=np.clip(np.searchsorted(keep, edges.index), 0, len(keep) - 1))
    pts_px = pts_px[keep]
    centred = full_centred[keep]

    # each sample's edge, its side, and whether it is clear of the silhouette (_edge_sides)
    meas, clear, side = _edge_sides(edges)

    model = edge_model(plane, pts_px, edges, radius)
    line = edges.normal * side[:, None]
    last: dict[str, np.ndarray] = {}

    def residual(x: np.ndarray, use: np.ndarray) -> np.ndarray:
        h = base + rigid_heights(centred, x[2:4] * 1e-2)
        pred, _, seg = predict_edges(model, h, x[:2], side, x[4] * LAMP_K_UNIT)
        last.update(x=x.copy(), pred=pred, seg=seg)
        res = np.where(np.isfinite(pred), meas - pred, SCORE_CLIP_MM)
        return np.where(use, res, 0.0)

    def jacobian(x: np.ndarray, use: np.ndarray) -> np.ndarray:
        """``residual``'s forward differences (least_squares' own steps for a relative
        step DIFF_STEP), each crossing followed on the segment it lies on at ``x``."""
        if "x" not in last or not np.array_equal(last["x"], x):
            residual(x, use)
        pred0, seg = last["pred"], last["seg"]
        xs = x + np.diag(forward_steps(x, DIFF_STEP))
        dx = np.diag(xs) - x
        rel = (xs[:, 2:4] * 1e-2) @ centred.T
        heights = base + (rel - rel.min(axis=1, keepdims=True))
        _, edge = model.curve(heights, xs[:, :2], xs[:, 4] * LAMP_K_UNIT)
        pred = model.along_segments(edge, seg, line)
        jac = ((meas - pred) - (meas - pred0)) / dx[:, None]
        return np.where(use & np.isfinite(pred0) & np.isfinite(pred), jac, 0.0).T

    def distant(x4: np.ndarray, use: np.ndarray) -> np.ndarray:
        return residual(np.append(x4, 0.0), use)

    def distant_jac(x4: np.ndarray, use: np.ndarray) -> np.ndarray:
        return jacobian(np.append(x4, 0.0), use)[:, :4]

    # start (flat part, no perspective): the side with the shadow is the sign of n.s and
    # the outer edge u = r (x + sqrt(1 + x^2)), x = |n.s|, so n.s is linear in s
    u0 = meas / radius
    ok0 = clear & (u0 > 1.0)
    if ok0.sum() < 20:
        return _with(empty, "the shadow's edge is nowhere clear of the wire")
    s0 = _start_shadow_vector(u0[ok0], side[ok0], edges.normal[ok0])

    def refine(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        use = clear.copy()  # the edges clear of the silhouette: a fixed set
        for _ in range(3):  # refit: the used edges follow the shadow's side; drop outliers
            if use.sum() < 20:
                break
            fit = least_squares(distant, x[:4], distant_jac, args=(use,), loss="soft_l1",
                                f_scale=0.1, x_scale=X_SCALE[:4])  # fmt: skip
            x, fitted = np.append(fit.x, 0.0), use
            use = clear.copy()  # the edges clear of the silhouette: a fixed set
            res = residual(x, use)
            med = float(np.median(res[use])) if use.any() else 0.0
            mad = 1.4826 * float(np.median(np.abs(res[use] - med))) + 1e-6 if use.any() else 1.0
            use &= np.abs(res - med) < max(4.0 * mad, OUTLIER_MM)
            if np.array_equal(use, fitted):  # the same edges: a refit starts at its minimum
                break
        return x, use

    def score(x: np.ndarray) -> float:
        """One objective for every start: clipped squares, an edge not used costs the clip."""
        use = clear.copy()  # the edges clear of the silhouette: a fixed set
        res = residual(x, use)
        clipped = np.minimum(res**2, SCORE_CLIP_MM**2)
        return float(np.sum(np.where(use, clipped, SCORE_CLIP_MM**2)[have.any(axis=1)]))

    best = None
    for x_start in _starts(s0, centred):
        x_fit, use_fit = refine(x_start)
        sc = score(x_fit)
        if best is None or sc < best[0]:
            best = (sc, x_fit, use_fit)
    _, x, use = best
    n_used = int(use.sum())
    if n_used < 20:
        return _with(empty, "too few shadow edges clear of the wire")
    x, res, cov, length = _final_fit(
        (distant, distant_jac), (residual, jacobian), x, use, edges, wire_diameter_mm
    )
    shadow = _shadow_lift(x, cov, full_centred, res, n_used, length)
    return _refused_if_misfit(shadow, res, edges.axis_mm[use], wire_diameter_mm)


def _final_fit(
    distant: tuple[Any, Any],
    lamp: tuple[Any, Any],
    x: np.ndarray,
    use: np.ndarray,
    edges: ShadowEdges,
    wire_diameter_mm: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The last fit on the edges ``use``: a distant lamp's (``distant``: residual and
    Jacobian of the 4 parameters), or, where the edges pin its height, a lamp's at that
    height (``lamp``: of all 5). Returns the parameters (5), the used edges' residuals, the
    covariance and the wire length the edges span (mm).

    A lamp near the part shadows along a vector that changes across it, which a distant
    lamp's model takes for a tilt; the lamp's height is kept where it is over 2 sigma above
    0 and fits better, else the distant lamp's fewer parameters leave the tilt better known.
    """
    fit = least_squares(distant[0], x[:4], distant[1], args=(use,), x_scale=X_SCALE[:4])
    x, res = np.append(fit.x, 0.0), fit.fun[use]
    residual, jacobian = lamp
    cov, length = _fit_covariance(residual, x, use, res, edges, wire_diameter_mm, 4)
    k_max = 1.0 / (LAMP_K_UNIT * MIN_LAMP_HEIGHT_MM)
    bounds = ([-np.inf] * 4 + [0.0], [np.inf] * 4 + [k_max])
    near = least_squares(residual, x + np.eye(5)[4], jacobian, args=(use,), x_scale=X_SCALE,
                         bounds=bounds)  # fmt: skip
    near_res = near.fun[use]
    near_cov, _ = _fit_covariance(residual, near.x, use, near_res, edges, wire_diameter_mm)
    if near.x[4] > 2.0 * np.sqrt(near_cov[4, 4]) and near.cost < fit.cost:
        return near.x, near_res, near_cov, length
    return x, res, cov, length


def _refused_if_misfit(
    shadow: ShadowLift, res: np.ndarray, axis_mm: np.ndarray, wire_diameter_mm: float
) -> ShadowLift:
    """``shadow``, its lift dropped with the reason where the edges' residuals ``res`` (K,)
    (at the axis points ``axis_mm`` (K, 2), in order along the wire), averaged over two wire
    diameters, keep more than :data:`MISFIT_MM` rms: the model does not describe this
    shadow, and its lift would absorb the difference."""
    along = arclength_mm(axis_mm)
    window = 2.0 * wire_diameter_mm
    misfit = float(np.sqrt(np.mean(_smooth_along(res, along, window) ** 2)))
    if misfit <= MISFIT_MM:
        return shadow
    return _with(
        replace(shadow, lift=None),
        f"the shadow's edge departs from one small lamp's shadow of a rigid part by "
        f"{misfit:.2f} mm (rms over {window:g} mm of wire) > {MISFIT_MM:.2f} mm: a large or "
        "doubled lamp's soft shadow, or a pattern on the sheet, which its lift would absorb",
    )


def _smooth_along(res: np.ndarray, pos_mm: np.ndarray, window_mm: float) -> np.ndarray:
    """``res`` (K,) averaged over ``window_mm`` of wire around each sample (``pos_mm`` (K,)
    its position along the wire): the residuals' systematic part, the edges' noise averaged out."""
    near = np.abs(pos_mm[:, None] - pos_mm[None, :]) <= 0.5 * window_mm
    return (near @ res) / near.sum(axis=1)


def _model_samples(flat_mm: np.ndarray) -> np.ndarray:
    """The centreline points the model runs on: one every MODEL_STEP_MM along the axis (the
    photo's centres are ~1 px apart), and the last."""
    along = arclength_mm(flat_mm)
    keep = np.unique(np.searchsorted(along, np.arange(0.0, along[-1], MODEL_STEP_MM)))
    return np.unique(np.concatenate((keep[keep < len(flat_mm)], [len(flat_mm) - 1])))


def _starts(s0: np.ndarray, centred: np.ndarray) -> list[np.ndarray]:
    """The fit's starts: flat, and lifted by MAX_LIFT_MM towards eight directions (the
    tilt's fit has local minima where the lamp's length trades against the lift)."""
    extent = float(np.max(np.ptp(centred, axis=0))) + 1e-9
    starts = [np.array([s0[0], s0[1], 0.0, 0.0, 0.0])]
    for ang in np.radians(np.arange(0.0, 360.0, 45.0)):
        g = 100.0 * MAX_LIFT_MM / extent
        starts.append(np.array([s0[0], s0[1], g * np.cos(ang), g * np.sin(ang), 0.0]))
    return starts


def _edge_sides(edges: ShadowEdges) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each sample's measured edge, whether it is clear of the silhouette, and its side.

    The shadow side is where the sample's edge was found (the darker band when both); an
    edge is used where it is clear of the wire's silhouette: a fixed set, so the fit cannot
    drop an awkward edge by moving its prediction behind the wire.
    """
    k_side = np.where(
        np.isfinite(edges.offset_mm[:, 0])
        & (~np.isfinite(edges.offset_mm[:, 1]) | (edges.contrast[:, 0] >= edges.contrast[:, 1])),
        0,
        1,
    )
    rows = np.arange(len(k_side))
    meas = edges.offset_mm[rows, k_side]
    clear = np.isfinite(meas) & (meas > edges.silhouette_mm[rows, k_side] + edges.margin_mm)
    return meas, clear, np.where(k_side == 0, 1.0, -1.0)


def _start_shadow_vector(u0: np.ndarray, side: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """The shadow vector of a flat part from the edges' outer offsets ``u0`` (in radii).

    The outer edge is ``u = r (x + sqrt(1 + x^2))``, ``x = |n.s|``, so ``n.s`` is linear
    in ``s``; a few edges off the shadow (a centreline defect) do not turn it.
    """
    xs = (u0**2 - 1.0) / (2.0 * u0) * side
    s0 = np.linalg.lstsq(normal, xs, rcond=None)[0]
    for _ in range(5):
        r0 = xs - normal @ s0
        w = np.abs(r0) < 3.0 * 1.4826 * float(np.median(np.abs(r0))) + 1e-6
        s0 = np.linalg.lstsq(normal[w], xs[w], rcond=None)[0]
    return s0


def _fit_covariance(
    residual: Any,
    x: np.ndarray,
    use: np.ndarray,
    res: np.ndarray,
    edges: ShadowEdges,
    wire_diameter_mm: float,
    n_par: int = 5,
) -> tuple[np.ndarray, float]:
    """The covariance of the first ``n_par`` fitted parameters (the rest held), and the
    length of wire the used edges span (mm)."""
    n_used = int(use.sum())
    # the covariance's Jacobian by central differences over physical steps (a lamp's shadow
    # vector by 0.01 mm/mm, the tilt by 0.5 mm/m): the optimiser's own forward differences
    # at 1e-5 can land on a kink of the crossing (a column of zeros, or a jump) and state a
    # sigma of nothing
    steps = np.array([0.01, 0.01, 0.05, 0.05, 0.1])[:n_par]
    jac = np.column_stack([
        (residual(x + h * e, use) - residual(x - h * e, use))[use] / (2.0 * h)
        for h, e in zip(steps, np.eye(5)[:n_par], strict=True)
    ])  # fmt: skip
    sigma2 = float(np.sum(res**2) / max(n_used - n_par, 1))
    along = edges.axis_mm[use]
    length = float(np.sum(np.hypot(*np.diff(along, axis=0).T)))
    n_eff = max(4.0, min(n_used, length / wire_diameter_mm))
    pinv = np.linalg.pinv(jac)
    cov_stat = pinv @ pinv.T * sigma2 * n_used / n_eff
    # the edges' errors are correlated along the wire where a texture (a stain, the grain)
    # moves neighbouring edges alike: their covariance from the residuals' own correlation
    pos = arclength_mm(along)
    cov_corr = _correlated_cov(pinv, res, pos)
    cov_stat = np.maximum(cov_stat, cov_corr) if np.all(np.diag(cov_corr) > 0) else cov_stat
    # the edges' bias: blur, penumbra and tone curve move every edge alike, and the plate's
    # texture and light (vignetting, defocus) drift across it; a texture that scatters the
    # edges by their rms moves them by as much over a stain, so the bias is not known
    # better than that scatter (clean renders: 0.02-0.06 mm, below EDGE_BIAS_MM); nor than
    # the sheet's own share of the edges' errors (a shadow step laid on its bare stretch
    # beside the wire and measured, texture_edge_errors): the fit absorbs the smooth part
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
    return cov, length


def _shadow_lift(
    x: np.ndarray,
    cov: np.ndarray,
    full_centred: np.ndarray,
    res: np.ndarray,
    n_used: int,
    length: float,
) -> ShadowLift:
    """The :class:`ShadowLift` of the fitted shadow vector and tilt ``x``."""
    slope = x[2:4] * 1e-2
    slope_cov = cov[2:4, 2:4] * 1e-4
    height = rigid_heights(full_centred, slope)
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
        lamp_height_mm=float(1.0 / (x[4] * LAMP_K_UNIT)) if x[4] > 0 else float("inf"),
    )


def _texture_cov(pinv: np.ndarray, texture_mm: np.ndarray | None, use: np.ndarray) -> np.ndarray:
    """The parameters' covariance from the sheet's own edge errors (``texture_mm`` (K, D),
    :func:`texture_edge_errors`) on the used samples: the mean of the D draws' shifts'
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
