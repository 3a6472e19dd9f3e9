"""A JPEG decoded to its Y, Cb, Cr planes; BGR made only where it is read.

libjpeg-turbo's TurboJPEG library (``libturbojpeg.so.0``, Debian's ``libturbojpeg0``;
loaded with ctypes, optional) decodes a baseline YCbCr JPEG to its planes
(``tjDecompressToYUVPlanes``: Huffman decoding and the accurate integer IDCT of every
component, as a full decode does) but skips the chroma upsampling and the colour
conversion of every pixel, and writes half the memory (4:2:0). On one core that is
~0.72x of ``simplejpeg.decode_jpeg`` to BGR at 4608x3072 (q90: 19.5 vs 26.8 ms CPU).

:class:`JpegPlanes` then gives BGR pixels where they are needed:

* :meth:`JpegPlanes.region_bgr`: a rectangle at full resolution, its chroma upsampled
  the way libjpeg-turbo's fancy upsampling does (the triangle filter: bilinear between
  the chroma samples' centres, edges replicated) and converted by OpenCV's full-range
  (JFIF) YCrCb -> BGR; the same pixels as ``simplejpeg.decode_jpeg`` up to rounding
  (at most 2 levels; on rendered photos 0.1 % of the samples differ:
  tests/cvmeasure/test_jpegplanes.py);
* :meth:`JpegPlanes.sampled_bgr`: every ``step``-th pixel with the chroma sample it lies
  in (the marker search's reduced copy; different only next to colour edges);
* :meth:`JpegPlanes.lazy_bgr`: a full-size BGR image whose pixels are made on
  reading: ``img[y0:y1, x0:x1]`` makes that region, ``img[::s, ::s]`` the sampled copy,
  any other indexing or ``np.asarray`` the whole image (so numpy code stays right; it
  is no ndarray, so OpenCV functions refuse it instead of reading unmade pixels).

Only what this covers is read: 8-bit baseline or extended Huffman, three YCbCr
components, chroma 4:4:4, 4:2:2 or 4:2:0; for anything else, a damaged file (any
libjpeg warning) or a machine without libturbojpeg, :func:`read_planes` returns None and
the caller decodes the whole file as before.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

__all__ = ["JpegPlanes", "LazyBGR", "available", "read_planes"]

# TurboJPEG constants (turbojpeg.h, stable since libjpeg-turbo 1.4)
_TJSAMP_FACTORS = {0: (1, 1), 1: (2, 1), 2: (2, 2)}  # TJSAMP_444, _422, _420 -> (sx, sy)
_TJCS_YCBCR = 1
_TJFLAG_ACCURATEDCT = 4096
_TJFLAG_STOPONWARNING = 8192


@functools.lru_cache(maxsize=1)
def _library() -> Any:
    """libturbojpeg through ctypes, or None when it is not installed."""
    names = ["libturbojpeg.so.0", "libturbojpeg.so", "libturbojpeg.0.dylib"]
    found = ctypes.util.find_library("turbojpeg")
    if found:
        names.append(found)
    for name in names:
        try:
            lib = ctypes.CDLL(name)
            break
        except OSError:
            continue
    else:
        return None
    c_int_p = ctypes.POINTER(ctypes.c_int)
    try:
        lib.tjInitDecompress.restype = ctypes.c_void_p
        lib.tjInitDecompress.argtypes = []
        lib.tjDecompressHeader3.restype = ctypes.c_int
        lib.tjDecompressHeader3.argtypes = [
            ctypes.c_void_p,
            ctypes.c_char_p,
            ctypes.c_ulong,
            c_int_p,
            c_int_p,
            c_int_p,
            c_int_p,
        ]
        lib.tjPlaneWidth.restype = ctypes.c_int
        lib.tjPlaneWidth.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int]
        lib.tjPlaneHeight.restype = ctypes.c_int
        lib.tjPlaneHeight.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int]
        lib.tjDecompressToYUVPlanes.restype = ctypes.c_int
        lib.tjDecompressToYUVPlanes.argtypes = [
            ctypes.c_void_p,
            ctypes.c_char_p,
            ctypes.c_ulong,
            ctypes.POINTER(ctypes.c_void_p),
            ctypes.c_int,
            c_int_p,
            ctypes.c_int,
            ctypes.c_int,
        ]
        lib.tjDestroy.restype = ctypes.c_int
        lib.tjDestroy.argtypes = [ctypes.c_void_p]
    except AttributeError:  # pragma: no cover - a TurboJPEG without the planes API
        return None
    return lib


def available() -> bool:
    """True when libturbojpeg can be loaded (the planes path can run)."""
    return _library() is not None


@dataclass(frozen=True)
class JpegPlanes:
    """The decoded planes of a YCbCr JPEG: ``y`` (H, W), ``cb`` and ``cr`` (ceil(H / sy), ceil(W / sx)).

    ``sx``, ``sy``: the chroma subsampling factors (1 or 2). Pixel coordinates are
    full-resolution image pixels, x right, y down.
    """

    y: np.ndarray
    cb: np.ndarray
    cr: np.ndarray
    sx: int
    sy: int

    @property
    def shape(self) -> tuple[int, int, int]:
        """(H, W, 3): the shape of the decoded BGR image."""
        return (self.y.shape[0], self.y.shape[1], 3)

    def _to_bgr(self, y: np.ndarray, cb: np.ndarray, cr: np.ndarray) -> np.ndarray:
        """BGR uint8 from same-size Y, Cb, Cr: OpenCV's full-range (JFIF) YCrCb -> BGR."""

        # contiguous planes first: cv2.merge takes row-strided views (a region's) several
        # times slower than it takes their copies
        planes = [np.ascontiguousarray(p) for p in (y, cr, cb)]
        return cv2.cvtColor(cv2.merge(planes), cv2.COLOR_YCrCb2BGR)

    def region_bgr(self, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        """BGR uint8 of rows [y0, y1), columns [x0, x1) (inside the image): (y1 - y0, x1 - x0, 3)."""

        if self.sx == 1 and self.sy == 1:
            return self._to_bgr(self.y[y0:y1, x0:x1], self.cb[y0:y1, x0:x1], self.cr[y0:y1, x0:x1])
        # the chroma samples round the region, one more each side (clipped at the image's
        # edge), upsampled by cv2.resize: its bilinear output pixel x sits at (x + 0.5) / sx
        # - 0.5 of its input, as libjpeg-turbo's fancy upsampling, and it replicates the
        # input's edge, which matters only at the image's own edge (as in libjpeg-turbo).
        # Cr and Cb each on its own: row-contiguous views that cv2.merge takes without the
        # copies a 2-channel resize's strided channels need (the same pixels)
        hc, wc = self.cb.shape
        cy0, cy1 = max(0, y0 // self.sy - 1), min(hc, (y1 - 1) // self.sy + 2)
        cx0, cx1 = max(0, x0 // self.sx - 1), min(wc, (x1 - 1) // self.sx + 2)
        size = ((cx1 - cx0) * self.sx, (cy1 - cy0) * self.sy)
        oy, ox = y0 - cy0 * self.sy, x0 - cx0 * self.sx
        cr, cb = (
            cv2.resize(p[cy0:cy1, cx0:cx1], size, interpolation=cv2.INTER_LINEAR)[
                oy : oy + y1 - y0, ox : ox + x1 - x0
            ]
            for p in (self.cr, self.cb)
        )
        return self._to_bgr(self.y[y0:y1, x0:x1], cb, cr)

    def sampled_bgr(self, step: int) -> np.ndarray:
        """BGR uint8 of every ``step``-th pixel from (0, 0), for a search: ~``decoded[::step, ::step]``.

        Each pixel's own luma with the chroma sample it lies in (not interpolated between
        samples: 4.5x cheaper than the upsampling's remap at 4608x3072, step 10); so it
        differs from the decoded image's pixel only next to a colour edge (up to half a
        chroma sample away).
        """
        h, w = self.y.shape
        if step % self.sy == 0 and step % self.sx == 0:
            # pixel k * step lies in chroma sample k * step / s: a strided view, no gather
            cb, cr = (p[:: step // self.sy, :: step // self.sx] for p in (self.cb, self.cr))
        else:
            rows = np.arange(0, h, step) // self.sy
            cols = np.arange(0, w, step) // self.sx
            cb, cr = (np.take(p[rows], cols, axis=1) for p in (self.cb, self.cr))
        return self._to_bgr(self.y[::step, ::step], cb, cr)

    def lazy_bgr(self) -> LazyBGR:
        """A full-size BGR image whose pixels are made when they are read (:class:`LazyBGR`)."""
        return LazyBGR.for_planes(self)


def read_planes(data: bytes | np.ndarray, *, max_pixels: int | None = None) -> JpegPlanes | None:
    """Decode a JPEG's Y, Cb, Cr planes; None where this path does not apply.

    None for anything but a three-component YCbCr JPEG with 4:4:4, 4:2:2 or 4:2:0 chroma,
    for a damaged file (libjpeg's warnings stop the decode), a header declaring more
    than ``max_pixels`` pixels (nothing decoded), or without libturbojpeg: the caller
    then decodes the whole file as before.
    """
    lib = _library()
    if lib is None:
        return None
    buf = bytes(data) if not isinstance(data, bytes) else data
    handle = lib.tjInitDecompress()
    if not handle:
        return None
    try:
        w, h, samp, cs = (ctypes.c_int() for _ in range(4))
        if lib.tjDecompressHeader3(
            handle, buf, len(buf), ctypes.byref(w), ctypes.byref(h), ctypes.byref(samp),
            ctypes.byref(cs),
        ):  # fmt: skip
            return None
        if cs.value != _TJCS_YCBCR or samp.value not in _TJSAMP_FACTORS:
            return None
        width, height = w.value, h.value
        if max_pixels is not None and width * height > max_pixels:
            return None
        planes = [
            np.empty(
                (lib.tjPlaneHeight(c, height, samp.value), lib.tjPlaneWidth(c, width, samp.value)),
                np.uint8,
            )
            for c in range(3)
        ]
        ptrs = (ctypes.c_void_p * 3)(*(p.ctypes.data for p in planes))
        if lib.tjDecompressToYUVPlanes(
            handle, buf, len(buf), ptrs, width, None, height,
            _TJFLAG_ACCURATEDCT | _TJFLAG_STOPONWARNING,
        ):  # fmt: skip
            return None
    finally:
        lib.tjDestroy(handle)
    sx, sy = _TJSAMP_FACTORS[samp.value]
    # the luma plane is padded to whole chroma samples (an odd size under 4:2:x)
    return JpegPlanes(planes[0][:height, :width], planes[1], planes[2], sx, sy)


class LazyBGR:
    """A full-size BGR uint8 image whose pixels are made from :class:`JpegPlanes` when read.

    Not an ndarray (so no code can read pixels that were never made): it has ``shape``
    (H, W, 3), ``dtype`` uint8 and ``ndim``, and indexing. ``img[y0:y1, x0:x1]`` (slices
    of step 1) returns that region as a plain array (regions made before are kept and
    reused when one holds the request); ``img[::s, ::s]`` the sampled copy. Any other
    indexing, and ``np.asarray(img)`` (``__array__``: every numpy function), make the
    whole image first (once; kept). OpenCV functions refuse it (cv2.error), and so do
    Python's operators (TypeError): give them ``np.asarray(img)`` or a region.
    """

    __slots__ = ("_planes", "_regions", "_whole", "shape")
    ndim = 3
    dtype = np.dtype(np.uint8)

    def __init__(self, planes: JpegPlanes) -> None:
        self._planes = planes
        self._regions: list[tuple[int, int, int, int, np.ndarray]] = []
        self._whole: np.ndarray | None = None
        self.shape: tuple[int, int, int] = planes.shape

    @classmethod
    def for_planes(cls, planes: JpegPlanes) -> LazyBGR:
        return cls(planes)

    def __len__(self) -> int:
        return self.shape[0]

    def __repr__(self) -> str:
        h, w, _ = self.shape
        return f"LazyBGR({w}x{h}, {len(self._regions)} regions made, whole {'made' if self._whole is not None else 'not made'})"

    def _whole_image(self) -> np.ndarray:
        if self._whole is None:
            h, w = self.shape[:2]
            self._whole = self._planes.region_bgr(0, h, 0, w)
        return self._whole

    def __array__(self, dtype: Any = None, copy: bool | None = None) -> np.ndarray:
        whole = self._whole_image()
        if dtype is not None and np.dtype(dtype) != whole.dtype:
            return whole.astype(dtype)
        return whole.copy() if copy else whole

    def _region(self, y0: int, y1: int, x0: int, x1: int) -> np.ndarray:
        for ry0, ry1, rx0, rx1, arr in self._regions:
            if ry0 <= y0 and y1 <= ry1 and rx0 <= x0 and x1 <= rx1:
                return arr[y0 - ry0 : y1 - ry0, x0 - rx0 : x1 - rx0]
        # grown a little: a refinement's next pass re-centres by a few pixels
        h, w = self.shape[:2]
        my = REGION_MARGIN[0] + int(REGION_MARGIN[1] * (y1 - y0))
        mx = REGION_MARGIN[0] + int(REGION_MARGIN[1] * (x1 - x0))
        ry0, ry1 = max(0, y0 - my), min(h, y1 + my)
        rx0, rx1 = max(0, x0 - mx), min(w, x1 + mx)
        arr = self._planes.region_bgr(ry0, ry1, rx0, rx1)
        self._regions.append((ry0, ry1, rx0, rx1, arr))
        return arr[y0 - ry0 : y1 - ry0, x0 - rx0 : x1 - rx0]

    def __getitem__(self, key: Any) -> Any:
        if self._whole is not None:
            return self._whole[key]
        h, w = self.shape[:2]
        if isinstance(key, tuple) and len(key) >= 2 and all(isinstance(k, slice) for k in key[:2]):
            (y0, y1, sy), (x0, x1, sx) = key[0].indices(h), key[1].indices(w)
            rest = (slice(None), slice(None), *key[2:])
            if sy == 1 and sx == 1 and y1 > y0 and x1 > x0:
                return self._region(y0, y1, x0, x1)[rest]
            if sy == sx > 1 and y0 == x0 == 0 and y1 == h and x1 == w:
                return self._planes.sampled_bgr(sy)[rest]
        return self._whole_image()[key]


#: How much a region made for a request is grown on each side: (pixels, fraction of the
#: request's size). 8 px holds a refinement's re-centred pass (a disc's search centre is
#: within a few px) and the lateral-colour probe round the fitted centre; a request
#: outside it makes another region (the same pixels: only time). (8, 0.1) before: the
#: regions 1.5x the pixels, q90 4608x3072 post-decode 60.0M -> 59.2M instructions.
REGION_MARGIN = (8, 0.0)
