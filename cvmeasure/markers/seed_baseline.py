"""The seed paper's marker method, kept as a baseline (seed paper part III, source code 12).

Fixed colour boxes per marker in OpenCV's 8-bit LAB (or BGR), a binary AND of
the three channel filters, ``medianBlur(7)``, ``HoughCircles`` (HOUGH_GRADIENT,
dp 1, minDist 100, param1 100, param2 15, radii 40-100 px at 4608 px width;
the lower radius is 20 px here, the paper's 40 px missing this kit's 8 mm
discs photographed from 0.5 m),
the first circle as the centre, and ``arctan2`` on raw pixel centres: no white
balance, no sub-pixel refinement, no lens model.

The paper's boxes (:data:`SEED_LAB_BOXES_PAPER`) were typed for its own printed
markers and light; to compare *methods* on this project's kit, the baseline
keeps the paper's box widths and centres each box on the kit's colour
(converted to OpenCV's 8-bit LAB: L*255/100, a+128, b+128). The paper gives no
RGB numbers; its RGB baseline here is the kit's sRGB +- 40 per channel.
(The paper's listing also thresholds the BGR image instead of the LAB one --
``l = image[:, :, 0]`` -- a slip not reproduced here.)
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from cvmeasure.kit import ROLES, MarkerKit

__all__ = [
    "SEED_LAB_BOXES_PAPER",
    "SEED_RGB_HALF_WIDTH",
    "SeedCircle",
    "seed_boxes",
    "seed_find_circles",
]

#: Source code 12 of the seed paper: [L_min, L_max, a_min, a_max, b_min, b_max], OpenCV 8-bit LAB.
SEED_LAB_BOXES_PAPER: dict[str, tuple[int, int, int, int, int, int]] = {
    "origin": (70, 120, 100, 120, 120, 140),  # dark green
    "axis": (110, 150, 110, 130, 140, 160),  # yellow-green
    "pin": (130, 190, 120, 135, 150, 190),  # yellow
    "wire_a": (70, 130, 110, 130, 80, 110),  # blue
    "wire_b": (70, 115, 150, 200, 130, 150),  # magenta
}
#: Half-width (8-bit units) of the RGB boxes around the kit's sRGB colour.
SEED_RGB_HALF_WIDTH = 40


@dataclass(frozen=True)
class SeedCircle:
    """The first Hough circle of one role (image pixels), or None fields when not found."""

    role: str
    centre_px: tuple[float, float] | None
    radius_px: float | None
    n_circles: int


def seed_boxes(kit: MarkerKit, space: str = "lab") -> dict[str, np.ndarray]:
    """Fixed (lower, upper) boxes per role: ndarray (2, 3) in OpenCV's channel order of ``space``."""
    boxes = {}
    for role in ROLES:
        marker = kit.by_role(role)
        if space == "lab":
            paper = np.asarray(SEED_LAB_BOXES_PAPER[role], dtype=np.float64).reshape(3, 2)
            half = (paper[:, 1] - paper[:, 0]) / 2
            lab = marker.lab_d65
            centre = np.array([lab[0] * 255 / 100, lab[1] + 128, lab[2] + 128])
        elif space == "rgb":
            half = np.full(3, float(SEED_RGB_HALF_WIDTH))
            centre = np.asarray(marker.srgb[::-1], dtype=np.float64)  # BGR
        else:
            raise ValueError(f"unknown colour space {space!r}; valid: ('lab', 'rgb')")
        boxes[role] = np.clip(np.stack((centre - half, centre + half)), 0, 255)
    return boxes


def seed_find_circles(
    bgr8: np.ndarray, kit: MarkerKit, space: str = "lab"
) -> dict[str, SeedCircle]:
    """Run the seed method on one photo: the first Hough circle per role.

    Radii and minimum distance are the paper's, scaled by image width / 4608.
    """
    img = np.asarray(bgr8)
    scale = img.shape[1] / 4608.0
    conv = cv2.cvtColor(img, cv2.COLOR_BGR2LAB) if space == "lab" else img
    out = {}
    for role, box in seed_boxes(kit, space).items():
        lo = np.floor(box[0]).astype(np.uint8)
        hi = np.ceil(box[1]).astype(np.uint8)
        mask = cv2.inRange(conv, lo, hi)
        blurred = cv2.medianBlur(mask, 7)
        circles = cv2.HoughCircles(
            blurred,
            cv2.HOUGH_GRADIENT,
            dp=1,
            minDist=max(4.0, 100 * scale),
            param1=100,
            param2=max(5, round(15 * scale)),
            minRadius=max(2, round(20 * scale)),
            maxRadius=max(4, round(100 * scale)),
        )
        if circles is None:
            out[role] = SeedCircle(role, None, None, 0)
        else:
            x, y, r = (float(v) for v in circles[0, 0])
            out[role] = SeedCircle(role, (x, y), r, int(circles.shape[1]))
    return out
