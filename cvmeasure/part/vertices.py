"""The polyline whose bends are a round wire's vertex bends.

From each chord's whole cross-profile where the silhouette edges allow
(:func:`cvmeasure.part.chord_profiles.profile_polyline`), else from the edge pairs'
centres, combined with the lit edge's on a part measured lifted.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from cvmeasure.part.centreline import Centreline
from cvmeasure.part.chord_profiles import profile_polyline
from cvmeasure.part.fit import (
    PolylineFit,
    fit_polyline,
)
from cvmeasure.part.segment import gray_float

__all__ = ["LIT_MIN_LIFT_MM", "vertex_polyline", "profile_vertices", "combine_chords"]


#: A part whose lift is measured (two photos, the shadow) at least this high (mm) has its
#: vertex bends from the pairs' and the lit side's chords combined (:func:`vertex_polyline`).
#: The pairs' midpoints drift with the shadow's gap in proportion to the lift (0.05-0.13 deg
#: at 3 mm at full size); the lit edge alone has a shading error of its own (0.07 deg on a
#: flat noise-free part at half size where the pairs gave 0.02), which the
#: combination would read as the pairs' drift, so a part lying about flat keeps the pairs.
LIT_MIN_LIFT_MM = 2.0


def vertex_polyline(
    lit_points_px: np.ndarray | None,
    to_mm: Any,
    divisions: int | None,
    poly: PolylineFit | None,
    fractions: np.ndarray | None = None,
) -> PolylineFit | None:
    """The polyline whose bends are the vertex bends: the pairs' and the lit side's chords.

    A round wire's centres between its silhouette edges bend where a lifted part's shadow
    parts from it (the shadow side's edge shifts with the gap;
    :func:`cvmeasure.part.centreline._silhouette_centres`); the centres on the lit side's
    edge (``lit_points_px``, mapped to mm by ``to_mm``) do not, but carry one edge's noise
    instead of two's. Each chord's direction is combined from both fits
    (:func:`combine_chords`). ``poly`` (the pairs' midpoints) when there are no lit
    centres.
    """
    if poly is None or lit_points_px is None or not divisions:
        return poly
    try:
        lit = fit_polyline(to_mm(lit_points_px), divisions, fractions=fractions)
    except ValueError:
        return poly
    return combine_chords(poly, lit)


def profile_vertices(
    image: np.ndarray,
    centre: Centreline,
    to_mm: Any,
    poly: PolylineFit | None,
    fractions: np.ndarray | None = None,
) -> PolylineFit | None:
    """The vertex bends' polyline from each chord's whole cross-profile (lit side).

    :func:`cvmeasure.part.chord_profiles.profile_polyline` on a centreline between silhouette
    edges (``poly`` splits it into chords); None when there are no silhouette edges or the
    fit fails (the caller keeps its edge-based polyline).
    """
    widths = centre.edge_width_px
    if poly is None or widths is None or not np.isfinite(widths).any():
        return None
    return profile_polyline(
        gray_float(image),
        centre.points_px,
        to_mm,
        poly,
        width_px=float(np.nanmedian(widths)),
        fractions=fractions,
    )


def combine_chords(pairs: PolylineFit, lit: PolylineFit) -> PolylineFit:
    """Each chord's direction from the pairs' fit and the lit side's, by their errors.

    With ``S``, ``L`` the two edges' noise on a chord's direction and ``b`` the shadow
    side's bias (halved in the pairs' midpoints), the pairs read ``b + (S + L) / 2``
    (variance ``sp^2``) and the lit side ``L`` (``sl^2``), so their difference ``D`` is ``b``
    plus noise of variance ``sp^2`` (``S`` and ``L`` independent). The direction
    ``lit + w (pairs - lit)`` has the mean square error
    ``(1 - w/2)^2 sl^2 + w^2 ss^2 / 4 + w^2 b^2`` (``ss^2 = 4 sp^2 - sl^2``, the shadow
    side's noise), least at ``w = (sl^2 / 2) / (sp^2 + b^2)``; ``b^2`` is estimated as
    ``max(D^2 - sp^2, 0)``, so a chord whose two fits agree within their noise takes
    about the pairs (less noise) and one whose pairs drift with the shadow takes the lit
    edge. The bend's sigma is the two chords' errors (their fits share no point) in
    quadrature. The vertices and the rest are the lit fit's.
    """
    if (
        pairs.direction_deg is None
        or lit.direction_deg is None
        or pairs.direction_sigma_deg is None
        or lit.direction_sigma_deg is None
        or len(pairs.direction_deg) != len(lit.direction_deg)
    ):
        return lit
    sp2 = np.radians(pairs.direction_sigma_deg) ** 2
    sl2 = np.radians(lit.direction_sigma_deg) ** 2
    diff = np.radians((pairs.direction_deg - lit.direction_deg + 180.0) % 360.0 - 180.0)
    if not (np.all(np.isfinite(sp2)) and np.all(np.isfinite(sl2)) and np.all(sp2 > 0)):
        return lit
    b2 = np.maximum(diff**2 - sp2, 0.0)
    w = np.clip(0.5 * sl2 / (sp2 + b2), 0.0, 1.0)
    ss2 = np.maximum(4.0 * sp2 - sl2, 0.0)
    mse = (1.0 - 0.5 * w) ** 2 * sl2 + 0.25 * w**2 * ss2 + w**2 * b2
    turn = np.degrees(w * diff)  # each chord's direction moved from the lit fit's
    return replace(
        lit,
        bend_deg=lit.bend_deg + np.diff(turn),
        bend_sigma_deg=np.degrees(np.sqrt(mse[:-1] + mse[1:])),
        direction_deg=lit.direction_deg + turn,
        direction_sigma_deg=np.degrees(np.sqrt(mse)),
    )
