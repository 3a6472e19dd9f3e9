"""Reading photos: JPEG, PNG, TIFF and camera RAW (NEF, DNG, CR2, ... via rawpy).

Every reader returns a :class:`Photo` whose ``bgr`` is an OpenCV-order colour
image: uint8 for 8-bit files, uint16 for 16-bit TIFF/PNG and RAW. RAW files are
decoded *linear* (gamma 1), with the camera's white balance and no
auto-brightening, so colour work can use the linear data directly
(:meth:`Photo.linear_rgb` gives the same scene-linear floats for every file
type). Files named ``*.linear.png`` / ``*.linear.tiff`` are read as linear too.
An unreadable file raises :class:`~cvmeasure.errors.InputError` naming it.

JPEGs are decoded by libjpeg-turbo through simplejpeg (accurate integer IDCT and
fancy chroma upsampling: the same pixels as ``cv2.imdecode``, bit for bit, in
0.45-0.93x its time on one core; :func:`decode_jpeg`); what simplejpeg refuses
(CMYK, 12-bit, damaged files) goes to OpenCV as before. A marker measurement from a
JPEG file (``measure_photo_file``) decodes only its Y, Cb, Cr planes where Debian's
libturbojpeg is installed, and makes BGR only where it reads (:mod:`cvmeasure.jpegplanes`).

Pillow and simplejpeg are imported in the functions that read a photo, so the commands
that import this module without reading one start without them.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from cvmeasure.colorimetry import srgb_decode, srgb_encode
from cvmeasure.errors import InputError
from cvmeasure.extras import require

__all__ = [
    "Photo",
    "RAW_SUFFIXES",
    "LINEAR_SUFFIXES",
    "PHOTO_SUFFIXES",
    "read_photo",
    "check_pixel_count",
    "MAX_PHOTO_PIXELS",
    "is_raw",
    "is_linear_name",
    "to_bgr8",
    "decode_jpeg",
    "is_jpeg_data",
]

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

#: Suffixes of every photo file read_photo understands (lower case).
PHOTO_SUFFIXES = (
    frozenset({".jpg", ".jpeg", ".png", ".tif", ".tiff", ".bmp", ".webp"}) | RAW_SUFFIXES
)

#: Suffixes of 16-bit files that may hold linear data (named ``*.linear<suffix>``).
LINEAR_SUFFIXES = frozenset({".png", ".tif", ".tiff"})


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

    def linear_rgb(self) -> np.ndarray:
        """Scene-linear colour in [0, 1], float32, BGR order (H, W, 3).

        RAW and other linear data are only scaled; gamma-encoded files (JPEG, PNG,
        TIFF) are decoded with the sRGB transfer function. This is what colour
        segmentation should work on: the same pixel values whichever file type.
        """
        img = self.bgr.astype(np.float32) / float(np.iinfo(self.bgr.dtype).max)
        if self.linear:
            return img
        return srgb_decode(img).astype(np.float32)

    def bgr8(self) -> np.ndarray:
        """Display-referred 8-bit BGR (linear data sRGB-encoded first); the same array for JPEGs."""
        return to_bgr8(self.bgr, linear=self.linear)

    def gray8(self) -> np.ndarray:
        """An 8-bit grey image (display-referred: linear data is gamma-encoded first)."""

        return cv2.cvtColor(self.bgr8(), cv2.COLOR_BGR2GRAY)


def to_bgr8(image: np.ndarray, *, linear: bool = False) -> np.ndarray:
    """Any (H, W, 3) uint8/uint16 BGR image -> display-referred uint8 BGR.

    ``linear`` data (RAW, linear renders) is sRGB-encoded first; an 8-bit
    gamma-encoded image is returned as it is (no copy; an ndarray subclass stays one).
    """
    img = np.asanyarray(image)
    if img.ndim != 3 or img.shape[2] != 3:
        raise ValueError("a colour (H, W, 3) BGR image is needed")
    if img.dtype == np.uint8 and not linear:
        return img
    if img.dtype not in (np.uint8, np.uint16):
        raise ValueError(f"unsupported sample type {img.dtype}")
    scaled = img.astype(np.float32) / float(np.iinfo(img.dtype).max)
    if linear:
        scaled = srgb_encode(scaled)
    return np.clip(scaled * 255.0 + 0.5, 0, 255).astype(np.uint8)


def is_raw(path: str | os.PathLike[str]) -> bool:
    """True when the file name has a camera-RAW suffix."""
    return Path(path).suffix.lower() in RAW_SUFFIXES


def is_linear_name(path: str | os.PathLike[str]) -> bool:
    """True for ``*.linear.png`` / ``*.linear.tif(f)``: a 16-bit file holding linear data."""
    suffixes = [s.lower() for s in Path(path).suffixes]
    return len(suffixes) >= 2 and suffixes[-2] == ".linear" and suffixes[-1] in LINEAR_SUFFIXES


#: Most pixels a photo may declare (150 MP: above any DSLR's 102 MP): a small file that
#: declares 30000 x 30000 pixels would otherwise take gigabytes to decode.
MAX_PHOTO_PIXELS = 150_000_000


def check_pixel_count(path: str | os.PathLike[str], *, limit: int = MAX_PHOTO_PIXELS) -> None:
    """Refuse (InputError naming the file) a photo whose header declares more than ``limit``
    pixels, from the header alone (Pillow's lazy open), before anything is decoded."""

    from PIL import Image, UnidentifiedImageError

    pillow_limit = Image.MAX_IMAGE_PIXELS
    try:
        Image.MAX_IMAGE_PIXELS = None  # our limit, our message; only the header is read
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)
            with Image.open(path) as im:
                w, h = im.size
    except (UnidentifiedImageError, OSError, ValueError):
        return  # not an image Pillow knows: the decoder reports it
    finally:
        Image.MAX_IMAGE_PIXELS = pillow_limit
    _check_declared(path, w, h, limit)


def _check_declared(path: str | os.PathLike[str], width: int, height: int, limit: int) -> None:
    """InputError naming ``path`` when a header's ``width`` x ``height`` exceeds ``limit`` pixels."""
    if width * height > limit:
        raise InputError(
            path,
            f"photo declares {width} x {height} pixels ({width * height / 1e6:.0f} MP); at most "
            f"{limit / 1e6:.0f} MP are read",
        )


def read_photo(
    path: str | os.PathLike[str], *, half_size: bool = False, linear: bool | None = None
) -> Photo:
    """Decode a photo file.

    Parameters
    ----------
    path : path-like
        JPEG, PNG, TIFF or camera RAW file.
    half_size : bool
        Honoured for RAW only: 2x2 binning without demosaicing (fast preview).
    linear : bool, optional
        Whether the pixel values are scene-linear. Default: True for RAW and for
        ``*.linear.png`` / ``*.linear.tif(f)`` files (how the photo lab writes its
        16-bit linear renders), False otherwise (gamma-encoded sRGB).
    """
    path = Path(path)
    if not path.is_file():
        raise InputError(path, "photo not found")
    if is_raw(path):
        return Photo(str(path), _read_raw(path, half_size=half_size), linear=True)
    if linear is None:
        linear = is_linear_name(path)
    data = np.fromfile(path, dtype=np.uint8)
    img = decode_jpeg(data, path) if is_jpeg_data(data) else None
    if img is not None:
        return Photo(str(path), img, linear=bool(linear))
    check_pixel_count(path)

    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise InputError(path, "unreadable photo (not a JPEG/PNG/TIFF/RAW image, or truncated)")
    if img.ndim == 2:
        img = cv2.cvtColor(img, cv2.COLOR_GRAY2BGR)
    elif img.shape[2] == 4:
        img = cv2.cvtColor(img, cv2.COLOR_BGRA2BGR)
    if img.dtype not in (np.uint8, np.uint16):
        raise InputError(path, f"unsupported sample type {img.dtype}")
    return Photo(str(path), np.ascontiguousarray(img), linear=bool(linear))


def is_jpeg_data(data: np.ndarray | bytes) -> bool:
    """True when the bytes start with a JPEG's SOI marker and a marker (``FF D8 FF``)."""
    return bytes(data[:3]) == b"\xff\xd8\xff"


def decode_jpeg(
    data: np.ndarray | bytes,
    path: str | os.PathLike[str] = "photo",
    *,
    limit: int = MAX_PHOTO_PIXELS,
) -> np.ndarray | None:
    """Full-resolution BGR uint8 (H, W, 3) of an 8-bit JPEG, or None where simplejpeg cannot.

    libjpeg-turbo (simplejpeg's wheel bundles it) with the accurate integer IDCT and
    fancy upsampling, strict about damaged data: the pixels ``cv2.imdecode`` gives,
    bit for bit, in 0.45-0.93x its time on one core (benchmarks/decode_speed.py).
    None (CMYK, 12-bit, truncated or otherwise damaged, simplejpeg missing) lets the
    caller fall back to OpenCV. A header declaring more than ``limit`` pixels raises
    InputError naming ``path`` before anything is decoded.
    """
    try:
        import simplejpeg
    except ImportError:  # pragma: no cover - a dependency; OpenCV still decodes
        return None
    buf = memoryview(data).cast("B") if not isinstance(data, bytes) else data
    try:
        h, w, colour, _ = simplejpeg.decode_jpeg_header(buf)
    except ValueError:
        return None
    _check_declared(path, w, h, limit)
    if colour not in ("YCbCr", "Gray", "RGB"):
        return None
    try:
        return simplejpeg.decode_jpeg(buf, colorspace="BGR", strict=True)
    except ValueError:
        return None


def _read_raw(path: Path, *, half_size: bool) -> np.ndarray:
    rawpy = require("rawpy", "raw", str(path))

    try:
        with rawpy.imread(str(path)) as raw:
            if raw.raw_type == rawpy.RawType.Stack:
                rgb = _stack_to_rgb16(raw)
            else:
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


def _stack_to_rgb16(raw: object) -> np.ndarray:
    """RGB uint16 from a RAW file whose data is already 3-channel (``RawType.Stack``).

    Scanner NEFs and linear DNGs store RGB per pixel, not a Bayer mosaic. LibRaw's
    ``postprocess`` scales them by a white level that can be far below the data
    (the Nikon scan: white 255, data up to 55000) and clips most pixels; here the
    channels are taken as stored, minus black, scaled by the real white level (the
    declared one, or the 16-bit full scale when the data exceed it), and multiplied
    by the camera white balance when the file has a usable one (all of R, G, B > 0).
    """
    data = np.asarray(raw.raw_image_visible)[..., :3].astype(np.float32)
    black = np.asarray(raw.black_level_per_channel[:3], dtype=np.float32)
    white = float(raw.white_level)
    if float(data.max(initial=0.0)) > white:
        white = float(np.iinfo(np.uint16).max)
    scale = 1.0 / np.maximum(white - black, 1.0)
    wb = np.asarray(raw.camera_whitebalance[:3], dtype=np.float32)
    if np.all(wb > 0):
        scale = scale * wb / wb[1]
    linear = np.clip((data - black) * scale, 0.0, 1.0)
    return (linear * 65535.0 + 0.5).astype(np.uint16)
