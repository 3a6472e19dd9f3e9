"""The affine plane check and the rectifying homography (seed paper, section 2.3.2).

A board lying on the measurement plane fixes the plane's pose against the
camera. From it this module reports how far the plane is tilted against the
image plane, the scale in mm per pixel, whether ignoring the tilt (treating
the photo as a rotated, scaled copy of the plane -- the paper's "affine"
assumption) keeps angle errors within a tolerance, and the homography that
maps undistorted image pixels to millimetres on the plane.

Frames
------
* image: distorted pixels as in the photo (OpenCV convention);
* undistorted image: ideal pinhole pixels of the same camera matrix;
* board: the board frame of the spec (mm, z = 0 on the plane).

``H_board_image`` maps homogeneous undistorted pixels to board mm.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.calibration.detect import BoardDetection, detect_board
from cvmeasure.camera import CameraModel
from cvmeasure.errors import InputError

__all__ = [
    "PlaneFit",
    "DEFAULT_TOLERANCE_DEG",
    "estimate_plane",
    "fit_plane",
    "worst_angle_error_deg",
    "rectify_image",
    "load_plane_homography",
]

#: Default worst angle error (deg) an affine (tilt-ignoring) model may cause.
DEFAULT_TOLERANCE_DEG = 0.05


def _apply_h(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    hom = np.column_stack((pts, np.ones(len(pts)))) @ h.T
    return hom[:, :2] / hom[:, 2:3]


def _h_jacobians(h: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Jacobians (N, 2, 2) of the homography map at ``pts`` (N, 2)."""
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    hom = np.column_stack((pts, np.ones(len(pts)))) @ h.T
    w = hom[:, 2]
    jac = np.empty((len(pts), 2, 2))
    for i in range(2):
        for j in range(2):
            jac[:, i, j] = (h[i, j] * w - hom[:, i] * h[2, j]) / w**2
    return jac


def worst_angle_error_deg(
    h_plane_image: np.ndarray, region_px: np.ndarray, *, n_dirs: int = 36
) -> tuple[float, float, float]:
    """Worst angle error from replacing a homography by a similarity over a region.

    Fits the best similarity (rotation, uniform scale, translation) to the
    homography over the region and compares, at every region point and in
    ``n_dirs`` directions, the direction the homography gives a short segment
    with the direction the similarity gives it.

    Parameters
    ----------
    h_plane_image : ndarray (3, 3)
        Undistorted image px -> plane mm.
    region_px : ndarray (N, 2)
        Sample points of the measured region, undistorted px.

    Returns
    -------
    (worst_deg, similarity_scale_mm_per_px, similarity_rotation_deg)
    """
    pts = np.asarray(region_px, dtype=np.float64).reshape(-1, 2)
    mapped = _apply_h(h_plane_image, pts)
    # Similarity fit in complex form: z_mm = a * z_px + b.
    zp = pts[:, 0] + 1j * pts[:, 1]
    zm = mapped[:, 0] + 1j * mapped[:, 1]
    a_mat = np.column_stack((zp, np.ones_like(zp)))
    (a, _b), *_ = np.linalg.lstsq(a_mat, zm, rcond=None)
    jac = _h_jacobians(h_plane_image, pts)
    theta = np.linspace(0.0, np.pi, n_dirs, endpoint=False)
    dirs = np.stack((np.cos(theta), np.sin(theta)))  # (2, D)
    true = np.einsum("nij,jd->nid", jac, dirs)
    true_ang = np.arctan2(true[:, 1], true[:, 0])
    sim_ang = np.angle(a) + theta
    err = np.angle(np.exp(1j * (true_ang - sim_ang[None, :])))
    # Direction error relative to the region's mean: a global rotation is not an error.
    err = err - np.angle(np.mean(np.exp(1j * err)))
    err = np.angle(np.exp(1j * err))
    return float(np.degrees(np.max(np.abs(err)))), float(abs(a)), float(np.degrees(np.angle(a)))


@dataclass(frozen=True)
class PlaneFit:
    """The measurement plane seen through one photo.

    Attributes
    ----------
    camera : CameraModel
        The camera used (distortion is removed before the homography).
    H_board_image : ndarray (3, 3)
        Undistorted image px -> board mm (homogeneous).
    rvec, tvec_mm : ndarray (3,)
        Board pose, camera <- board (OpenCV convention).
    tilt_deg : float
        Angle between the plane normal and the optical axis.
    tilt_direction_deg : float
        Image direction in which the plane recedes from the camera, degrees
        counter-clockwise from +x as seen in the photo (0 when the tilt is 0).
    mm_per_px : float
        Scale on the plane at the board centre, mm per (undistorted) pixel.
    worst_angle_error_deg : float
        Worst direction error, over the board's region in the image, from
        ignoring the tilt (a rotation + uniform scale model instead of the homography).
    tolerance_deg : float
    rms_px : float
        RMS reprojection error of the board corners under the pose, px.
    corner_count : int
    source : str
    """

    camera: CameraModel
    H_board_image: np.ndarray
    rvec: np.ndarray
    tvec_mm: np.ndarray
    tilt_deg: float
    tilt_direction_deg: float
    mm_per_px: float
    worst_angle_error_deg: float
    tolerance_deg: float
    rms_px: float
    corner_count: int
    source: str = "image"

    @property
    def affine_ok(self) -> bool:
        """True when ignoring the tilt keeps angle errors within the tolerance."""
        return self.worst_angle_error_deg <= self.tolerance_deg

    @property
    def H_image_board(self) -> np.ndarray:
        """Board mm -> undistorted image px."""
        inv = np.linalg.inv(self.H_board_image)
        return inv / inv[2, 2]

    def image_to_plane_mm(self, points_px: np.ndarray) -> np.ndarray:
        """Photo pixels (N, 2), distorted as taken -> board-frame mm (N, 2) on the plane."""
        pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            return np.zeros((0, 2))
        return _apply_h(self.H_board_image, self.camera.undistort_px(pts))

    def plane_to_image_px(self, points_mm: np.ndarray) -> np.ndarray:
        """Board-frame mm (N, 2) on the plane -> photo pixels (N, 2), with distortion."""
        pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            return np.zeros((0, 2))
        obj = np.column_stack((pts, np.zeros(len(pts))))
        import cv2

        img, _ = cv2.projectPoints(
            obj.reshape(-1, 1, 3),
            self.rvec,
            self.tvec_mm,
            self.camera.camera_matrix,
            self.camera.dist_coeffs,
        )
        return img.reshape(-1, 2)

    def lens_uncertainty_mm(self) -> dict[str, float | None]:
        """The camera calibration's own uncertainty, in mm on this plane.

        ``sigma_mm``: median 1-sigma projection uncertainty (corner noise only);
        ``cross_validation_mm``: the even/odd halves' central disagreement, which
        also holds model error -- the honest figure. None when the camera JSON
        does not carry them (not written by ``cvmeasure calibrate``).
        """
        cal = self.camera.calibration or {}
        unc = (cal.get("projection_uncertainty") or {}).get("median_px")
        cv = (cal.get("cross_validation") or {}).get("central_60pct_rms_px")
        return {
            "sigma_mm": None if unc is None else float(unc) * self.mm_per_px,
            "cross_validation_mm": None if cv is None else float(cv) * self.mm_per_px,
        }

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "tilt_deg": self.tilt_deg,
            "tilt_direction_deg": self.tilt_direction_deg,
            "mm_per_px": self.mm_per_px,
            "worst_angle_error_deg": self.worst_angle_error_deg,
            "tolerance_deg": self.tolerance_deg,
            "affine_ok": self.affine_ok,
            "rms_px": self.rms_px,
            "corner_count": self.corner_count,
            "H_board_image": (self.H_board_image / self.H_board_image[2, 2]).tolist(),
            "homography_frames": "undistorted image px -> board mm",
            "rvec": self.rvec.tolist(),
            "tvec_mm": self.tvec_mm.tolist(),
            "lens_uncertainty_mm": self.lens_uncertainty_mm(),
        }


def fit_plane(
    detection: BoardDetection,
    camera: CameraModel,
    *,
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
) -> PlaneFit:
    """Fit the plane pose and homography to one board detection.

    Raises :class:`InputError` (naming the detection's source) when the
    detection is unusable or the photo size does not match the camera.
    """
    import cv2

    if not detection.ok:
        raise InputError(detection.source, detection.reason)
    if tuple(detection.image_size_px) != tuple(camera.image_size_px):
        w, h = detection.image_size_px
        cw, ch = camera.image_size_px
        raise InputError(
            detection.source, f"photo is {w}x{h} but the camera was calibrated at {cw}x{ch}"
        )
    obj = detection.object_mm.astype(np.float64)
    img = detection.corners_px.astype(np.float64)
    und = camera.undistort_px(img)
    ok, rvec, tvec = cv2.solvePnP(
        obj.reshape(-1, 1, 3),
        und.reshape(-1, 1, 2),
        camera.camera_matrix,
        None,
        flags=cv2.SOLVEPNP_IPPE,
    )
    if not ok:
        raise InputError(detection.source, "the board pose could not be solved")
    rvec, tvec = cv2.solvePnPRefineLM(
        obj.reshape(-1, 1, 3), und.reshape(-1, 1, 2), camera.camera_matrix, None, rvec, tvec
    )
    rvec = rvec.ravel()
    tvec = tvec.ravel()
    rot, _ = cv2.Rodrigues(rvec)
    normal = rot[:, 2] * np.sign(rot[2, 2] or 1.0)  # away from the camera (n_z > 0)
    tilt_deg = float(np.degrees(np.arccos(np.clip(normal[2], -1.0, 1.0))))
    # Depth grows along -(n_x, n_y) in the image; y is down, so negate y for CCW angles.
    tilt_dir = float(np.degrees(np.arctan2(normal[1], -normal[0]))) if tilt_deg > 1e-9 else 0.0
    # Homography from the pose: board mm -> undistorted px is K [r1 r2 t].
    h_img_board = camera.camera_matrix @ np.column_stack((rot[:, 0], rot[:, 1], tvec))
    h_board_img = np.linalg.inv(h_img_board)
    h_board_img /= h_board_img[2, 2]
    proj, _ = cv2.projectPoints(
        obj.reshape(-1, 1, 3), rvec, tvec, camera.camera_matrix, camera.dist_coeffs
    )
    rms = float(np.sqrt(np.mean(np.sum((proj.reshape(-1, 2) - img) ** 2, axis=1))))
    centre_mm = obj[:, :2].mean(axis=0)
    centre_px = _apply_h(h_img_board / h_img_board[2, 2], centre_mm[None])[0]
    jac = _h_jacobians(h_board_img, centre_px[None])[0]
    mm_per_px = float(np.sqrt(abs(np.linalg.det(jac))))
    # Region: the board's corner hull in the undistorted image, sampled on a grid.
    lo, hi = obj[:, :2].min(axis=0), obj[:, :2].max(axis=0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 9), np.linspace(lo[1], hi[1], 9))
    region_px = _apply_h(h_img_board / h_img_board[2, 2], np.column_stack((gx.ravel(), gy.ravel())))
    worst, _, _ = worst_angle_error_deg(h_board_img, region_px)
    return PlaneFit(
        camera=camera,
        H_board_image=h_board_img,
        rvec=rvec,
        tvec_mm=tvec,
        tilt_deg=tilt_deg,
        tilt_direction_deg=tilt_dir,
        mm_per_px=mm_per_px,
        worst_angle_error_deg=worst,
        tolerance_deg=float(tolerance_deg),
        rms_px=rms,
        corner_count=detection.corner_count,
        source=detection.source,
    )


def estimate_plane(
    photo_gray: np.ndarray,
    board: BoardSpec,
    camera: CameraModel,
    *,
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
    source: str = "image",
) -> PlaneFit:
    """Detect ``board`` in a photo lying on the measurement plane and fit the plane.

    Parameters
    ----------
    photo_gray : ndarray (H, W) or (H, W, 3), uint8 or uint16
        The photo, at the size the camera was calibrated at.
    board : BoardSpec
    camera : CameraModel
    tolerance_deg : float
        Worst angle error (deg) the affine verdict allows.
    source : str
        Name used in errors (the photo's path).

    Returns
    -------
    PlaneFit
        Use :meth:`PlaneFit.image_to_plane_mm` to map photo pixels to board mm.
    """
    det = detect_board(photo_gray, board, source=source)
    return fit_plane(det, camera, tolerance_deg=tolerance_deg)


def rectify_image(
    image: np.ndarray,
    plane: PlaneFit,
    *,
    px_per_mm: float,
    region_mm: tuple[float, float, float, float] | None = None,
) -> np.ndarray:
    """Resample a photo onto the plane: a top-down image in board mm.

    One ``remap`` does distortion and perspective at once: output pixel
    (u, v) shows board point (x0 + u / px_per_mm, y0 + v / px_per_mm).

    Parameters
    ----------
    image : ndarray (H, W[, C])
    plane : PlaneFit
    px_per_mm : float
        Output resolution.
    region_mm : (x0, y0, x1, y1), optional
        Board-frame rectangle to render; default the whole image footprint.
    """
    import cv2

    if region_mm is None:
        w, h = plane.camera.image_size_px
        frame = np.array([[0, 0], [w - 1, 0], [w - 1, h - 1], [0, h - 1]], dtype=np.float64)
        mm = plane.image_to_plane_mm(frame)
        x0, y0 = mm.min(axis=0)
        x1, y1 = mm.max(axis=0)
    else:
        x0, y0, x1, y1 = region_mm
    out_w = int(np.ceil((x1 - x0) * px_per_mm))
    out_h = int(np.ceil((y1 - y0) * px_per_mm))
    if out_w <= 0 or out_h <= 0 or out_w * out_h > 400e6:
        raise ValueError(f"rectified size {out_w}x{out_h} px is not sensible")
    us, vs = np.meshgrid(np.arange(out_w, dtype=np.float64), np.arange(out_h, dtype=np.float64))
    pts_mm = np.column_stack((x0 + us.ravel() / px_per_mm, y0 + vs.ravel() / px_per_mm))
    src = plane.plane_to_image_px(pts_mm).astype(np.float32)
    map_x = src[:, 0].reshape(out_h, out_w)
    map_y = src[:, 1].reshape(out_h, out_w)
    return cv2.remap(image, map_x, map_y, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT)


def load_plane_homography(path: str | os.PathLike[str]) -> np.ndarray:
    """Read the homography ``H_board_image`` (undistorted px -> board mm) from a plane JSON.

    The plane JSON is what ``cvmeasure plane --json`` prints (:meth:`PlaneFit.to_dict`).
    Raises InputError naming the file when it is missing, corrupt or has no usable matrix.
    """
    from cvmeasure.fileio import read_json

    data = read_json(path, what="plane JSON")
    try:
        h = np.asarray(data["H_board_image"], dtype=np.float64)
    except (KeyError, TypeError, ValueError):
        raise InputError(path, "plane JSON lacks a 3x3 'H_board_image'") from None
    if h.shape != (3, 3) or not np.all(np.isfinite(h)) or abs(np.linalg.det(h)) < 1e-15:
        raise InputError(path, "'H_board_image' must be a finite, invertible 3x3 matrix")
    return h
