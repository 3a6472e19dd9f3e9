"""A part that does not lie flat: its lift read from the wire's apparent width.

A bent part rocks: it rests on the plate at its lowest points and one end lifts
(0-3 mm). A point lifted by ``h`` and mapped to the plate as if it lay there moves
about the camera's foot point by about ``h / distance`` of its offset (0.5 % of
the offset at 3 mm and 550 mm), which bends the measured part. The wire's
apparent width tells how far each point is from the camera: ``width_px ~ f d / D``
(``d`` the diameter, ``D`` the distance from the camera to the wire's axis), so a
lifted end looks wider by ``h / D``.

Model: the part is rigid and planar, so its lift is an affine function of plate
position, ``h = b x + c y + const``, zero at its lowest point (it rests there).
Per centreline point the width expected for the axis at the resting height is
computed through the plane's camera (the two silhouette generators projected with
the lens' distortion), and ``ln(measured / expected) = alpha + g (b x + c y)``
(``g`` = d ln width / d h, per point) is fitted by least squares; ``alpha`` takes
the unknown diameter error and any constant bias of the edges. The standard
uncertainty of ``(b, c)`` counts one independent sample per wire diameter along
the part (the edges' errors are correlated over about that length).

How it is used (:func:`cvmeasure.part.measure.measure_part`): as a **bound**, not a
correction. The lift is bounded by the estimate + 2 sigma, at most
:data:`MAX_LIFT_MM` (:func:`lift_bound_mm`); the part is measured on the resting
plane, and the largest change of its radius and bends when it is rocked that much
towards any direction (:func:`rocked_lift`; each point mapped to the plane of its
own height, the tilted plane unrolled into the part's own) is reported, added to
the bends' sigmas and warned about when it exceeds the targets (0.3 % radius,
0.03 deg bend). Why not correct: a correction needs the lift to about 0.5 mm (a
2 mm lift moves the radius by 0.15-0.76 % at 900 mm, almost all perspective), and
on ray-traced round wires lit from the side the silhouette edges' shading bias
changes with the wire's direction to the light by a few hundredths of a pixel,
which reads as 13-16 mm of lift on flat parts (full size, 19 px wire); a cast
shadow fit did not do better (docs/part-measurement.md).

Two photos of the part slid on the plate between them do measure it
(:func:`estimate_lift_moved`): the perspective difference of the two views is
``(foot shift / distance) x h(p)``, a non-rigid field for a tilted part; then the lift
is corrected (``cvmeasure part --moved``). Frames: board frame (mm), heights towards
the camera.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.spatial import cKDTree

from cvmeasure.contracts import PlaneModel
from cvmeasure.geometry import arclength_mm
from cvmeasure.part.compare import PolylineIndex, kabsch, resample_by_length

__all__ = [
    "MAX_LIFT_MM",
    "MIN_FOOT_SHIFT_MM",
    "MovedLift",
    "estimate_lift_moved",
    "LiftEstimate",
    "estimate_lift",
    "expected_width_px",
    "lift_bound_mm",
    "points_at_heights_mm",
    "rocked_lift",
]

#: The largest lift a finished part is taken to rock to (mm) when its lift is not
#: measured better: issue 14's range for a bent part lying on the plate (0-3 mm).
MAX_LIFT_MM = 3.0


@dataclass(frozen=True)
class LiftEstimate:
    """The part's lift above the plate along its centreline.

    Attributes
    ----------
    height_mm : ndarray (M,) lift of the axis above its resting height at each
        centreline point (0 at the lowest), mm.
    slope : (b, c), mm of lift per mm of board x and y.
    slope_cov : (2, 2) covariance of ``slope``.
    lift_mm : the largest lift along the part, mm.
    lift_sigma_mm : its standard uncertainty, mm.
    samples : centreline points with a width.
    width_scale : measured / expected width (exp(alpha)): the edges' bias and the
        diameter's error together.
    """

    height_mm: np.ndarray
    slope: tuple[float, float]
    slope_cov: np.ndarray
    lift_mm: float
    lift_sigma_mm: float
    samples: int
    width_scale: float

    @property
    def significant(self) -> bool:
        """True when the lift exceeds twice its uncertainty."""
        return self.lift_mm > 2.0 * self.lift_sigma_mm

    def to_dict(self) -> dict[str, Any]:
        return {
            "lift_mm": self.lift_mm,
            "lift_sigma_mm": self.lift_sigma_mm,
            "slope_mm_per_mm": list(self.slope),
            "samples": self.samples,
            "width_scale": self.width_scale,
        }


def points_at_heights_mm(plane: PlaneModel, points_px: np.ndarray, height_mm: Any) -> np.ndarray:
    """Photo pixels (M, 2) -> board mm (M, 2), each on the plane of its own height (M,) mm.

    Along a ray the board point is affine in the height, so two intersections give all.
    """
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    h = np.broadcast_to(np.asarray(height_mm, dtype=np.float64), (len(pts),))
    at0 = plane.image_to_plane_mm(pts, height_mm=1e-9)
    at1 = plane.image_to_plane_mm(pts, height_mm=1.0)
    return at0 + h[:, None] * (at1 - at0)


def silhouette_sides(plane: PlaneModel, xyz_mm: np.ndarray, tangent: np.ndarray) -> np.ndarray:
    """Unit directions (M, 3) from a round wire's axis to its silhouette generators.

    ``xyz_mm`` (M, 3): axis points in the board frame; ``tangent`` (M, 3): the axis'
    direction there. The generators lie ``+-radius`` along these directions, which are
    perpendicular to the axis and to the line of sight from the camera's centre.
    """
    side = np.cross(tangent, xyz_mm - plane.camera_centre_mm)
    side /= np.maximum(np.linalg.norm(side, axis=1), 1e-12)[:, None]
    return side


def expected_width_px(
    plane: PlaneModel, points_mm: np.ndarray, height_mm: Any, wire_diameter_mm: float
) -> np.ndarray:
    """Apparent width (M,) in photo pixels of a wire of ``wire_diameter_mm`` along an axis.

    ``points_mm`` (M, 2) ordered along the axis, board frame, at ``height_mm`` (scalar or
    (M,)) above the plate: the two silhouette generators (the axis offset by the radius
    perpendicular to the axis and to the line of sight) projected with the lens.
    """
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    h = np.broadcast_to(np.asarray(height_mm, dtype=np.float64), (len(pts),))
    xyz = np.column_stack((pts, -h))  # board z points away from the camera
    axis = np.gradient(xyz, axis=0)
    axis /= np.maximum(np.linalg.norm(axis, axis=1), 1e-12)[:, None]
    side = silhouette_sides(plane, xyz, axis)
    r = 0.5 * wire_diameter_mm
    both = np.vstack((xyz + r * side, xyz - r * side))
    px = plane.plane_to_image_px(both)
    return np.hypot(*(px[: len(pts)] - px[len(pts) :]).T)


def estimate_lift(
    plane: PlaneModel,
    points_px: np.ndarray,
    width_px: np.ndarray,
    *,
    wire_diameter_mm: float,
    axis_height_mm: float,
) -> LiftEstimate | None:
    """The part's lift from the apparent widths (M,) at its centreline points (M, 2) px.

    ``axis_height_mm`` is the axis' height where the part rests (the wire's radius
    for a part on the plate). None when fewer than 20 points have a width.
    """
    pts_px = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    widths = np.asarray(width_px, dtype=np.float64).reshape(-1)
    mm = points_at_heights_mm(plane, pts_px, axis_height_mm)
    ok = np.isfinite(widths) & (widths > 0)
    if ok.sum() < 20:
        return None
    w0 = expected_width_px(plane, mm, axis_height_mm, wire_diameter_mm)
    w1 = expected_width_px(plane, mm, axis_height_mm + 1.0, wire_diameter_mm)
    g = np.log(w1 / w0)  # d ln(width) / d h, per mm
    y = np.log(widths[ok] / w0[ok])
    xy = mm[ok] - mm[ok].mean(axis=0)
    design = np.column_stack((np.ones(ok.sum()), g[ok, None] * xy))
    weights = np.ones(ok.sum())
    for _ in range(5):  # Tukey-weighted least squares: a few bad edges do not tilt the part
        sw = np.sqrt(weights)
        coef, *_ = np.linalg.lstsq(design * sw[:, None], y * sw, rcond=None)
        res = y - design @ coef
        scale = 1.4826 * float(np.median(np.abs(res - np.median(res)))) + 1e-12
        u = res / (4.685 * scale)
        weights = np.where(np.abs(u) < 1, (1 - u * u) ** 2, 0.0)
    used = weights > 0
    # one independent sample per wire diameter along the part
    step = np.hypot(*np.diff(mm[ok], axis=0).T)
    n_eff = max(3.0, float(np.sum(step)) / wire_diameter_mm) * used.mean()
    sigma2 = float(np.sum(weights * res**2) / max(np.sum(weights) - 3, 1.0))
    cov = np.linalg.inv((design[used].T @ design[used]) * n_eff / used.sum()) * sigma2
    slope = (float(coef[1]), float(coef[2]))
    rel = (mm - mm[ok].mean(axis=0)) @ np.asarray(slope)
    low = int(np.argmin(rel[ok]))
    high = int(np.argmax(rel[ok]))
    height = rel - rel[ok][low]
    # the lift's uncertainty: the slope's along the line from the lowest to the highest point
    span = mm[ok][high] - mm[ok][low]
    lift_sigma = float(np.sqrt(span @ cov[1:, 1:] @ span))
    return LiftEstimate(
        height_mm=height,
        slope=slope,
        slope_cov=cov[1:, 1:],
        lift_mm=float(height[ok].max()),
        lift_sigma_mm=lift_sigma,
        samples=int(used.sum()),
        width_scale=float(np.exp(coef[0])),
    )


def unroll_mm(points_mm: np.ndarray, slope: tuple[float, float]) -> np.ndarray:
    """Board-plane points (M, 2) of a part on the tilted plane ``h = b x + c y`` -> its own plane.

    Distances along the slope's direction are lengthened by ``sqrt(1 + |slope|^2)``
    (the plane's foreshortening); across it they are kept.
    """
    pts = np.asarray(points_mm, dtype=np.float64)
    grad = np.asarray(slope, dtype=np.float64)
    g = float(np.hypot(*grad))
    if g == 0.0:
        return pts.copy()
    e = grad / g
    along = (pts - pts.mean(axis=0)) @ e
    return pts + ((np.sqrt(1.0 + g * g) - 1.0) * along)[:, None] * e


def rocked_lift(points_mm: np.ndarray, direction_deg: float, lift_mm: float) -> LiftEstimate:
    """A rigid planar part rocked towards ``direction_deg`` (board frame): exact heights.

    The part (its centreline (M, 2), board mm) rests at its point least far along the
    direction and rises linearly to ``lift_mm`` at the point farthest along it. Used to
    bound the effect of a lift that is not measured (uncertainty 0).
    """
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    u = np.array([np.cos(np.radians(direction_deg)), np.sin(np.radians(direction_deg))])
    along = pts @ u
    span = float(along.max() - along.min())
    grad = lift_mm / span if span > 0 else 0.0
    return LiftEstimate(
        height_mm=grad * (along - along.min()),
        slope=(float(grad * u[0]), float(grad * u[1])),
        slope_cov=np.zeros((2, 2)),
        lift_mm=float(lift_mm),
        lift_sigma_mm=0.0,
        samples=len(pts),
        width_scale=float("nan"),
    )


def lift_bound_mm(estimate: LiftEstimate | None, max_lift_mm: float = MAX_LIFT_MM) -> float:
    """How far the part may be lifted (mm): the estimate + 2 sigma, at most ``max_lift_mm``.

    No estimate: ``max_lift_mm``. Measured on the photo lab's ray-traced 3 mm wires at
    900 mm (full size), the width's estimate on flat parts is 13-16 mm +- 2.5-5 mm, so
    there the bound is ``max_lift_mm``: the width cannot measure a lift of 0-3 mm.
    """
    if estimate is None or not np.isfinite(estimate.lift_sigma_mm):
        return float(max_lift_mm)
    return float(min(max_lift_mm, estimate.lift_mm + 2.0 * estimate.lift_sigma_mm))


#: A second photo whose motion moves the camera's foot point less than this (mm) does not
#: measure a lift: the cue is ``foot shift / distance`` x the lift (at 20 mm and 600 mm, a
#: 0.5 mm lift is 0.017 mm of difference, a tenth of a pixel at full size).
MIN_FOOT_SHIFT_MM = 20.0


@dataclass(frozen=True)
class MovedLift:
    """The part's lift from two photos of it, slid on the plate between them.

    Attributes
    ----------
    lift : the lift along the first photo's centreline (heights 0 at the lowest point,
        ``slope`` in mm per board mm, ``lift_sigma_mm``); None when the photos do not
        measure it (``message`` says why).
    rotation_deg, shift_mm : the part's rigid motion on the plate from the second photo
        to the first (``first = R second + shift``, board frame), degrees and mm.
    foot_shift_mm : how far that motion moves the point under the camera, mm: the cue's
        lever (the perspective difference is ``foot_shift / distance`` x the height).
    distance_mm : the camera's height above the plate, mm.
    residual_rms_mm : rms distance of the registered second centreline from the first, mm.
    samples : second-photo points used.
    message : '' when measured, else why not.
    """

    lift: LiftEstimate | None
    rotation_deg: float
    shift_mm: tuple[float, float]
    foot_shift_mm: float
    distance_mm: float
    residual_rms_mm: float
    samples: int
    message: str = ""

    def to_dict(self) -> dict[str, Any]:
        return {
            **(self.lift.to_dict() if self.lift is not None else {"lift_mm": None}),
            "rotation_deg": self.rotation_deg,
            "shift_mm": list(self.shift_mm),
            "foot_shift_mm": self.foot_shift_mm,
            "distance_mm": self.distance_mm,
            "residual_rms_mm": self.residual_rms_mm,
            "samples": self.samples,
            "message": self.message,
        }


def _rigid(theta: float, shift: np.ndarray, pts: np.ndarray) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return pts @ np.array([[c, s], [-s, c]]) + shift


def _register_rigid(src: np.ndarray, dst: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """Rigid (angle rad, shift) taking the curve ``src`` onto ``dst`` (ICP to the curve),
    and the mask of ``src`` points whose foot lies inside ``dst`` (2 mm from its ends)."""
    a = resample_by_length(src, 200)
    b = resample_by_length(dst, 200)
    best = None
    for cand in (a, a[::-1]):
        r, t = kabsch(cand, b, mirror=False)
        rms = float(np.sqrt(np.mean(np.sum((cand @ r.T + t - b) ** 2, axis=1))))
        if best is None or rms < best[0]:
            best = (rms, r, t)
    _, r, t = best
    index = PolylineIndex(dst)
    for _ in range(30):
        moved = src @ r.T + t
        r, t = kabsch(src, index.feet(moved), mirror=False)
    theta = float(np.arctan2(r[1, 0], r[0, 0]))
    feet = index.feet(src @ r.T + t)
    s = arclength_mm(dst)
    d_start = np.hypot(*(feet - dst[0]).T)
    d_end = np.hypot(*(feet - dst[-1]).T)
    inside = (d_start > 2.0) & (d_end > 2.0) & (s[-1] > 4.0)
    return theta, t, inside


def _signed_distance(points: np.ndarray, curve: np.ndarray) -> np.ndarray:
    """Signed distance (N,) of points from a dense curve (M, 2), left of travel positive."""
    feet = PolylineIndex(curve).feet(points)
    tangent = np.gradient(curve, axis=0)
    _, k = cKDTree(curve).query(points)
    tg = tangent[k] / np.maximum(np.linalg.norm(tangent[k], axis=1), 1e-12)[:, None]
    rel = points - feet
    return tg[:, 0] * rel[:, 1] - tg[:, 1] * rel[:, 0]


def _fit_without_outliers(residual: Any, x: np.ndarray, n: int) -> tuple[Any, np.ndarray]:
    """Least squares of ``residual(x, used)`` over ``n`` points, refitted without the points
    a centreline defect puts off (beyond 4 robust sigmas); the final fit and the points used."""
    scale = np.array([1e-4, 0.05, 0.05, 0.1, 0.1])
    used = np.ones(n, dtype=bool)
    for _ in range(3):
        fit = least_squares(residual, x, args=(used,), x_scale=scale, diff_step=1e-6)
        x = fit.x
        every = residual(x, np.ones_like(used))
        med = float(np.median(every))
        used = np.abs(every - med) < 4.0 * 1.4826 * float(np.median(np.abs(every - med))) + 1e-9
    return least_squares(residual, x, args=(used,), x_scale=scale, diff_step=1e-6), used


def estimate_lift_moved(
    plane: PlaneModel,
    points_px: np.ndarray,
    plane_moved: PlaneModel,
    points_moved_px: np.ndarray,
    *,
    axis_height_mm: float,
    wire_diameter_mm: float,
    min_foot_shift_mm: float = MIN_FOOT_SHIFT_MM,
) -> MovedLift:
    """The part's lift from its centreline in two photos, the part slid between them.

    ``points_px`` (M, 2) and ``points_moved_px`` (K, 2): the wire's centreline in the
    first and the second photo (ordered along the wire), each photo with its plane.
    The part is rigid and planar and keeps its rocking pose when slid (its lift an
    affine function of position on the part, 0 at its lowest point). A point ``h`` up
    images ``h / D`` farther from the camera's foot point; mapped to the plate, the
    two views of the part then differ by a rigid motion plus ``(foot shift / D) h(p)``,
    which for a tilted part is a non-rigid (linear) field no rigid motion absorbs. So
    the tilt (2 parameters) and the rigid motion (3) are fitted together by robust
    least squares: the first photo's points and the second's, each mapped to the plane
    of its own height, moved onto the first by the rigid motion, at the least normal
    distance from the first photo's centreline. The lift's constant is not observable
    (it scales both views alike): the part rests at its lowest point, height 0. The
    standard uncertainty counts one independent sample per wire diameter along the
    part. ``axis_height_mm``: the axis' height where the part rests (the wire's radius).
    """
    p1 = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
    p2 = np.asarray(points_moved_px, dtype=np.float64).reshape(-1, 2)
    q1 = points_at_heights_mm(plane, p1, axis_height_mm)
    q2 = points_at_heights_mm(plane_moved, p2, axis_height_mm)
    centre = plane.camera_centre_mm
    foot, distance = centre[:2], float(abs(centre[2]))
    theta0, shift0, inside = _register_rigid(q2, q1)
    # the motion first -> second moves the foot point F to R^-1 (F - shift)
    c0, s0 = np.cos(theta0), np.sin(theta0)
    r0 = np.array([[c0, -s0], [s0, c0]])
    foot_shift = float(np.hypot(*(r0.T @ (foot - shift0) - foot)))
    res0 = _signed_distance(_rigid(theta0, shift0, q2[inside]), q1)
    rms0 = float(np.sqrt(np.mean(res0**2))) if inside.any() else float("nan")
    base = MovedLift(None, float(np.degrees(theta0)), (float(shift0[0]), float(shift0[1])),
                     foot_shift, distance, rms0, int(inside.sum()))  # fmt: skip
    if inside.sum() < 20:
        return replace(base, message="the two centrelines do not overlap")
    if foot_shift < min_foot_shift_mm:
        return replace(
            base,
            message=f"the part was not moved between the photos (the point under the camera "
            f"moves {foot_shift:.1f} mm < {min_foot_shift_mm:.0f} mm): its lift cannot be "
            "measured from them",
        )
    mid = q1.mean(axis=0)

    def heights(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        slope = x[3:5] * 1e-2  # parameters in % (of mm per mm)
        h1 = (q1 - mid) @ slope
        low = float(h1.min())
        h2 = (_rigid(x[0], x[1:3], q2[inside]) - mid) @ slope
        return h1 - low, h2 - low

    def residual(x: np.ndarray, keep: np.ndarray) -> np.ndarray:
        h1, h2 = heights(x)
        x1 = points_at_heights_mm(plane, p1, axis_height_mm + h1)
        x2 = points_at_heights_mm(plane_moved, p2[inside][keep], axis_height_mm + h2[keep])
        return _signed_distance(_rigid(x[0], x[1:3], x2), x1)

    x = np.array([theta0, shift0[0], shift0[1], 0.0, 0.0])
    fit, used = _fit_without_outliers(residual, x, int(inside.sum()))
    res = fit.fun
    jac = fit.jac
    sigma2 = float(np.sum(res**2) / max(used.sum() - 5, 1))
    length = float(np.sum(np.hypot(*np.diff(q2[inside], axis=0).T)))
    n_eff = max(6.0, length / wire_diameter_mm)
    cov = np.linalg.pinv(jac.T @ jac) * sigma2 * used.sum() / n_eff
    slope = fit.x[3:5] * 1e-2
    slope_cov = cov[3:5, 3:5] * 1e-4
    h1, _ = heights(fit.x)
    rel = (q1 - mid) @ slope
    span = q1[int(np.argmax(rel))] - q1[int(np.argmin(rel))]
    lift = LiftEstimate(
        height_mm=h1,
        slope=(float(slope[0]), float(slope[1])),
        slope_cov=slope_cov,
        lift_mm=float(h1.max()),
        lift_sigma_mm=float(np.sqrt(span @ slope_cov @ span)),
        samples=int(used.sum()),
        width_scale=float("nan"),
    )
    return replace(
        base,
        lift=lift,
        rotation_deg=float(np.degrees(fit.x[0])),
        shift_mm=(float(fit.x[1]), float(fit.x[2])),
        residual_rms_mm=float(np.sqrt(np.mean(res**2))),
        samples=int(used.sum()),
    )
