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

import cv2
import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.errors import InputError
from cvmeasure.lens.detect import BoardDetection, detect_board
from cvmeasure.plane_model import PlaneModel, apply_homography

__all__ = [
    "PlaneModel",
    "DEFAULT_TOLERANCE_DEG",
    "estimate_plane",
    "fit_plane",
    "worst_angle_error_deg",
    "mm_per_px_at",
    "rectify_image",
]

#: Default worst angle error (deg) an affine (tilt-ignoring) model may cause.
DEFAULT_TOLERANCE_DEG = 0.05


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


def mm_per_px_at(h_board_image: np.ndarray, point_px: np.ndarray) -> float:
    """The plane's scale (mm per px, the square root of the area ratio) at an undistorted
    image point, from the homography image px -> board mm."""
    jac = _h_jacobians(h_board_image, np.asarray(point_px, dtype=np.float64)[None])[0]
    return float(np.sqrt(abs(np.linalg.det(jac))))


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
    mapped = apply_homography(h_plane_image, pts)
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


def fit_plane(
    detection: BoardDetection,
    camera: CameraModel,
    *,
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
) -> PlaneModel:
    """Fit the plane pose and homography to one board detection.

    Raises :class:`InputError` (naming the detection's source) when the
    detection is unusable or the photo size does not match the camera.
    """
    if not detection.ok:
        raise InputError(detection.source, detection.reason)
    # a photo resized by one factor (a reduced JPEG, a half-size RAW) gets the camera rescaled
    camera = camera.for_image(tuple(detection.image_size_px), detection.source)
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
    centre_px = apply_homography(h_img_board / h_img_board[2, 2], centre_mm[None])[0]
    mm_per_px = mm_per_px_at(h_board_img, centre_px)
    # Region: the board's corner hull in the undistorted image, sampled on a grid.
    lo, hi = obj[:, :2].min(axis=0), obj[:, :2].max(axis=0)
    gx, gy = np.meshgrid(np.linspace(lo[0], hi[0], 9), np.linspace(lo[1], hi[1], 9))
    region_px = apply_homography(
        h_img_board / h_img_board[2, 2], np.column_stack((gx.ravel(), gy.ravel()))
    )
    worst, _, _ = worst_angle_error_deg(h_board_img, region_px)
    return PlaneModel(
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
) -> PlaneModel:
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
    PlaneModel
        Use :meth:`PlaneModel.image_to_plane_mm` to map photo pixels to board mm.
    """
    det = detect_board(photo_gray, board, source=source)
    return fit_plane(det, camera, tolerance_deg=tolerance_deg)


def rectify_image(
    image: np.ndarray,
    plane: PlaneModel,
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
    plane : PlaneModel
    px_per_mm : float
        Output resolution.
    region_mm : (x0, y0, x1, y1), optional
        Board-frame rectangle to render; default the whole image footprint.
    """
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
