"""How a part's lift off the plate is used: bounded, or corrected from its shadow or a second photo.

The lift itself is measured in :mod:`cvmeasure.part.lift` (width, two photos) and
:mod:`cvmeasure.part.shadow` (the cast shadow); here its effect on the radius and the
bends is bounded (the part rocked towards 16 directions), a reading is checked against
the bound before it is used, and points are mapped at their own heights.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.contracts import PlaneModel
from cvmeasure.part.arc import arc_from_points
from cvmeasure.part.ends import EndShape
from cvmeasure.part.fit import (
    PolylineFit,
)
from cvmeasure.part.lift import (
    MAX_LIFT_MM,
    LiftEstimate,
    estimate_lift_moved,
    lift_bound_mm,
    points_at_heights_mm,
    rocked_lift,
    unroll_mm,
)
from cvmeasure.part.locate import axis_height_for, measure_centreline_mm
from cvmeasure.part.result import ArcResult, LiftSource, LiftUse, PartLift
from cvmeasure.warning import StageWarning

__all__ = [
    "LIFT_RADIUS_PCT",
    "LIFT_BEND_DEG",
    "lifted_points_mm",
    "lift_effects",
    "SHADOW_MAX_2SIGMA_MM",
    "SHADOW_WIDE_MAX_2SIGMA_MM",
    "ShadowRefusal",
    "shadow_unusable",
    "shadow_lift_scale",
    "MOVED_MAX_RMS_PX",
    "moved_lift",
]


#: What a lift may change before it is warned about: the parts targets.
LIFT_RADIUS_PCT = 0.3

LIFT_BEND_DEG = 0.03


def lifted_points_mm(
    plane: PlaneModel, points_px: np.ndarray, base_mm: float, lift: LiftEstimate, factor: float
) -> np.ndarray:
    """The centreline with each point on its own height (``factor`` x the lift), unrolled."""
    pts = points_at_heights_mm(plane, points_px, base_mm + factor * lift.height_mm)
    return unroll_mm(pts, (factor * lift.slope[0], factor * lift.slope[1]))


def lift_effects(
    plane: PlaneModel,
    points_px: np.ndarray,
    used_mm: np.ndarray,
    lift: LiftEstimate | None,
    ours: ArcResult,
    poly: PolylineFit | None,
    divisions: int | None,
    base_mm: float,
    max_lift_mm: float = MAX_LIFT_MM,
    standard: bool = False,
    fractions: np.ndarray | None = None,
) -> tuple[PartLift, np.ndarray | None, StageWarning | None]:
    """The lift's bound (:class:`PartLift`, used as a bound from the width's estimate), the
    bends' extra sigma (deg) and a warning (None when none).

    The lift is bounded by :func:`cvmeasure.part.lift.lift_bound_mm` (the width's
    estimate + 2 sigma, at most ``max_lift_mm``); its effect is the largest change of
    the radius and of each vertex bend when the part, rocked that much towards any of
    16 directions, is measured with each point on the plane of its own height (the
    tilted plane unrolled into the part's own) instead of flat. Half the worst change
    of each vertex bend is added to its sigma (so 2 sigma covers the bound); with
    ``standard`` (a measured lift whose 2 sigma is ``max_lift_mm``) half the rms change
    over the 16 directions instead: the standard uncertainty of a tilt error of one
    sigma in a direction not known.
    """

    def effect(other_mm: np.ndarray) -> tuple[float, float, np.ndarray | None]:
        try:
            res, _, p = arc_from_points(other_mm, divisions, fractions)
        except ValueError:
            return float("nan"), float("nan"), None
        d_r = 100.0 * (res.radius_mm / ours.radius_mm - 1.0)
        d_s = float((res.segment_bend_deg or 0.0) - (ours.segment_bend_deg or 0.0))
        if p is None or poly is None or len(p.bend_deg) != len(poly.bend_deg):
            return d_r, d_s, None
        return d_r, d_s, np.abs(np.asarray(p.bend_deg) - np.asarray(poly.bend_deg))

    bound = lift_bound_mm(lift, max_lift_mm)
    worst_r, worst_s = 0.0, 0.0
    changes: list[np.ndarray] = []  # each direction's change of every vertex bend
    if bound > 0:
        for direction in np.arange(0.0, 360.0, 22.5):
            rocked = rocked_lift(used_mm, float(direction), bound)
            d_r, d_s, d_b = effect(lifted_points_mm(plane, points_px, base_mm, rocked, 1.0))
            if not np.isfinite(d_r):
                continue
            worst_r, worst_s = max(worst_r, abs(d_r)), max(worst_s, abs(d_s))
            if d_b is not None:
                changes.append(d_b)
    worst_b = np.max(changes, axis=0) if changes else None
    worst_vertex = float(np.max(worst_b)) if worst_b is not None and len(worst_b) else 0.0
    estimate = lift.to_dict() if lift is not None else {}
    info = PartLift(
        used=LiftUse.BOUND,
        source=LiftSource.WIDTH,
        lift_mm=estimate.pop("lift_mm", None),
        lift_sigma_mm=estimate.pop("lift_sigma_mm", None),
        bound_mm=bound,
        effect_radius_pct=worst_r,
        effect_segment_bend_deg=worst_s,
        effect_bend_deg=worst_vertex,
        details=estimate,
    )
    warning = None
    if worst_r > LIFT_RADIUS_PCT or worst_s > LIFT_BEND_DEG or worst_vertex > LIFT_BEND_DEG:
        seen = (
            "the wire's apparent width gives no usable estimate"
            if lift is None or bound >= max_lift_mm
            else f"the wire's apparent width puts it at {lift.lift_mm:.2f} +- "
            f"{lift.lift_sigma_mm:.2f} mm"
        )
        warning = StageWarning(
            "part_lifted",
            f"the part may not lie flat and its lift is not measured ({seen}); "
            f"a lift of up to {bound:.1f} mm at one end would move the radius by up to "
            f"{worst_r:.2f} %, the bend per chord by up to {worst_s:.3f} deg and a vertex bend "
            f"by up to {worst_vertex:.3f} deg (half of it is in the vertex bends' sigmas): lay "
            "the part flat, or press it down, to measure it within "
            f"{LIFT_RADIUS_PCT} % / {LIFT_BEND_DEG} deg",
        )
    if worst_b is None:
        return info, None, warning
    if standard:
        return info, 0.5 * np.sqrt(np.mean(np.square(changes), axis=0)), warning
    return info, 0.5 * worst_b, warning


#: The shadow's lift (one photo, ``shadow_lift=True``) is corrected when its 2 sigma is at
#: most this (mm): the part's radius needs its mean height to about 1 mm (0.3 % of 550 mm
#: is 1.6 mm of camera distance).
SHADOW_MAX_2SIGMA_MM = 1.0

#: A shadow's lift wider than :data:`SHADOW_MAX_2SIGMA_MM` is still corrected when its 2
#: sigma is at most this (mm) (and :func:`shadow_unusable` finds it consistent): wider,
#: its stated effect on the radius (0.5-1.4 % for 2 sigma of 2-3 mm) is over the 0.3 %
#: target anyway, and the bound covers the lift by construction where the shadow covers it
#: at 2 sigma only (a flat part on a textured sheet can read 3.00 +- 1.43 mm).
SHADOW_WIDE_MAX_2SIGMA_MM = 2.0


@dataclass(frozen=True)
class ShadowRefusal:
    """Why a shadow's lift reading is not corrected (:func:`shadow_unusable`).

    ``message``: the reason in words; ``inconsistent``: the reading is more than 2 sigma
    above the lift bound (an edge misread), warned about whatever the bound's effect, where
    a reading only too uncertain to correct is named in the bound's own warning, if any.
    """

    message: str
    inconsistent: bool


def shadow_unusable(shadow: LiftEstimate, bound_mm: float) -> ShadowRefusal | None:
    """Why a shadow's lift is not corrected (None if it is).

    ``bound_mm``: the lift bound otherwise used (the width's estimate + 2 sigma, at most
    the largest lift a part rocks to), what the photo says about the lift without the
    shadow. Any reading more than 2 sigma above it is inconsistent with it and not used (a
    shadow edge taken for another: a full-size 3 mm lift once read 6.39 +- 1.20 mm, and a
    confident 7.42 +- 0.29 mm). A reading wider than :data:`SHADOW_MAX_2SIGMA_MM`
    is also not corrected when its 2 sigma is no smaller than that bound (it tells nothing
    the bound does not), or over :data:`SHADOW_WIDE_MAX_2SIGMA_MM`.
    """
    two_sigma = 2.0 * shadow.lift_sigma_mm
    if not np.isfinite(two_sigma) or two_sigma > SHADOW_WIDE_MAX_2SIGMA_MM:
        return ShadowRefusal(
            f"too uncertain to correct (2 sigma over {SHADOW_WIDE_MAX_2SIGMA_MM:.1f} mm)", False
        )
    if shadow.lift_mm - two_sigma > bound_mm:
        return ShadowRefusal(
            f"more than 2 sigma above the lift bound of {bound_mm:.1f} mm, inconsistent with "
            "it (a shadow edge taken for another?): not corrected",
            True,
        )
    if two_sigma > SHADOW_MAX_2SIGMA_MM and two_sigma >= bound_mm:
        return ShadowRefusal(
            f"too uncertain to correct (2 sigma is not below the bound of {bound_mm:.1f} mm)",
            False,
        )
    return None


def shadow_lift_scale(shadow: LiftEstimate, bound_mm: float) -> float:
    """The factor a shadow's lift is corrected with (1, or less when the lift is read above
    ``bound_mm``, the lift bound otherwise used: it is then scaled down to it)."""
    return min(1.0, bound_mm / max(shadow.lift_mm, 1e-9))


#: Two views of a slid part whose registered centrelines differ by more than this rms
#: (photo pixels) disagree beyond their noise (a centreline defect in one of them, e.g. an
#: edge lost to a shadow): their lift is not used. Measured on the round-wire renders at
#: half size: 0.08-0.12 px where the lift came out right, 0.43 px on one that read 6 mm
#: for 1.5 mm.
MOVED_MAX_RMS_PX = 0.25


def moved_lift(
    moved_image: np.ndarray,
    moved_plane: PlaneModel | None,
    board: BoardSpec | None,
    camera: CameraModel | None,
    plane: PlaneModel,
    points_px: np.ndarray,
    wire_diameter_mm: float,
    axis_height_mm: float | None,
    end_shape: EndShape,
    between_edges: bool,
) -> tuple[dict[str, Any], Any, StageWarning | None]:
    """The lift from a second photo of the slid part: (info, the MovedLift when usable, warning).

    ``between_edges``: the first photo's centres lie between the wire's silhouette edges
    (:attr:`cvmeasure.part.centreline.Centreline.between_edges`); only then is the two
    views' difference the lift.
    """
    plane2, _, centre2, _ = measure_centreline_mm(
        moved_image, board, camera, axis_height_mm=axis_height_mm, end_shape=end_shape,
        source="moved photo", wire_diameter_mm=wire_diameter_mm, plane=moved_plane,
    )  # fmt: skip
    if not (between_edges and centre2.between_edges):
        return (
            {"lift_mm": None, "message": "silhouette edges lost"},
            None,
            StageWarning(
                "moved_photo_unused",
                "the wire's silhouette edges were not found along the whole wire in "
                + ("the moved photo" if between_edges else "the first photo")
                + ": the profiles' centre of symmetry follows the highlight, which moves with "
                "the view, so the two views' difference is not the lift; the lift is bounded "
                "instead",
            ),
        )
    moved = estimate_lift_moved(
        plane, points_px, plane2, centre2.points_px,
        axis_height_mm=axis_height_for(axis_height_mm, wire_diameter_mm),
        wire_diameter_mm=wire_diameter_mm,
    )  # fmt: skip
    info = moved.to_dict()
    if moved.lift is None:
        return (
            info,
            None,
            StageWarning("moved_photo_unused", f"{moved.message}; the lift is bounded instead"),
        )
    rms_px = moved.residual_rms_mm / plane.mm_per_px
    info["residual_rms_px"] = rms_px
    if rms_px > MOVED_MAX_RMS_PX:
        return (
            info,
            None,
            StageWarning(
                "moved_photo_unused",
                f"the two views of the part disagree ({rms_px:.2f} px rms after registration > "
                f"{MOVED_MAX_RMS_PX} px: a centreline defect in one of them), so their lift "
                f"({moved.lift.lift_mm:.2f} mm) is not used; the lift is bounded instead",
            ),
        )
    return info, moved, None
