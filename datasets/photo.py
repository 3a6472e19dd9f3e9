"""The rendered photo with its ground truth, and the shared render driver."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.camera_model import CameraModel
from cvmeasure.fileio import atomic_write_bytes, atomic_write_json, to_jsonable
from cvmeasure_datasets.blur import defocus_diameter_px, depth_of_field, motion_blur
from cvmeasure_datasets.effects import SceneEffects
from cvmeasure_datasets.lighting import Lighting, develop
from cvmeasure_datasets.optics import Frame, Pose, default_camera, project_frame_points
from cvmeasure_datasets.raster import Layer, rasterise

__all__ = [
    "RenderedPhoto",
    "render_scene",
    "resolve_camera",
    "circle_image_geometry",
    "px_per_mm_at",
]


@dataclass(frozen=True)
class RenderedPhoto:
    """A synthetic photo and its exact ground truth.

    Attributes
    ----------
    bgr : ndarray (H, W, 3), uint8; the photo as a reader sees it (decoded JPEG
        when the lighting compresses, else the 8-bit sRGB image).
    camera : the exact camera model the photo was rendered with (at its size).
    truth : JSON-able dict; the geometry, pose, lighting and per-kind truth.
    linear_rgb16 : ndarray (H, W, 3), uint16, linear RGB (RGB order) after white
        balance, before gamma and JPEG; only when rendered with ``linear=True``.
    jpeg_bytes : the JPEG file exactly as written by :meth:`save`, if compressed.
    """

    bgr: np.ndarray
    camera: CameraModel
    truth: dict[str, Any]
    linear_rgb16: np.ndarray | None = None
    jpeg_bytes: bytes | None = None

    def save(self, path_stem: str | os.PathLike[str]) -> tuple[Path, Path]:
        """Write ``<stem>.jpg`` (or ``<stem>.png`` when uncompressed) and ``<stem>.truth.json``.

        Both writes are atomic. Returns ``(photo_path, truth_json_path)``.
        """
        import cv2

        stem = Path(path_stem)
        if self.jpeg_bytes is not None:
            photo = atomic_write_bytes(stem.with_name(stem.name + ".jpg"), self.jpeg_bytes)
        else:
            ok, buf = cv2.imencode(".png", self.bgr)
            if not ok:  # pragma: no cover
                raise RuntimeError("PNG encoding failed")
            photo = atomic_write_bytes(stem.with_name(stem.name + ".png"), buf.tobytes())
        truth = dict(self.truth)
        truth["photo"] = photo.name
        truth_path = atomic_write_json(stem.with_name(stem.name + ".truth.json"), truth)
        return photo, truth_path

    def save_linear_tiff(self, path: str | os.PathLike[str]) -> Path:
        """Write the 16-bit linear RGB image as a TIFF (atomic)."""
        import cv2

        if self.linear_rgb16 is None:
            raise ValueError("this photo was rendered without linear=True")
        ok, buf = cv2.imencode(".tiff", np.ascontiguousarray(self.linear_rgb16[..., ::-1]))
        if not ok:  # pragma: no cover
            raise RuntimeError("TIFF encoding failed")
        return atomic_write_bytes(path, buf.tobytes())


def circle_image_geometry(
    camera: CameraModel,
    rot: np.ndarray,
    t_mm: np.ndarray,
    centre_mm: Sequence[float],
    radius_mm: float,
    z_mm: float = 0.0,
) -> dict[str, Any]:
    """Where a plane circle lands in the photo.

    The circle lies in the plane z = ``z_mm`` of the frame (a disc above the plate).

    Returns ``centre_px`` (the projection of the circle's centre, distorted:
    the truth for "where is the marker"), ``ellipse_centre_px`` (the centre of
    the circle's image ellipse under the pinhole model, pushed through the
    distortion; a fitted ellipse finds this, not ``centre_px``),
    ``ellipse_axes_px`` (semi-axes, pinhole) and ``r_px`` (sqrt of their product).
    """
    k = camera.camera_matrix
    # plane (x, y, 1) -> pinhole px
    hom = k @ np.column_stack((rot[:, 0], rot[:, 1], t_mm + z_mm * rot[:, 2]))
    cx, cy = centre_mm
    conic = np.array(
        [[1.0, 0.0, -cx], [0.0, 1.0, -cy], [-cx, -cy, cx * cx + cy * cy - radius_mm**2]]
    )
    hinv = np.linalg.inv(hom)
    img_conic = hinv.T @ conic @ hinv
    a = img_conic[:2, :2]
    b = img_conic[:2, 2]
    centre_ideal = -np.linalg.solve(a, b)
    f0 = img_conic[2, 2] + b @ centre_ideal
    evals = np.linalg.eigvalsh(a)
    axes = np.sqrt(np.abs(-f0 / evals))
    # push the pinhole ellipse centre through the distortion
    norm = (centre_ideal - k[:2, 2]) / np.diag(k)[:2]
    ell_px = camera.project(np.array([[norm[0], norm[1], 1.0]]))[0]
    centre_px = project_frame_points(camera, rot, t_mm, np.array([[cx, cy, z_mm]]))[0]
    return {
        "centre_px": [float(centre_px[0]), float(centre_px[1])],
        "ellipse_centre_px": [float(ell_px[0]), float(ell_px[1])],
        "ellipse_axes_px": sorted((float(axes[0]), float(axes[1])), reverse=True),
        "r_px": float(np.sqrt(axes[0] * axes[1])),
    }


def px_per_mm_at(
    camera: CameraModel, rot: np.ndarray, t_mm: np.ndarray, point_mm: Sequence[float]
) -> float:
    """Image scale at a plane point, px per mm (geometric mean of the two plane directions)."""
    x, y = point_mm
    px = project_frame_points(
        camera, rot, t_mm, np.array([[x - 0.5, y], [x + 0.5, y], [x, y - 0.5], [x, y + 0.5]])
    )
    return float(np.sqrt(np.linalg.norm(px[1] - px[0]) * np.linalg.norm(px[3] - px[2])))


def resolve_camera(
    camera: CameraModel | None, scale: float, image_size_px: tuple[int, int] | None = None
) -> CameraModel:
    """The camera a photo is rendered with.

    ``camera`` (default: the seed camera) resized by ``scale``, or to
    ``image_size_px`` (same aspect ratio) when that is given.
    """
    cam = camera if camera is not None else default_camera()
    if image_size_px is not None:
        w, h = (int(v) for v in image_size_px)
        factor = w / cam.image_size_px[0]
        if abs(h - cam.image_size_px[1] * factor) > 1.0:
            raise ValueError(
                f"image_size_px {image_size_px} does not keep the camera's aspect ratio "
                f"{cam.image_size_px}"
            )
        return cam.scaled(factor) if (w, h) != cam.image_size_px else cam
    if scale <= 0:
        raise ValueError(f"scale must be positive, got {scale}")
    return cam.scaled(scale) if scale != 1.0 else cam


def image_tilt_direction_deg(rot_cam_frame: np.ndarray) -> float:
    """The pose's tilt direction in the image frame, as ``cvmeasure plane`` reports it.

    The image direction in which the plane recedes from the camera, degrees
    counter-clockwise from +x as seen in the photo (0 when the plane is square to
    the optical axis). :class:`~cvmeasure_datasets.optics.Pose` gives its tilt
    direction in the scene frame instead; the two differ by the yaw and the frame's
    handedness in the photo.
    """
    normal = rot_cam_frame[:, 2] * np.sign(rot_cam_frame[2, 2] or 1.0)
    if math.hypot(normal[0], normal[1]) < 1e-12:
        return 0.0
    return float(np.degrees(np.arctan2(normal[1], -normal[0])))


def _focus_depth_mm(rot: np.ndarray, t_mm: np.ndarray, frame: Frame, height_mm: float) -> float:
    """Camera depth where the optical axis meets the plane ``height_mm`` above the scene plane."""
    z = height_mm if frame == "machine" else -height_mm
    centre = -rot.T @ t_mm
    axis = rot[2]  # the optical axis in the frame (unit; depth = distance along it)
    return float((z - centre[2]) / axis[2])


def render_scene(
    layers: Sequence[Layer],
    *,
    frame: Frame,
    camera: CameraModel | None,
    pose: Pose,
    lighting: Lighting | None,
    seed: int,
    scale: float,
    linear: bool,
    truth: dict[str, Any],
    effects: SceneEffects | None = None,
) -> RenderedPhoto:
    """Rasterise, light, develop; return the photo with ``truth`` plus the common fields.

    ``effects`` adds the camera's scene-dependent blur before development (thin-lens
    depth of field from each pixel's depth, motion blur) and the Bayer mosaic.
    """
    cam = resolve_camera(camera, scale)
    light = lighting if lighting is not None else Lighting()
    rot, t_mm = pose.extrinsics(frame)
    fx = effects or SceneEffects()
    if fx.depth_of_field:
        albedo, depth = rasterise(layers, cam, rot, t_mm, depth=True)
        focus_mm = _focus_depth_mm(rot, t_mm, frame, fx.focus_height_mm)
        diameter = defocus_diameter_px(depth, focus_mm, cam.fx, fx.focal_length_mm, fx.f_number)
        albedo = depth_of_field(albedo, diameter)
        truth = {
            **truth,
            "depth_of_field": {
                "focus_depth_mm": focus_mm,
                "blur_diameter_px_min": float(diameter.min()),
                "blur_diameter_px_max": float(diameter.max()),
            },
        }
        del depth, diameter
    else:
        albedo = rasterise(layers, cam, rot, t_mm)
    if fx.motion_blur_px > 0:
        albedo = motion_blur(albedo, fx.motion_blur_px, fx.motion_blur_deg)
    if fx.bayer and not light.bayer:
        light = replace(light, bayer=True)
    dev = develop(albedo, light, seed=seed, keep_linear=linear, centre_px=cam.principal_point_px)
    import cv2

    rvec, _ = cv2.Rodrigues(rot)
    common = {
        "seed": int(seed),
        "frame": frame,
        "image_size": list(cam.image_size_px),
        "camera": cam.to_dict(),
        "pose": {
            **pose.to_dict(),
            "R_cam_frame": rot.tolist(),
            "tilt_direction_image_deg": image_tilt_direction_deg(rot),
            "rvec": rvec.ravel().tolist(),
            "tvec_mm": t_mm.tolist(),
        },
        "lighting": light.to_dict(),
    }
    full = to_jsonable({**common, **truth})
    return RenderedPhoto(
        bgr=dev.bgr,
        camera=cam,
        truth=full,
        linear_rgb16=dev.linear_rgb16,
        jpeg_bytes=dev.jpeg_bytes,
    )
