"""A finished part as a round wire, ray-traced as 3D cylinders through a known camera.

part14's stop-gap until the photo lab's 3D scenes (branch rend14) render parts:
only the part on a uniform plate (no board; the plane comes from a separate board
photo, as benchmarks/_calibrated.py does). Independent of the measuring code and of the photo lab's flat stripes: each pixel's
ray (the camera's exact undistortion) is intersected with the wire's cylinders and
joint spheres (radius r, axis at r above the plate plus the part's lift) and with
the plate; the wire is shaded Lambert + Blinn-Phong from a light at ``light_elev_deg``
(so the specular highlight lies off the wire's top line, on the light's side), and
the plate point is shadowed by the wire towards the light with a soft penumbra (an
extended source). 3 x 3 rays per pixel, a Gaussian optical blur, noise, sRGB 8 bit.

Frames: the board frame (x, y on the plate, z away from the camera), mm; a height h
above the plate is z = -h. The part is rigid: its own plane is turned about the line
through its lowest point so that the far end lifts ``lift_mm``.

Kept deliberately separate from :func:`cvmeasure_datasets.parts.render_part_photo`, now that
it has a 3D wire too: an independent generator to judge the measuring code on, so do not
merge the two.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from cvmeasure.camera_model import CameraModel
from cvmeasure.contracts import PlaneModel
from cvmeasure.lens.plane import mm_per_px_at
from cvmeasure_datasets.optics import Pose, _undistort_normalized

#: The plate's albedo per sheet: black card, a mid-tone sheet (a cork or card about as
#: light as the wire's lit top, so its dark limb is darker and its crest lighter than the
#: plate) and a light one.
SHEET_ALBEDO = {"dark": 0.04, "grey": 0.2, "light": 0.55}


@dataclass(frozen=True)
class RoundWirePhoto:
    bgr: np.ndarray
    plane: PlaneModel  # the true plane (the renderer's lens and pose)
    vertices_mm: np.ndarray  # (N + 1, 3) axis vertices, board frame, z = -height
    lift_mm: float


def true_plane(camera: CameraModel, pose: Pose) -> PlaneModel:
    """The plate's exact plane for ``pose`` (board frame), as ``cvmeasure plane`` states one.

    Its ``mm_per_px`` is the scale at the board origin's image, as the measured plane's is
    at the board's centre: the measurement reads the wire's expected width in pixels, the
    resolution and every pixel tolerance from it, so a misstated scale misleads them all.
    """
    rot, t_mm = pose.extrinsics("board")
    h = camera.camera_matrix @ np.column_stack((rot[:, 0], rot[:, 1], t_mm))
    h_board_image = np.linalg.inv(h)
    mm_per_px = mm_per_px_at(h_board_image, h[:2, 2] / h[2, 2])  # at the origin's image
    nan = float("nan")
    return PlaneModel(
        camera, h_board_image, cv2.Rodrigues(rot)[0], t_mm, 0.0, 0.0, mm_per_px, nan, nan, 0.0, 0
    )


def lifted_vertices(
    vertices_mm: np.ndarray, radius_mm: float, lift_mm: float, direction_deg: float
) -> np.ndarray:
    """Plate vertices (N + 1, 2) -> 3D axis vertices (N + 1, 3), rigidly tilted.

    The part's extent along ``direction_deg`` (in the plate) rises from 0 at its
    lowest point to ``lift_mm`` at the far end: a rotation about the line through
    the lowest point, so lengths and angles in the part's own plane are kept.
    """
    v = np.asarray(vertices_mm, dtype=np.float64)
    e = np.array([np.cos(np.radians(direction_deg)), np.sin(np.radians(direction_deg))])
    s = v @ e
    s0, span = s.min(), s.max() - s.min()
    theta = np.arcsin(lift_mm / span) if lift_mm > 0 else 0.0
    along = (s - s0) * np.cos(theta)
    flat = v + np.outer(along - (s - s0), e)
    height = radius_mm + (s - s0) * np.sin(theta)
    return np.column_stack((flat, -height))


def _hit_cylinders(origin, all_rays, verts, r, groups):
    """Nearest ray parameter t (M,) and surface normal (M, 3) over cylinders and spheres.

    ``groups[i]`` holds the indices of the rays that can meet segment i (and its end spheres).
    """
    m = len(all_rays)
    best = np.full(m, np.inf)
    normal = np.zeros((m, 3))
    for i, (a, b) in enumerate(zip(verts[:-1], verts[1:], strict=True)):
        idx = groups[i]
        rays = all_rays[idx]
        ax = b - a
        length = np.linalg.norm(ax)
        ax = ax / length
        oc = origin - a
        d = rays - np.outer(rays @ ax, ax)
        mo = oc - (oc @ ax) * ax
        qa = np.einsum("ij,ij->i", d, d)
        qb = 2 * d @ mo
        qc = mo @ mo - r * r
        disc = qb * qb - 4 * qa * qc
        ok = disc > 0
        t = np.where(ok, (-qb - np.sqrt(np.where(ok, disc, 0))) / (2 * qa), np.inf)
        hit = origin + np.where(ok, t, 0.0)[:, None] * rays
        along = (hit - a) @ ax
        ok &= (along >= 0) & (along <= length) & (t > 0)
        closer = ok & (t < best[idx])
        n = hit - a - along[:, None] * ax
        best[idx[closer]] = t[closer]
        normal[idx[closer]] = n[closer] / r
        for c in (a, b):
            oc = origin - c
            qb = 2 * rays @ oc
            qc = oc @ oc - r * r
            disc = qb * qb - 4 * qc
            ok = disc > 0
            t = np.where(ok, (-qb - np.sqrt(np.where(ok, disc, 0))) / 2, np.inf)
            closer = ok & (t > 0) & (t < best[idx])
            hit = origin + np.where(ok, t, 0.0)[:, None] * rays
            best[idx[closer]] = t[closer]
            normal[idx[closer]] = (hit[closer] - c) / r
    return best, normal


def _segment_distance(all_points, all_dirs, verts, groups):
    """Least distance (M,) between rays points + s dirs (s > 0) and the axis polyline."""
    out = np.full(len(all_points), np.inf)
    for i, (a, b) in enumerate(zip(verts[:-1], verts[1:], strict=True)):
        idx = groups[i]
        points, dirs = all_points[idx], all_dirs[idx]
        u = b - a
        w0 = points - a
        uu = u @ u
        ud = dirs @ u
        dd = np.einsum("ij,ij->i", dirs, dirs)
        wu = w0 @ u
        wd = np.einsum("ij,ij->i", w0, dirs)
        den = uu * dd - ud * ud
        s = np.clip(np.where(den > 1e-12, (ud * wu - uu * wd) / den, 0.0), 0.0, None)
        t = np.clip((wu + s * ud) / uu, 0.0, 1.0)
        s = np.clip(((a + t[:, None] * u - points) * dirs).sum(1) / dd, 0.0, None)
        diff = points + s[:, None] * dirs - (a + t[:, None] * u)
        out[idx] = np.minimum(out[idx], np.linalg.norm(diff, axis=1))
    return out


def render_round_wire(
    vertices_mm: np.ndarray,
    *,
    camera: CameraModel,
    pose: Pose,
    wire_diameter_mm: float = 3.0,
    lift_mm: float = 0.0,
    lift_direction_deg: float = 0.0,
    sheet: str = "dark",
    light_azimuth_deg: float = 30.0,
    light_elev_deg: float = 50.0,
    light_size_deg: float = 6.0,
    blur_px: float = 0.7,
    noise: float = 1.5,
    seed: int = 0,
    specular: float = 1.4,
    shininess: float = 25.0,
    ambient: float = 0.25,
) -> RoundWirePhoto:
    """The part (plate vertices (N + 1, 2), mm) as a lifted, shaded, shadowing cylinder.

    ``specular`` and ``shininess`` are the highlight's strength and Blinn-Phong exponent:
    the defaults a polished wire's narrow bright highlight, a weaker broader lobe rough
    (brushed or drawn) steel's. ``ambient``: the room's light on the plate, relative to the
    lamp's at normal incidence (0.9); a lamp a few degrees above the plate adds little to a
    lit room's, so its shadow is faint.
    """
    r = wire_diameter_mm / 2
    verts = lifted_vertices(vertices_mm, r, lift_mm, lift_direction_deg)
    rot, t_mm = pose.extrinsics("board")
    centre = -rot.T @ t_mm
    w, h = camera.image_size_px
    albedo = SHEET_ALBEDO[sheet]
    az, el = np.radians(light_azimuth_deg), np.radians(light_elev_deg)
    light = np.array([np.cos(az) * np.cos(el), np.sin(az) * np.cos(el), -np.sin(el)])
    direct = 0.9
    plate_lit = albedo * (ambient + direct * np.sin(el))
    img = np.full((h, w), plate_lit)
    # pixels near the wire or its shadow: draw both polylines on the plate, dilate
    near = np.zeros((h, w), np.uint8)
    shade_offset = np.array([-light[0], -light[1]]) / np.sin(el)  # per mm of height
    for pts in (verts[:, :2], verts[:, :2] + np.outer(-verts[:, 2], shade_offset)):
        dense = np.vstack([np.linspace(a, b, 50) for a, b in zip(pts[:-1], pts[1:], strict=True)])
        px = camera.project(np.column_stack((dense, np.zeros(len(dense)))) @ rot.T + t_mm)
        cv2.polylines(near, [np.round(px).astype(np.int32)], False, 1, 1)
    mm_px = camera.fx / pose.distance_mm
    reach = int(np.ceil((r + 1.5) * mm_px + 4 * blur_px + 3))
    near = cv2.dilate(near, np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)).astype(bool)
    ys, xs = np.nonzero(near)
    sub = (np.arange(3) - 1) / 3.0
    ox, oy = np.meshgrid(sub, sub)
    px = np.column_stack(((xs[:, None] + ox.ravel()).ravel(), (ys[:, None] + oy.ravel()).ravel()))
    norm = _undistort_normalized(camera, px)
    rays = np.column_stack((norm, np.ones(len(norm)))) @ rot  # board frame
    rays /= np.linalg.norm(rays, axis=1)[:, None]
    shadow_end = verts[:, :2] + np.outer(-verts[:, 2], shade_offset)
    seg_px = [
        camera.project(np.column_stack((p, np.zeros(len(p)))) @ rot.T + t_mm)
        for p in (verts[:, :2], shadow_end)
    ]

    def groups_of(points_px: np.ndarray) -> list[np.ndarray]:
        out = []
        for i in range(len(verts) - 1):
            ends = np.vstack([s[i : i + 2] for s in seg_px])
            lo, hi = ends.min(axis=0) - 1.5 * reach, ends.max(axis=0) + 1.5 * reach
            inside = np.all((points_px >= lo) & (points_px <= hi), axis=1)
            out.append(np.nonzero(inside)[0])
        return out

    groups = groups_of(px)
    t_wire, n = _hit_cylinders(centre, rays, verts, r, groups)
    on_wire = np.isfinite(t_wire)
    value = np.empty(len(rays))
    # the wire: steel, dim diffuse, a strong narrow highlight
    hit = centre + t_wire[on_wire, None] * rays[on_wire]
    nn = n[on_wire]
    to_light = light  # unit vector towards the light
    view = centre - hit
    view /= np.linalg.norm(view, axis=1)[:, None]
    half = to_light + view
    half /= np.linalg.norm(half, axis=1)[:, None]
    lam = np.clip(nn @ to_light, 0, None)
    spec = np.clip(np.einsum("ij,ij->i", nn, half), 0, None) ** shininess
    up = np.clip(-nn[:, 2], 0, None)  # sky light from above
    value[on_wire] = 0.22 * (0.6 * up + direct * lam) + specular * spec
    # the plate, shadowed by the wire towards an extended light
    t_plate = -centre[2] / rays[~on_wire, 2]
    ground = centre + t_plate[:, None] * rays[~on_wire]
    ground_groups = groups_of(px[~on_wire])
    dist = _segment_distance(
        ground, np.repeat(to_light[None], len(ground), 0), verts, ground_groups
    )
    # penumbra: the occluder's distance along the light ray times the light's size
    along = np.clip(-verts[:, 2].mean() / np.sin(el), 1e-3, None)
    pen = along * np.tan(np.radians(light_size_deg))
    vis = np.clip(0.5 + (dist - r) / pen, 0.0, 1.0)
    vis = vis * vis * (3 - 2 * vis)
    value[~on_wire] = albedo * (ambient + direct * np.sin(el) * vis)
    img[ys, xs] = value.reshape(-1, 9).mean(axis=1)
    if blur_px > 0:
        img = cv2.GaussianBlur(img, (0, 0), blur_px)
    rng = np.random.default_rng(seed)
    lin = np.clip(img, 0, 1)
    srgb = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055) * 255
    srgb = np.clip(srgb + rng.normal(0, noise, srgb.shape), 0, 255).astype(np.uint8)
    bgr = cv2.cvtColor(srgb, cv2.COLOR_GRAY2BGR)
    return RoundWirePhoto(bgr, true_plane(camera, pose), verts, lift_mm)
