"""Camera blur that depends on the scene: thin-lens depth of field and motion.

Both act on the linear albedo image before :func:`~cvmeasure_datasets.lighting.develop`
(which adds the lens's own blur, the mosaic, noise and JPEG); both kernels are
symmetric, so they spread edges without moving the centre of a flat disc.
"""

from __future__ import annotations

import numpy as np

__all__ = ["defocus_diameter_px", "depth_of_field", "motion_blur", "motion_kernel"]


def defocus_diameter_px(
    depth_mm: np.ndarray, focus_mm: float, focal_px: float, focal_length_mm: float, f_number: float
) -> np.ndarray:
    """Thin-lens blur-circle diameter in pixels at camera depth ``depth_mm``.

    ``c = (f / N) * f / (s_f - f) * |s - s_f| / s`` on the sensor, in pixels
    ``f_px / f_mm`` per mm (the aperture's diameter is ``f / N``).
    """
    f = focal_length_mm
    aperture_px = focal_px / f_number  # (f / N) in pixels of the sensor
    return aperture_px * f / (focus_mm - f) * np.abs(depth_mm - focus_mm) / depth_mm


_LEVELS = np.array([0.0, 0.35, 0.7, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0])


def depth_of_field(img: np.ndarray, blur_diameter_px: np.ndarray) -> np.ndarray:
    """Spatially varying defocus of ``img`` (H, W, C) float32.

    The blur circle of diameter ``c`` (pillbox) is taken as a Gaussian of the same
    second moment (sigma = c / 4); each pixel blends the two nearest of a ladder of
    Gaussian-blurred copies by its sigma.
    """
    import cv2

    sigma = np.clip(blur_diameter_px.astype(np.float32) / 4.0, 0.0, _LEVELS[-1])
    # fractional index of each pixel's sigma in the ladder; level k weighs 1 - |p - k|
    pos = np.interp(sigma, _LEVELS, np.arange(len(_LEVELS))).astype(np.float32)
    out = np.zeros_like(img)
    for k in range(int(np.floor(pos.min())), int(np.ceil(pos.max())) + 1):
        w = np.clip(1.0 - np.abs(pos - np.float32(k)), 0.0, 1.0)
        rows = np.nonzero(w.any(axis=1))[0]
        if len(rows) == 0:
            continue
        # blur a band of rows with a margin of 4 sigma, then keep the weighted rows
        r0, r1 = rows[0], rows[-1] + 1
        pad = int(np.ceil(4 * _LEVELS[k])) + 1
        a0, a1 = max(0, r0 - pad), min(img.shape[0], r1 + pad)
        band = img[a0:a1]
        level = band if k == 0 else cv2.GaussianBlur(band, (0, 0), sigmaX=float(_LEVELS[k]))
        out[r0:r1] += w[r0:r1, :, None] * level[r0 - a0 : r1 - a0]
    return out


def motion_kernel(length_px: float, angle_deg: float) -> np.ndarray:
    """A normalised straight smear ``length_px`` long at ``angle_deg`` (image x, y down).

    Sampled densely along the segment and splatted bilinearly: symmetric about its centre.
    """
    half = int(np.ceil(length_px / 2)) + 1
    size = 2 * half + 1
    k = np.zeros((size, size), dtype=np.float64)
    n = max(2, int(length_px * 16) + 1)
    t = np.linspace(-length_px / 2, length_px / 2, n)
    xs = half + t * np.cos(np.radians(angle_deg))
    ys = half + t * np.sin(np.radians(angle_deg))
    x0, y0 = np.floor(xs).astype(int), np.floor(ys).astype(int)
    fx, fy = xs - x0, ys - y0
    for dx, dy, wgt in (
        (0, 0, (1 - fx) * (1 - fy)),
        (1, 0, fx * (1 - fy)),
        (0, 1, (1 - fx) * fy),
        (1, 1, fx * fy),
    ):
        np.add.at(k, (y0 + dy, x0 + dx), wgt)
    return (k / k.sum()).astype(np.float32)


def motion_blur(img: np.ndarray, length_px: float, angle_deg: float) -> np.ndarray:
    """Smear ``img`` along a straight line (see :func:`motion_kernel`)."""
    import cv2

    if length_px <= 0:
        return img
    return cv2.filter2D(img, -1, motion_kernel(length_px, angle_deg), borderType=cv2.BORDER_REFLECT)
