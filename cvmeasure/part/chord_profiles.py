"""Each straight chord's whole cross-profile: station shifts against the chord's own template.

Along a straight chord the profile across the wire is the same at every station up to a
shift, so the chord is fitted as ``I(t, u) = T(u - c(t))``: ``T`` the chord's mean
profile, re-made from the aligned profiles, and ``c(t)`` each station's shift by
Gauss-Newton with every pixel weighted by ``T'^2``.
"""

from __future__ import annotations

from typing import Any, Literal

import numpy as np

from cvmeasure.geometry import arclength_mm
from cvmeasure.part.fit import PolylineFit, fit_polyline
from cvmeasure.part.profiles import sample_image

__all__ = ["TEMPLATE_STEP_PX", "chord_profile_centres", "profile_polyline"]


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
        prof = sample_image(g, grid)
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
    s = arclength_mm(pts_mm)
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
