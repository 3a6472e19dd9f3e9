"""The measurement plane: a camera, the plate's pose and the pixel <-> board-mm homography.

:class:`PlaneModel` is what ``cvmeasure plane`` writes (``cvmeasure-plane/1`` JSON) and every
measuring stage takes: ``image_to_plane_mm`` maps undistorted photo pixels to board
millimetres (at a height above the plate when given), ``for_image`` rescales it for a
reduced photo. It crosses stages, so :mod:`cvmeasure.contracts` re-exports it.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from cvmeasure.camera_model import CameraModel
from cvmeasure.errors import InputError
from cvmeasure.fileio import atomic_write_json, read_json, to_jsonable

__all__ = ["PLANE_FORMAT", "apply_homography", "PlaneModel"]


#: Format tag of a saved plane (``cvmeasure plane --json`` / ``-o plane.json``).
PLANE_FORMAT = "cvmeasure-plane/1"


def _pose_from_homography(
    camera: CameraModel, h_board_image: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(rvec, tvec_mm), camera <- plane, from an undistorted px -> plane mm homography.

    ``K^-1 H_image_board = s [r1 r2 t]``: the scale from the first two columns, the
    rotation completed and made orthonormal (nearest rotation, SVD), the sign chosen
    so that the plane lies in front of the camera.
    """

    m = np.linalg.inv(camera.camera_matrix) @ np.linalg.inv(h_board_image)
    m = m / math.sqrt(np.linalg.norm(m[:, 0]) * np.linalg.norm(m[:, 1]))
    if m[2, 2] < 0:
        m = -m
    r = np.column_stack((m[:, 0], m[:, 1], np.cross(m[:, 0], m[:, 1])))
    u, _, vt = np.linalg.svd(r)
    rot = u @ vt
    if np.linalg.det(rot) < 0:
        rot = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    return cv2.Rodrigues(rot)[0].reshape(3), m[:, 2].copy()


def apply_homography(h: NDArray[np.float64], points: Any) -> NDArray[np.float64]:
    """Points (N, 2) through the 3x3 homography ``h`` (homogeneous, divided out).

    >>> apply_homography(np.diag([2.0, 2.0, 1.0]), [[1.0, 3.0]]).tolist()
    [[2.0, 6.0]]
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    hom = np.column_stack((pts, np.ones(len(pts)))) @ np.asarray(h, dtype=np.float64).T
    return hom[:, :2] / hom[:, 2:3]


@dataclass(frozen=True)
class PlaneModel:
    """The measurement plane seen by one camera: camera + homography + pose.

    What ``cvmeasure plane`` measures from a board lying on the plane, saved with
    :meth:`save` and read back whole with :meth:`load` (camera included), and
    rescaled with the photo like the camera (:meth:`for_image`).

    Attributes
    ----------
    camera : CameraModel
        The camera (distortion is removed before the homography).
    H_board_image : ndarray (3, 3)
        Undistorted image px -> board mm (homogeneous, [2, 2] = 1).
    rvec, tvec_mm : ndarray (3,)
        Board pose, camera <- board (OpenCV convention; mm).
    tilt_deg : float
        Angle between the plane normal and the optical axis.
    tilt_direction_deg : float
        Image direction in which the plane recedes from the camera, degrees
        counter-clockwise from +x as seen in the photo (0 when the tilt is 0).
    mm_per_px : float
        Scale on the plane at the board centre, mm per (undistorted) pixel.
    worst_angle_error_deg : float
        Worst direction error over the board's region from ignoring the tilt
        (a rotation + uniform scale model instead of the homography).
    tolerance_deg : float
        What the affine verdict allows.
    rms_px : float
        RMS reprojection error of the board corners under the pose, px.
    corner_count : int
    source : str
        The photo the plane was measured on.
    """

    camera: CameraModel
    H_board_image: NDArray[np.float64]
    rvec: NDArray[np.float64]
    tvec_mm: NDArray[np.float64]
    tilt_deg: float
    tilt_direction_deg: float
    mm_per_px: float
    worst_angle_error_deg: float
    tolerance_deg: float
    rms_px: float
    corner_count: int
    source: str = "image"

    def __post_init__(self) -> None:
        h = np.asarray(self.H_board_image, dtype=np.float64).reshape(3, 3)
        object.__setattr__(self, "H_board_image", h / h[2, 2])
        object.__setattr__(self, "rvec", np.asarray(self.rvec, dtype=np.float64).reshape(3))
        object.__setattr__(self, "tvec_mm", np.asarray(self.tvec_mm, dtype=np.float64).reshape(3))

    @property
    def affine_ok(self) -> bool:
        """True when ignoring the tilt keeps angle errors within the tolerance."""
        return self.worst_angle_error_deg <= self.tolerance_deg

    @property
    def H_image_board(self) -> NDArray[np.float64]:
        """Board mm -> undistorted image px."""
        inv = np.linalg.inv(self.H_board_image)
        return inv / inv[2, 2]

    def image_to_plane_mm(self, points_px: Any, *, height_mm: float = 0.0) -> NDArray[np.float64]:
        """Photo pixels (N, 2), distorted as taken -> board-frame (x, y) mm (N, 2).

        ``height_mm`` 0 is the board's plane (its homography). Otherwise each pixel's
        undistorted ray meets the parallel plane ``height_mm`` above the board
        (towards the camera, whichever way the frame's z points): a marker on
        top of the pin, the axis of a wire lying on the plate. Mapping such a point
        to the board plane instead moves it about the camera's foot point by about
        height / distance of its offset (1 mm at 20 mm height, 25 mm off axis, 500 mm).
        """
        pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            return np.zeros((0, 2))
        if height_mm == 0.0:
            return apply_homography(self.H_board_image, self.camera.undistort_px(pts))

        rot, _ = cv2.Rodrigues(self.rvec)
        rays = np.column_stack((self.camera.normalized(pts), np.ones(len(pts))))
        # board point X = R^T (s ray - t); pick s so that its z is the raised plane's
        rt_rays = rays @ rot  # rows: R^T ray
        rt_t = rot.T @ self.tvec_mm
        scale = (rt_t[2] + self._board_z_mm(height_mm)) / rt_rays[:, 2]
        board = scale[:, None] * rt_rays - rt_t[None, :]
        return board[:, :2]

    def _board_z_mm(self, height_mm: float) -> float:
        """The board frame's z of the plane ``height_mm`` above the board towards the camera."""
        if height_mm == 0.0:
            return 0.0
        rot, _ = cv2.Rodrigues(self.rvec)
        # the camera is at z = -(R^T t)[2]: a board frame's z points away from it when that
        # is positive (a plane from ``cvmeasure plane``)
        away = (rot.T @ np.asarray(self.tvec_mm, dtype=np.float64).reshape(3))[2] >= 0
        return -height_mm if away else height_mm

    @property
    def camera_centre_mm(self) -> NDArray[np.float64]:
        """The camera's centre (3,) in the board frame, mm (``-R^T t``; its z is negative for
        a plane from ``cvmeasure plane``: the board frame's z points away from the camera)."""

        rot, _ = cv2.Rodrigues(self.rvec)
        return -rot.T @ np.asarray(self.tvec_mm, dtype=np.float64).reshape(3)

    def plane_to_image_px(self, points_mm: Any, *, height_mm: float = 0.0) -> NDArray[np.float64]:
        """Board-frame mm (N, 2) on the plane, or board-frame points (N, 3) -> photo pixels (N, 2).

        With distortion. (N, 2) points lie ``height_mm`` above the board (towards the camera,
        as in :meth:`image_to_plane_mm`, which this inverts): the axis of a wire lying on the
        plate is drawn where the photo shows it, not about ``height / distance`` of its offset
        from the camera's foot point nearer to it. For (N, 3), z is the board frame's own
        (away from the camera for a plane from ``cvmeasure plane``: a height above the plate
        is -z) and ``height_mm`` must be 0.
        """

        arr = np.asarray(points_mm, dtype=np.float64)
        if arr.ndim == 2 and arr.shape[1] == 3:
            if height_mm != 0.0:
                raise ValueError("height_mm is for (N, 2) points; (N, 3) points carry their z")
            obj = arr
        else:
            pts = arr.reshape(-1, 2)
            obj = np.column_stack((pts, np.full(len(pts), self._board_z_mm(height_mm))))
        if len(obj) == 0:
            return np.zeros((0, 2))
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

        ``sigma_mm``: median 1-sigma projection uncertainty (corner noise and the errors
        a view's corners share);
        ``cross_validation_mm``: the even/odd halves' central disagreement, which
        also holds model error -- the honest figure. None when the camera JSON
        does not carry them (not written by ``cvmeasure calibrate``); a camera rescaled
        for a resized photo carries them in its pixels
        (:meth:`cvmeasure.camera_model.CameraModel.scaled`).
        """
        cal = self.camera.lens_record or {}
        unc = (cal.get("projection_uncertainty") or {}).get("median_px")
        cv = (cal.get("cross_validation") or {}).get("central_60pct_rms_px")
        return {
            "sigma_mm": None if unc is None else float(unc) * self.mm_per_px,
            "cross_validation_mm": None if cv is None else float(cv) * self.mm_per_px,
        }

    def scaled(self, factor: float) -> PlaneModel:
        """The same plane for the photo resized by ``factor`` (camera and homography rescaled)."""
        camera = self.camera.scaled(factor)
        # undistorted px of the resized photo = S @ undistorted px of the original
        s = camera.camera_matrix @ np.linalg.inv(self.camera.camera_matrix)
        return replace(
            self,
            camera=camera,
            H_board_image=self.H_board_image @ np.linalg.inv(s),
            mm_per_px=self.mm_per_px / factor,
            rms_px=self.rms_px * factor,
        )

    def for_image(self, size_px: tuple[int, int], source: str = "photo") -> PlaneModel:
        """This plane for a photo of ``size_px`` (width, height): itself or rescaled.

        InputError naming ``source`` for a photo of another aspect ratio.
        """
        camera = self.camera.for_image(size_px, source)
        if camera is self.camera:
            return self
        return self.scaled(camera.image_size_px[0] / self.camera.image_size_px[0])

    def to_dict(self) -> dict[str, Any]:
        """The plane JSON: the check's figures, the homography, the pose and the camera."""
        return {
            "format": PLANE_FORMAT,
            "source": self.source,
            "tilt_deg": self.tilt_deg,
            "tilt_direction_deg": self.tilt_direction_deg,
            "mm_per_px": self.mm_per_px,
            "worst_angle_error_deg": self.worst_angle_error_deg,
            "tolerance_deg": self.tolerance_deg,
            "affine_ok": self.affine_ok,
            "rms_px": self.rms_px,
            "corner_count": self.corner_count,
            "H_board_image": self.H_board_image.tolist(),
            "homography_frames": "undistorted image px -> board mm",
            "rvec": self.rvec.tolist(),
            "tvec_mm": self.tvec_mm.tolist(),
            "lens_uncertainty_mm": self.lens_uncertainty_mm(),
            "camera": self.camera.to_dict(),
        }

    @classmethod
    def from_dict(
        cls,
        d: Any,
        *,
        camera: CameraModel | None = None,
        source: str | os.PathLike[str] = "plane JSON",
    ) -> PlaneModel:
        """Read a plane JSON back whole; InputError names ``source`` and the problem.

        A plane JSON carries its camera. ``camera``, when given, must be that camera
        (same intrinsics and distortion): a plane measured through one lens model
        does not map another's pixels. A plane JSON written before the camera was
        saved with it (no ``camera`` key) is read with ``camera``, and refused without.
        """
        if not isinstance(d, dict):
            raise InputError(source, "a plane JSON must be an object")
        try:
            h = np.asarray(d["H_board_image"], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise InputError(source, "plane JSON lacks a 3x3 'H_board_image'") from None
        if h.shape != (3, 3) or not np.all(np.isfinite(h)) or abs(np.linalg.det(h)) < 1e-15:
            raise InputError(source, "'H_board_image' must be a finite, invertible 3x3 matrix")
        saved = d.get("camera")
        if saved is not None:
            own = CameraModel.from_dict(saved, source=f"{source}: camera")
            if camera is not None and not own.same_lens(camera):
                raise InputError(
                    source,
                    "the plane was measured with another camera model than the one given "
                    "(re-run `cvmeasure plane` with this camera, or drop --camera)",
                )
            camera = own
        if camera is None:
            raise InputError(
                source, "plane JSON has no camera (written by an older cvmeasure): give --camera"
            )
        try:
            if "rvec" in d and "tvec_mm" in d:
                rvec = np.asarray(d["rvec"], dtype=np.float64).reshape(3)
                tvec = np.asarray(d["tvec_mm"], dtype=np.float64).reshape(3)
            else:  # an older plane JSON: the pose is in the homography and the camera
                rvec, tvec = _pose_from_homography(camera, h)
            numbers = {
                k: float(d.get(k, default))
                for k, default in (
                    ("tilt_deg", math.nan),
                    ("tilt_direction_deg", math.nan),
                    ("mm_per_px", math.nan),
                    ("worst_angle_error_deg", math.nan),
                    ("tolerance_deg", math.nan),
                    ("rms_px", math.nan),
                )
            }
            corners = int(d.get("corner_count", 0))
        except (TypeError, ValueError) as exc:
            raise InputError(source, f"plane JSON has a malformed value: {exc}") from None
        return cls(
            camera=camera,
            H_board_image=h,
            rvec=rvec,
            tvec_mm=tvec,
            corner_count=corners,
            source=str(d.get("source", source)),
            **numbers,
        )

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the plane JSON atomically; return its path."""

        return atomic_write_json(path, to_jsonable(self.to_dict()))

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, camera: CameraModel | None = None) -> PlaneModel:
        """Read a plane JSON (see :meth:`from_dict`); InputError names the file."""

        return cls.from_dict(read_json(path, what="plane JSON"), camera=camera, source=str(path))
