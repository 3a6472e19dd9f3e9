"""Per-photo overlay thumbnails: the photo, small, with what was measured drawn on it.

Pillow is imported only when a thumbnail is made.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from cvmeasure.imageio import read_photo
from cvmeasure.report.plots import numeric

__all__ = ["find_photo", "overlay_thumbnail"]

#: BGR drawing colour of each marker role (close to the kit's printed colours).
ROLE_COLOURS_BGR: dict[str, tuple[int, int, int]] = {
    "origin": (70, 110, 0),
    "axis": (40, 200, 150),
    "pin": (0, 220, 255),
    "wire_a": (220, 90, 20),
    "wire_b": (200, 40, 220),
}
_SHIFT = 4  # sub-pixel drawing: coordinates in 1/16 px


def find_photo(record: Mapping[str, Any], roots: tuple[Path, ...] = ()) -> Path | None:
    """The photo file a record names: as written, else under each root (path, then file name)."""
    name = record.get("photo") or record.get("file_name")
    if not name:
        return None
    path = Path(str(name))
    candidates = [path] if path.is_absolute() else []
    for root in roots:
        candidates += [root / path, root / path.name]
    if not path.is_absolute():
        candidates.append(path)
    return next((c for c in candidates if c.is_file()), None)


def _read_small(path: Path, width_px: int) -> tuple[np.ndarray, float]:
    """An 8-bit BGR image at most ``width_px`` wide and its scale (thumbnail px per photo px)."""

    if path.suffix.lower() in (".jpg", ".jpeg"):
        from PIL import Image

        with Image.open(path) as im:
            full_w = im.size[0]
        flag = cv2.IMREAD_COLOR
        for factor, reduced in (
            (8, cv2.IMREAD_REDUCED_COLOR_8),
            (4, cv2.IMREAD_REDUCED_COLOR_4),
            (2, cv2.IMREAD_REDUCED_COLOR_2),
        ):
            if full_w >= factor * width_px:
                flag = reduced
                break
        img = cv2.imread(os.fspath(path), flag)
        if img is None:
            raise ValueError("unreadable")
        scale = img.shape[1] / full_w
    else:
        img = read_photo(path).bgr8()
        scale = 1.0
    if img.shape[1] > width_px:
        f = width_px / img.shape[1]
        img = cv2.resize(img, None, fx=f, fy=f, interpolation=cv2.INTER_AREA)
        scale *= f
    return np.ascontiguousarray(img), scale


def _marker_circles(record: Mapping[str, Any]) -> dict[str, tuple[float, float, float]]:
    markers = record.get("markers")
    out: dict[str, tuple[float, float, float]] = {}
    if not isinstance(markers, Mapping):
        return out
    for role, m in markers.items():
        if isinstance(m, Mapping):
            x, y, r = numeric(m.get("x_px")), numeric(m.get("y_px")), numeric(m.get("r_px"))
            if x is not None and y is not None:
                out[str(role)] = (x, y, r or 0.0)
    return out


def _read_crop(
    path: Path, box: tuple[float, float, float, float], width_px: int
) -> tuple[np.ndarray, float, float, float]:
    """The region ``box`` (x0, y0, x1, y1 photo px) of the photo at ``width_px``; (img, ox, oy, scale)."""

    full = read_photo(path).bgr8()
    h, w = full.shape[:2]
    x0, y0 = max(0, int(box[0])), max(0, int(box[1]))
    x1, y1 = min(w, int(np.ceil(box[2]))), min(h, int(np.ceil(box[3])))
    if x1 - x0 < 2 or y1 - y0 < 2:
        raise ValueError("markers outside the photo")
    crop = full[y0:y1, x0:x1]
    f = width_px / crop.shape[1]
    crop = cv2.resize(
        crop, None, fx=f, fy=f, interpolation=cv2.INTER_AREA if f < 1 else cv2.INTER_CUBIC
    )
    return np.ascontiguousarray(crop), float(x0), float(y0), f


def _points(value: Any) -> np.ndarray | None:
    """An (N, 2) array of finite points from a record field, or None."""
    try:
        pts = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return None
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        return None
    return pts


def overlay_thumbnail(
    record: Mapping[str, Any], path: Path, *, width_px: int = 360, quality: int = 82
) -> bytes:
    """A JPEG thumbnail of the photo with the record's markers / disc / lines drawn on it.

    With marker circles (``markers``: role -> ``x_px``, ``y_px``, ``r_px``, image
    frame) the thumbnail shows the region around the markers (so they can be
    checked by eye), each circle in its role's colour, with the feed axis
    (axis -> origin), the pin direction (origin -> pin) and the bent leg
    (wire_a -> wire_b). A part record (``centreline_px``) shows the region around
    the part with its measured centreline (red) and chord vertices (green).
    Otherwise it shows the whole photo; a record with top-level ``x_px``,
    ``y_px``, ``r_px`` (a disc) gets its circle.
    """

    circles = _marker_circles(record)
    line_px = _points(record.get("centreline_px"))
    vertices_px = _points(record.get("vertices_px"))
    if line_px is not None and not circles:
        lo, hi = line_px.min(axis=0), line_px.max(axis=0)
        margin = 0.15 * float(max(hi - lo)) + 20.0
        box = (lo[0] - margin, lo[1] - margin, hi[0] + margin, hi[1] + margin)
        img, ox, oy, scale = _read_crop(path, box, width_px)
    elif circles:
        xs = [c[0] for c in circles.values()]
        ys = [c[1] for c in circles.values()]
        rmax = max(c[2] for c in circles.values())
        span = max(max(xs) - min(xs), max(ys) - min(ys), 10 * rmax, 40.0)
        margin = 0.25 * span + 2 * rmax
        box = (min(xs) - margin, min(ys) - margin, max(xs) + margin, max(ys) + margin)
        img, ox, oy, scale = _read_crop(path, box, width_px)
    else:
        img, scale = _read_small(path, width_px)
        ox = oy = 0.0

    def pt(x: float, y: float) -> tuple[int, int]:
        return (
            int(round((x - ox) * scale * (1 << _SHIFT))),
            int(round((y - oy) * scale * (1 << _SHIFT))),
        )

    for role, (x, y, r) in circles.items():
        colour = ROLE_COLOURS_BGR.get(role, (255, 255, 255))
        radius = int(round(max(r * scale, 3.0) * (1 << _SHIFT)))
        cv2.circle(img, pt(x, y), radius, (255, 255, 255), 4, cv2.LINE_AA, _SHIFT)
        cv2.circle(img, pt(x, y), radius, colour, 2, cv2.LINE_AA, _SHIFT)
        tx, ty = int((x - ox) * scale + r * scale) + 3, int((y - oy) * scale) - 3
        cv2.putText(img, role, (tx, ty), cv2.FONT_HERSHEY_SIMPLEX, 0.35, (0, 0, 0), 2, cv2.LINE_AA)
        cv2.putText(img, role, (tx, ty), cv2.FONT_HERSHEY_SIMPLEX, 0.35, colour, 1, cv2.LINE_AA)
    for a, b, colour in (
        ("axis", "origin", (60, 60, 60)),
        ("origin", "pin", (0, 160, 255)),
        ("wire_a", "wire_b", (200, 40, 220)),
    ):
        if a in circles and b in circles:
            cv2.line(img, pt(*circles[a][:2]), pt(*circles[b][:2]), colour, 1, cv2.LINE_AA, _SHIFT)
    if line_px is not None:  # a part: its measured centreline and chord vertices
        pts = np.array([pt(x, y) for x, y in line_px], dtype=np.int32)
        cv2.polylines(img, [pts], False, (255, 255, 255), 3, cv2.LINE_AA, _SHIFT)
        cv2.polylines(img, [pts], False, (0, 0, 220), 1, cv2.LINE_AA, _SHIFT)
        for x, y in vertices_px if vertices_px is not None else ():
            cv2.circle(img, pt(x, y), 3 << _SHIFT, (0, 180, 0), 1, cv2.LINE_AA, _SHIFT)
    x, y, r = (numeric(record.get(k)) for k in ("x_px", "y_px", "r_px"))
    if x is not None and y is not None and r is not None:
        radius = int(round(r * scale * (1 << _SHIFT)))
        cv2.circle(img, pt(x, y), radius, (0, 0, 255), 2, cv2.LINE_AA, _SHIFT)
        centre = (int(round((x - ox) * scale)), int(round((y - oy) * scale)))
        cv2.drawMarker(img, centre, (0, 0, 255), cv2.MARKER_CROSS, 8, 1)
    ok, data = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:  # pragma: no cover - encoding an 8-bit image does not fail
        raise ValueError("JPEG encoding failed")
    return data.tobytes()
