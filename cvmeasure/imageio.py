"""Reading photos: JPEG, PNG, TIFF and camera RAW (NEF, DNG, CR2, ... via rawpy).

Every reader returns a :class:`Photo` whose ``bgr`` is an OpenCV-order colour
image: uint8 for 8-bit files, uint16 for 16-bit TIFF/PNG and RAW. RAW files are
decoded *linear* (gamma 1), with the camera's white balance and no
auto-brightening, so colour work can use the linear data directly.
An unreadable file raises :class:`~cvmeasure.errors.InputError` naming it.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cvmeasure.errors import InputError

__all__ = ["Photo", "RAW_SUFFIXES", "read_photo", "is_raw"]

RAW_SUFFIXES = frozenset(
    {
        ".nef",
        ".nrw",
        ".dng",
        ".cr2",
        ".cr3",
        ".crw",
        ".arw",
        ".srf",
        ".sr2",
        ".orf",
        ".rw2",
        ".raf",
        ".pef",
        ".srw",
        ".x3f",
        ".3fr",
        ".erf",
        ".kdc",
        ".mos",
        ".mrw",
        ".iiq",
        ".rwl",
    }
)


@dataclass(frozen=True)
class Photo:
    """A decoded photo. ``bgr`` (H, W, 3) uint8 or uint16; ``linear`` says whether it is gamma 1."""

    path: str
    bgr: np.ndarray
    linear: bool

    @property
    def size_px(self) -> tuple[int, int]:
        h, w = self.bgr.shape[:2]
        return w, h

    def gray8(self) -> np.ndarray:
        """An 8-bit grey image (display-referred: linear data is gamma-encoded first)."""
        import cv2

        img = self.bgr
        if img.dtype != np.uint8:
            scaled = img.astype(np.float32) / float(np.iinfo(img.dtype).max)
            if self.linear:
                scaled = np.where(
                    scaled <= 0.0031308, 12.92 * scaled, 1.055 * np.power(scaled, 1 / 2.4) - 0.055
                )
            img = np.clip(scaled * 255.0 + 0.5, 0, 255).astype(np.uint8)
        return cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)


def is_raw(path: str | os.PathLike[str]) -> bool:
    """True when the file name has a camera-RAW suffix."""
    return Path(path).suffix.lower() in RAW_SUFFIXES


def read_photo(path: str | os.PathLike[str], *, half_size: bool = False) -> Photo:
    """Decode a photo file. ``half_size`` is honoured for RAW only (fast preview)."""
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "photo not found")
    if is_raw(path):
        return Photo(str(path), _read_raw(path, half_size=half_size), linear=True)
    import cv2

    data = np.fromfile(path, dtype=np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise InputError(path, "unreadable photo (not a JPEG/PNG/TIFF/RAW image, or truncated)")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    elif img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    if img.dtype not in (np.uint8, np.uint16):
        raise InputError(path, f"unsupported sample type {img.dtype}")
    return Photo(str(path), np.ascontiguousarray(img), linear=False)


def _read_raw(path: Path, *, half_size: bool) -> np.ndarray:
    import rawpy

    try:
        with rawpy.imread(str(path)) as raw:
            rgb = raw.postprocess(
                gamma=(1, 1),
                no_auto_bright=True,
                use_camera_wb=True,
                output_bps=16,
                user_flip=0,
                half_size=half_size,
            )
    except (rawpy.LibRawError, OSError, ValueError) as exc:
        raise InputError(path, f"unreadable RAW photo: {exc}") from None
    return np.ascontiguousarray(rgb[:, :, ::-1])
