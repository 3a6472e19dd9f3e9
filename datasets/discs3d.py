"""Marker discs at their heights above the plate, by forward projection (a minimal 3D scene).

An independent check of measuring at heights, until the photo lab traces every
pixel's ray to its own plane: each disc's and ring's outline is a 3D circle at its
kit height (machine frame, z up, mm), projected point by point through the lens
with ``cv2.projectPoints`` (distortion included) and filled, anti-aliased by 8x8
supersampling, in linear light over a uniform grey plate. The measuring code
goes the other way (pixel rays intersected with height planes), so the two share
no geometry code. Effects the measuring code does not assume can be switched on:
a dark bar across a disc's edge (the wire, a tool) and a soft shadow edge across
a marker, a stray disc of a marker's colour, optical blur, noise and JPEG.

Positions follow the bender's layout (:func:`cvmeasure_datasets.bender.bender_wire_polyline`):
origin at (0, 0), axis at (-70, 0), the pin 18 mm out at ``pin_angle_deg``,
``wire_a`` and ``wire_b`` 30 and 70 mm along the bent leg. Truth: the angles of
the discs' true centres' plate coordinates (the spec's definitions).

Kept deliberately separate from the photo lab's 3D scenes (:mod:`cvmeasure_datasets.bender`),
now that they trace rays too: an independent generator to judge the measuring code on, so
do not merge the two.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cvmeasure.camera_model import CameraModel
from cvmeasure.colorimetry import srgb_decode, srgb_encode
from cvmeasure.geometry import direction_deg
from cvmeasure.kit import ROLES, MarkerKit, default_kit
from cvmeasure_datasets.bender import RING_SRGB, BenderGeometry, bender_wire_polyline
from cvmeasure_datasets.optics import Pose

__all__ = ["Bar", "Stray", "DiscScene", "render_discs_at_heights"]

_PLATE_SRGB = (150, 152, 156)
_SS = 8  # supersampling per axis


@dataclass(frozen=True)
class Bar:
    """A straight bar (machine mm) at ``height_mm``: the wire or a tool across a marker.

    ``through_mm`` a point on its axis, ``direction_deg`` its direction, ``width_mm``,
    ``srgb`` its colour; ``shadow`` > 0 darkens instead (a soft shadow band of that
    depth, 0..1, with ``soft_mm`` penumbra), drawn on everything below it.
    """

    through_mm: tuple[float, float]
    direction_deg: float
    width_mm: float
    height_mm: float = 20.0
    srgb: tuple[int, int, int] = (60, 62, 66)
    shadow: float = 0.0
    soft_mm: float = 1.5
    length_mm: float = 30.0


@dataclass(frozen=True)
class Stray:
    """A stray coloured disc (machine mm, on the plate or above it), optionally on a white ring."""

    centre_mm: tuple[float, float]
    radius_mm: float
    srgb: tuple[int, int, int]
    height_mm: float = 0.0
    ring_mm: float = 0.0


@dataclass(frozen=True)
class DiscScene:
    """The scene: angles, the kit (with heights), the camera pose and the effects."""

    pin_angle_deg: float
    bend_angle_deg: float
    kit: MarkerKit = field(default_factory=default_kit)
    pose: Pose = field(default_factory=lambda: Pose(distance_mm=550.0, offset_mm=(-10.0, 0.0)))
    bars: tuple[Bar, ...] = ()
    strays: tuple[Stray, ...] = ()
    blur_px: float = 0.7
    noise: float = 0.006
    jpeg_quality: int | None = 92
    flat: bool = False


def marker_centres_mm(pin_angle_deg: float, bend_angle_deg: float) -> dict[str, np.ndarray]:
    """The five disc centres' plate coordinates (machine frame, mm)."""
    geo = BenderGeometry()
    _, start, direction = bender_wire_polyline(bend_angle_deg, geo)
    rad = math.radians(pin_angle_deg)
    return {
        "origin": np.zeros(2),
        "axis": np.array([geo.axis_x_mm, 0.0]),
        "pin": geo.pin_radius_mm * np.array([math.cos(rad), math.sin(rad)]),
        "wire_a": start + geo.wire_a_mm * direction,
        "wire_b": start + geo.wire_b_mm * direction,
    }


def _project(camera, rot, t_mm, pts3):
    return camera.project(np.asarray(pts3, dtype=np.float64) @ rot.T + t_mm)


def _coverage(poly_px: np.ndarray, shape: tuple[int, int]) -> tuple[tuple[int, int], np.ndarray]:
    """Anti-aliased coverage (0..1, float32) of a polygon in its bounding box: (x0, y0), alpha."""
    import cv2

    h, w = shape
    x0 = max(0, int(math.floor(poly_px[:, 0].min())) - 1)
    y0 = max(0, int(math.floor(poly_px[:, 1].min())) - 1)
    x1 = min(w, int(math.ceil(poly_px[:, 0].max())) + 2)
    y1 = min(h, int(math.ceil(poly_px[:, 1].max())) + 2)
    if x1 <= x0 or y1 <= y0:
        return (0, 0), np.zeros((0, 0), np.float32)
    big = np.zeros(((y1 - y0) * _SS, (x1 - x0) * _SS), np.uint8)
    # pixel centres at integers: a supersample's centre is (k + 0.5) / SS - 0.5
    shift = 8
    pts = ((poly_px - (x0, y0) + 0.5) * _SS - 0.5) * (1 << shift)
    cv2.fillPoly(big, [np.round(pts).astype(np.int32)], 255, cv2.LINE_8, shift)
    small = cv2.resize(big, (x1 - x0, y1 - y0), interpolation=cv2.INTER_AREA)
    return (x0, y0), small.astype(np.float32) / 255.0


def _paint(img: np.ndarray, poly_px: np.ndarray, lin_bgr: np.ndarray) -> None:
    (x0, y0), a = _coverage(poly_px, img.shape[:2])
    if a.size:
        roi = img[y0 : y0 + a.shape[0], x0 : x0 + a.shape[1]]
        roi *= 1.0 - a[..., None]
        roi += a[..., None] * lin_bgr


def _circle3(centre_mm, radius_mm, height_mm, n=720):
    t = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
    return np.column_stack(
        (
            centre_mm[0] + radius_mm * np.cos(t),
            centre_mm[1] + radius_mm * np.sin(t),
            np.full(n, height_mm),
        )
    )


def _lin(srgb8) -> np.ndarray:
    rgb = srgb_decode(np.asarray(srgb8, dtype=np.float64) / 255.0)
    return rgb[::-1].astype(np.float32)  # BGR


def render_discs_at_heights(
    scene: DiscScene, *, camera: CameraModel, seed: int = 0
) -> tuple[np.ndarray, dict[str, Any]]:
    """Render ``scene`` through ``camera`` (distortion included): (BGR uint8 photo, truth).

    ``scene.flat`` puts every disc on the plate (heights 0) whatever the kit says.
    Truth: ``pin_angle_deg``, ``bend_angle_deg``, per role ``x_mm``, ``y_mm``,
    ``height_mm``, ``centre_px`` (projection of the disc's 3D centre).
    """
    import cv2

    rot, t_mm = scene.pose.extrinsics("machine")
    w, h = camera.image_size_px
    img = np.empty((h, w, 3), np.float32)
    img[:] = _lin(_PLATE_SRGB)
    centres = marker_centres_mm(scene.pin_angle_deg, scene.bend_angle_deg)
    kit = scene.kit
    height = {r: 0.0 if scene.flat else kit.height_mm(r) for r in ROLES}
    # paint from the lowest surface up: strays and markers by height, bars on top of
    # what lies below them
    items: list[tuple[float, int, Any]] = []
    for i, s in enumerate(scene.strays):
        items.append((s.height_mm, i, ("stray", s)))
    for i, r in enumerate(ROLES):
        items.append((height[r], 100 + i, ("marker", r)))
    for i, b in enumerate(scene.bars):
        items.append((b.height_mm, 200 + i, ("bar", b)))
    for _, _, (kind, obj) in sorted(items, key=lambda x: (x[0], x[1])):
        if kind == "stray":
            if obj.ring_mm > 0:
                ring = _circle3(obj.centre_mm, obj.ring_mm / 2, obj.height_mm)
                _paint(img, _project(camera, rot, t_mm, ring), _lin(RING_SRGB))
            disc = _circle3(obj.centre_mm, obj.radius_mm, obj.height_mm)
            _paint(img, _project(camera, rot, t_mm, disc), _lin(obj.srgb))
        elif kind == "marker":
            spec = kit.by_role(obj)
            c, z = centres[obj], height[obj]
            ring = _circle3(c, spec.ring_mm / 2, z)
            _paint(img, _project(camera, rot, t_mm, ring), _lin(RING_SRGB))
            disc = _circle3(c, spec.diameter_mm / 2, z)
            _paint(img, _project(camera, rot, t_mm, disc), _lin(spec.srgb))
        else:
            _bar(img, obj, camera, rot, t_mm)
    rng = np.random.default_rng([seed, 0xD15C])
    if scene.blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), scene.blur_px)
    if scene.noise > 0:
        img += rng.normal(0.0, scene.noise, img.shape).astype(np.float32) * np.sqrt(
            np.clip(img, 0.0, 1.0) + 0.02
        )
    bgr = np.round(srgb_encode(np.clip(img, 0.0, 1.0)) * 255.0).astype(np.uint8)
    if scene.jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, scene.jpeg_quality])
        bgr = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    truth_markers = {}
    for r in ROLES:
        c3 = np.array([[centres[r][0], centres[r][1], height[r]]])
        truth_markers[r] = {
            "x_mm": float(centres[r][0]),
            "y_mm": float(centres[r][1]),
            "height_mm": height[r],
            "centre_px": _project(camera, rot, t_mm, c3)[0].tolist(),
        }
    truth = {
        "pin_angle_deg": float(direction_deg(centres["origin"], centres["pin"])),
        "bend_angle_deg": float(direction_deg(centres["wire_a"], centres["wire_b"])),
        "markers": truth_markers,
        "pose": scene.pose.to_dict(),
    }
    return bgr, truth


def _bar(img, bar: Bar, camera, rot, t_mm) -> None:
    d = np.array(
        [math.cos(math.radians(bar.direction_deg)), math.sin(math.radians(bar.direction_deg))]
    )
    n = np.array([-d[1], d[0]])
    c = np.asarray(bar.through_mm, dtype=np.float64)
    length = bar.length_mm / 2
    s = np.linspace(-length, length, 200)
    if bar.shadow <= 0:
        half = bar.width_mm / 2
        side_a = c + np.outer(s, d) + half * n
        side_b = c + np.outer(s[::-1], d) - half * n
        poly = np.vstack((side_a, side_b))
        pts3 = np.column_stack((poly, np.full(len(poly), bar.height_mm)))
        _paint(img, _project(camera, rot, t_mm, pts3), _lin(bar.srgb))
        return
    # a shadow band on the plate level of the markers it crosses: multiply, soft edges
    # (a stack of nested bands, each taking a share of the depth)
    steps = 8
    for k in range(steps):
        half = bar.width_mm / 2 + bar.soft_mm * (0.5 - (k + 0.5) / steps)
        side_a = c + np.outer(s, d) + half * n
        side_b = c + np.outer(s[::-1], d) - half * n
        poly = np.vstack((side_a, side_b))
        pts3 = np.column_stack((poly, np.full(len(poly), bar.height_mm)))
        (x0, y0), a = _coverage(_project(camera, rot, t_mm, pts3), img.shape[:2])
        if a.size:
            roi = img[y0 : y0 + a.shape[0], x0 : x0 + a.shape[1]]
            factor = (1.0 - bar.shadow) ** (1.0 / steps)
            roi *= 1.0 - a[..., None] * (1.0 - factor)
