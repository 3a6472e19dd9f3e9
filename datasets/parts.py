"""Finished wire parts (chord arcs, saddles) lying on a matte sheet beside a ChArUco board.

A part is a polyline of N equal chords (N + 1 vertices, bent at the N - 1 inner
vertices), the wire's centreline. The sheet lies to the right of the board in
the same plane, so the part's geometry is known in the board frame (mm).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from cvmeasure.board import BoardSpec, CharucoBoardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.geometry import wrap_deg
from cvmeasure.kit import default_kit
from cvmeasure_datasets.boards import board_layers, board_truth, table_layer
from cvmeasure_datasets.clutter import stray_layers, stray_objects, textured
from cvmeasure_datasets.effects import SceneEffects
from cvmeasure_datasets.lighting import Lighting, srgb8_to_linear
from cvmeasure_datasets.optics import Pose
from cvmeasure_datasets.photo import RenderedPhoto, px_per_mm_at, render_scene, resolve_camera
from cvmeasure_datasets.raster import (
    Layer,
    sdf_alpha,
    sdf_rect,
)
from cvmeasure_datasets.solids import (
    dense_polyline,
    flat_wire_layer,
    lamp_direction,
    tube_layer,
    wire_cast_shadow_layer,
    wire_shadow_layer,
)

__all__ = [
    "PartSpec",
    "arc_part",
    "saddle_part",
    "polyline_part",
    "vertex_bend_angles_deg",
    "lifted_centreline",
    "render_part_photo",
]

_SHEETS = {"dark": (38, 38, 42), "light": (212, 212, 206)}
_WIRE = (170, 171, 175)
#: The flat wire's shading (:func:`~cvmeasure_datasets.solids.flat_wire_layer`).
_WIRE_SHADING = {"shade": (0.3, 0.7), "highlight": (0.7, 0.2)}


def vertex_bend_angles_deg(vertices_mm: np.ndarray) -> np.ndarray:
    """Signed turn at each inner vertex (N - 1,), degrees, counter-clockwise positive in (x, y)."""
    seg = np.diff(np.asarray(vertices_mm, dtype=np.float64), axis=0)
    heading = np.degrees(np.arctan2(seg[:, 1], seg[:, 0]))
    return np.asarray(wrap_deg(np.diff(heading)), dtype=np.float64).reshape(-1)


@dataclass(frozen=True)
class PartSpec:
    """A wire part: its centreline vertices (N + 1, 2) in part mm and what it is.

    ``radius_mm``, ``chord_width_mm`` (end-to-end distance), ``height_mm``
    (sagitta: largest distance of a vertex from the end-to-end line) and
    ``arc_angle_deg`` describe the design; for a saddle ``radius_mm`` is NaN.
    """

    kind: Literal["arc", "saddle", "polyline"]
    vertices_mm: np.ndarray
    radius_mm: float
    arc_angle_deg: float
    wire_diameter_mm: float = 2.0

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices_mm, dtype=np.float64)
        if v.ndim != 2 or v.shape[1] != 2 or len(v) < 2:
            raise ValueError("vertices_mm must have shape (N + 1, 2) with N >= 1")
        object.__setattr__(self, "vertices_mm", v)

    @property
    def divisions(self) -> int:
        return len(self.vertices_mm) - 1

    @property
    def chord_mm(self) -> float:
        """Mean chord (segment) length, mm."""
        return float(np.mean(np.linalg.norm(np.diff(self.vertices_mm, axis=0), axis=1)))

    @property
    def chord_width_mm(self) -> float:
        return float(np.linalg.norm(self.vertices_mm[-1] - self.vertices_mm[0]))

    @property
    def height_mm(self) -> float:
        a, b = self.vertices_mm[0], self.vertices_mm[-1]
        d = (b - a) / np.linalg.norm(b - a)
        rel = self.vertices_mm - a
        return float(np.max(np.abs(rel[:, 0] * d[1] - rel[:, 1] * d[0])))

    @property
    def segment_bend_deg(self) -> np.ndarray:
        return vertex_bend_angles_deg(self.vertices_mm)

    def placed(self, angle_deg: float, centre_mm: tuple[float, float]) -> np.ndarray:
        """Vertices rotated by ``angle_deg`` about their bounding-box centre, moved to ``centre_mm``."""
        v = self.vertices_mm
        mid = (v.min(axis=0) + v.max(axis=0)) / 2
        c, s = np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))
        rot = np.array([[c, -s], [s, c]])
        return (v - mid) @ rot.T + np.asarray(centre_mm)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "divisions": self.divisions,
            "radius_mm": self.radius_mm,
            "arc_angle_deg": self.arc_angle_deg,
            "chord_mm": self.chord_mm,
            "chord_width_mm": self.chord_width_mm,
            "height_mm": self.height_mm,
            "segment_bend_deg": self.segment_bend_deg.tolist(),
            "wire_diameter_mm": self.wire_diameter_mm,
            "vertices_mm": self.vertices_mm.tolist(),
        }


def arc_part(
    radius_mm: float, arc_angle_deg: float, divisions: int, *, wire_diameter_mm: float = 2.0
) -> PartSpec:
    """An arc of ``divisions`` equal chords inscribed in a circle of ``radius_mm``.

    Vertices lie on the circle; each inner vertex turns by ``arc_angle_deg /
    divisions`` (counter-clockwise).
    """
    if radius_mm <= 0 or divisions < 1 or not 0 < arc_angle_deg <= 360:
        raise ValueError("need radius_mm > 0, divisions >= 1, 0 < arc_angle_deg <= 360")
    phi = np.radians(-90.0 - arc_angle_deg / 2 + np.linspace(0.0, arc_angle_deg, divisions + 1))
    verts = radius_mm * np.column_stack((np.cos(phi), np.sin(phi)))
    return PartSpec("arc", verts, float(radius_mm), float(arc_angle_deg), wire_diameter_mm)


def _equal_chords(curve: np.ndarray, n: int) -> np.ndarray:
    """N + 1 points on a dense curve (M, 2) with equal straight-line spacing, ends included."""
    seglen = np.linalg.norm(np.diff(curve, axis=0), axis=1)
    s = np.concatenate(([0.0], np.cumsum(seglen)))

    def walk(chord: float) -> tuple[np.ndarray, float]:
        pts = [curve[0]]
        idx = 0
        for _ in range(n):
            p = pts[-1]
            d = np.linalg.norm(curve[idx:] - p, axis=1)
            beyond = np.nonzero(d >= chord)[0]
            if len(beyond) == 0:
                return np.array(pts), -np.inf
            j = idx + beyond[0]
            # exact crossing on segment j-1 -> j (solve |a + t (b - a) - p| = chord)
            a, b = curve[j - 1], curve[j]
            e, f = b - a, a - p
            qa, qb, qc = e @ e, 2 * e @ f, f @ f - chord**2
            t = (-qb + np.sqrt(max(qb * qb - 4 * qa * qc, 0.0))) / (2 * qa)
            pts.append(a + t * e)
            idx = j - 1
        remaining = s[-1] - (s[idx] + np.linalg.norm(pts[-1] - curve[idx]))
        return np.array(pts), remaining

    lo, hi = 0.0, s[-1] / n * 1.0001
    for _ in range(80):
        mid = (lo + hi) / 2
        _, rem = walk(mid)
        lo, hi = (mid, hi) if rem > 0 else (lo, mid)
    pts, _ = walk(lo)
    pts[-1] = curve[-1]
    return pts


def saddle_part(
    width_mm: float = 200.0,
    height_mm: float = 20.0,
    divisions: int = 13,
    *,
    wire_diameter_mm: float = 2.0,
) -> PartSpec:
    """A saddle: a raised-cosine bump ``width_mm`` long and ``height_mm`` high.

    Its vertices lie on ``y = height * (1 - cos(2 pi x / width)) / 2`` at equal
    chord lengths, so the bends change sign (concave at the ends, convex in
    the middle), like the seed paper's 200 x 20 mm saddle with 13 chords.
    """
    x = np.linspace(0.0, width_mm, 20001)
    y = height_mm * (1.0 - np.cos(2 * np.pi * x / width_mm)) / 2
    verts = _equal_chords(np.column_stack((x - width_mm / 2, y)), divisions)
    return PartSpec("saddle", verts, float("nan"), 0.0, wire_diameter_mm)


def polyline_part(vertices_mm: Any, *, wire_diameter_mm: float = 2.0) -> PartSpec:
    """Any polyline as a part (no design radius)."""
    v = np.asarray(vertices_mm, dtype=np.float64)
    turn = float(np.sum(vertex_bend_angles_deg(v))) if len(v) > 2 else 0.0
    return PartSpec("polyline", v, float("nan"), turn, wire_diameter_mm)


def render_part_photo(
    *,
    part: PartSpec | np.ndarray,
    board: BoardSpec | None = None,
    sheet: Literal["dark", "light"] = "dark",
    camera: CameraModel | None = None,
    pose: Pose | None = None,
    lighting: Lighting | None = None,
    seed: int = 0,
    scale: float = 1.0,
    image_size_px: tuple[int, int] | None = None,
    placement_deg: float | None = None,
    linear: bool = False,
    effects: SceneEffects | None = None,
    part_shift_mm: tuple[float, float] = (0.0, 0.0),
) -> RenderedPhoto:
    """Render a finished part on a matte sheet to the right of a ChArUco board.

    Parameters
    ----------
    part : a :class:`PartSpec` or a polyline (N + 1, 2) in mm.
    board : default ``CharucoBoardSpec(14, 10, 20 mm, 15 mm, DICT_5X5_100)``.
    sheet : "dark" or "light" matte sheet, 250 mm square, 10 mm right of the board.
    pose : camera pose in the board frame (default: straight down from 900 mm,
        centred between board and sheet).
    placement_deg : rotation of the part on the sheet (default: drawn from ``seed``).
    effects : real-scene effects (:class:`SceneEffects`): ``wire_3d`` renders the wire
        as a ray-traced cylinder lying on the sheet (axis one radius above it) with a
        highlight and a soft cast shadow; ``part_lift_mm`` rocks the part (a rigid tilt
        about a line on the sheet through its lowest end) so that its other end lifts
        that much; the camera effects, a textured sheet and stray objects on the sheet
        as for the bender. Default: all off, the flat render.
    part_shift_mm : slide the part by this much on the sheet (board frame, mm), keeping
        its placement and its rocking pose: the same seed and a shift give a second photo
        of the same part moved (``cvmeasure part --moved``).

    Returns
    -------
    RenderedPhoto whose truth holds ``part`` (design values and
    ``centreline_mm``: the wire's vertices in the board frame), ``radius_mm``,
    ``chord_width_mm``, ``height_mm``, ``arc_angle_deg``, ``segment_bend_deg``,
    the board's corners and the pose. With effects, ``part.centreline_3d_mm`` (the
    wire's axis in 3D, board frame: z is away from the camera, so heights are
    negative z), ``lift_mm``, ``tilt_deg`` and ``projected_segment_bend_deg`` (the
    bends of the centreline's projection onto the sheet: what ignoring the lift gives);
    ``radius_mm`` and ``segment_bend_deg`` stay the part's own (a rigid part).
    """
    fx = effects or SceneEffects()
    if sheet not in _SHEETS:
        raise ValueError(f"sheet must be one of {sorted(_SHEETS)}, got {sheet!r}")
    spec = part if isinstance(part, PartSpec) else polyline_part(part)
    board = board if board is not None else CharucoBoardSpec(14, 10, 20.0, 15.0)
    bw, bh = board.size_mm
    sheet_mm = 250.0
    sheet_c = (bw + 10.0 + sheet_mm / 2, bh / 2)
    rng = np.random.default_rng([seed, 0xA2])
    angle = float(rng.uniform(0.0, 360.0)) if placement_deg is None else float(placement_deg)
    centre = (
        sheet_c[0] + rng.uniform(-5, 5) + part_shift_mm[0],
        sheet_c[1] + rng.uniform(-5, 5) + part_shift_mm[1],
    )
    verts = spec.placed(angle, centre)
    pose = pose or Pose(
        distance_mm=900.0, offset_mm=((bw + 10.0 + sheet_mm - 20.0) / 2 + 10.0, bh / 2)
    )
    light = lighting if lighting is not None else Lighting()
    r = spec.wire_diameter_mm / 2
    lin = srgb8_to_linear
    az = np.radians(light.light_azimuth_deg)
    # board frame has z away from the camera; shadows fall away from the light
    shadow = verts - np.array([np.cos(az), np.sin(az)]) * 0.85 * spec.wire_diameter_mm
    layers = [
        table_layer(),
        *board_layers(board),
        Layer(
            (
                sheet_c[0] - sheet_mm / 2 - 1,
                sheet_c[1] - sheet_mm / 2 - 1,
                sheet_c[0] + sheet_mm / 2 + 1,
                sheet_c[1] + sheet_mm / 2 + 1,
            ),
            lambda w: sdf_alpha(sdf_rect(w.u, w.v, sheet_c, (sheet_mm / 2, sheet_mm / 2))),
            lin(_SHEETS[sheet]),
        ),
    ]
    extra: dict[str, Any] = {}
    if fx.flat:
        if light.shadow_strength > 0:
            layers.append(wire_shadow_layer(shadow, r, light.shadow_strength, soft_mm=1.0))
        layers.append(flat_wire_layer(verts, r, lin(_WIRE), **_WIRE_SHADING))
    else:
        layers, extra = _effect_layers(
            layers, verts, r, spec, fx, light, seed, sheet, sheet_c, sheet_mm
        )
    cam = resolve_camera(camera, scale, image_size_px)
    rot, t_mm = pose.extrinsics("board")
    placed = PartSpec(spec.kind, verts, spec.radius_mm, spec.arc_angle_deg, spec.wire_diameter_mm)
    truth = {
        "kind": "part",
        "sheet": sheet,
        "placement_deg": angle,
        "part": {**spec.to_dict(), "centreline_mm": verts.tolist()},
        "radius_mm": spec.radius_mm,
        "chord_width_mm": spec.chord_width_mm,
        "height_mm": spec.height_mm,
        "arc_angle_deg": spec.arc_angle_deg,
        "divisions": spec.divisions,
        "chord_mm": spec.chord_mm,
        "segment_bend_deg": placed.segment_bend_deg.tolist(),
        "notes": "centreline_mm is in the board frame (x right, y down on the board); "
        "segment_bend_deg is counter-clockwise positive in that frame's (x, y), which appears "
        "clockwise in the photo. The wire is flat at z = 0 (its height is ignored).",
        "px_per_mm_at_part": px_per_mm_at(cam, rot, t_mm, tuple(verts.mean(axis=0))),
        **board_truth(board, cam, rot, t_mm),
        "effects": fx.to_dict(),
    }
    if extra:
        truth["part"].update(extra.pop("part"))
        truth.update(extra)
        truth["notes"] = (
            "centreline_mm is in the board frame (x right, y down on the board): the wire's "
            "axis projected along the sheet's normal onto the sheet; centreline_3d_mm is the "
            "axis in 3D (board frame, z away from the camera: heights above the sheet are -z). "
            "radius_mm and segment_bend_deg are the rigid part's own (counter-clockwise "
            "positive in the board's (x, y)); projected_segment_bend_deg those of the "
            "projection."
        )
    return render_scene(
        layers,
        frame="board",
        camera=cam,
        pose=pose,
        lighting=light,
        seed=seed,
        scale=1.0,
        linear=linear,
        truth=truth,
        effects=fx,
    )


def lifted_centreline(
    verts_mm: np.ndarray, radius_mm: float, lift_mm: float
) -> tuple[np.ndarray, dict[str, Any]]:
    """A part lying on the sheet, rocked so that one end lifts ``lift_mm``: its 3D axis.

    The part (vertices (N + 1, 2) on the sheet, board frame) tilts rigidly about the
    line on the sheet perpendicular to its end-to-end chord through its lowest point
    (the vertex least far along the chord); the vertex farthest along rises by
    ``lift_mm``. Returns the axis (N + 1, 3) with z = -height (board frame: z away from
    the camera; the axis lies one wire radius above the sheet) and a description.
    """
    v = np.asarray(verts_mm, dtype=np.float64)
    chord = v[-1] - v[0]
    c_hat = chord / np.linalg.norm(chord)
    proj = (v - v[0]) @ c_hat
    pivot = float(proj.min())
    span = float(proj.max() - pivot)
    sin_t = lift_mm / span if span > 0 else 0.0
    cos_t = float(np.sqrt(1.0 - sin_t**2))
    along = proj - pivot
    xy = v + np.outer(along * (cos_t - 1.0), c_hat)
    height = radius_mm + along * sin_t
    axis3 = np.column_stack((xy, -height))
    info = {
        "lift_mm": float(lift_mm),
        "tilt_deg": float(np.degrees(np.arcsin(sin_t))),
        "tilt_axis_point_mm": (v[0] + pivot * c_hat).tolist(),
        "tilt_axis_direction": [float(-c_hat[1]), float(c_hat[0])],
    }
    return axis3, info


def _effect_layers(
    layers: list[Layer],
    verts: np.ndarray,
    r: float,
    spec: PartSpec,
    fx: SceneEffects,
    light: Lighting,
    seed: int,
    sheet: str,
    sheet_c: tuple[float, float],
    sheet_mm: float,
) -> tuple[list[Layer], dict[str, Any]]:
    """The part scene's layers with effects (textured sheet, strays, 3D wire, lift)."""
    lin = srgb8_to_linear
    half = sheet_mm / 2
    box = (sheet_c[0] - half, sheet_c[1] - half, sheet_c[0] + half, sheet_c[1] + half)
    if fx.textured_background:
        layers = list(layers)
        layers[-1] = Layer(
            layers[-1].bbox_mm,
            layers[-1].alpha,
            textured(seed + 3, _SHEETS[sheet], "plate", box),
        )
    strays: list[dict[str, Any]] = []
    if fx.clutter:
        clear = [(float(p[0]), float(p[1]), r + 15.0) for p in dense_polyline(verts, 4.0)]
        strays = stray_objects(seed, fx.clutter, default_kit(), clear, box)
        layers = [*layers, *stray_layers(strays)]
    lift = fx.part_lift_mm
    if fx.wire_3d or lift > 0:
        axis3, info = lifted_centreline(verts, r, lift)
    else:
        axis3, info = np.column_stack((verts, np.zeros(len(verts)))), {"lift_mm": 0.0}
    xy = axis3[:, :2]
    lamp = lamp_direction(light.light_azimuth_deg, up=-1.0)
    if light.shadow_strength > 0 and fx.wire_3d:
        # a cylinder's own shadow under the distant lamp: r sqrt(1 + (n . s)^2) about the
        # axis' shadow, wider than the wire where it runs across the light
        layers.append(
            wire_cast_shadow_layer(axis3, r, lamp, light.shadow_strength, soft_mm=1.0, band_mm=3.0)
        )
    elif light.shadow_strength > 0:
        az = np.radians(light.light_azimuth_deg)
        shadow = xy - np.array([np.cos(az), np.sin(az)]) * 0.85 * spec.wire_diameter_mm
        layers.append(wire_shadow_layer(shadow, r, light.shadow_strength, soft_mm=1.0, band_mm=3.0))
    if fx.wire_3d:
        layers.append(tube_layer(axis3, r, lin(_WIRE), lamp))
    else:
        layers.append(flat_wire_layer(xy, r, lin(_WIRE), **_WIRE_SHADING))
    extra = {
        "part": {"centreline_3d_mm": axis3.tolist(), "projected_centreline_mm": xy.tolist()},
        **info,
        "projected_segment_bend_deg": vertex_bend_angles_deg(xy).tolist(),
        "stray_objects": [{k: v for k, v in o.items() if k != "reach_mm"} for o in strays],
    }
    return layers, extra
