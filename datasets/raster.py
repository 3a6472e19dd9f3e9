"""Anti-aliased rasterisation of flat scenes traced back to their plane.

A scene is a list of :class:`Layer` objects painted in order (painter's
algorithm) onto a linear-RGB albedo image. Each layer has a bounding box in
plane mm; only the pixels inside its projected box are evaluated. For those
pixels the plane coordinates come from :class:`cvmeasure_datasets.optics.RayMap`
(exact undistortion, spline-interpolated to ~1e-11 px, + ray/plane intersection) and the layer returns a coverage
``alpha`` in [0, 1]:

* signed-distance layers (discs, capsules, rectangles): the exact box-filtered
  coverage of a straight edge at the local distance and orientation (from the
  sdf and its pixel gradient, :func:`box_coverage`); the profile is symmetric
  about the true edge, so edge positions are unbiased;
* the checker of a board: the product of two such per-axis coverages (the
  exact box filter of the pattern where the pixel grid is aligned with it);
* ArUco bit patterns: separable "sharp bilinear" sampling of the bit grid,
  again the box filter of the cells.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from cvmeasure.camera_model import CameraModel
from cvmeasure_datasets.optics import RayMap, project_frame_points

__all__ = [
    "Rays",
    "Window",
    "Layer",
    "box_coverage",
    "sdf_alpha",
    "sdf_circle",
    "sdf_capsules",
    "sdf_rect",
    "circle_bbox",
    "polyline_bbox",
    "rasterise",
]

BBox = tuple[float, float, float, float]  # xmin, ymin, xmax, ymax in plane mm


class Rays:
    """The camera rays of a block of pixels, in the scene frame.

    ``centre_mm`` (3,) is the camera centre; ``dx``, ``dy``, ``dz`` the ray
    directions (arrays), scaled so that the camera-frame depth of the point
    ``centre + s * d`` is ``s`` mm.
    """

    def __init__(self, centre_mm: np.ndarray, dx: np.ndarray, dy: np.ndarray, dz: np.ndarray):
        self.centre = centre_mm
        self.dx, self.dy, self.dz = dx, dy, dz

    def depth_at_z(self, z_mm: float) -> np.ndarray:
        """Camera depth (mm) where each ray meets the plane z = ``z_mm`` of the frame."""
        if z_mm == 0.0:
            return -self.centre[2] / self.dz
        return (z_mm - self.centre[2]) / self.dz

    def at_z(self, z_mm: float) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) in mm where each ray meets the plane z = ``z_mm`` of the frame."""
        s = self.depth_at_z(z_mm)
        return self.centre[0] + s * self.dx, self.centre[1] + s * self.dy

    def sub(self, rows: slice, cols: slice) -> Rays:
        return Rays(self.centre, self.dx[rows, cols], self.dy[rows, cols], self.dz[rows, cols])


class Window:
    """A rectangle of pixels with its plane coordinates ``u``, ``v`` (mm).

    ``u``, ``v`` lie in the layer's plane (z = ``z_mm`` of the scene frame, 0 for
    the scene plane); ``rays`` (when the rasteriser provides them) let a layer
    trace its pixels to other heights (3D objects). The arrays include a
    one-pixel halo on every side so that pixel-space gradients are central
    differences everywhere; :meth:`crop` removes it.
    """

    def __init__(
        self, u_mm: np.ndarray, v_mm: np.ndarray, rays: Rays | None = None, z_mm: float = 0.0
    ) -> None:
        self.u = u_mm
        self.v = v_mm
        self.rays = rays
        self.z_mm = z_mm
        self._jac: tuple[np.ndarray, ...] | None = None
        self.cache: dict[str, object] = {}

    def jacobian(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(du/dx, du/dy, dv/dx, dv/dy) in mm per pixel."""
        if self._jac is None:
            du_dy, du_dx = np.gradient(self.u)
            dv_dy, dv_dx = np.gradient(self.v)
            self._jac = (du_dx, du_dy, dv_dx, dv_dy)
        return self._jac  # type: ignore[return-value]

    @staticmethod
    def crop(a: np.ndarray) -> np.ndarray:
        return a[1:-1, 1:-1]


def box_coverage(dist_px: np.ndarray, gx: np.ndarray, gy: np.ndarray) -> np.ndarray:
    """Exact coverage of a unit square pixel by the half-plane behind a straight edge.

    ``dist_px`` is the signed distance (pixels, positive outside) of the pixel
    centre from the edge, ``(gx, gy)`` the edge normal in pixel axes (any
    length). Projected on the normal, the pixel's area is the sum of two
    uniform variables of widths ``|nx|`` and ``|ny|`` (a trapezoid), whose
    CDF gives the covered fraction.
    """
    norm = np.hypot(gx, gy)
    flat = norm < 1e-12  # no direction (a constant field): treat as axis-aligned
    norm = np.where(flat, 1.0, norm)
    a = np.where(flat, 1.0, np.abs(gx) / norm)
    b = np.where(flat, 0.0, np.abs(gy) / norm)
    a, b = np.maximum(a, b), np.minimum(a, b)
    x = -np.abs(dist_px)  # evaluate the lower tail, mirror afterwards
    lo = -(a + b) / 2
    mid = -(a - b) / 2
    quad = np.where(b > 1e-9, (x - lo) ** 2 / (2 * a * np.maximum(b, 1e-9)), 0.0)
    tail = np.where(x <= lo, 0.0, np.where(x <= mid, quad, (x + a / 2) / a))
    return np.where(dist_px >= 0, tail, 1.0 - tail)


def sdf_alpha(sdf_mm: np.ndarray, soft_mm: float = 0.0) -> np.ndarray:
    """Pixel coverage of the region ``sdf_mm < 0``.

    The exact box filter of a straight edge at the local orientation
    (:func:`box_coverage`); ``soft_mm`` instead uses a linear ramp widened by
    that many mm (soft shadows).
    """
    gy, gx = np.gradient(sdf_mm)
    mm_per_px = np.maximum(np.hypot(gx, gy), 1e-12)
    if soft_mm > 0:
        return np.clip(0.5 - sdf_mm / (mm_per_px + soft_mm), 0.0, 1.0)
    dist_px = sdf_mm / mm_per_px
    alpha = (dist_px < 0).astype(np.float64)
    # only pixels within a pixel of the edge are partly covered
    edge = np.nonzero(np.abs(dist_px) < 0.75)
    alpha[edge] = box_coverage(dist_px[edge], gx[edge], gy[edge])
    return alpha


def sdf_circle(u: np.ndarray, v: np.ndarray, centre_mm: Sequence[float], radius_mm: float):
    """Signed distance (mm, negative inside) to a circle."""
    return np.hypot(u - centre_mm[0], v - centre_mm[1]) - radius_mm


def sdf_capsules(
    u: np.ndarray,
    v: np.ndarray,
    polyline_mm: np.ndarray,
    radius_mm: float,
    band_mm: float | None = None,
):
    """Signed distance to the union of capsules of ``radius_mm`` around a polyline (N, 2).

    Exact within a band of a few pixels around the capsules (or ``band_mm``: a soft
    edge needs a band at least as wide as its ramp); farther away the value is
    capped (it only ever feeds an anti-aliased coverage). Each segment is
    evaluated only on the pixels inside its own padded bounding box.
    """
    pts = np.asarray(polyline_mm, dtype=np.float64)
    # the band: 4 pixels beyond the surface (pixel size from the window's extent)
    steps = [np.abs(np.diff(a, axis=ax)).max() for a in (u, v) for ax in (0, 1) if a.shape[ax] > 1]
    px_mm = max(steps) if steps else 1.0
    cap = radius_mm + 4.0 * px_mm + 1e-6
    if band_mm is not None:
        cap = max(cap, radius_mm + band_mm)
    best = np.full(np.shape(u), cap)
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        lo = np.minimum(a, b) - cap
        hi = np.maximum(a, b) + cap
        rows = np.nonzero(((u >= lo[0]) & (u <= hi[0]) & (v >= lo[1]) & (v <= hi[1])).any(axis=1))[
            0
        ]
        if len(rows) == 0:
            continue
        r0, r1 = rows[0], rows[-1] + 1
        cols = np.nonzero(
            (
                (u[r0:r1] >= lo[0])
                & (u[r0:r1] <= hi[0])
                & (v[r0:r1] >= lo[1])
                & (v[r0:r1] <= hi[1])
            ).any(axis=0)
        )[0]
        c0, c1 = cols[0], cols[-1] + 1
        su, sv = u[r0:r1, c0:c1], v[r0:r1, c0:c1]
        d = b - a
        length2 = float(d @ d)
        pu, pv = su - a[0], sv - a[1]
        h = np.clip((pu * d[0] + pv * d[1]) / length2, 0.0, 1.0) if length2 > 0 else 0.0
        sub = best[r0:r1, c0:c1]
        np.minimum(sub, np.hypot(pu - h * d[0], pv - h * d[1]), out=sub)
    return best - radius_mm


def sdf_rect(
    u: np.ndarray,
    v: np.ndarray,
    centre_mm: Sequence[float],
    half_size_mm: Sequence[float],
    angle_deg: float = 0.0,
):
    """Signed distance to a rectangle rotated by ``angle_deg`` about its centre."""
    c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
    du, dv = u - centre_mm[0], v - centre_mm[1]
    lu = np.abs(c * du + s * dv) - half_size_mm[0]
    lv = np.abs(-s * du + c * dv) - half_size_mm[1]
    outside = np.hypot(np.maximum(lu, 0.0), np.maximum(lv, 0.0))
    return outside + np.minimum(np.maximum(lu, lv), 0.0)


def circle_bbox(centre_mm: Sequence[float], radius_mm: float) -> BBox:
    return (
        centre_mm[0] - radius_mm,
        centre_mm[1] - radius_mm,
        centre_mm[0] + radius_mm,
        centre_mm[1] + radius_mm,
    )


def polyline_bbox(polyline_mm: np.ndarray, pad_mm: float) -> BBox:
    pts = np.asarray(polyline_mm, dtype=np.float64)
    lo, hi = pts.min(axis=0) - pad_mm, pts.max(axis=0) + pad_mm
    return float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1])


@dataclass(frozen=True)
class Layer:
    """One thing painted on the scene.

    Attributes
    ----------
    bbox_mm : (xmin, ymin, xmax, ymax) in plane mm, or None for the whole image.
    alpha : function Window -> coverage array (with the halo), in [0, 1]; None
        paints the whole box (a background fill).
    colour : linear RGB albedo (3,) or a function Window -> array (h, w, 3) (with halo).
    kind : "paint" (over-paint with ``colour``) or "shadow" (multiply by
        ``1 - strength * alpha``).
    strength : shadow darkness in [0, 1].
    z_mm : the frame z of the plane the window's ``u``, ``v`` lie in (0: the scene
        plane; the machine frame's z is up, the board frame's away from the camera).
    z_extent_mm : (z_lo, z_hi) the object spans, for its pixel box (default ``z_mm``).
    """

    bbox_mm: BBox | None
    alpha: Callable[[Window], np.ndarray] | None
    colour: Sequence[float] | Callable[[Window], np.ndarray] = (0.0, 0.0, 0.0)
    kind: Literal["paint", "shadow"] = "paint"
    strength: float = 0.0
    z_mm: float = 0.0
    z_extent_mm: tuple[float, float] | None = None


def _bbox_px(
    bbox_mm: BBox | None,
    camera: CameraModel,
    rot: np.ndarray,
    t_mm: np.ndarray,
    z_extent_mm: tuple[float, float] = (0.0, 0.0),
) -> tuple[int, int, int, int] | None:
    """Pixel box (x0, y0, x1, y1), end-exclusive, clipped to the image; None if empty.

    The box is the frame box ``bbox_mm`` at the heights ``z_extent_mm`` (both ends).
    """
    w, h = camera.image_size_px
    if bbox_mm is None:
        return 0, 0, w, h
    x0, y0, x1, y1 = bbox_mm
    s = np.linspace(0.0, 1.0, 17)
    border = np.concatenate(
        [
            np.column_stack((x0 + (x1 - x0) * s, np.full_like(s, y0))),
            np.column_stack((x0 + (x1 - x0) * s, np.full_like(s, y1))),
            np.column_stack((np.full_like(s, x0), y0 + (y1 - y0) * s)),
            np.column_stack((np.full_like(s, x1), y0 + (y1 - y0) * s)),
        ]
    )
    zs = sorted(set(z_extent_mm))
    border = np.vstack([np.column_stack((border, np.full(len(border), z))) for z in zs])
    cam_z = (border @ rot.T + t_mm)[:, 2]
    if np.any(cam_z <= 1e-6):
        return 0, 0, w, h
    px = project_frame_points(camera, rot, t_mm, border)
    pad = 3
    bx0 = max(0, int(np.floor(px[:, 0].min())) - pad)
    by0 = max(0, int(np.floor(px[:, 1].min())) - pad)
    bx1 = min(w, int(np.ceil(px[:, 0].max())) + pad + 1)
    by1 = min(h, int(np.ceil(px[:, 1].max())) + pad + 1)
    if bx1 <= bx0 or by1 <= by0:
        return None
    return bx0, by0, bx1, by1


def rasterise(
    layers: Sequence[Layer],
    camera: CameraModel,
    rot: np.ndarray,
    t_mm: np.ndarray,
    *,
    rows_per_strip: int = 256,
    depth: bool = False,
) -> np.ndarray | tuple[np.ndarray, np.ndarray]:
    """Paint ``layers`` into a linear-RGB albedo image (H, W, 3), float32.

    Work proceeds in horizontal strips so that memory stays bounded at 14 MP;
    within a strip only the columns some layer needs are traced to the plane.
    Each layer's window is traced to its own plane (``Layer.z_mm``).
    With ``depth=True`` also returns the camera depth (H, W) in mm of what each
    pixel shows (painted layers blended by coverage, at their ``z_mm``).
    """
    w, h = camera.image_size_px
    img = np.zeros((h, w, 3), dtype=np.float32)
    depth_map = np.zeros((h, w), dtype=np.float32) if depth else None
    if (
        layers
        and layers[0].alpha is None
        and layers[0].bbox_mm is None
        and not callable(layers[0].colour)
    ):
        img[...] = np.asarray(layers[0].colour, dtype=np.float32)  # a plain background
        if depth_map is not None:
            depth_map[...] = _plane_depth(camera, rot, t_mm, 0.0)
        layers = layers[1:]
    boxes = [
        _bbox_px(layer.bbox_mm, camera, rot, t_mm, layer.z_extent_mm or (layer.z_mm, layer.z_mm))
        for layer in layers
    ]
    rays = RayMap(camera)
    for sy0 in range(0, h, rows_per_strip):
        sy1 = min(h, sy0 + rows_per_strip)
        active = [
            (layer, box)
            for layer, box in zip(layers, boxes, strict=True)
            if box is not None and box[1] < sy1 and box[3] > sy0
        ]
        if not active:
            continue
        cx0 = min(box[0] for _, box in active)
        cx1 = max(box[2] for _, box in active)
        # plane coordinates of the strip plus a one-pixel halo
        ys = np.arange(sy0 - 1, sy1 + 1, dtype=np.float64)
        xs = np.arange(cx0 - 1, cx1 + 1, dtype=np.float64)
        strip_rays = Rays(-rot.T @ t_mm, *rays.direction_grid(rot, xs, ys))
        u, v = strip_rays.at_z(0.0)
        for layer, (bx0, by0, bx1, by1) in active:
            y0, y1 = max(by0, sy0), min(by1, sy1)
            # window indices into the strip arrays (which start at (cx0 - 1, sy0 - 1))
            r0, r1 = y0 - sy0, y1 - sy0 + 2
            c0, c1 = bx0 - cx0, bx1 - cx0 + 2
            sub = strip_rays.sub(slice(r0, r1), slice(c0, c1))
            if layer.z_mm == 0.0:
                win = Window(u[r0:r1, c0:c1], v[r0:r1, c0:c1], sub)
            else:
                win = Window(*sub.at_z(layer.z_mm), sub, layer.z_mm)
            target = img[y0:y1, bx0:bx1]
            if layer.alpha is None:
                col = layer.colour(win) if callable(layer.colour) else layer.colour
                target[...] = Window.crop(col) if callable(layer.colour) else col
                if depth_map is not None:
                    depth_map[y0:y1, bx0:bx1] = Window.crop(sub.depth_at_z(layer.z_mm))
                continue
            alpha = Window.crop(layer.alpha(win)).astype(np.float32)[..., None]
            if layer.kind == "shadow":
                target *= 1.0 - layer.strength * alpha
                continue
            colour = layer.colour
            if callable(colour):
                col = Window.crop(colour(win)).astype(np.float32)
            else:
                col = np.asarray(colour, dtype=np.float32)
            target += alpha * (col - target)
            if depth_map is not None:
                dtarget = depth_map[y0:y1, bx0:bx1]
                dtarget += alpha[..., 0] * (Window.crop(sub.depth_at_z(layer.z_mm)) - dtarget)
    return (img, depth_map) if depth_map is not None else img


def _plane_depth(camera: CameraModel, rot: np.ndarray, t_mm: np.ndarray, z_mm: float) -> np.ndarray:
    """Camera depth (H, W) in mm of the plane z = ``z_mm`` at every pixel."""
    w, h = camera.image_size_px
    dirs = RayMap(camera, step_px=64).direction_grid(
        rot, np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64)
    )
    return Rays(-rot.T @ t_mm, *dirs).depth_at_z(z_mm).astype(np.float32)
