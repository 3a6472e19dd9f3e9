"""Camera placement for synthetic photos: the seed camera, poses, pixel <-> plane maps.

Frames
------
A *scene frame* is either the **board frame** (OpenCV's ChArUco object frame:
x right, y down on the printed board, z into the table, i.e. away from the
camera) or the **machine frame** of the spec (x along the feed, y 90 degrees
counter-clockwise as seen in the photo, z up towards the camera). All scene
geometry lies in the plane z = 0 of its frame, in mm.

``R_cam_frame`` (3x3) and ``t_cam_frame_mm`` (3,) map a frame point ``p`` to the
camera frame (x right, y down, z forward, mm): ``p_cam = R @ p + t``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from cvmeasure.camera_model import CameraModel

__all__ = [
    "Frame",
    "Pose",
    "RayMap",
    "default_camera",
    "plane_coords_mm",
    "project_frame_points",
]

#: Which scene frame a pose is expressed in.
Frame = Literal["board", "machine"]

#: Seed camera: Nikon D3100 (23.1 mm x 15.4 mm sensor, 4608 x 3072, 5.0 um pixels)
#: with the 18-55 mm kit zoom at about 35 mm -> f = 35 mm / 5.0 um = 7000 px.
_SEED_SIZE_PX = (4608, 3072)
_SEED_FOCAL_PX = 7000.0
_SEED_PP_OFFSET_PX = (11.3, -7.6)  # principal point off the image centre (assembly tolerance)
_SEED_DIST = (-0.082, 0.115, 2.1e-4, -1.4e-4, -0.03)  # k1 k2 p1 p2 k3 (barrel, mid-zoom)


def default_camera(image_size_px: tuple[int, int] = _SEED_SIZE_PX) -> CameraModel:
    """The seed camera (Nikon D3100 + 18-55 mm at ~35 mm), resized to ``image_size_px``.

    f = 7000 px at 4608 x 3072 (5.0 um pixels), principal point (11.3, -7.6) px
    off centre, Brown-Conrady distortion k1 = -0.082, k2 = 0.115, k3 = -0.03,
    p1 = 2.1e-4, p2 = -1.4e-4 (about 34 px of barrel distortion in the corners).
    Other sizes must keep the 3:2 aspect ratio (the lens is scaled, not cropped).
    """
    w0, h0 = _SEED_SIZE_PX
    cx = (w0 - 1) / 2 + _SEED_PP_OFFSET_PX[0]
    cy = (h0 - 1) / 2 + _SEED_PP_OFFSET_PX[1]
    cam = CameraModel.ideal(_SEED_SIZE_PX, _SEED_FOCAL_PX, _SEED_DIST, (cx, cy))
    w, h = (int(v) for v in image_size_px)
    if (w, h) == (w0, h0):
        return cam
    factor = w / w0
    if abs(h - h0 * factor) > 1.0:
        raise ValueError(f"image_size_px {image_size_px} must keep the 3:2 aspect ratio")
    return cam.scaled(factor)


@dataclass(frozen=True)
class Pose:
    """Where the camera is, relative to the scene plane.

    The camera looks at the plane point ``offset_mm`` (x, y in the scene frame)
    from ``distance_mm`` away. With ``tilt_deg = 0`` its optical axis is the
    plane normal; otherwise the camera is moved towards the in-plane direction
    ``tilt_direction_deg`` (measured in the scene frame from +x towards +y) and
    looks back at the same point, so its axis makes ``tilt_deg`` with the
    normal. ``yaw_deg`` turns the camera about its optical axis: at zero tilt
    the frame's +x axis appears rotated ``yaw_deg`` counter-clockwise in the
    photo (0: +x points right).
    """

    tilt_deg: float = 0.0
    tilt_direction_deg: float = 0.0
    yaw_deg: float = 0.0
    distance_mm: float = 850.0
    offset_mm: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if not 0.0 <= self.tilt_deg < 80.0:
            raise ValueError(f"tilt_deg must be in [0, 80), got {self.tilt_deg}")
        if self.distance_mm <= 0:
            raise ValueError(f"distance_mm must be positive, got {self.distance_mm}")
        object.__setattr__(self, "offset_mm", tuple(float(v) for v in self.offset_mm))

    def extrinsics(self, frame: Frame = "board") -> tuple[np.ndarray, np.ndarray]:
        """``(R_cam_frame, t_cam_frame_mm)`` for a scene in ``frame`` ("board" or "machine")."""
        if frame not in ("board", "machine"):
            raise ValueError(f"frame must be 'board' or 'machine', got {frame!r}")
        up = np.array([0.0, 0.0, 1.0 if frame == "machine" else -1.0])  # towards the camera
        tilt = np.radians(self.tilt_deg)
        phi = np.radians(self.tilt_direction_deg)
        target = np.array([self.offset_mm[0], self.offset_mm[1], 0.0])
        centre = target + self.distance_mm * (
            np.sin(tilt) * np.array([np.cos(phi), np.sin(phi), 0.0]) + np.cos(tilt) * up
        )
        z_c = (target - centre) / self.distance_mm
        ex = np.array([1.0, 0.0, 0.0])
        x0 = ex - ex.dot(z_c) * z_c
        x0 /= np.linalg.norm(x0)
        y0 = np.cross(z_c, x0)
        yaw = np.radians(self.yaw_deg)
        x_c = np.cos(yaw) * x0 + np.sin(yaw) * y0
        y_c = -np.sin(yaw) * x0 + np.cos(yaw) * y0
        rot = np.vstack((x_c, y_c, z_c))
        return rot, -rot @ centre

    @classmethod
    def from_extrinsics(cls, rot: np.ndarray, t_mm: np.ndarray, frame: Frame = "board") -> Pose:
        """The pose whose :meth:`extrinsics` in ``frame`` are ``(rot, t_mm)`` (camera <- frame).

        The camera must look at the plane (its optical axis meets z = 0 in front of it).
        """
        rot = np.asarray(rot, dtype=np.float64).reshape(3, 3)
        centre = -rot.T @ np.asarray(t_mm, dtype=np.float64).reshape(3)
        z_c = rot[2]
        if abs(z_c[2]) < 1e-9:
            raise ValueError("the optical axis is parallel to the plane")
        s = -centre[2] / z_c[2]
        if s <= 0:
            raise ValueError("the camera looks away from the plane")
        target = centre + s * z_c
        up = 1.0 if frame == "machine" else -1.0
        away = (centre - target) / s
        tilt = float(np.degrees(np.arccos(np.clip(away[2] * up, -1.0, 1.0))))
        direction = float(np.degrees(np.arctan2(away[1], away[0]))) if tilt > 1e-9 else 0.0
        ex = np.array([1.0, 0.0, 0.0])
        x0 = ex - ex.dot(z_c) * z_c
        x0 /= np.linalg.norm(x0)
        y0 = np.cross(z_c, x0)
        yaw = float(np.degrees(np.arctan2(rot[0].dot(y0), rot[0].dot(x0))))
        return cls(tilt, direction % 360.0, yaw, float(s), (float(target[0]), float(target[1])))

    def to_dict(self) -> dict[str, Any]:
        return {
            "tilt_deg": self.tilt_deg,
            "tilt_direction_deg": self.tilt_direction_deg,
            "yaw_deg": self.yaw_deg,
            "distance_mm": self.distance_mm,
            "offset_mm": list(self.offset_mm),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> Pose:
        return cls(
            tilt_deg=float(data.get("tilt_deg", 0.0)),
            tilt_direction_deg=float(data.get("tilt_direction_deg", 0.0)),
            yaw_deg=float(data.get("yaw_deg", 0.0)),
            distance_mm=float(data.get("distance_mm", 850.0)),
            offset_mm=tuple(data.get("offset_mm", (0.0, 0.0))),
        )


def project_frame_points(
    camera: CameraModel, rot: np.ndarray, t_mm: np.ndarray, points_mm: np.ndarray
) -> np.ndarray:
    """Scene-frame points (N, 2) or (N, 3), mm -> distorted pixels (N, 2)."""
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, np.shape(points_mm)[-1])
    if pts.shape[1] == 2:
        pts = np.column_stack((pts, np.zeros(len(pts))))
    return camera.project(pts @ rot.T + t_mm)


def plane_coords_mm(
    camera: CameraModel,
    rot: np.ndarray,
    t_mm: np.ndarray,
    xs_px: np.ndarray,
    ys_px: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Trace pixels back to the plane z = 0 of the scene frame.

    Each pixel (distorted, OpenCV centre convention) is undistorted exactly
    (iterative, to ~1e-12 px), turned into a camera ray and intersected with the
    plane analytically.

    Parameters
    ----------
    xs_px, ys_px : ndarray of shape (H, W), float; pixel coordinates.

    Returns
    -------
    (u_mm, v_mm) : two ndarrays of shape (H, W), float64; the scene-frame x, y in mm.
    """
    shape = np.shape(xs_px)
    pts = np.stack((np.ravel(xs_px), np.ravel(ys_px)), axis=1).astype(np.float64)
    norm = _undistort_normalized(camera, pts)
    u, v = _intersect(rot, t_mm, norm[:, 0], norm[:, 1])
    return u.reshape(shape), v.reshape(shape)


def _undistort_normalized(camera: CameraModel, pts_px: np.ndarray) -> np.ndarray:
    """Distorted pixels (N, 2) -> normalised ray coordinates (N, 2), exact to ~1e-12 px."""
    import cv2

    # 10 iterations: 2e-12 px round trip for the seed lens (30 cost twice the time)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 10, 1e-13)
    eye = np.eye(3)
    return cv2.undistortPoints(
        pts_px.reshape(-1, 1, 2), camera.camera_matrix, camera.dist_coeffs, None, eye, eye, crit
    ).reshape(-1, 2)


def _intersect(rot: np.ndarray, t_mm: np.ndarray, xn: np.ndarray, yn: np.ndarray):
    """Rays (xn, yn, 1) of the camera frame meet the plane z = 0 of the scene frame at (u, v)."""
    centre = -rot.T @ t_mm
    # ray direction in the frame: R^T (xn, yn, 1)
    dx = rot[0, 0] * xn + rot[1, 0] * yn + rot[2, 0]
    dy = rot[0, 1] * xn + rot[1, 1] * yn + rot[2, 1]
    dz = rot[0, 2] * xn + rot[1, 2] * yn + rot[2, 2]
    s = -centre[2] / dz
    return centre[0] + s * dx, centre[1] + s * dy


class RayMap:
    """Normalised ray coordinates of every pixel of a camera, for fast grid look-ups.

    The exact undistortion is computed on a lattice every ``step_px`` pixels
    (plus a margin) and interpolated with quintic tensor splines; for the seed
    lens the result matches the exact per-pixel undistortion to ~1e-11 px at a
    fraction of the cost.
    """

    def __init__(self, camera: CameraModel, step_px: int = 16) -> None:
        from scipy.interpolate import RectBivariateSpline

        w, h = camera.image_size_px
        gx = np.arange(-3 * step_px, w + 4 * step_px, step_px, dtype=np.float64)
        gy = np.arange(-3 * step_px, h + 4 * step_px, step_px, dtype=np.float64)
        mx, my = np.meshgrid(gx, gy)
        norm = _undistort_normalized(camera, np.column_stack((mx.ravel(), my.ravel())))
        self._sx = RectBivariateSpline(gy, gx, norm[:, 0].reshape(mx.shape), kx=5, ky=5)
        self._sy = RectBivariateSpline(gy, gx, norm[:, 1].reshape(mx.shape), kx=5, ky=5)

    def direction_grid(
        self, rot: np.ndarray, xs_px: np.ndarray, ys_px: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Ray directions ``R^T (xn, yn, 1)`` in the frame (len(ys), len(xs)) each.

        Scaled so that ``centre + s * d`` lies at camera depth ``s``; the same
        arithmetic as :meth:`plane_grid_mm`.
        """
        xn = self._sx(ys_px, xs_px, grid=True)
        yn = self._sy(ys_px, xs_px, grid=True)
        dx = rot[0, 0] * xn + rot[1, 0] * yn + rot[2, 0]
        dy = rot[0, 1] * xn + rot[1, 1] * yn + rot[2, 1]
        dz = rot[0, 2] * xn + rot[1, 2] * yn + rot[2, 2]
        return dx, dy, dz

    def plane_grid_mm(
        self, rot: np.ndarray, t_mm: np.ndarray, xs_px: np.ndarray, ys_px: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Plane coordinates (len(ys), len(xs)) in mm of the pixel grid ``xs_px`` x ``ys_px``."""
        xn = self._sx(ys_px, xs_px, grid=True)
        yn = self._sy(ys_px, xs_px, grid=True)
        return _intersect(rot, t_mm, xn, yn)
