"""sRGB, CIE XYZ and CIE L*a*b* (D65): the few colour formulas the hot paths need.

These are the IEC 61966-2-1 sRGB transfer functions and primaries and the
CIE 15 L*a*b* formulas, written in NumPy so that measuring a photo does not
import colour-science (about 0.7 s of CPU per worker process). The tests check
them against colour-science, which stays the reference and is used wherever
speed does not matter (chromatic adaptation, delta E).
Values: gamma-encoded and linear sRGB in 0..1 unless the name says ``8`` (0..255);
XYZ with the white at Y = 1.
"""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "SRGB_TO_XYZ",
    "XYZ_TO_SRGB",
    "D65_XY",
    "D65_XYZ",
    "SRGB8_TO_LINEAR",
    "srgb_decode",
    "srgb_encode",
    "srgb_encode_floats",
    "xyz_to_lab_d65",
    "srgb8_to_lab_d65",
]

#: Linear sRGB -> CIE XYZ (D65), IEC 61966-2-1.
SRGB_TO_XYZ = np.array(
    [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]]
)
XYZ_TO_SRGB = np.linalg.inv(SRGB_TO_XYZ)
#: CIE 1931 2-degree chromaticity of D65 and its XYZ with Y = 1.
D65_XY = np.array([0.3127, 0.3290])
D65_XYZ = np.array([D65_XY[0] / D65_XY[1], 1.0, (1 - D65_XY.sum()) / D65_XY[1]])


def srgb_decode(v: ArrayLike) -> np.ndarray:
    """Gamma-encoded sRGB (0..1) -> linear; keeps a float32 input float32."""
    v = np.asarray(v)
    if not np.issubdtype(v.dtype, np.floating):
        v = v.astype(np.float64)
    return np.where(v <= 0.04045, v / 12.92, np.power((v + 0.055) / 1.055, 2.4))


def srgb_encode(v: ArrayLike, *, clip: bool = True) -> np.ndarray:
    """Linear sRGB -> gamma-encoded; ``clip`` limits to 0..1, else only negatives are cut."""
    v = np.asarray(v)
    if not np.issubdtype(v.dtype, np.floating):
        v = v.astype(np.float64)
    v = np.clip(v, 0.0, 1.0) if clip else np.maximum(v, 0.0)
    return np.where(v <= 0.0031308, 12.92 * v, 1.055 * np.power(v, 1 / 2.4) - 0.055)


def srgb_encode_floats(values: Iterable[float]) -> tuple[float, ...]:
    """:func:`srgb_encode` (clipped to 0..1) of a few Python floats, by scalar arithmetic:
    for a handful of values numpy's per-call overhead is most of the cost."""
    out = []
    for v in values:
        v = min(max(float(v), 0.0), 1.0)
        out.append(12.92 * v if v <= 0.0031308 else 1.055 * v ** (1 / 2.4) - 0.055)
    return tuple(out)


#: 8-bit gamma-encoded value -> linear, float32 (a lookup table for cv2.LUT).
SRGB8_TO_LINEAR = srgb_decode(np.arange(256) / 255.0).astype(np.float32)


def xyz_to_lab_d65(xyz: ArrayLike) -> np.ndarray:
    """CIE XYZ (..., 3), white Y = 1 -> CIE L*a*b* (..., 3) under D65 (CIE 15)."""
    t = np.asarray(xyz, dtype=np.float64) / D65_XYZ
    eps, kappa = 216 / 24389, 24389 / 27
    f = np.where(t > eps, np.cbrt(t), (kappa * t + 16) / 116)
    return np.stack(
        (116 * f[..., 1] - 16, 500 * (f[..., 0] - f[..., 1]), 200 * (f[..., 1] - f[..., 2])),
        axis=-1,
    )


def srgb8_to_lab_d65(srgb8: ArrayLike) -> np.ndarray:
    """8-bit gamma-encoded sRGB (..., 3) -> CIE L*a*b* under D65 (..., 3)."""
    lin = srgb_decode(np.asarray(srgb8, dtype=np.float64) / 255.0)
    return xyz_to_lab_d65(lin @ SRGB_TO_XYZ.T)
