"""3D objects above the scene plane, ray traced per pixel inside their boxes.

The rasteriser gives every layer the rays of its pixels (:class:`~cvmeasure_datasets.raster.Rays`);
these helpers intersect them with objects that are not flat on the plane:

* :func:`tube_hits`: a round wire of radius ``r`` around a 3D polyline (exact
  ray-to-segment distances; the coverage comes from their signed distance, the
  shading from the exact surface normal where the ray first meets the cylinder);
* :func:`post_sdf`: a vertical cylinder (a marker's printed support) standing
  from one height to another; its silhouette is where the ray's trace between
  the two heights passes within the radius of the axis;
* :func:`shade_metal`: diffuse + Phong specular shading of a shiny steel wire
  under a directional lamp, and :func:`lamp_direction`, :func:`shadow_on_plane`.

And the flat wire both scenes draw when ``wire_3d`` is off: :func:`flat_wire_layer`
(a shaded capsule strip on the plane) and :func:`wire_shadow_layer` (its cast shadow).

All lengths are mm in the scene frame; ``up`` is +1 for the machine frame (z
towards the camera) and -1 for the board frame (z away from it).
"""

from __future__ import annotations

import numpy as np

from cvmeasure_datasets.raster import Layer, Window, polyline_bbox, sdf_alpha, sdf_capsules

__all__ = [
    "LAMP_ELEVATION_DEG",
    "dense_polyline",
    "flat_wire_layer",
    "tube_layer",
    "lamp_direction",
    "post_sdf",
    "shade_metal",
    "shadow_on_plane",
    "tube_hits",
    "wire_shadow_layer",
    "wire_cast_shadow_layer",
]

#: Elevation of the workshop lamp above the plate (the flat renders' shadows use
#: the same: 0.85 mm of shadow offset per mm of height).
LAMP_ELEVATION_DEG = 49.6


def _box_within(
    u: np.ndarray, v: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> tuple[int, int, int, int] | None:
    """Rows ``r0:r1`` and columns ``c0:c1`` of the grid ``(u, v)`` (mm) bounding the points
    inside the box ``lo``..``hi`` (mm), or None when no point is inside."""
    inside = (u >= lo[0]) & (u <= hi[0]) & (v >= lo[1]) & (v <= hi[1])
    rows = np.nonzero(inside.any(axis=1))[0]
    if len(rows) == 0:
        return None
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    cols = np.nonzero(inside[r0:r1].any(axis=0))[0]
    return r0, r1, int(cols[0]), int(cols[-1]) + 1


def lamp_direction(azimuth_deg: float, up: float = 1.0) -> np.ndarray:
    """Unit vector towards the lamp (3,) in the frame, from its azimuth in the plane."""
    az, el = np.radians(azimuth_deg), np.radians(LAMP_ELEVATION_DEG)
    return np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), up * np.sin(el)])


def shadow_on_plane(points_mm: np.ndarray, lamp: np.ndarray) -> np.ndarray:
    """Where 3D points (N, 3) cast their shadow on the plane z = 0, (N, 2) mm."""
    p = np.asarray(points_mm, dtype=np.float64)
    s = p[:, 2] / lamp[2]
    return p[:, :2] - s[:, None] * lamp[:2]


def tube_hits(win: Window, polyline_mm: np.ndarray, radius_mm: float) -> dict[str, np.ndarray]:
    """Rays of ``win`` against a round wire around ``polyline_mm`` (N, 3).

    Returns ``sdf`` (mm, the ray's distance from the axis minus the radius: negative
    on the wire), ``normal`` (3, H, W) the unit surface normal where the ray first
    meets the wire (valid where ``sdf < 0``) and ``view`` (3, H, W) the unit vector
    from the surface towards the camera. Cached on the window.
    """
    key = f"tube:{id(polyline_mm)}:{radius_mm}"
    if key in win.cache:
        return win.cache[key]  # type: ignore[return-value]
    rays = win.rays
    if rays is None:
        raise ValueError("tube_hits needs a window with rays (rasterise provides them)")
    pts = np.asarray(polyline_mm, dtype=np.float64)
    o = rays.centre
    d = (rays.dx, rays.dy, rays.dz)
    shape = rays.dx.shape
    # candidate pixels per segment: trace to the window's plane, pad by the parallax
    slope = float(np.max(np.hypot(rays.dx, rays.dy) / np.abs(rays.dz)))
    steps = [np.abs(np.diff(a, axis=ax)).max() for a in (win.u, win.v) for ax in (0, 1)]
    px_mm = max(steps) if min(shape) > 1 else 1.0
    dzmax = float(np.max(np.abs(pts[:, 2] - win.z_mm)))
    cap = radius_mm * (1.0 + slope) + dzmax * slope + 4.0 * px_mm + 1e-6
    best = np.full(shape, cap + radius_mm)
    diff_best = np.zeros((3, *shape))
    axis_best = np.zeros((3, *shape))
    u, v = win.u, win.v
    for a, b in zip(pts[:-1], pts[1:], strict=True):
        lo = np.minimum(a[:2], b[:2]) - cap
        hi = np.maximum(a[:2], b[:2]) + cap
        box = _box_within(u, v, lo, hi)
        if box is None:
            continue
        r0, r1, c0, c1 = box
        dd = [c[r0:r1, c0:c1] for c in d]
        e = b - a
        w = [o[i] - a[i] for i in range(3)]
        aa = dd[0] ** 2 + dd[1] ** 2 + dd[2] ** 2
        bb = dd[0] * e[0] + dd[1] * e[1] + dd[2] * e[2]
        cc = float(e @ e)
        dw = dd[0] * w[0] + dd[1] * w[1] + dd[2] * w[2]
        ew = float(e[0] * w[0] + e[1] * w[1] + e[2] * w[2])
        denom = aa * cc - bb * bb
        t = np.where(denom > 1e-12 * aa * cc, (aa * ew - bb * dw) / np.maximum(denom, 1e-300), 0.0)
        t = np.clip(t, 0.0, 1.0)
        s = (bb * t - dw) / aa
        diff = [w[i] + s * dd[i] - t * e[i] for i in range(3)]
        dist = np.sqrt(diff[0] ** 2 + diff[1] ** 2 + diff[2] ** 2)
        sub = best[r0:r1, c0:c1]
        better = dist < sub
        sub[better] = dist[better]
        en = e / np.sqrt(cc)
        for i in range(3):
            diff_best[i, r0:r1, c0:c1][better] = diff[i][better]
            axis_best[i, r0:r1, c0:c1][better] = en[i]
    norm_d = np.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
    view = np.stack([-c / norm_d for c in d])
    # the view direction's part across the axis, and the unit offset of the ray
    along = np.sum(view * axis_best, axis=0)
    across = view - along * axis_best
    across /= np.maximum(np.sqrt(np.sum(across**2, axis=0)), 1e-12)
    off = diff_best / np.maximum(best, 1e-12)
    q = np.clip(best / radius_mm, 0.0, 1.0)
    normal = q * off + np.sqrt(1.0 - q * q) * across
    normal /= np.maximum(np.sqrt(np.sum(normal**2, axis=0)), 1e-12)
    out = {"sdf": best - radius_mm, "normal": normal, "view": view}
    win.cache[key] = out
    return out


def shade_metal(
    normal: np.ndarray,
    view: np.ndarray,
    lamp: np.ndarray,
    base: np.ndarray,
    *,
    ambient: float = 0.3,
    specular: float = 1.2,
    shininess: float = 40.0,
) -> np.ndarray:
    """Linear RGB (H, W, 3) of a shiny metal surface: ambient + diffuse + Phong specular."""
    n_l = np.tensordot(lamp, normal, axes=(0, 0))
    refl = 2.0 * n_l * normal - lamp[:, None, None]
    r_v = np.clip(np.sum(refl * view, axis=0), 0.0, 1.0)
    shade = ambient + (1.0 - ambient) * np.clip(n_l, 0.0, 1.0)
    spec = specular * r_v**shininess
    return shade[..., None] * np.asarray(base)[None, None, :] + spec[..., None]


def post_sdf(
    win: Window, centre_mm: tuple[float, float], radius_mm: float, z0_mm: float, z1_mm: float
) -> np.ndarray:
    """Signed distance (mm) of each ray from a vertical cylinder between heights z0 and z1.

    The ray's trace in the plane between the two heights is a segment; the ray meets
    the solid cylinder (with its caps) where that segment comes within ``radius_mm``
    of the axis.
    """
    rays = win.rays
    if rays is None:
        raise ValueError("post_sdf needs a window with rays")
    ua, va = rays.at_z(z0_mm)
    ub, vb = rays.at_z(z1_mm)
    du, dv = ub - ua, vb - va
    pu, pv = centre_mm[0] - ua, centre_mm[1] - va
    length2 = du * du + dv * dv
    h = np.clip((pu * du + pv * dv) / np.maximum(length2, 1e-18), 0.0, 1.0)
    return np.hypot(pu - h * du, pv - h * dv) - radius_mm


def dense_polyline(polyline: np.ndarray, step_mm: float) -> np.ndarray:
    """Points along a polyline (N, 2) at most ``step_mm`` apart."""
    out = [polyline[0]]
    for a, b in zip(polyline[:-1], polyline[1:], strict=True):
        n = max(1, int(np.ceil(np.linalg.norm(b - a) / step_mm)))
        out.extend(a + (b - a) * k / n for k in range(1, n + 1))
    return np.array(out)


def tube_layer(axis_mm: np.ndarray, radius_mm: float, base: np.ndarray, lamp: np.ndarray) -> Layer:
    """A shiny round wire around the 3D polyline ``axis_mm`` (N, 3), ray traced."""
    z_mid = float(np.mean(axis_mm[:, 2]))

    def alpha(w: Window) -> np.ndarray:
        return sdf_alpha(tube_hits(w, axis_mm, radius_mm)["sdf"])

    def colour(w: Window) -> np.ndarray:
        hit = tube_hits(w, axis_mm, radius_mm)
        return shade_metal(hit["normal"], hit["view"], lamp, base)

    return Layer(
        polyline_bbox(axis_mm[:, :2], radius_mm * 2 + 2.0),
        alpha,
        colour,
        z_mm=z_mid,
        z_extent_mm=(
            float(axis_mm[:, 2].min() - radius_mm),
            float(axis_mm[:, 2].max() + radius_mm),
        ),
    )


def flat_wire_layer(
    polyline_mm: np.ndarray,
    radius_mm: float,
    base: np.ndarray,
    *,
    shade: tuple[float, float],
    highlight: tuple[float, float],
) -> Layer:
    """A wire flat on the plane: capsules of ``radius_mm`` around ``polyline_mm`` (N, 2), mm.

    Shaded as a cylinder seen from above: ``shade`` = (ambient, diffuse) gives
    ``ambient + diffuse * n_z`` times ``base`` (linear RGB), plus a specular line
    along the crest, ``highlight`` = (strength, width as a fraction of the radius).
    """
    ambient, diffuse = shade
    strength, width = highlight

    def colour(win: Window) -> np.ndarray:
        t = np.clip(
            (sdf_capsules(win.u, win.v, polyline_mm, radius_mm) + radius_mm) / radius_mm, 0, 1
        )
        nz = np.sqrt(1.0 - t * t)
        spec = strength * np.exp(-((t / width) ** 2))
        return (ambient + diffuse * nz)[..., None] * base + spec[..., None]

    return Layer(
        polyline_bbox(polyline_mm, radius_mm + 1.0),
        lambda w: sdf_alpha(sdf_capsules(w.u, w.v, polyline_mm, radius_mm)),
        colour,
    )


def wire_shadow_layer(
    polyline_mm: np.ndarray,
    radius_mm: float,
    strength: float,
    *,
    soft_mm: float,
    band_mm: float | None = None,
) -> Layer:
    """A wire's shadow on the plane: capsules of ``radius_mm`` around ``polyline_mm`` (N, 2).

    ``soft_mm``: width of its soft edge; ``band_mm``: see :func:`sdf_capsules`;
    ``strength``: darkness in [0, 1].
    """
    return Layer(
        polyline_bbox(polyline_mm, radius_mm + 3.0),
        lambda w: sdf_alpha(sdf_capsules(w.u, w.v, polyline_mm, radius_mm, band_mm), soft_mm),
        kind="shadow",
        strength=strength,
    )


def cast_shadow_sdf(
    u: np.ndarray,
    v: np.ndarray,
    axis_mm: np.ndarray,
    radius_mm: float,
    lamp: np.ndarray,
    cap_mm: float,
) -> np.ndarray:
    """Signed distance (mm, in the plane z = 0) to the shadow of a round wire.

    A point of the plane is in the shadow when its ray towards the (distant) lamp passes
    within ``radius_mm`` of the axis polyline ``axis_mm`` (N, 3): the exact shadow of a
    cylinder, a band ``r sqrt(1 + (n . s)^2)`` wide about the axis' shadow (``s`` the shadow
    vector per mm of height, ``n`` the band's normal), wider than the wire when the wire
    runs across the light. Per segment the ray's distance from the axis minus the radius is
    turned into a distance in the plane (divided by the rate at which it changes across
    the band), so the edge (0) is exact and its ramp is in mm of plane; capped at ``cap_mm``.
    """
    pts = np.asarray(axis_mm, dtype=np.float64)
    lamp = np.asarray(lamp, dtype=np.float64)
    best = np.full(np.shape(u), cap_mm)
    ground = shadow_on_plane(pts, lamp)
    ll = float(lamp @ lamp)
    for i in range(len(pts) - 1):
        a, b = pts[i], pts[i + 1]
        e = b - a
        m = np.cross(e, lamp)
        rate = float(np.hypot(m[0], m[1]) / max(np.linalg.norm(m), 1e-12))  # |d dist / d plane|
        pad = radius_mm / max(rate, 1e-3) + cap_mm
        lo = np.minimum(ground[i], ground[i + 1]) - pad
        hi = np.maximum(ground[i], ground[i + 1]) + pad
        box = _box_within(u, v, lo, hi)
        if box is None:
            continue
        r0, r1, c0, c1 = box
        w = [u[r0:r1, c0:c1] - a[0], v[r0:r1, c0:c1] - a[1], np.full((r1 - r0, c1 - c0), -a[2])]
        bb = float(lamp @ e)
        cc = float(e @ e)
        dw = lamp[0] * w[0] + lamp[1] * w[1] + lamp[2] * w[2]
        ew = e[0] * w[0] + e[1] * w[1] + e[2] * w[2]
        denom = ll * cc - bb * bb
        t = np.clip((ll * ew - bb * dw) / denom if denom > 1e-12 else 0.0 * ew, 0.0, 1.0)
        s_ray = np.maximum((bb * t - dw) / ll, 0.0)  # towards the lamp only
        t = np.clip((s_ray * bb + ew) / cc, 0.0, 1.0)
        diff = [w[k] + s_ray * lamp[k] - t * e[k] for k in range(3)]
        dist = np.sqrt(diff[0] ** 2 + diff[1] ** 2 + diff[2] ** 2)
        sub = best[r0:r1, c0:c1]
        np.minimum(sub, np.minimum((dist - radius_mm) / max(rate, 1e-3), cap_mm), out=sub)
    return best


def wire_cast_shadow_layer(
    axis_mm: np.ndarray,
    radius_mm: float,
    lamp: np.ndarray,
    strength: float,
    *,
    soft_mm: float,
    band_mm: float = 3.0,
) -> Layer:
    """A round wire's shadow under a distant lamp (:func:`cast_shadow_sdf`).

    ``axis_mm`` (N, 3) the wire's axis (z = -height), ``lamp`` the unit vector towards the
    lamp (:func:`lamp_direction`), ``soft_mm`` the width of its soft edge, ``band_mm`` how
    far beyond the edge the distance is exact, ``strength`` its darkness in [0, 1].
    """
    ground = shadow_on_plane(axis_mm, lamp)
    reach = radius_mm * float(np.hypot(1.0, np.hypot(*lamp[:2]) / abs(lamp[2])))
    return Layer(
        polyline_bbox(ground, reach + band_mm + 3.0),
        lambda w: sdf_alpha(
            cast_shadow_sdf(w.u, w.v, axis_mm, radius_mm, lamp, radius_mm + band_mm), soft_mm
        ),
        kind="shadow",
        strength=strength,
    )
