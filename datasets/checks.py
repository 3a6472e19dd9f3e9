"""Fidelity checks of rendered photos against their own truth.

Used by the tests, the demo and ``benchmarks/renderer_fidelity.py``. They
measure the photos with independent, standard methods (OpenCV's ChArUco
detector + ``cornerSubPix``, sub-pixel disc edges + an ellipse fit) and report
how far the measurement lands from the truth.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.board import CharucoBoardSpec
from cvmeasure.kit import MarkerKit, default_kit
from cvmeasure_datasets.bender import RING_SRGB
from cvmeasure_datasets.lighting import srgb8_to_linear
from cvmeasure_datasets.photo import RenderedPhoto

__all__ = ["CornerCheck", "DiscCheck", "check_charuco_corners", "check_disc_centre"]

_SUBPIX = (3, 100, 1e-4)  # cv2.TERM_CRITERIA_EPS | COUNT, 100 iterations, 1e-4 px


@dataclass(frozen=True)
class CornerCheck:
    """Detected ChArUco corners against the truth, pixels."""

    ids: np.ndarray
    detected_px: np.ndarray
    true_px: np.ndarray

    @property
    def errors_px(self) -> np.ndarray:
        return np.linalg.norm(self.detected_px - self.true_px, axis=1)

    @property
    def median_px(self) -> float:
        return float(np.median(self.errors_px)) if len(self.ids) else float("nan")

    def to_dict(self) -> dict[str, Any]:
        e = self.errors_px
        return {
            "corners": int(len(self.ids)),
            "median_px": self.median_px,
            "p95_px": float(np.percentile(e, 95)) if len(e) else None,
            "max_px": float(e.max()) if len(e) else None,
        }


def check_charuco_corners(
    photo: RenderedPhoto, board: CharucoBoardSpec, *, window_px: int = 5
) -> CornerCheck:
    """Detect ChArUco corners (CharucoDetector, then cornerSubPix) and pair them with the truth."""
    import cv2

    gray = cv2.cvtColor(photo.bgr, cv2.COLOR_BGR2GRAY)
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board.cv_board()).detectBoard(gray)
    if ids is None or len(ids) == 0:
        return CornerCheck(np.zeros(0, int), np.zeros((0, 2)), np.zeros((0, 2)))
    refined = cv2.cornerSubPix(
        gray, corners.astype(np.float32), (window_px, window_px), (-1, -1), _SUBPIX
    )
    ids = ids.ravel().astype(int)
    truth = np.asarray(photo.truth["corners_px"], dtype=np.float64)[ids]
    return CornerCheck(ids, refined.reshape(-1, 2).astype(np.float64), truth)


@dataclass(frozen=True)
class DiscCheck:
    """An ellipse fitted to a marker disc's sub-pixel edge, against the truth (pixels)."""

    role: str
    fitted_centre_px: tuple[float, float]
    ellipse_centre_px: tuple[float, float]
    centre_px: tuple[float, float]
    fitted_mean_axis_px: float
    true_mean_axis_px: float

    @property
    def error_px(self) -> float:
        """Fitted centre minus the truth's image-ellipse centre."""
        return float(np.hypot(*np.subtract(self.fitted_centre_px, self.ellipse_centre_px)))

    @property
    def perspective_shift_px(self) -> float:
        """How far the projected disc centre lies from its image-ellipse centre."""
        return float(np.hypot(*np.subtract(self.centre_px, self.ellipse_centre_px)))

    def to_dict(self) -> dict[str, Any]:
        return {
            "role": self.role,
            "error_px": self.error_px,
            "perspective_shift_px": self.perspective_shift_px,
            "axis_error_px": self.fitted_mean_axis_px - self.true_mean_axis_px,
        }


def check_disc_centre(
    photo: RenderedPhoto, role: str, *, kit: MarkerKit | None = None
) -> DiscCheck:
    """Fit an ellipse to the edge of a marker's disc in a noise-free linear render.

    Compositing is linear in linear RGB, so near the disc every pixel is
    ``alpha * disc + (1 - alpha) * white``; the 0.5 contour of alpha (found
    with sub-pixel interpolation) is the disc's edge. Needs ``linear=True``.
    """
    from skimage.measure import EllipseModel, find_contours

    if photo.linear_rgb16 is None:
        raise ValueError("check_disc_centre needs a photo rendered with linear=True")
    kit = kit or default_kit()
    t = photo.truth["markers"][role]
    lin = photo.linear_rgb16.astype(np.float64) / 65535.0
    cx, cy = t["centre_px"]
    half = int(t["ring_r_px"] * 1.5) + 3
    x0, y0 = int(cx) - half, int(cy) - half
    patch = lin[y0 : y0 + 2 * half, x0 : x0 + 2 * half]
    disc = srgb8_to_linear(kit.by_role(role).srgb)
    white = srgb8_to_linear(RING_SRGB)
    ch = int(np.argmax(np.abs(white - disc)))
    alpha = (white[ch] - patch[..., ch]) / (white[ch] - disc[ch])
    yy, xx = np.mgrid[y0 : y0 + 2 * half, x0 : x0 + 2 * half]
    alpha[np.hypot(xx - cx, yy - cy) > 0.5 * (t["r_px"] + t["ring_r_px"])] = 0.0
    edge = max(find_contours(alpha, 0.5), key=len)[:, ::-1] + [x0, y0]
    model = EllipseModel.from_estimate(edge)
    centre = np.asarray(model.center, dtype=np.float64)
    return DiscCheck(
        role=role,
        fitted_centre_px=(float(centre[0]), float(centre[1])),
        ellipse_centre_px=tuple(t["ellipse_centre_px"]),
        centre_px=tuple(t["centre_px"]),
        fitted_mean_axis_px=float(np.mean(model.axis_lengths)),
        true_mean_axis_px=float(np.mean(t["ellipse_axes_px"])),
    )
