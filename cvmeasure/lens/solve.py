"""Camera calibration from board detections: model choice and iterative rejection.

The solve is OpenCV 5's ``calibrateCameraExtended`` (Zhang's method followed by
Levenberg-Marquardt) with one of six distortion models (k1 only up to thin prism), wrapped in a loop that
drops outlier corners (residual beyond 4 robust sigmas from the median residual
of the corner's board neighbours, so smooth model error is not mistaken for bad
corners; sigma the larger of the pooled and the corner's own view's, since blur and
distance make some views noisier) and bad views (RMS above
3x the median view RMS, or too few corners left) and solves again. Each round judges
every detected corner of the remaining views again, so the kept set is a fixed point
of the rule rather than an erosion of the residuals' tails.

References
----------
Z. Zhang, "A flexible new technique for camera calibration", IEEE TPAMI 22(11),
2000, doi:10.1109/34.888718.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import cv2
import numpy as np

from cvmeasure.camera_model import CameraModel
from cvmeasure.errors import InputError
from cvmeasure.lens.detect import MIN_CORNERS, BoardDetection
from cvmeasure.lens.warp import refine_board_warp

__all__ = [
    "DistortionModel",
    "DISTORTION_MODELS",
    "INTRINSIC_NAMES",
    "ViewResult",
    "RejectedView",
    "CalibrationResult",
    "calibrate_views",
    "model_flags",
    "view_residuals_px",
    "tilt_deg_from_rvec",
    "MIN_VIEWS",
]

DistortionModel = Literal["1", "2", "5", "8", "rational", "thin-prism"]

#: Model name -> (description, number of free distortion coefficients), simplest first.
DISTORTION_MODELS: dict[str, tuple[str, int]] = {
    "1": ("k1 (radial, one term)", 1),
    "2": ("k1 k2 (radial, two terms)", 2),
    "5": ("k1 k2 p1 p2 k3", 5),
    "8": ("rational: k1 k2 p1 p2 k3 k4 k5 k6", 8),
    "rational": ("rational: k1 k2 p1 p2 k3 k4 k5 k6", 8),
    "thin-prism": ("rational + thin prism: k1..k6, s1..s4", 12),
}

#: Names of the 18 intrinsics whose standard deviations OpenCV returns, in its order.
INTRINSIC_NAMES = (
    "fx", "fy", "cx", "cy", "k1", "k2", "p1", "p2", "k3",
    "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tau_x", "tau_y",
)  # fmt: skip

#: Fewest usable views a calibration accepts.
MIN_VIEWS = 3

_OUTLIER_SIGMAS = 4.0
_OUTLIER_FLOOR_PX = 0.25
_VIEW_RMS_FACTOR = 3.0
_VIEW_RMS_FLOOR_PX = 0.5
#: A corner dropped in an earlier round comes back only when its residual is within this
#: fraction of the limit (hysteresis: corners right at the limit do not flip every round).
_READMIT = 0.8


def model_flags(model: str) -> int:
    """OpenCV calibration flags for a distortion model name (see :data:`DISTORTION_MODELS`).

    ``CALIB_DISABLE_SCHUR_COMPLEMENT`` is never used: in OpenCV 5.0.0 it has the
    same value as ``CALIB_TILTED_MODEL`` (0x40000) and silently frees tau_x, tau_y.
    """
    if model not in DISTORTION_MODELS:
        raise ValueError(
            f"unknown distortion model {model!r}; choose one of {list(DISTORTION_MODELS)}"
        )
    if model == "1":
        return cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if model == "2":
        return cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
    if model == "5":
        return 0
    if model in ("8", "rational"):
        return cv2.CALIB_RATIONAL_MODEL
    return cv2.CALIB_RATIONAL_MODEL | cv2.CALIB_THIN_PRISM_MODEL


def tilt_deg_from_rvec(rvec: np.ndarray) -> float:
    """Angle between the board normal and the optical axis, degrees (0 = fronto-parallel)."""
    rot, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
    return float(np.degrees(np.arccos(np.clip(abs(rot[2, 2]), 0.0, 1.0))))


@dataclass(frozen=True)
class ViewResult:
    """One view used by the solve: its error and the board pose (camera <- board)."""

    source: str
    rms_px: float
    corner_count: int
    corners_rejected: int
    tilt_deg: float
    rvec: np.ndarray
    tvec_mm: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "rms_px": self.rms_px,
            "corner_count": self.corner_count,
            "corners_rejected": self.corners_rejected,
            "tilt_deg": self.tilt_deg,
            "rvec": self.rvec.tolist(),
            "tvec_mm": self.tvec_mm.tolist(),
        }


@dataclass(frozen=True)
class RejectedView:
    """A photo left out of the solve, and why."""

    source: str
    reason: str

    def to_dict(self) -> dict[str, Any]:
        return {"source": self.source, "reason": self.reason}


@dataclass(frozen=True)
class CalibrationResult:
    """The solved camera and everything needed to judge and redo the solve.

    Attributes
    ----------
    camera : CameraModel
        Intrinsics and distortion (no calibration record attached).
    model : str
        Distortion model name (:data:`DISTORTION_MODELS`).
    flags : int
        OpenCV flags used.
    rms_px : float
        RMS reprojection error over all used corners, px.
    std_devs : dict of str -> float
        One standard deviation of every free intrinsic (px for fx..cy).
    views : tuple of ViewResult
    rejected : tuple of RejectedView
    detections : tuple of BoardDetection
        The corner sets actually used (outliers removed), parallel to ``views``.
    rounds : int
        Solves run by the rejection loop.
    board_warp : BoardWarp or None
        The board's bow solved with the lens (:mod:`cvmeasure.lens.warp`), or None
        for a flat board.
    """

    camera: CameraModel
    model: str
    flags: int
    rms_px: float
    std_devs: dict[str, float]
    views: tuple[ViewResult, ...]
    rejected: tuple[RejectedView, ...]
    detections: tuple[BoardDetection, ...] = field(repr=False)
    rounds: int = 1
    board_warp: Any = None  # calibration.warp.BoardWarp when solved with a board warp

    @property
    def image_size_px(self) -> tuple[int, int]:
        return self.camera.image_size_px

    @property
    def corner_count(self) -> int:
        return int(sum(v.corner_count for v in self.views))

    @property
    def corners_rejected(self) -> int:
        """Outlier corners dropped from the views used (views skipped not counted)."""
        return int(sum(v.corners_rejected for v in self.views))

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": self.model,
            "flags": self.flags,
            "rms_px": self.rms_px,
            "std_devs": dict(self.std_devs),
            "views_used": [v.to_dict() for v in self.views],
            "views_rejected": [r.to_dict() for r in self.rejected],
            "corner_count": self.corner_count,
            "corners_rejected": self.corners_rejected,
            "rounds": self.rounds,
            "board_warp": self.board_warp.to_dict() if self.board_warp is not None else None,
        }


def view_residuals_px(
    camera: CameraModel, detection: BoardDetection, rvec: np.ndarray, tvec: np.ndarray
) -> np.ndarray:
    """Reprojection residuals (N, 2), observed minus projected, px."""
    proj, _ = cv2.projectPoints(
        detection.object_mm.reshape(-1, 1, 3),
        np.asarray(rvec, dtype=np.float64),
        np.asarray(tvec, dtype=np.float64),
        camera.camera_matrix,
        camera.dist_coeffs,
    )
    return detection.corners_px - proj.reshape(-1, 2)


def _robust_residuals(
    camera: CameraModel, det: BoardDetection, rvec: np.ndarray, tvec: np.ndarray
) -> np.ndarray:
    """Residuals under the view's pose refitted to its best-fitting corners (LM).

    With the joint solve's pose, a few gross outliers drag the whole view and
    make good corners look bad; refitting the pose to the corners within 3x the
    median residual isolates them.
    """
    obj = det.object_mm.reshape(-1, 1, 3)
    img = det.corners_px.reshape(-1, 1, 2)
    k, d = camera.camera_matrix, camera.dist_coeffs
    res = view_residuals_px(camera, det, rvec, tvec)
    r, t = rvec.reshape(3, 1).copy(), tvec.reshape(3, 1).copy()
    for _ in range(2):
        norms = np.linalg.norm(res, axis=1)
        keep = norms <= 3.0 * float(np.median(norms)) + 1e-9
        if keep.all() or keep.sum() < MIN_CORNERS:
            break
        try:
            r, t = cv2.solvePnPRefineLM(obj[keep], img[keep], k, d, r, t)
        except cv2.error:
            break
        new = view_residuals_px(camera, det, r.ravel(), t.ravel())
        if np.median(np.linalg.norm(new, axis=1)) > np.median(norms):
            break
        res = new
    return res


def _neighbour_relative(det: BoardDetection, res: np.ndarray) -> np.ndarray:
    """Each corner's residual minus the median residual of its board neighbours, px (N, 2).

    Neighbours are the corners of the same view within 1.5 board spacings. Lens-model
    or pose error moves neighbouring corners together and cancels here; a mis-detected
    corner stands out. A corner with fewer than 2 neighbours keeps its own residual.
    """
    obj = np.asarray(det.object_mm, dtype=np.float64)[:, :2]
    dist = np.linalg.norm(obj[:, None, :] - obj[None, :, :], axis=2)
    np.fill_diagonal(dist, np.inf)
    spacing = float(np.median(np.min(dist, axis=1)))
    out = res.copy()
    for i, row in enumerate(dist):
        near = np.flatnonzero(row <= 1.5 * spacing)
        if near.size >= 2:
            out[i] = res[i] - np.median(res[near], axis=0)
    return out


def _solve(
    dets: Sequence[BoardDetection], image_size: tuple[int, int], flags: int
) -> tuple[float, CameraModel, list[np.ndarray], list[np.ndarray], np.ndarray, np.ndarray]:
    objs = [d.object_mm.astype(np.float32).reshape(-1, 1, 3) for d in dets]
    imgs = [d.corners_px.astype(np.float32).reshape(-1, 1, 2) for d in dets]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 100, 1e-12)
    # one thread: OpenCV's parallel sums make identical runs differ (1e-10 px in f on
    # OpenCV's sample set, amplified to other printed digits by an ill-conditioned model);
    # on one thread they are bit-identical, and no slower at these sizes
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    try:
        rms, k, dist, rvecs, tvecs, sd_intr, _sd_extr, per_view = cv2.calibrateCameraExtended(
            objs, imgs, image_size, None, None, flags=flags, criteria=crit
        )
    finally:
        cv2.setNumThreads(threads)
    dist = np.asarray(dist, dtype=np.float64).ravel()
    n_dist = (
        12 if flags & cv2.CALIB_THIN_PRISM_MODEL else (8 if flags & cv2.CALIB_RATIONAL_MODEL else 5)
    )
    camera = CameraModel(image_size, k, dist[:n_dist])  # OpenCV 5 pads to 14 with zeros
    return (
        float(rms),
        camera,
        [np.asarray(r, dtype=np.float64).ravel() for r in rvecs],
        [np.asarray(t, dtype=np.float64).ravel() for t in tvecs],
        np.asarray(sd_intr, dtype=np.float64).ravel(),
        np.asarray(per_view, dtype=np.float64).ravel(),
    )


def _free_intrinsics(model: str) -> tuple[str, ...]:
    n_dist = DISTORTION_MODELS[model][1]
    if n_dist == 12:
        return INTRINSIC_NAMES[:16]
    return INTRINSIC_NAMES[: 4 + n_dist]


def calibrate_views(
    detections: Sequence[BoardDetection],
    image_size_px: tuple[int, int],
    *,
    model: DistortionModel = "5",
    reject_outliers: bool = True,
    max_rounds: int = 8,
    min_views: int = MIN_VIEWS,
    source: str = "calibration photos",
    board_warp: bool = False,
    board_extent_mm: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> CalibrationResult:
    """Calibrate a camera from board detections, dropping bad corners and views.

    Parameters
    ----------
    detections : sequence of BoardDetection
        One per photo; detections that are not ``ok`` are reported as rejected.
    image_size_px : (width, height)
        Every detection must come from a photo of this size (others are rejected).
    model : {"5", "8", "rational", "thin-prism"}
        Distortion model (see :data:`DISTORTION_MODELS`).
    reject_outliers : bool
        Run the rejection loop (corners off their neighbours' residual by more than
        4 robust sigmas, the larger of the pooled and their view's; views above 3x
        the median view RMS), at most ``max_rounds`` solves. Every round judges every
        detected corner again (one dropped earlier returns within 0.8 of the limit).
        A round that drops a view drops no corners and re-admits every corner of the
        remaining views.
    min_views : int
        Fewer usable views raise :class:`InputError` naming ``source``.
    board_warp : bool
        Refine the result with mrcal's two-parameter board warp
        (:func:`cvmeasure.lens.warp.refine_board_warp`) on the corners the
        rejection kept; ``board_extent_mm`` is the corner grid it is relative to (default:
        every corner the detections saw).

    Returns
    -------
    CalibrationResult
    """
    flags = model_flags(model)
    size = (int(image_size_px[0]), int(image_size_px[1]))
    active, rejected = _usable_views(detections, size)
    n_rejected_corners = {id(d): 0 for d in active}
    original = {id(d): d for d in active}  # each corner set as detected, before rejection
    _check_count(active, rejected, min_views, source)
    rounds = 0
    seen = {tuple((d.source, d.ids.tobytes()) for d in active)}
    while True:
        rounds += 1
        try:
            rms, camera, rvecs, tvecs, sd_intr, per_view = _solve(active, size, flags)
        except cv2.error as exc:  # degenerate views (e.g. all boards parallel)
            raise InputError(source, f"the calibration solve failed: {exc}") from None
        if not reject_outliers or rounds >= max_rounds:
            break
        # every corner each view was detected with is judged again under this round's
        # solve (a corner dropped earlier comes back if it now fits): the kept set is a
        # fixed point of the rule, not the end of an erosion of the residuals' tails
        full = [original[id(d)] for d in active]
        outlier, bad_views = _judge_round(camera, active, full, rvecs, tvecs, per_view)
        new_active, changed = _next_active(
            active, full, outlier, bad_views, rejected, n_rejected_corners, original
        )
        state = tuple((d.source, d.ids.tobytes()) for d in new_active)
        if not changed or state in seen:
            # no change, or back to a corner set already solved (the rule cycles between
            # corners on the edge of its limit): the last solve stands
            if not changed:
                active = new_active
            break
        seen.add(state)
        active = new_active
        _check_count(active, rejected, min_views, source)
    out = _calibration_result(
        (camera, rms, rvecs, tvecs, sd_intr, per_view),
        model,
        flags,
        active,
        rejected,
        n_rejected_corners,
        rounds,
    )
    if board_warp:
        out = refine_board_warp(out, extent_mm=board_extent_mm)
    return out


def _calibration_result(
    solve: tuple,
    model: str,
    flags: int,
    active: Sequence[BoardDetection],
    rejected: Sequence[RejectedView],
    n_rejected_corners: dict[int, int],
    rounds: int,
) -> CalibrationResult:
    """The result of the last solve (``solve``: what :func:`_solve` returned, in the order
    camera, RMS, rvecs, tvecs, intrinsic sigmas, per-view RMS) on the corner sets ``active``."""
    camera, rms, rvecs, tvecs, sd_intr, per_view = solve
    names = _free_intrinsics(model)
    views = tuple(
        ViewResult(
            d.source,
            float(e),
            d.corner_count,
            n_rejected_corners[id(d)],
            tilt_deg_from_rvec(r),
            r,
            t,
        )
        for d, e, r, t in zip(active, per_view, rvecs, tvecs, strict=True)
    )
    return CalibrationResult(
        camera=camera,
        model=model,
        flags=flags,
        rms_px=rms,
        std_devs={n: float(sd_intr[INTRINSIC_NAMES.index(n)]) for n in names},
        views=views,
        rejected=tuple(rejected),
        detections=tuple(active),
        rounds=rounds,
    )


def _usable_views(
    detections: Sequence[BoardDetection], size: tuple[int, int]
) -> tuple[list[BoardDetection], list[RejectedView]]:
    """The detections a solve can use (ok, of ``size``, enough corners), and the others
    with the reason each is left out."""
    rejected: list[RejectedView] = []
    active: list[BoardDetection] = []
    for det in detections:
        if not det.ok:
            rejected.append(RejectedView(det.source, det.reason))
        elif tuple(det.image_size_px) != size:
            rejected.append(
                RejectedView(
                    det.source,
                    f"image size {det.image_size_px[0]}x{det.image_size_px[1]} differs from "
                    f"{size[0]}x{size[1]}",
                )
            )
        elif det.corner_count < MIN_CORNERS:
            rejected.append(RejectedView(det.source, f"too few corners ({det.corner_count})"))
        else:
            active.append(det)
    return active, rejected


def _check_count(
    active: Sequence[BoardDetection],
    rejected: Sequence[RejectedView],
    min_views: int,
    source: str,
) -> None:
    """Raise :class:`InputError` naming ``source`` when fewer than ``min_views`` are left."""
    if len(active) < min_views:
        why = "; ".join(f"{r.source}: {r.reason}" for r in rejected[:6])
        raise InputError(
            source,
            f"only {len(active)} usable view(s), need at least {min_views}"
            + (f" (skipped: {why})" if why else ""),
        )


def _judge_round(
    camera: CameraModel,
    active: Sequence[BoardDetection],
    full: Sequence[BoardDetection],
    rvecs: Sequence[np.ndarray],
    tvecs: Sequence[np.ndarray],
    per_view: np.ndarray,
) -> tuple[list[np.ndarray], dict[int, str]]:
    """One round's verdict under its solve: per view the outlier mask over every corner it
    was detected with (``full``), and the views to drop with the reason.

    A corner is an outlier when its residual, less its board neighbours' median, is beyond
    4 robust sigmas (the larger of the pooled and its view's); one dropped in an earlier
    round (absent from ``active``) comes back only within 0.8 of that limit. A view goes
    when most of its corners are outliers or its inlier RMS is above 3x the median view's.
    """
    residuals = [
        _robust_residuals(camera, d, r, t) for d, r, t in zip(full, rvecs, tvecs, strict=True)
    ]
    # a corner is judged against its neighbours: model error is smooth over the board
    # (rejecting it biased SimpleSLAM's focal length by 3 sigma), a bad corner is not
    local = [_neighbour_relative(d, res) for d, res in zip(full, residuals, strict=True)]
    allres = np.concatenate(local).ravel()
    sigma = 1.4826 * float(np.median(np.abs(allres - np.median(allres))))
    # and against its own view's noise when that is larger than the pool's: blur and
    # distance make some views' corners noisier (LifeCam: view sigma 0.13-0.70 px),
    # and a corner of a blurred view is not a mis-detection for being 4 pooled sigmas off
    limits = []
    for loc in local:
        s_view = 1.4826 * float(np.median(np.abs(loc.ravel() - np.median(loc.ravel()))))
        limits.append(max(_OUTLIER_SIGMAS * max(sigma, s_view), _OUTLIER_FLOOR_PX))
    view_limit = max(_VIEW_RMS_FACTOR * float(np.median(per_view)), _VIEW_RMS_FLOOR_PX)
    # hysteresis: a corner dropped in an earlier round comes back only well inside the
    # limit (x _READMIT), so corners right at it do not flip in and out every round
    outlier = []
    for d, orig, loc, lim in zip(active, full, local, limits, strict=True):
        norm = np.linalg.norm(loc, axis=1)
        was_out = ~np.isin(orig.ids, d.ids)
        outlier.append(np.where(was_out, norm > _READMIT * lim, norm > lim))
    # Views are judged on their inlier corners, so a few outliers drop corners, not the view
    bad_views: dict[int, str] = {}
    for k, res in enumerate(residuals):
        norms = np.linalg.norm(res, axis=1)
        n_out = int(np.sum(outlier[k]))
        inliers = norms[~outlier[k]]
        vrms = float(np.sqrt(np.mean(inliers**2))) if inliers.size else float("inf")
        if n_out > 0.5 * len(norms):
            bad_views[k] = (
                f"{n_out} of {len(norms)} corners are off their neighbours by more than "
                f"{limits[k]:.3f} px (blurred or moved photo, or a different lens setting?)"
            )
        elif vrms > view_limit:
            bad_views[k] = (
                f"view RMS {vrms:.3f} px (inlier corners) is above {view_limit:.3f} px "
                f"({_VIEW_RMS_FACTOR:g}x the median view)"
            )
    return outlier, bad_views


def _next_active(
    active: Sequence[BoardDetection],
    full: Sequence[BoardDetection],
    outlier: Sequence[np.ndarray],
    bad_views: dict[int, str],
    rejected: list[RejectedView],
    n_rejected_corners: dict[int, int],
    original: dict[int, BoardDetection],
) -> tuple[list[BoardDetection], bool]:
    """The corner sets of the next round and whether they changed.

    Views first: a round that drops a view (appended to ``rejected``) drops no corners and
    re-admits every corner of the remaining views, because a bad view distorts the solve
    and with it every other view's residuals. Otherwise each view keeps its inliers; a view
    left with too few corners is rejected. ``n_rejected_corners`` and ``original`` are
    updated for every new corner subset.
    """
    changed = bool(bad_views)
    new_active: list[BoardDetection] = []
    for k, det in enumerate(active):
        if k in bad_views:
            rejected.append(RejectedView(det.source, bad_views[k]))
            continue
        orig = full[k]
        keep = np.ones(orig.corner_count, bool) if bad_views else ~outlier[k]
        if keep.all():
            if det is not orig:
                changed = True
            det = orig
        else:
            if det.corner_count != int(keep.sum()) or not np.array_equal(det.ids, orig.ids[keep]):
                changed = True
            sub = orig.subset(keep)
            n_rejected_corners[id(sub)] = int((~keep).sum())
            original[id(sub)] = orig
            if sub.corner_count < MIN_CORNERS:
                rejected.append(
                    RejectedView(
                        det.source,
                        f"too few corners left after outlier removal ({sub.corner_count})",
                    )
                )
                changed = True
                continue
            det = sub
        new_active.append(det)
    return new_active, changed
