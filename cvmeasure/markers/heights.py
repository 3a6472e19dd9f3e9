"""Marker heights without a plane pose: the parallax they cause, bounded, and a correction.

With a plane pose each disc's edge is mapped to its own height above the plate
(:meth:`cvmeasure.contracts.PlaneModel.image_to_plane_mm`), exactly. Without one
(camera only, or image pixels) the angles are computed in the image, where a disc
``h`` mm above the plate appears where a plate point ``D / (D - h)`` times farther
from the camera's foot point would (``D`` the camera's distance from the plate,
mm): a homothety about the foot point, whatever the camera's tilt. Discs at
different heights are thus displaced differently, by ``h / D`` of their distance
from the foot point.

:func:`height_parallax` estimates ``D`` from each disc's apparent size and the
focal length (``D = f r_mm / r_px + h``), and computes

* the angles with every disc moved back to the plate about the principal point
  (the foot point of a camera square to the plate): the *parallel* correction;
* the worst angle change the heights cause for any foot point within
  ``f tan(tilt_deg)`` of the principal point (a camera tilted up to ``tilt_deg``):
  the bound of the uncorrected angles, and the bound of the corrected ones
  (what the foot point's unknown offset leaves).

Frames: centres in image or undistorted pixels (x right, y down as in the photo);
angles in degrees.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.geometry import wrap_deg
from cvmeasure.kit import ROLES, MarkerKit
from cvmeasure.markers.angles import pin_bend_deg
from cvmeasure.warning import StageWarning

__all__ = [
    "HeightParallax",
    "height_parallax",
    "BOUND_TILT_DEG",
    "fallback_focal_px",
    "height_angle_jacobian",
    "height_angle_variance_deg2",
    "heights_take_up_bias",
    "move_to_heights",
    "HEIGHT_WARN_DEG",
    "NOMINAL_HEIGHT_TOLERANCE",
    "plane_heights_sigma",
    "nominal_heights_bound",
    "other_plane_warning",
]

#: The camera tilt (deg, optical axis from the plate's normal) the no-pose bounds allow:
#: the camera's foot point anywhere within ``f tan(BOUND_TILT_DEG)`` of the principal point.
BOUND_TILT_DEG = 3.0
#: Height bounds (deg) below this are not warned about (the heights barely matter).
HEIGHT_WARN_DEG = 1e-3
#: How far printed caps may stand off a kit's nominal heights (a share of each height):
#: the bound stated beside the sigma while the heights are not measured.
NOMINAL_HEIGHT_TOLERANCE = 0.10
#: Foot-point directions sampled for the worst case (the change is near linear in it).
_DIRECTIONS = 24


def fallback_focal_px(size_px: tuple[int, int]) -> float:
    """Focal length (px) assumed without a camera: half the image diagonal.

    A 90 deg diagonal field of view; a longer lens (all but the widest) puts the
    camera farther for the same disc size, so the heights matter less and the
    bound computed with this focal length holds.
    """
    return 0.5 * math.hypot(*size_px)


@dataclass(frozen=True)
class HeightParallax:
    """What the markers' heights do to angles measured in the image (no plane pose).

    ``distance_mm`` is the camera's estimated distance from the plate (median over
    the discs); ``centres`` / ``covariances`` the centres moved back to the plate
    about the principal point (same frame as the input); ``bound_none_deg`` the
    worst angle change the heights cause (pin, bend), i.e. the bound of the
    uncorrected angles; ``bound_parallel_deg`` the worst error left after the
    parallel correction, both for a tilt up to ``tilt_deg``.
    """

    distance_mm: float
    centres: dict[str, np.ndarray]
    covariances: dict[str, np.ndarray]
    bound_none_deg: dict[str, float]
    bound_parallel_deg: dict[str, float]
    tilt_deg: float


def height_parallax(
    centres_px: Mapping[str, np.ndarray],
    covariances_px: Mapping[str, np.ndarray],
    radii_px: Mapping[str, float],
    kit: MarkerKit,
    *,
    focal_px: float,
    principal_point_px: tuple[float, float],
    y_down: bool = True,
    tilt_deg: float = BOUND_TILT_DEG,
) -> HeightParallax:
    """The heights' effect on angles measured in image (or undistorted) pixels.

    Parameters
    ----------
    centres_px, covariances_px : each role's disc centre (2,) and its covariance (2, 2), px.
    radii_px : each role's disc radius, px (its apparent size gives the distance).
    kit : the kit (heights and diameters, mm).
    focal_px : focal length, px (:func:`fallback_focal_px` without a camera).
    principal_point_px : where the optical axis meets the image, px.
    tilt_deg : the largest camera tilt the bounds allow for.
    """
    pp = np.asarray(principal_point_px, dtype=np.float64)
    heights = {r: kit.height_mm(r) for r in ROLES}
    dist = [
        focal_px * 0.5 * kit.by_role(r).diameter_mm / float(radii_px[r]) + heights[r] for r in ROLES
    ]
    d_mm = float(np.median(dist))
    shrink = {r: (d_mm - heights[r]) / d_mm for r in ROLES}
    c = {r: np.asarray(centres_px[r], dtype=np.float64).reshape(2) for r in ROLES}

    raw = pin_bend_deg(c, y_down=y_down)
    reach = focal_px * math.tan(math.radians(tilt_deg))
    t = np.linspace(0.0, 2 * math.pi, _DIRECTIONS, endpoint=False)
    # the principal point first (the parallel correction), then the circle of foot points
    feet = np.vstack((pp, pp + reach * np.column_stack((np.cos(t), np.sin(t)))))
    # the angles with every disc moved towards each foot point by its shrink
    a = pin_bend_deg({r: feet + (c[r] - feet) * shrink[r] for r in ROLES}, y_down=y_down)
    corrected = a[0]
    worst_none = np.abs(wrap_deg(raw - a)).max(axis=0)
    worst_par = np.abs(wrap_deg(corrected - a)).max(axis=0)
    keys = ("pin_angle_deg", "bend_angle_deg")
    return HeightParallax(
        d_mm,
        {r: pp + (c[r] - pp) * shrink[r] for r in ROLES},
        {r: np.asarray(covariances_px[r]) * shrink[r] ** 2 for r in ROLES},
        {k: float(v) for k, v in zip(keys, worst_none, strict=True)},
        {k: float(v) for k, v in zip(keys, worst_par, strict=True)},
        float(tilt_deg),
    )


def move_to_heights(
    centres_mm: Mapping[str, np.ndarray],
    from_mm: Mapping[str, float],
    to_mm: Mapping[str, float],
    camera_centre_mm: np.ndarray,
) -> dict[str, np.ndarray]:
    """Plate-frame centres measured at heights ``from_mm`` moved to heights ``to_mm``.

    Along each pixel's ray, the planes at heights ``a`` and ``b`` above the plate are a
    homothety about the camera's foot point with factor ``(Z - b) / (Z - a)`` (``Z`` the
    camera's height above the plate): a circle's centre maps exactly. ``camera_centre_mm``
    is the camera's centre in the plate frame (``PlaneModel.camera_centre_mm``; its z
    sign does not matter).
    """
    c = np.asarray(camera_centre_mm, dtype=np.float64).reshape(3)
    foot, z = c[:2], abs(float(c[2]))
    return {
        r: foot + (np.asarray(p, dtype=np.float64) - foot) * (z - to_mm[r]) / (z - from_mm[r])
        for r, p in centres_mm.items()
    }


def height_angle_jacobian(
    centres_mm: Mapping[str, np.ndarray],
    kit: MarkerKit,
    camera_centre_mm: np.ndarray,
    *,
    y_down: bool = True,
    step_mm: float = 0.5,
) -> np.ndarray:
    """d(pin, bend angle)/d(height) (2, 5), deg/mm, for the heights in :data:`ROLES` order.

    ``centres_mm`` are the centres on the plate measured at the kit's heights.
    Central differences of ``step_mm`` (the angles are near linear in the heights).
    """
    heights = {r: kit.height_mm(r) for r in ROLES}
    jac = np.zeros((2, len(ROLES)))
    for j, role in enumerate(ROLES):
        ends = []
        for sign in (1.0, -1.0):
            to = dict(heights)
            to[role] = heights[role] + sign * step_mm
            moved = move_to_heights({role: centres_mm[role]}, heights, to, camera_centre_mm)
            ends.append(pin_bend_deg({**centres_mm, **moved}, y_down=y_down))
        jac[:, j] = wrap_deg(ends[0] - ends[1]) / (2 * step_mm)
    return jac


def height_angle_variance_deg2(
    centres_mm: Mapping[str, np.ndarray],
    kit: MarkerKit,
    camera_centre_mm: np.ndarray,
    *,
    y_down: bool = True,
) -> dict[str, float]:
    """The angles' variance (deg^2) the kit's height uncertainties cause, on a plane pose.

    ``J C J^T`` with ``J`` from :func:`height_angle_jacobian` and ``C`` the kit's height
    covariance (:meth:`cvmeasure.kit.MarkerKit.height_cov_mm2`; zeros for exact or flat
    heights). Keys ``pin_angle_deg`` and ``bend_angle_deg``.
    """
    cov = kit.height_cov_mm2()
    if not np.any(cov):
        return {"pin_angle_deg": 0.0, "bend_angle_deg": 0.0}
    jac = height_angle_jacobian(centres_mm, kit, camera_centre_mm, y_down=y_down)
    var = np.diag(jac @ cov @ jac.T)
    return {"pin_angle_deg": float(var[0]), "bend_angle_deg": float(var[1])}


def heights_take_up_bias(
    covariances_mm2: Mapping[str, np.ndarray],
    bias_mm2: Mapping[str, np.ndarray],
    kit: MarkerKit,
    plane_pose: tuple[Any, Any],
) -> dict[str, np.ndarray]:
    """The centres' covariances on a plane pose, less their pose-constant part where the
    kit's heights were measured through this plane; else unchanged.

    A centre's covariance is a per-photo part (the edge fit's sampling, what a partly
    hidden disc's halves disagree on) and a pose-constant one (``bias_mm2``: the edge's
    shift from the disc's wall, shading, blur and colour, the same on every photo from
    one pose, :func:`cvmeasure.markers.measure.unseen_bias_cov`). Heights fitted
    through this plane (``cvmeasure markers heights``) were fitted to centres carrying
    that bias, and the plane's own errors, on every photo of the sweep: they take both
    up, and a photo from the same pose, carrying them again, has them cancel (caps at
    known heights on the benchmark's scenes: pin error -0.003 deg on every photo of a
    pose with the true heights, +0.001 with the measured ones, the scatter unchanged).
    What the fit leaves is in the heights' covariance, which :func:`plane_heights_sigma`
    carries through the geometry; counting the bias again stated the angles' sigma a
    quarter to a half too wide. ``plane_pose``: this plane's ``(rvec, tvec_mm)``.
    """
    pose = kit.heights_pose
    if pose is None or not pose.matches(*plane_pose):
        return dict(covariances_mm2)
    return {
        role: np.asarray(cov) - bias_mm2.get(role, np.zeros((2, 2)))
        for role, cov in covariances_mm2.items()
    }


def plane_heights_sigma(
    centres: Mapping[str, np.ndarray],
    kit: MarkerKit,
    camera_centre_mm: np.ndarray,
    y_down: bool,
    sigma: dict[str, float],
    warnings: list[StageWarning],
    plane_pose: tuple[Any, Any] | None = None,
) -> tuple[dict[str, float], dict[str, float] | None]:
    """On a plane pose: the kit's height uncertainties (measured or stated) carried into
    the angles' sigma (a stated sigma of 0: heights known exactly, nothing added); nominal
    heights bounded beside it instead (and warned about). ``plane_pose``: the plane's
    ``(rvec, tvec_mm)``; heights measured through another plane are warned about
    (:func:`other_plane_warning`)."""
    var = height_angle_variance_deg2(centres, kit, camera_centre_mm, y_down=y_down)
    if plane_pose is not None and (warning := other_plane_warning(kit, *plane_pose)):
        warnings.append(warning)
    sigma = {k: math.hypot(v, math.sqrt(var[k])) for k, v in sigma.items()}
    if kit.heights_stated:
        return sigma, None
    return sigma, nominal_heights_bound(centres, kit, camera_centre_mm, y_down, warnings)


def other_plane_warning(kit: MarkerKit, rvec: Any, tvec_mm: Any) -> StageWarning | None:
    """``heights_other_plane`` when the kit's heights were measured through a plane other
    than the one of pose (``rvec``, ``tvec_mm``), else None.

    Heights fitted through a plane take up the errors that plane puts on every photo;
    through the same plane those cancel, through another they stay in the heights and
    move the angles by an amount their stated uncertainty does not hold (only the
    heights' own scatter is in it).
    """
    pose = kit.heights_pose
    if pose is None or pose.matches(rvec, tvec_mm):
        return None
    return StageWarning(
        "heights_other_plane",
        "the kit's heights were measured through another plane (markers heights --plane): "
        "they carry that plane's errors, which this plane does not cancel, so the angles "
        "may be off by more than the +-; measure the heights again through this plane, "
        "or measure through the plane they were measured with",
        "kit",
    )


def nominal_heights_bound(
    centres: Mapping[str, np.ndarray],
    kit: MarkerKit,
    camera_centre_mm: np.ndarray,
    y_down: bool,
    warnings: list[StageWarning],
) -> dict[str, float] | None:
    """What caps standing up to :data:`NOMINAL_HEIGHT_TOLERANCE` off a kit's nominal
    (unmeasured) heights can do to the angles, deg; warned about beside the sigma."""
    jac = height_angle_jacobian(centres, kit, camera_centre_mm, y_down=y_down)
    tol = np.array([NOMINAL_HEIGHT_TOLERANCE * kit.height_mm(r) for r in ROLES])
    bound = {
        "pin_angle_deg": float(np.abs(jac[0]) @ tol),
        "bend_angle_deg": float(np.abs(jac[1]) @ tol),
    }
    if max(bound.values()) < HEIGHT_WARN_DEG:
        return None
    warnings.append(
        StageWarning(
            "heights_nominal",
            f"the +- leaves out the kit's heights, which are nominal, not measured: caps "
            f"standing up to {100 * NOMINAL_HEIGHT_TOLERANCE:.0f} % off them can add up to "
            f"{bound['pin_angle_deg']:.3f} deg (pin) and {bound['bend_angle_deg']:.3f} deg "
            "(bend) of error (height_bound_deg): measure them once with `cvmeasure markers "
            "heights` (or give each height_sigma_mm) to remove this bound",
            "kit",
        )
    )
    return bound
