"""Synthetic photos of the bender's top plate with the five kit markers.

Geometry (machine frame of the spec, mm, z = 0 plane): the die of radius
``die_radius_mm`` is centred on the origin (the pin's rotation centre, where
the ``origin`` marker sits). The wire (diameter ``wire_diameter_mm``) comes in
along -x, tangent to the die, on the side away from the bend; it wraps around
the die on an arc of radius ``die_radius_mm + wire_diameter_mm / 2`` through
the bend angle and leaves as a straight leg at ``bend_angle_deg`` from +x.
``wire_a`` and ``wire_b`` sit on the leg's centreline ``wire_a_mm`` and
``wire_b_mm`` along it from the end of the wrap; ``axis`` sits upstream on the
wire guide at (``axis_x_mm``, 0); ``pin`` on the pin, ``pin_radius_mm`` from the
origin at ``pin_angle_deg``. By default all shapes are flat (heights are
ignored, so the truth is exact for the plane z = 0); shadows are cast as if the
wire and the markers stood a few mm above the plate.

With :class:`~cvmeasure_datasets.effects.SceneEffects` the scene is 3D: discs at
their kit heights (each pixel's ray traced to the disc's plane), printed supports
under them, the wire as a shiny cylinder at its axis height with a cast shadow,
a textured plate and table, stray coloured objects, a loose wire across a ring's
edge and a tool's shadow; and camera effects (depth of field, motion blur,
Bayer mosaic) in :func:`~cvmeasure_datasets.photo.render_scene`.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cvmeasure.camera_model import CameraModel
from cvmeasure.geometry import direction_deg
from cvmeasure.kit import MarkerKit, default_kit
from cvmeasure_datasets.clutter import stray_layers, stray_objects, textured, tool_shadow_layer
from cvmeasure_datasets.effects import SceneEffects
from cvmeasure_datasets.lighting import Lighting, srgb8_to_linear
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.photo import (
    RenderedPhoto,
    circle_image_geometry,
    px_per_mm_at,
    render_scene,
    resolve_camera,
)
from cvmeasure_datasets.raster import (
    Layer,
    Window,
    circle_bbox,
    polyline_bbox,
    sdf_alpha,
    sdf_capsules,
    sdf_circle,
    sdf_rect,
)
from cvmeasure_datasets.solids import (
    dense_polyline,
    flat_wire_layer,
    lamp_direction,
    post_sdf,
    shadow_on_plane,
    tube_layer,
    wire_shadow_layer,
)

__all__ = ["RING_SRGB", "BenderGeometry", "bender_wire_polyline", "render_bender_photo"]

_TABLE = (62, 56, 50)
_PLATE = (150, 152, 156)
_GUIDE = (96, 98, 104)
_DIE = (120, 122, 128)
_PIN = (185, 186, 190)
_WIRE = (165, 166, 170)
_HOLE = (30, 30, 32)
#: Printed white of the marker rings (sRGB 8-bit).
RING_SRGB = (236, 236, 232)
_OCCLUDER = (45, 40, 36)
_SUPPORT = (84, 86, 92)
#: The flat wire's shading (:func:`~cvmeasure_datasets.solids.flat_wire_layer`).
_WIRE_SHADING = {"shade": (0.35, 0.65), "highlight": (0.6, 0.22)}


@dataclass(frozen=True)
class BenderGeometry:
    """Sizes and positions of the bender's parts (machine frame, mm)."""

    die_radius_mm: float = 8.0
    wire_diameter_mm: float = 3.0
    pin_radius_mm: float = 18.0
    pin_diameter_mm: float = 5.0
    axis_x_mm: float = -70.0
    wire_a_mm: float = 30.0
    wire_b_mm: float = 70.0
    leg_length_mm: float = 105.0
    infeed_length_mm: float = 160.0
    plate_mm: tuple[float, float, float, float] = (-190.0, -130.0, 150.0, 130.0)
    wire_height_mm: float = 3.0
    marker_height_mm: float = 4.0

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def bender_wire_polyline(
    bend_angle_deg: float, geometry: BenderGeometry = BenderGeometry()
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Wire centreline (N, 2) in machine mm, and the start and direction of the bent leg.

    Returns ``(polyline_mm, leg_start_mm, leg_direction)``.
    """
    theta = np.radians(bend_angle_deg)
    side = 1.0 if bend_angle_deg >= 0 else -1.0
    rho = geometry.die_radius_mm + geometry.wire_diameter_mm / 2
    infeed = np.array([[-geometry.infeed_length_mm, -side * rho], [0.0, -side * rho]])
    n_arc = max(2, int(np.ceil(abs(bend_angle_deg) / 1.5)) + 1)
    phi = -side * np.pi / 2 + np.linspace(0.0, theta, n_arc)
    arc = rho * np.column_stack((np.cos(phi), np.sin(phi)))
    direction = np.array([np.cos(theta), np.sin(theta)])
    start = arc[-1]
    leg = start + np.outer([0.0, geometry.leg_length_mm], direction)
    polyline = np.vstack((infeed, arc[1:], leg[1:]))
    return polyline, start, direction


def _brushed(seed: int, base: np.ndarray) -> Any:
    """Brushed-metal albedo: fine streaks along x, deterministic in plane mm."""
    rng = np.random.default_rng([seed, 0xB0])
    freqs = rng.uniform(0.8, 6.0, 6)
    phases = rng.uniform(0, 2 * np.pi, 6)
    amps = rng.uniform(0.004, 0.012, 6)
    # the streaks depend on y only: tabulate them every 0.005 mm
    ys = np.arange(-400.0, 400.0, 0.005)
    table = 1.0 + sum(a * np.sin(f * ys + p) for f, p, a in zip(freqs, phases, amps, strict=True))
    base32 = np.asarray(base, dtype=np.float32)

    def colour(win: Window) -> np.ndarray:
        m = np.interp(win.v, ys, table).astype(np.float32)
        return m[..., None] * base32

    return colour


def _circle_layer(centre, radius_mm, colour, *, kind="paint", strength=0.0, soft_mm=0.0):
    return Layer(
        bbox_mm=circle_bbox(centre, radius_mm + soft_mm + 0.5),
        alpha=lambda w: sdf_alpha(sdf_circle(w.u, w.v, centre, radius_mm), soft_mm),
        colour=colour,
        kind=kind,
        strength=strength,
    )


def render_bender_photo(
    *,
    pin_angle_deg: float,
    bend_angle_deg: float,
    kit: MarkerKit | None = None,
    camera: CameraModel | None = None,
    pose: Pose | None = None,
    lighting: Lighting | None = None,
    seed: int = 0,
    scale: float = 1.0,
    image_size_px: tuple[int, int] | None = None,
    occlude: dict[str, float] | None = None,
    geometry: BenderGeometry | None = None,
    linear: bool = False,
    effects: SceneEffects | None = None,
) -> RenderedPhoto:
    """Render a photo of the bender from above with the kit's five markers.

    Parameters
    ----------
    pin_angle_deg : angle of origin -> pin from +x (machine frame), degrees.
    bend_angle_deg : angle of the bent leg from +x, degrees; 0 is straight.
    kit : marker kit (default :func:`cvmeasure.kit.default_kit`).
    camera : camera model at 4608 px width (default :func:`default_camera`); ``scale``
        resizes it (and the photo), or ``image_size_px`` (w, h) sets the size directly.
    pose : camera pose in the machine frame (default: straight down from 850 mm
        above (-10, 0), about 8 px/mm at full size).
    lighting : see :class:`Lighting` (default: a realistic workshop photo).
    seed : drives noise, surface texture and the direction of occluders.
    occlude : ``{role: fraction}``, hide that fraction (0..1) of a marker's ring
        diameter under a dark occluder (1 hides it completely).
    geometry : sizes of the machine parts.
    linear : also return the 16-bit linear RGB image.
    effects : real-scene effects (:class:`SceneEffects`; default all off: the flat scene).

    Returns
    -------
    RenderedPhoto whose truth holds ``pin_angle_deg`` and ``bend_angle_deg``
    computed from the rendered marker centres (spec definitions), and for every
    role ``x_mm``, ``y_mm``, ``centre_px`` (the projected disc centre: the
    truth), ``ellipse_centre_px`` (centre of the disc's image ellipse, which
    differs from ``centre_px`` under perspective), ``r_px`` and ``occluded_fraction``;
    ``height_mm`` (the disc's height above the plate in this render) and
    ``centre_3d_mm``. The angles are plate-plane angles: from the marker centres
    projected along the plate normal onto the plate.
    """
    fx = effects or SceneEffects()
    return _render(
        pin_angle_deg=pin_angle_deg,
        bend_angle_deg=bend_angle_deg,
        kit=kit or default_kit(),
        camera=camera,
        pose=pose or Pose(distance_mm=850.0, offset_mm=(-10.0, 0.0)),
        lighting=lighting if lighting is not None else Lighting(),
        seed=seed,
        scale=scale,
        image_size_px=image_size_px,
        occlude=dict(occlude or {}),
        geo=geometry or BenderGeometry(),
        linear=linear,
        fx=fx,
    )


def _render(
    *,
    pin_angle_deg: float,
    bend_angle_deg: float,
    kit: MarkerKit,
    camera: CameraModel | None,
    pose: Pose,
    lighting: Lighting,
    seed: int,
    scale: float,
    image_size_px: tuple[int, int] | None,
    occlude: dict[str, float],
    geo: BenderGeometry,
    linear: bool,
    fx: SceneEffects,
) -> RenderedPhoto:
    """The bender scene with the switchable effects of ``fx`` (see the module doc).

    With every effect off (``fx.flat``) this is the flat scene: the wire's diameter from
    ``geo`` (not the kit), occluders on the plate and the flat truth (no 3D keys).
    """
    flat = fx.flat
    for role, frac in occlude.items():
        kit.by_role(role)
        if not 0.0 <= frac <= 1.0:
            raise ValueError(f"occlude[{role!r}] must be in [0, 1], got {frac}")
    for role in (*fx.wire_across, *fx.tool_shadow):
        kit.by_role(role)
    light = lighting
    polyline, leg_start, leg_dir = bender_wire_polyline(bend_angle_deg, geo)
    pin_rad = np.radians(pin_angle_deg)
    pin_centre = geo.pin_radius_mm * np.array([np.cos(pin_rad), np.sin(pin_rad)])
    centres = {
        "origin": np.zeros(2),
        "axis": np.array([geo.axis_x_mm, 0.0]),
        "pin": pin_centre,
        "wire_a": leg_start + geo.wire_a_mm * leg_dir,
        "wire_b": leg_start + geo.wire_b_mm * leg_dir,
    }
    heights = {m.role: (kit.height_mm(m.role) if fx.marker_heights else 0.0) for m in kit.markers}
    wire_d = geo.wire_diameter_mm if flat else (kit.wire_diameter_mm or geo.wire_diameter_mm)
    wire_r = wire_d / 2
    wire_z = (
        (kit.wire_axis_height_mm if kit.wire_axis_height_mm is not None else 5.0)
        if fx.wire_3d
        else 0.0
    )
    lamp = lamp_direction(light.light_azimuth_deg)
    az = np.radians(light.light_azimuth_deg)
    away = -np.array([np.cos(az), np.sin(az)]) * 0.85
    rng = np.random.default_rng([seed, 0xBE])
    lin = srgb8_to_linear
    x0, y0, x1, y1 = geo.plate_mm
    table = textured(seed, _TABLE, "wood", cell_mm=0.5) if fx.textured_background else lin(_TABLE)
    plate = (
        textured(seed + 7, _PLATE, "plate", (x0 - 1, y0 - 1, x1 + 1, y1 + 1))
        if fx.textured_background
        else _brushed(seed, lin(_PLATE))
    )
    layers: list[Layer] = [
        Layer(None, None, table),
        Layer(
            (x0 - 1, y0 - 1, x1 + 1, y1 + 1),
            lambda w: sdf_alpha(
                sdf_rect(w.u, w.v, ((x0 + x1) / 2, (y0 + y1) / 2), ((x1 - x0) / 2, (y1 - y0) / 2))
            ),
            plate,
        ),
    ]
    for hx, hy in ((x0 + 15, y0 + 15), (x1 - 15, y0 + 15), (x0 + 15, y1 - 15), (x1 - 15, y1 - 15)):
        layers.append(_circle_layer((hx, hy), 3.2, lin(_HOLE)))
    guide_c = ((geo.axis_x_mm - 60 + geo.axis_x_mm + 45) / 2, 0.0)
    layers.append(
        Layer(
            (guide_c[0] - 53.5, -15.5, guide_c[0] + 53.5, 15.5),
            lambda w: sdf_alpha(sdf_rect(w.u, w.v, guide_c, (52.5, 14.0))),
            lin(_GUIDE),
        )
    )
    layers.append(_circle_layer((0.0, 0.0), geo.die_radius_mm, lin(_DIE)))
    layers.append(_circle_layer(tuple(pin_centre), geo.pin_diameter_mm / 2, lin(_PIN)))
    strays: list[dict[str, Any]] = []
    if fx.clutter:
        clear = [
            (float(c[0]), float(c[1]), kit.by_role(r).ring_mm / 2 + 8.0) for r, c in centres.items()
        ]
        clear += [(float(p[0]), float(p[1]), wire_r + 6.0) for p in dense_polyline(polyline, 4.0)]
        clear.append((0.0, 0.0, geo.pin_radius_mm + 10.0))  # the pin sweeps around the die
        area = (x0 - 60.0, y0 - 40.0, x1 + 60.0, y1 + 40.0)
        strays = stray_objects(seed, fx.clutter, kit, clear, area)
        layers += stray_layers(strays)
    wire3 = np.column_stack((polyline, np.full(len(polyline), wire_z)))
    support_z = {
        m.role: (
            (wire_z + wire_r if m.role in ("wire_a", "wire_b") else 0.0),
            heights[m.role],
        )
        for m in kit.markers
    }
    if light.shadow_strength > 0:
        if fx.wire_3d:
            wire_shadow = shadow_on_plane(wire3, lamp)
        else:
            wire_shadow = polyline + away * geo.wire_height_mm
        band_mm = None if flat else 3.0
        layers.append(
            wire_shadow_layer(
                wire_shadow, wire_r, light.shadow_strength, soft_mm=1.2, band_mm=band_mm
            )
        )
        for marker in kit.markers:
            if occlude.get(marker.role, 0.0) >= 1.0:
                continue
            h = heights[marker.role] if fx.marker_heights else geo.marker_height_mm
            c0 = centres[marker.role]
            if fx.supports and heights[marker.role] > 0:
                z_lo, z_hi = support_z[marker.role]
                seg = np.array([c0 + away * z_lo, c0 + away * z_hi])
                layers.append(
                    Layer(
                        polyline_bbox(seg, marker.ring_mm / 2 + 4.0),
                        lambda w, seg=seg, r=marker.ring_mm / 2: sdf_alpha(
                            sdf_capsules(w.u, w.v, seg, r, 3.5), 2.0
                        ),
                        kind="shadow",
                        strength=light.shadow_strength,
                    )
                )
            else:
                layers.append(
                    _circle_layer(
                        tuple(c0 + away * h),
                        marker.ring_mm / 2,
                        None,
                        kind="shadow",
                        strength=light.shadow_strength,
                        soft_mm=2.0,
                    )
                )
    if fx.wire_3d:
        layers.append(tube_layer(wire3, wire_r, lin(_WIRE), lamp))
    else:
        layers.append(flat_wire_layer(polyline, wire_r, lin(_WIRE), **_WIRE_SHADING))
    order = sorted(kit.markers, key=lambda m: heights[m.role])
    if fx.supports:
        for marker in order:
            z_lo, z_hi = support_z[marker.role]
            if z_hi <= z_lo:
                continue
            c = tuple(centres[marker.role])
            r = marker.ring_mm / 2
            layers.append(
                Layer(
                    circle_bbox(c, r + 1.0),
                    lambda w, c=c, r=r, a=z_lo, b=z_hi: sdf_alpha(post_sdf(w, c, r, a, b)),
                    lin(_SUPPORT),
                    z_mm=z_hi,
                    z_extent_mm=(z_lo, z_hi),
                )
            )
    for marker in order:
        c = tuple(centres[marker.role])
        z = heights[marker.role]
        for radius, colour in (
            (marker.ring_mm / 2, RING_SRGB),
            (marker.diameter_mm / 2, marker.srgb),
        ):
            layers.append(
                Layer(
                    circle_bbox(c, radius + 0.5),
                    lambda w, c=c, radius=radius: sdf_alpha(sdf_circle(w.u, w.v, c, radius)),
                    lin(colour),
                    z_mm=z,
                )
            )
    extra: dict[str, Any] = {"wire_across": {}, "tool_shadow": {}}
    for role in fx.wire_across:
        # a loose wire lying across the ring's edge, 2 mm above the disc, clear of the others
        ring_r = kit.by_role(role).ring_mm / 2
        # the wire's axis over the ring's edge
        ang, _, ends = _line_across(rng, centres, role, 360.0, ring_r - 0.5, 12.0)
        z = heights[role] + 2.0 + wire_r
        loose = np.column_stack((ends, np.full(2, z)))
        layers.append(tube_layer(loose, wire_r, lin(_WIRE), lamp))
        extra["wire_across"][role] = {"axis_mm": loose.tolist(), "direction_deg": ang}
    for role in fx.tool_shadow:
        # a tool's shadow: a band 8 mm wide across the marker (off its centre), 50 mm long,
        # kept clear of the other markers
        ring_r = kit.by_role(role).ring_mm / 2
        ang, mid, _ = _line_across(rng, centres, role, 180.0, ring_r * 0.5, 16.0)
        layers.append(tool_shadow_layer(mid, ang, 8.0, 0.55, length_mm=50.0))
        extra["tool_shadow"][role] = {
            "centre_mm": mid.tolist(),
            "direction_deg": ang,
            "width_mm": 8.0,
            "length_mm": 50.0,
        }
    occluders = {}
    for role, frac in sorted(occlude.items()):
        if frac <= 0:
            continue
        ring_r = kit.by_role(role).ring_mm / 2
        ang = float(rng.uniform(0.0, 360.0))
        d = np.array([np.cos(np.radians(ang)), np.sin(np.radians(ang))])
        edge = ring_r - 2.0 * ring_r * frac - 1e-3
        half = (2.0 * ring_r + 2.0, 1.6 * ring_r)
        oc = tuple(centres[role] + d * (edge + half[0]))
        occluders[role] = {"fraction": frac, "direction_deg": ang, "edge_offset_mm": edge}
        reach = float(np.hypot(*half)) + 0.5
        layers.append(
            Layer(
                (oc[0] - reach, oc[1] - reach, oc[0] + reach, oc[1] + reach),
                lambda w, oc=oc, ang=ang, half=half: sdf_alpha(sdf_rect(w.u, w.v, oc, half, ang)),
                lin(_OCCLUDER),
                z_mm=0.0 if flat else heights[role] + 1.0,
            )
        )
    pin_true = float(direction_deg(centres["origin"], centres["pin"]))
    bend_true = float(direction_deg(centres["wire_a"], centres["wire_b"]))
    truth: dict[str, Any] = {
        "kind": "bender",
        "pin_angle_deg": pin_true,
        "bend_angle_deg": bend_true,
        "requested": {"pin_angle_deg": pin_angle_deg, "bend_angle_deg": bend_angle_deg},
        "kit": kit.to_dict(),
        "geometry": {**geo.to_dict(), "wire_centreline_mm": polyline.tolist()},
        "occluders": occluders,
    }
    if flat:
        truth["notes"] = (
            "centre_px is the projection of each disc's centre (the truth); "
            "ellipse_centre_px is the centre of the disc's image ellipse, which differs under "
            "perspective. Shapes are flat at machine z = 0."
        )
    else:
        truth["geometry"]["wire_centreline_3d_mm"] = wire3.tolist()
        truth["geometry"]["wire_axis_height_mm"] = wire_z
        truth["effects"] = fx.to_dict()
        truth["stray_objects"] = [{k: v for k, v in o.items() if k != "reach_mm"} for o in strays]
        truth.update(extra)
        truth["notes"] = (
            "3D scene: each disc lies at height_mm above the plate (centre_3d_mm); "
            "pin_angle_deg and bend_angle_deg are plate-plane angles between the marker centres "
            "projected along the plate normal onto the plate (x_mm, y_mm). centre_px is the "
            "projection of the disc's 3D centre; ellipse_centre_px the centre of its image "
            "ellipse."
        )
    cam = resolve_camera(camera, scale, image_size_px)
    rot, t_mm = pose.extrinsics("machine")
    markers = {}
    for marker in kit.markers:
        c = centres[marker.role]
        z = heights[marker.role]
        disc = circle_image_geometry(cam, rot, t_mm, c, marker.diameter_mm / 2, z)
        ring = circle_image_geometry(cam, rot, t_mm, c, marker.ring_mm / 2, z)
        markers[marker.role] = {
            "x_mm": float(c[0]),
            "y_mm": float(c[1]),
            "diameter_mm": marker.diameter_mm,
            "ring_mm": marker.ring_mm,
            "x_px": disc["centre_px"][0],
            "y_px": disc["centre_px"][1],
            **disc,
            "ring_r_px": ring["r_px"],
            "occluded_fraction": float(occlude.get(marker.role, 0.0)),
            "height_mm": z,
            "centre_3d_mm": [float(c[0]), float(c[1]), z],
        }
        if not flat:
            markers[marker.role]["wire_across"] = marker.role in fx.wire_across
            markers[marker.role]["tool_shadow"] = marker.role in fx.tool_shadow
    truth["markers"] = markers
    truth["effects"] = fx.to_dict()  # after the markers in the flat truth (its historic order)
    truth["px_per_mm_at_origin"] = px_per_mm_at(cam, rot, t_mm, (0.0, 0.0))
    return render_scene(
        layers,
        frame="machine",
        camera=cam,
        pose=pose,
        lighting=light,
        seed=seed,
        scale=1.0,
        linear=linear,
        truth=truth,
        effects=fx,
    )


def _line_across(
    rng: np.random.Generator,
    centres: dict[str, np.ndarray],
    role: str,
    max_deg: float,
    offset_mm: float,
    clearance_mm: float,
) -> tuple[float, np.ndarray, np.ndarray]:
    """A 50 mm line past the marker ``role``, clear of the other markers (plate mm).

    Its direction is drawn from ``rng`` in [0, ``max_deg``) deg, its middle lies
    ``offset_mm`` off the marker's centre (perpendicular to it); redrawn (50 times at
    most) until every other centre is more than ``clearance_mm`` from it.
    Returns (direction_deg, middle (2,), ends (2, 2)).
    """
    c = centres[role]
    others = [centres[r] for r in centres if r != role]
    for _ in range(50):
        ang = float(rng.uniform(0.0, max_deg))
        n = np.array([np.cos(np.radians(ang + 90)), np.sin(np.radians(ang + 90))])
        d = np.array([np.cos(np.radians(ang)), np.sin(np.radians(ang))])
        mid = c + n * offset_mm
        ends = np.array([mid - 25.0 * d, mid + 25.0 * d])
        if all(np.hypot(*(o - _closest(ends, o))) > clearance_mm for o in others):
            break
    return ang, mid, ends


def _closest(segment: np.ndarray, point: np.ndarray) -> np.ndarray:
    """The point of a segment (2, 2) closest to ``point`` (2,)."""
    a, b = segment
    d = b - a
    t = float(np.clip((point - a) @ d / (d @ d), 0.0, 1.0))
    return a + t * d
