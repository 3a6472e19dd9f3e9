"""Dilations computed only where they can change anything (the same pixels as ``cv2.dilate``).

A dilation of a thin wire's mask by a disc a wire wide, run on a whole 14-45 MP photo,
spends nearly all its time on pixels far from the wire; and whether a few points lie
near a large region needs the dilation at those points only. Both give exactly what
``cv2.dilate`` with the same structuring element (anchor at its centre, pixels outside
the image not counted) gives there.
"""

from __future__ import annotations

import cv2
import numpy as np

__all__ = ["dilate_local", "dilated_at"]


def dilate_local(mask: np.ndarray, kernel: np.ndarray) -> np.ndarray:
    """``cv2.dilate(mask, kernel)`` computed on the mask's bounding box grown by the kernel.

    Parameters
    ----------
    mask : ndarray (H, W) uint8 or bool.
    kernel : ndarray (kh, kw) uint8, odd sizes; anchored at its centre.

    Returns
    -------
    ndarray (H, W), ``mask``'s dtype (bool in, bool out).
    """
    m8 = mask.astype(np.uint8, copy=False)
    out = np.zeros(m8.shape, dtype=np.uint8)
    ys, xs = np.nonzero(m8.any(axis=1))[0], np.nonzero(m8.any(axis=0))[0]
    if len(ys):
        ay, ax = kernel.shape[0] // 2, kernel.shape[1] // 2
        h, w = m8.shape
        y0, y1 = max(0, ys[0] - ay), min(h, ys[-1] + ay + 1)
        x0, x1 = max(0, xs[0] - ax), min(w, xs[-1] + ax + 1)
        out[y0:y1, x0:x1] = cv2.dilate(m8[y0:y1, x0:x1], kernel)
    return out.astype(bool) if mask.dtype == bool else out.astype(mask.dtype, copy=False)


def dilated_at(mask: np.ndarray, kernel: np.ndarray, points_px: np.ndarray) -> np.ndarray:
    """``cv2.dilate(mask, kernel)`` read at integer points (N, 2) x, y: bool (N,).

    Points outside the image read False.
    """
    m = np.asarray(mask)
    h, w = m.shape
    ay, ax = kernel.shape[0] // 2, kernel.shape[1] // 2
    k = np.asarray(kernel) != 0
    out = np.zeros(len(points_px), dtype=bool)
    for i, (x, y) in enumerate(np.asarray(points_px, dtype=np.int64).reshape(-1, 2)):
        if not (0 <= y < h and 0 <= x < w):
            continue
        # dst(x, y) = max of src(x + i - ax, y + j - ay) over the kernel's (i, j)
        y0, x0 = y - ay, x - ax
        ys0, xs0 = max(0, y0), max(0, x0)
        ys1, xs1 = min(h, y0 + k.shape[0]), min(w, x0 + k.shape[1])
        win = m[ys0:ys1, xs0:xs1] != 0
        sub = k[ys0 - y0 : ys1 - y0, xs0 - x0 : xs1 - x0]
        out[i] = bool(np.any(win & sub))
    return out
