"""Bender and board photos rendered by Mitsuba 3, a physically based renderer the project did not write.

A second, independent scene generator for the marker chain: the camera is Mitsuba's
pinhole (``perspective`` sensor), light is path traced from a ceiling area light and a low
desk lamp, the marker caps are closed plastic cylinders standing at their kit heights on
white rings, the pin is steel and the wire a rough-conductor tube. Nothing here imports
``cvmeasure`` or ``cvmeasure_datasets``: the kit and the board come in as the files the
CLI prints (``cvmeasure targets markers --format json``, ``cvmeasure targets charuco``).

World frame: millimetres, the top plate is ``z = 0`` with ``+z`` towards the camera. The
machine frame of the conventions (origin marker at the origin, ``+x`` from the axis marker
to the origin marker, counter-clockwise as seen from above positive) is placed in the world
by a yaw and a shift, so the truth angles do not depend on how the machine lies in the photo.
Each render is cached under its parameters' hash (JPEG + truth JSON).
"""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import cv2
import numpy as np

__all__ = [
    "BenderScene",
    "bender_truth",
    "BoardScene",
    "CameraRig",
    "project_points",
    "render_bender",
    "render_board",
    "render_part",
    "PartScene",
    "part_truth",
]

_SHEET_DPI = 300.0
_WIRE_RADIUS_MM = 1.0
_WIRE_Z_MM = 3.0
_PIN_RADIUS_MM = 2.5
_PIN_REACH_MM = 22.0
_AXIS_DISTANCE_MM = 70.0
_CLIP_A_MM = 40.0
_CLIP_B_MM = 80.0
_WIRE_SIDE_MM = 6.0
_INLAY_MM = 0.3


@dataclass(frozen=True)
class CameraRig:
    """A pinhole camera: image size, horizontal field of view and a look-at pose (world mm)."""

    width_px: int = 960
    height_px: int = 640
    fov_x_deg: float = 34.0
    eye_mm: tuple[float, float, float] = (10.0, -25.0, 430.0)
    target_mm: tuple[float, float, float] = (10.0, 5.0, 0.0)
    up: tuple[float, float, float] = (0.0, 1.0, 0.0)

    def matrix(self) -> np.ndarray:
        """OpenCV camera matrix (pixel centres at integers)."""
        f = (self.width_px / 2.0) / math.tan(math.radians(self.fov_x_deg) / 2.0)
        cx, cy = self.width_px / 2.0 - 0.5, self.height_px / 2.0 - 0.5
        return np.array([[f, 0.0, cx], [0.0, f, cy], [0.0, 0.0, 1.0]])

    def world_to_camera(self) -> tuple[np.ndarray, np.ndarray]:
        """Rotation and translation (OpenCV: x right, y down, z forward) from world mm."""
        eye, tgt, up = (np.asarray(v, float) for v in (self.eye_mm, self.target_mm, self.up))
        z = (tgt - eye) / np.linalg.norm(tgt - eye)
        x = np.cross(z, up)
        x /= np.linalg.norm(x)
        y = np.cross(z, x)
        rot = np.stack([x, y, z])
        return rot, -rot @ eye


def project_points(rig: CameraRig, points_mm: np.ndarray) -> np.ndarray:
    """Project world points (N x 3, mm) to pixels (N x 2) through the ideal pinhole."""
    rot, t = rig.world_to_camera()
    cam = (rot @ np.asarray(points_mm, float).T).T + t
    uvw = (rig.matrix() @ cam.T).T
    return uvw[:, :2] / uvw[:, 2:3]


@dataclass(frozen=True)
class BenderScene:
    """One bender photo: signed pin and bend angles (machine frame) and how the machine lies."""

    pin_angle_deg: float
    bend_angle_deg: float
    yaw_deg: float = 0.0
    shift_mm: tuple[float, float] = (0.0, 0.0)
    rig: CameraRig = field(default_factory=CameraRig)
    spp: int = 16
    lamp_mm: tuple[float, float, float] = (260.0, 160.0, 120.0)
    with_board: bool = False
    # reconstruction filter width: a real lens and demosaic blur about a pixel, which also
    # keeps few-sample Monte Carlo speckle from cutting a small cap into pieces
    filter_stddev_px: float = 1.0
    # the soft light stands off to the side, as a lab lights a glossy subject: overhead, its
    # mirror image would sit in every cap top and wash the colours out (see the README)
    ceiling_mm: tuple[float, float, float] = (-320.0, -220.0, 560.0)
    cap_alpha: float = 0.3
    # the sheet or table top the bender stands on (linear RGB reflectance): dark steel
    # plate by default, a light laminate or paper sheet as some shops have
    plate_rgb: tuple[float, float, float] = (0.12, 0.12, 0.13)
    # Mitsuba's sample generator: "independent" (plain random) or a stratified one
    # ("multijitter"): at 16 spp its noise on the caps is 1.6-2 % of the level (the
    # independent one's 4-5 %), that of a camera's sensor at base ISO, at the same cost
    sampler: str = "independent"


@dataclass(frozen=True)
class BoardScene:
    """The printed board sheet lying flat, posed by a rotation vector and a shift (world)."""

    rvec: tuple[float, float, float] = (0.0, 0.0, 0.0)
    shift_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rig: CameraRig = field(default_factory=CameraRig)
    spp: int = 16


def _mi():
    import mitsuba as mi

    if mi.variant() is None:
        mi.set_variant("scalar_rgb")
    return mi


def _linear(srgb: list[int]) -> list[float]:
    c = np.asarray(srgb, float) / 255.0
    lin = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return [float(v) for v in lin]


def _plastic(rgb: list[float], alpha: float = 0.15) -> dict:
    return {
        "type": "roughplastic",
        "distribution": "ggx",
        "alpha": alpha,
        "int_ior": 1.49,
        "diffuse_reflectance": {"type": "rgb", "value": rgb},
    }


# Complex refractive indices at about 650 / 550 / 450 nm (RGB), written out because a
# pip-installed Mitsuba ships without its spectral data files.
_METALS = {
    "Fe": ([2.87, 2.95, 2.65], [3.12, 2.93, 2.81]),
    "Al": ([1.66, 0.88, 0.52], [9.22, 6.27, 4.84]),
}


def _metal(name: str, alpha: float) -> dict:
    eta, k = _METALS[name]
    return {
        "type": "roughconductor",
        "distribution": "ggx",
        "alpha": alpha,
        "eta": {"type": "rgb", "value": eta},
        "k": {"type": "rgb", "value": k},
    }


def _disk(mi, x: float, y: float, z: float, r: float, bsdf: dict) -> dict:
    tf = mi.ScalarTransform4f
    return {"type": "disk", "to_world": tf().translate([x, y, z]).scale([r, r, 1.0]), "bsdf": bsdf}


def _closed_cylinder(mi, p0, p1, r: float, bsdf: dict) -> dict[str, dict]:
    """A cylinder with both ends closed by disks (Mitsuba's cylinder is an open tube)."""
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    axis = (p1 - p0) / np.linalg.norm(p1 - p0)
    tf = mi.ScalarTransform4f
    out = {
        "side": {
            "type": "cylinder",
            "p0": p0.tolist(),
            "p1": p1.tolist(),
            "radius": r,
            "bsdf": bsdf,
        }
    }
    for name, p, n in (("cap0", p0, -axis), ("cap1", p1, axis)):
        frame = tf().look_at(origin=p.tolist(), target=(p + n).tolist(), up=_any_up(n))
        out[name] = {"type": "disk", "to_world": frame @ tf().scale([r, r, 1.0]), "bsdf": bsdf}
    return out


def _any_up(n: np.ndarray) -> list[float]:
    return [0.0, 1.0, 0.0] if abs(n[1]) < 0.9 else [1.0, 0.0, 0.0]


def _machine_to_world(scene: BenderScene, xy: np.ndarray) -> np.ndarray:
    a = math.radians(scene.yaw_deg)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return (rot @ np.asarray(xy, float).T).T + np.asarray(scene.shift_mm)


def machine_layout(scene: BenderScene, kit: dict) -> dict[str, dict]:
    """Each role's marker centre in the machine frame (x, y) and its cap height (mm)."""
    b = math.radians(scene.bend_angle_deg)
    p = math.radians(scene.pin_angle_deg)
    side = -1.0 if scene.bend_angle_deg >= 0 else 1.0
    bend_point = np.array([0.0, side * _WIRE_SIDE_MM])
    d = np.array([math.cos(b), math.sin(b)])
    xy = {
        "origin": np.zeros(2),
        "axis": np.array([-_AXIS_DISTANCE_MM, 0.0]),
        "pin": _PIN_REACH_MM * np.array([math.cos(p), math.sin(p)]),
        "wire_a": bend_point + _CLIP_A_MM * d,
        "wire_b": bend_point + _CLIP_B_MM * d,
    }
    heights = {m["role"]: float(m.get("height_mm", 0.0)) for m in kit["markers"]}
    return {role: {"xy": xy[role], "height_mm": heights[role]} for role in xy}


def _wire_shapes(mi, scene: BenderScene) -> dict[str, dict]:
    side = -1.0 if scene.bend_angle_deg >= 0 else 1.0
    b = math.radians(scene.bend_angle_deg)
    pts = np.array(
        [[-200.0, side * _WIRE_SIDE_MM], [0.0, side * _WIRE_SIDE_MM]]
        + [[130.0 * math.cos(b), side * _WIRE_SIDE_MM + 130.0 * math.sin(b)]]
    )
    w = _machine_to_world(scene, pts)
    steel = _metal("Fe", 0.25)
    z = _WIRE_Z_MM
    shapes = {
        "wire0": {
            "type": "cylinder",
            "p0": [*w[0], z],
            "p1": [*w[1], z],
            "radius": _WIRE_RADIUS_MM,
            "bsdf": steel,
        },
        "wire1": {
            "type": "cylinder",
            "p0": [*w[1], z],
            "p1": [*w[2], z],
            "radius": _WIRE_RADIUS_MM,
            "bsdf": steel,
        },
        "wirej": {"type": "sphere", "center": [*w[1], z], "radius": _WIRE_RADIUS_MM, "bsdf": steel},
    }
    return shapes


def _marker_shapes(mi, scene: BenderScene, kit: dict, layout: dict) -> dict[str, dict]:
    white = _plastic([0.8, 0.8, 0.8])
    shapes: dict[str, dict] = {}
    for m in kit["markers"]:
        role = m["role"]
        x, y = _machine_to_world(scene, layout[role]["xy"][None, :])[0]
        h = max(layout[role]["height_mm"], 2 * _INLAY_MM)
        ring = _closed_cylinder(mi, [x, y, 0.0], [x, y, h - _INLAY_MM], m["ring_mm"] / 2.0, white)
        cap = _closed_cylinder(
            mi,
            [x, y, h - _INLAY_MM],
            [x, y, h],
            m["diameter_mm"] / 2.0,
            _plastic(_linear(m["srgb"]), scene.cap_alpha),
        )
        shapes.update({f"{role}_ring_{k}": v for k, v in ring.items()})
        shapes.update({f"{role}_cap_{k}": v for k, v in cap.items()})
    px, py = _machine_to_world(scene, layout["pin"]["xy"][None, :])[0]
    steel = _metal("Fe", 0.2)
    pin = _closed_cylinder(mi, [px, py, 0.0], [px, py, _WIRE_Z_MM + 4.0], _PIN_RADIUS_MM, steel)
    shapes.update({f"steelpin_{k}": v for k, v in pin.items()})
    return shapes


def _base_scene(
    mi,
    rig: CameraRig,
    spp: int,
    lamp_mm,
    plate_z_mm: float = 0.0,
    filter_stddev_px: float = 0.5,
    ceiling_mm: tuple[float, float, float] = (0.0, 0.0, 700.0),
    plate_rgb: tuple[float, float, float] = (0.12, 0.12, 0.13),
    sampler: str = "independent",
) -> dict:
    tf = mi.ScalarTransform4f
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 5},
        "sensor": {
            "type": "perspective",
            "fov": rig.fov_x_deg,
            "fov_axis": "x",
            "near_clip": 1.0,
            "far_clip": 10000.0,
            "to_world": tf().look_at(
                origin=list(rig.eye_mm), target=list(rig.target_mm), up=list(rig.up)
            ),
            "film": {
                "type": "hdrfilm",
                "width": rig.width_px,
                "height": rig.height_px,
                "pixel_format": "rgb",
                "rfilter": {"type": "gaussian", "stddev": filter_stddev_px},
            },
            "sampler": {"type": sampler, "sample_count": spp},
        },
        "ceiling": {
            "type": "rectangle",
            "to_world": tf()
            .translate([0.0, 0.0, 700.0])
            .rotate([1, 0, 0], 180)
            .scale([250.0, 250.0, 1.0]),
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [4.0, 4.0, 4.0]}},
        },
        "lamp": {
            "type": "sphere",
            "center": list(lamp_mm),
            "radius": 30.0,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [15.0, 14.0, 11.0]}},
        },
        "plate": {
            "type": "rectangle",
            "to_world": tf().translate([0.0, 0.0, plate_z_mm]).scale([400.0, 300.0, 1.0]),
            "bsdf": _plastic(list(plate_rgb), alpha=0.4),
        },
    }


def _sheet_shape(mi, sheet_png: Path, rvec, shift_mm) -> dict:
    """The printed sheet at its true size (300 dpi PNG), centred, lying in z = 0 before the pose."""
    h_px, w_px = cv2.imread(str(sheet_png), cv2.IMREAD_GRAYSCALE).shape
    w_mm, h_mm = w_px * 25.4 / _SHEET_DPI, h_px * 25.4 / _SHEET_DPI
    rot, _ = cv2.Rodrigues(np.asarray(rvec, float))
    pose = np.eye(4)
    pose[:3, :3] = rot
    pose[:3, 3] = np.asarray(shift_mm, float) + [0.0, 0.0, 0.05]
    tf = mi.ScalarTransform4f
    # Mitsuba's rectangle spans [-1, 1]^2 with uv (0, 0) at (-1, -1); flip v so the sheet reads upright.
    local = tf().scale([w_mm / 2.0, -h_mm / 2.0, 1.0])
    return {
        "type": "rectangle",
        "to_world": tf(pose.tolist()) @ local,
        "bsdf": {
            "type": "diffuse",
            "reflectance": {
                "type": "bitmap",
                "filename": str(sheet_png),
                "filter_type": "bilinear",
            },
        },
    }


def _key(kind: str, params: dict, extra: list[Path]) -> str:
    if params.get("sampler") == "independent":
        # the default sampler keeps the keys (and cached renders) from before it was a choice
        params = {k: v for k, v in params.items() if k != "sampler"}
    h = hashlib.sha256(json.dumps([kind, params], sort_keys=True, default=list).encode())
    for p in extra:
        h.update(Path(p).read_bytes())
    return h.hexdigest()[:16]


def _write_jpeg(mi, img, path: Path) -> None:
    bmp = mi.Bitmap(img).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.UInt8, srgb_gamma=True)
    rgb = np.array(bmp)
    tmp = path.with_suffix(".tmp.jpg")
    cv2.imwrite(str(tmp), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 95])
    tmp.replace(path)


def _truth_bender(scene: BenderScene, kit: dict, layout: dict) -> dict:
    rig = scene.rig
    markers = {}
    for role, v in layout.items():
        wx, wy = _machine_to_world(scene, v["xy"][None, :])[0]
        world = np.array([wx, wy, v["height_mm"]])
        u, vv = project_points(rig, world[None, :])[0]
        markers[role] = {
            "machine_x_mm": float(v["xy"][0]),
            "machine_y_mm": float(v["xy"][1]),
            "world_mm": world.tolist(),
            "x_px": float(u),
            "y_px": float(vv),
        }
    rot, t = rig.world_to_camera()
    return {
        "pin_angle_deg": scene.pin_angle_deg,
        "bend_angle_deg": scene.bend_angle_deg,
        "markers": markers,
        "camera": {
            "image_size": [rig.width_px, rig.height_px],
            "camera_matrix": rig.matrix().tolist(),
            "rotation_world_to_camera": rot.tolist(),
            "translation_mm": t.tolist(),
        },
        "kit": kit["name"],
    }


def bender_truth(scene: BenderScene, kit_json: Path) -> dict:
    """The truth of a bender scene without rendering it (angles, marker centres, camera)."""
    kit = json.loads(Path(kit_json).read_text())
    return _truth_bender(scene, kit, machine_layout(scene, kit))


def render_bender(
    scene: BenderScene, kit_json: Path, cache_dir: Path, board_png: Path | None = None
) -> tuple[Path, dict]:
    """Render one bender photo (cached); return the JPEG path and its truth.

    With ``scene.with_board`` the printed sheet ``board_png`` lies on the plate beside the
    machine (the photo ``cvmeasure plane`` takes).
    """
    mi = _mi()
    kit = json.loads(Path(kit_json).read_text())
    extra = [Path(kit_json)] + ([Path(board_png)] if scene.with_board else [])
    key = _key("bender", asdict(scene), extra)
    cache_dir = Path(cache_dir)
    cache_dir.mkdir(parents=True, exist_ok=True)
    jpg, tj = cache_dir / f"bender_{key}.jpg", cache_dir / f"bender_{key}.json"
    layout = machine_layout(scene, kit)
    truth = _truth_bender(scene, kit, layout)
    if not jpg.exists():
        d = _base_scene(
            mi,
            scene.rig,
            scene.spp,
            scene.lamp_mm,
            0.0,
            scene.filter_stddev_px,
            scene.ceiling_mm,
            scene.plate_rgb,
            scene.sampler,
        )
        d.update(_wire_shapes(mi, scene))
        d.update(_marker_shapes(mi, scene, kit, layout))
        if scene.with_board:
            d["sheet"] = _sheet_shape(mi, Path(board_png), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        _write_jpeg(mi, mi.render(mi.load_dict(d)), jpg)
        tj.write_text(json.dumps(truth, indent=1))
    return jpg, truth


def render_board(scene: BoardScene, board_png: Path, cache_dir: Path) -> Path:
    """Render the printed board sheet at one pose (cached); return the JPEG path."""
    mi = _mi()
    key = _key("board", asdict(scene), [Path(board_png)])
    cache_dir = Path(cache_dir)
    cache_dir.mkdir(parents=True, exist_ok=True)
    jpg = cache_dir / f"board_{key}.jpg"
    if not jpg.exists():
        # a board held up off the plate (calibration views) is shot against the plate far below
        plate_z = 0.0 if scene.shift_mm[2] <= 1.0 and not any(scene.rvec) else -400.0
        d = _base_scene(mi, scene.rig, scene.spp, (260.0, 160.0, 120.0), plate_z)
        d["sheet"] = _sheet_shape(mi, Path(board_png), scene.rvec, scene.shift_mm)
        _write_jpeg(mi, mi.render(mi.load_dict(d)), jpg)
    return jpg


@dataclass(frozen=True)
class PartScene:
    """A finished part: a round wire bent to one circular arc, lying on a matte sheet beside
    the board sheet (the photo ``cvmeasure part`` takes). Lengths in mm.

    ``chords`` 0 renders a smooth arc (3 deg facets); N > 0 renders the polygon of N equal
    chords a bender makes, its vertices on the circle of ``radius_mm``. ``sheet_rgb`` is the
    matte sheet's linear reflectance, or ``sheet_texture`` (a PNG given to ``render_part``)
    names a printed texture (cork, wood) instead. ``lift_mm`` raises the wire's far end off
    the sheet (the part rocking on its near end)."""

    radius_mm: float = 40.0
    arc_angle_deg: float = 120.0
    wire_diameter_mm: float = 2.0
    yaw_deg: float = 20.0
    rig: CameraRig = field(
        default_factory=lambda: CameraRig(eye_mm=(0.0, -30.0, 700.0), target_mm=(0.0, 0.0, 0.0))
    )
    spp: int = 16
    chords: int = 0
    sheet_rgb: tuple[float, float, float] = (0.8, 0.8, 0.8)
    sheet_texture: str = ""
    lamp_mm: tuple[float, float, float] = (300.0, 200.0, 150.0)
    steel_alpha: float = 0.25
    lift_mm: float = 0.0


def part_truth(scene: PartScene) -> dict:
    """The arc's radius, chord, sagitta and arc angle on the wire centreline (mm, deg)."""
    half = math.radians(scene.arc_angle_deg) / 2.0
    r = scene.radius_mm
    out = {
        "radius_mm": r,
        "chord_width_mm": 2.0 * r * math.sin(half),
        "height_mm": r * (1.0 - math.cos(half)),
        "arc_angle_deg": scene.arc_angle_deg,
        "wire_diameter_mm": scene.wire_diameter_mm,
        "lift_mm": scene.lift_mm,
    }
    if scene.chords > 0:
        out["divisions"] = scene.chords
        out["segment_bend_deg"] = scene.arc_angle_deg / scene.chords
        out["chord_mm"] = 2.0 * r * math.sin(half / scene.chords)
    return out


def _lifted(flat_xy: np.ndarray, lift_mm: float) -> np.ndarray:
    """The rigid part tilted about a horizontal axis through its first end (perpendicular to
    the end-to-end chord) until its far end stands ``lift_mm`` higher: (N, 3) x, y and rise (mm)."""
    chord = flat_xy[-1] - flat_xy[0]
    length = float(np.linalg.norm(chord))
    u = chord / length
    tilt = math.asin(min(lift_mm / length, 1.0))
    along = (flat_xy - flat_xy[0]) @ u
    across = flat_xy - flat_xy[0] - along[:, None] * u
    xy = flat_xy[0] + across + (along * math.cos(tilt))[:, None] * u
    return np.column_stack([xy, along * math.sin(tilt)])


#: The matte sheet's top above the board's plane (mm), and where the arc's midpoint sits
#: (over the matte sheet's centre, world mm).
SHEET_Z_MM = 0.05
MATTE_CENTRE_X_MM = 140.0


def part_axis_mm(scene: PartScene) -> np.ndarray:
    """The wire's axis as rendered: its polygon's vertices (N+1, 3), world mm (the arc's
    midpoint over the matte sheet's centre, the axis a wire radius above the sheet, lifted
    as the scene says). A smooth arc (no chords) is drawn as 3-degree chords."""
    half = math.radians(scene.arc_angle_deg) / 2.0
    yaw = math.radians(scene.yaw_deg)
    back = scene.radius_mm - part_truth(scene)["height_mm"] / 2.0
    centre = (MATTE_CENTRE_X_MM - back * math.cos(yaw), -back * math.sin(yaw))
    n = scene.chords if scene.chords > 0 else max(8, int(scene.arc_angle_deg / 3.0))
    ang = yaw + np.linspace(-half, half, n + 1)
    flat = np.column_stack(
        [centre[0] + scene.radius_mm * np.cos(ang), centre[1] + scene.radius_mm * np.sin(ang)]
    )
    pts = _lifted(flat, scene.lift_mm)
    pts[:, 2] += SHEET_Z_MM + scene.wire_diameter_mm / 2.0
    return pts


def _arc_shapes(scene: PartScene) -> dict[str, dict]:
    rw = scene.wire_diameter_mm / 2.0
    pts = [[float(v) for v in p] for p in part_axis_mm(scene)]
    steel = _metal("Fe", scene.steel_alpha)
    shapes: dict[str, dict] = {}
    for i in range(len(pts) - 1):
        shapes[f"arc{i}"] = {
            "type": "cylinder",
            "p0": pts[i],
            "p1": pts[i + 1],
            "radius": rw,
            "bsdf": steel,
        }
    for i, p in enumerate(pts):
        shapes[f"arcj{i}"] = {"type": "sphere", "center": p, "radius": rw, "bsdf": steel}
    return shapes


def _sheet_bsdf(scene: PartScene, texture_png: Path | None) -> dict:
    if scene.sheet_texture:
        if texture_png is None:
            raise ValueError(f"sheet texture {scene.sheet_texture!r} needs its PNG")
        tex = {"type": "bitmap", "filename": str(texture_png), "filter_type": "bilinear"}
        return {"type": "diffuse", "reflectance": tex}
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(scene.sheet_rgb)}}


def render_part(
    scene: PartScene, board_png: Path, cache_dir: Path, texture_png: Path | None = None
) -> tuple[Path, dict]:
    """Render a finished part beside the board (cached); return the JPEG path and its truth.

    ``texture_png`` is the matte sheet's printed texture when ``scene.sheet_texture`` names one.
    """
    mi = _mi()
    extra = [Path(board_png)] + ([Path(texture_png)] if scene.sheet_texture else [])
    key = _key("part", asdict(scene), extra)
    cache_dir = Path(cache_dir)
    cache_dir.mkdir(parents=True, exist_ok=True)
    jpg = cache_dir / f"part_{key}.jpg"
    truth = part_truth(scene)
    if not jpg.exists():
        tf = mi.ScalarTransform4f
        d = _base_scene(mi, scene.rig, scene.spp, scene.lamp_mm)
        d["sheet"] = _sheet_shape(mi, Path(board_png), (0.0, 0.0, 0.0), (-110.0, 0.0, 0.0))
        d["matte"] = {
            "type": "rectangle",
            "to_world": tf()
            .translate([MATTE_CENTRE_X_MM, 0.0, SHEET_Z_MM])
            .scale([100.0, 95.0, 1.0]),
            "bsdf": _sheet_bsdf(scene, texture_png),
        }
        d.update(_arc_shapes(scene))
        _write_jpeg(mi, mi.render(mi.load_dict(d)), jpg)
        jpg.with_suffix(".json").write_text(json.dumps(truth, indent=1))
    return jpg, truth
