"""The camera model: pinhole intrinsics plus OpenCV (Brown-Conrady) distortion.

Frames: image pixels in OpenCV's convention (x right, y down, the centre of the
top-left pixel at (0, 0)); camera frame x right, y down, z forward, in mm.
The camera JSON (spec ``camera JSON``) holds ``image_size`` [w, h],
``camera_matrix`` (3x3), ``dist_coeffs`` (OpenCV order, 4/5/8/12/14 values) and,
when written by ``cvmeasure calibrate``, the calibration record that lets a
user judge and redo the solve (RMS, standard deviations, per-view errors,
views used and rejected, ...), kept verbatim in :attr:`CameraModel.lens_record`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from cvmeasure.errors import InputError
from cvmeasure.fileio import atomic_write_json, read_json

__all__ = [
    "SCALED_LENS_FIGURES",
    "CameraModel",
    "implausible_distortion",
    "load_camera",
    "save_camera",
]

_VALID_DIST_LENGTHS = (4, 5, 8, 12, 14)

#: The lens record's figures a rescaled camera carries, each ``(section, key)`` in pixels
#: (:meth:`CameraModel.scaled`): the median projection uncertainty and the even/odd
#: halves' disagreement that :meth:`cvmeasure.plane_model.PlaneModel.lens_uncertainty_mm`
#: states in mm.
SCALED_LENS_FIGURES = (
    ("projection_uncertainty", "median_px"),
    ("cross_validation", "central_60pct_rms_px"),
)


@dataclass(frozen=True)
class CameraModel:
    """Intrinsics and distortion of one camera at one image size.

    Attributes
    ----------
    image_size_px : (width, height) in pixels.
    camera_matrix : ndarray (3, 3), float64, pixels.
    dist_coeffs : ndarray (K,), float64, OpenCV order (k1 k2 p1 p2 [k3 [k4 k5 k6 [s1..s4 [tx ty]]]]).
    lens_record : dict, everything else the camera JSON holds (RMS, sigmas, views...).
    """

    image_size_px: tuple[int, int]
    camera_matrix: np.ndarray
    dist_coeffs: np.ndarray
    lens_record: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        k = np.asarray(self.camera_matrix, dtype=np.float64).reshape(3, 3)
        d = np.asarray(self.dist_coeffs, dtype=np.float64).ravel()
        if d.size == 0:
            d = np.zeros(5)
        if d.size not in _VALID_DIST_LENGTHS:
            raise ValueError(
                f"dist_coeffs must have one of {_VALID_DIST_LENGTHS} values, got {d.size}"
            )
        w, h = (int(v) for v in self.image_size_px)
        object.__setattr__(self, "camera_matrix", k)
        object.__setattr__(self, "dist_coeffs", d)
        object.__setattr__(self, "image_size_px", (w, h))

    # -- convenience ---------------------------------------------------------
    @property
    def fx(self) -> float:
        return float(self.camera_matrix[0, 0])

    @property
    def fy(self) -> float:
        return float(self.camera_matrix[1, 1])

    @property
    def principal_point_px(self) -> tuple[float, float]:
        return float(self.camera_matrix[0, 2]), float(self.camera_matrix[1, 2])

    @classmethod
    def ideal(
        cls,
        image_size_px: tuple[int, int],
        focal_px: float,
        dist_coeffs: Any = (0.0, 0.0, 0.0, 0.0, 0.0),
        principal_point_px: tuple[float, float] | None = None,
    ) -> CameraModel:
        """A camera with square pixels and the given focal length (px)."""
        w, h = image_size_px
        cx, cy = (
            principal_point_px if principal_point_px is not None else ((w - 1) / 2, (h - 1) / 2)
        )
        k = np.array([[focal_px, 0, cx], [0, focal_px, cy], [0, 0, 1]], dtype=np.float64)
        return cls((w, h), k, np.asarray(dist_coeffs, dtype=np.float64))

    def scaled(self, factor: float) -> CameraModel:
        """The same lens for an image resized by ``factor`` (pixel-centre convention kept).

        The lens record keeps the calibration's own uncertainty, in pixels of the resized
        image (:data:`SCALED_LENS_FIGURES`), so that a reduced photo states the same
        uncertainty in mm on the plate as the photo the camera was calibrated at; the rest
        of the record (views, RMS of the calibration's own images) is not carried.
        """
        k = self.camera_matrix.copy()
        k[0, 0] *= factor
        k[1, 1] *= factor
        k[0, 2] = (k[0, 2] + 0.5) * factor - 0.5
        k[1, 2] = (k[1, 2] + 0.5) * factor - 0.5
        w, h = self.image_size_px
        record: dict[str, Any] = {}
        for section, key in SCALED_LENS_FIGURES:
            value = (self.lens_record.get(section) or {}).get(key)
            if value is not None:
                record[section] = {key: float(value) * factor}
        size = (round(w * factor), round(h * factor))
        return CameraModel(size, k, self.dist_coeffs.copy(), lens_record=record)

    def for_image(self, size_px: tuple[int, int], source: str = "photo") -> CameraModel:
        """This camera for a photo of ``size_px`` (width, height) px.

        Itself at the calibrated size; rescaled (:meth:`scaled`) for a photo resized
        by one factor (a reduced JPEG, a half-size RAW); InputError naming ``source``
        for another aspect ratio.

        >>> cam = CameraModel.ideal((4000, 3000), focal_px=3000.0)
        >>> cam.for_image((2000, 1500)).camera_matrix[0, 0]
        1500.0
        """
        w, h = (int(v) for v in size_px)
        cw, ch = self.image_size_px
        if (cw, ch) == (w, h):
            return self
        factor = w / cw
        if abs(h / ch - factor) > 0.01 * factor:
            raise InputError(
                source, f"photo is {w}x{h} px but the camera model is for {cw}x{ch} (other aspect)"
            )
        return self.scaled(factor)

    def same_lens(self, other: CameraModel) -> bool:
        """Same intrinsics and distortion as ``other``, once brought to this image size."""
        try:
            other = other.for_image(self.image_size_px)
        except InputError:
            return False
        n = max(self.dist_coeffs.size, other.dist_coeffs.size)
        da = np.pad(self.dist_coeffs, (0, n - self.dist_coeffs.size))
        db = np.pad(other.dist_coeffs, (0, n - other.dist_coeffs.size))
        return bool(
            np.allclose(self.camera_matrix, other.camera_matrix, rtol=1e-6, atol=1e-6)
            and np.allclose(da, db, rtol=1e-6, atol=1e-9)
        )

    # -- geometry ------------------------------------------------------------
    def project(self, points_cam_mm: np.ndarray) -> np.ndarray:
        """Project camera-frame points (N, 3) in mm to distorted pixels (N, 2)."""

        pts = np.asarray(points_cam_mm, dtype=np.float64).reshape(-1, 1, 3)
        img, _ = cv2.projectPoints(
            pts, np.zeros(3), np.zeros(3), self.camera_matrix, self.dist_coeffs
        )
        return img.reshape(-1, 2)

    def undistort_px(self, points_px: np.ndarray) -> np.ndarray:
        """Remove lens distortion: distorted pixels (N, 2) -> ideal pinhole pixels (N, 2)."""

        pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 1, 2)
        if pts.shape[0] == 0:
            return np.zeros((0, 2))
        crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        out = cv2.undistortPoints(
            pts, self.camera_matrix, self.dist_coeffs, P=self.camera_matrix, criteria=crit
        )
        return out.reshape(-1, 2)

    def normalized(self, points_px: np.ndarray) -> np.ndarray:
        """Distorted pixels (N, 2) -> normalised ray coordinates x/z, y/z (N, 2)."""
        und = self.undistort_px(points_px)
        k = self.camera_matrix
        return np.column_stack(((und[:, 0] - k[0, 2]) / k[0, 0], (und[:, 1] - k[1, 2]) / k[1, 1]))

    # -- serialisation -------------------------------------------------------
    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "image_size": list(self.image_size_px),
            "camera_matrix": self.camera_matrix.tolist(),
            "dist_coeffs": self.dist_coeffs.tolist(),
        }
        for key, value in self.lens_record.items():
            out.setdefault(key, value)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any], *, source: str = "camera JSON") -> CameraModel:
        """Build from the camera JSON of the spec; InputError names ``source`` on schema errors."""
        if not isinstance(data, dict):
            raise InputError(source, "camera JSON must be an object")
        try:
            size = data["image_size"]
            k = np.asarray(data["camera_matrix"], dtype=np.float64)
            d = np.asarray(data.get("dist_coeffs", []), dtype=np.float64).ravel()
        except KeyError as exc:
            raise InputError(source, f"camera JSON lacks {exc.args[0]!r}") from None
        except (TypeError, ValueError) as exc:
            raise InputError(source, f"camera JSON has a malformed value: {exc}") from None
        if k.shape != (3, 3) or not np.all(np.isfinite(k)) or k[0, 0] <= 0 or k[1, 1] <= 0:
            raise InputError(
                source, "camera_matrix must be a finite 3x3 matrix with positive focal lengths"
            )
        if len(size) != 2 or min(size) <= 0:
            raise InputError(source, "image_size must be [width, height] in pixels")
        if "dist_coeffs" not in data:
            # a file without its coefficients is not a lens without distortion ([] says that)
            raise InputError(source, "camera JSON lacks 'dist_coeffs' (give [] for none)")
        if d.size and d.size not in _VALID_DIST_LENGTHS:
            raise InputError(
                source, f"dist_coeffs must have one of {_VALID_DIST_LENGTHS} values, got {d.size}"
            )
        if not np.all(np.isfinite(d)):
            raise InputError(source, "dist_coeffs must be finite numbers")
        rms = data.get("rms_px")
        if rms is not None and (isinstance(rms, bool) or not isinstance(rms, (int, float))):
            raise InputError(source, f"rms_px must be a number of pixels, got {rms!r}")
        problem = implausible_distortion(k, d, (float(size[0]), float(size[1])))
        if problem:
            raise InputError(source, problem)
        rest = {
            k2: v
            for k2, v in data.items()
            if k2 not in ("image_size", "camera_matrix", "dist_coeffs")
        }
        return cls((int(size[0]), int(size[1])), k, d, rest)


def implausible_distortion(k: np.ndarray, d: np.ndarray, size: tuple[float, float]) -> str:
    """Why the radial distortion cannot be a real lens over this image ("" when it can).

    Over the image (out to its farthest corner) the radial factor must stay positive,
    move a point by less than its own distance from the centre, and keep the order of
    radii (monotonic): a coefficient off by orders of magnitude (a typo, a corrupt file)
    folds the image over itself.
    """
    if d.size < 5:
        return ""
    corners = np.array([[0.0, 0.0], [size[0], 0.0], [0.0, size[1]], [size[0], size[1]]])
    xn = (corners[:, 0] - k[0, 2]) / k[0, 0]
    yn = (corners[:, 1] - k[1, 2]) / k[1, 1]
    r = np.linspace(0.0, float(np.max(np.hypot(xn, yn))), 200)
    r2 = r * r
    num = 1 + d[0] * r2 + d[1] * r2**2 + d[4] * r2**3
    den = 1 + (d[5] * r2 + d[6] * r2**2 + d[7] * r2**3 if d.size >= 8 else 0.0)
    factor = num / den
    if np.any(factor <= 0) or np.any(np.abs(factor - 1) >= 1):
        worst = float(factor[np.argmax(np.abs(factor - 1))])
        return (
            f"dist_coeffs {np.array2string(d[:5], precision=4)} scale a radius by {worst:.3g} "
            "within the image: not a plausible lens (a wrong or corrupt coefficient?)"
        )
    if np.any(np.diff(r * factor) <= 0):
        return "dist_coeffs fold the image over itself (the distorted radius stops growing)"
    return ""


def load_camera(path: str | os.PathLike[str]) -> CameraModel:
    """Read a camera JSON file (spec); InputError naming the file on any problem."""
    return CameraModel.from_dict(read_json(path, what="camera JSON"), source=str(path))


def save_camera(path: str | os.PathLike[str], camera: CameraModel) -> Path:
    """Write a camera JSON file atomically."""
    return atomic_write_json(path, camera.to_dict())
