"""Textured backgrounds, stray coloured objects and occluders for real-scene renders.

Everything here is deterministic for a seed and lives in the scene frame (mm).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from cvmeasure.kit import MarkerKit
from cvmeasure_datasets.lighting import srgb8_to_linear
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

__all__ = ["stray_objects", "stray_layers", "textured", "tool_shadow_layer"]


def _texels(seed: int, kind: str, shape: tuple[int, int], cell_mm: float) -> np.ndarray:
    """A brightness map (rows, cols) float32 around 1: wood grain, or stains and scratches."""
    import cv2

    rng = np.random.default_rng([seed, 0x7E])
    rows, cols = shape

    def smooth(step_mm: float) -> np.ndarray:
        small = rng.uniform(
            -1.0, 1.0, (int(rows * cell_mm / step_mm) + 2, int(cols * cell_mm / step_mm) + 2)
        )
        return cv2.resize(small.astype(np.float32), (cols, rows), interpolation=cv2.INTER_CUBIC)

    fine = rng.uniform(-1.0, 1.0, shape).astype(np.float32)
    fine = cv2.GaussianBlur(fine, (0, 0), 1.0) * 2.0
    if kind == "wood":
        v = (np.arange(rows, dtype=np.float32) * cell_mm)[:, None]
        grain = np.sin(0.9 * v + 3.0 * smooth(25.0)) * 0.5 + 0.5
        return (0.8 + 0.25 * grain + 0.05 * fine).astype(np.float32)
    m = (1.0 + 0.10 * smooth(25.0) + 0.03 * fine).astype(np.float32)
    scratches = np.zeros(shape, dtype=np.float32)
    for _ in range(14):  # thin bright scratches, anti-aliased lines
        p0 = (int(rng.integers(0, cols)), int(rng.integers(0, rows)))
        length = rng.uniform(20.0, 120.0) / cell_mm
        a = rng.uniform(0.0, np.pi)
        p1 = (int(p0[0] + length * np.cos(a)), int(p0[1] + length * np.sin(a)))
        cv2.line(scratches, p0, p1, 0.12, 1, cv2.LINE_AA)
    return m + scratches


def textured(
    seed: int,
    base_srgb: Sequence[int],
    kind: str,
    extent_mm: tuple[float, float, float, float] = (-400.0, -400.0, 400.0, 400.0),
    cell_mm: float = 0.25,
) -> Any:
    """A colour function of the plane: ``"wood"`` grain or a ``"plate"`` with stains and scratches.

    The texture is baked once on a grid of ``cell_mm`` over ``extent_mm`` and looked
    up bilinearly (``cv2.remap``).
    """
    import cv2

    base = np.asarray(srgb8_to_linear(base_srgb), dtype=np.float32)
    x0, y0, x1, y1 = extent_mm
    shape = (int((y1 - y0) / cell_mm) + 1, int((x1 - x0) / cell_mm) + 1)
    tex = _texels(seed, kind, shape, cell_mm)

    def colour(win: Window) -> np.ndarray:
        mx = ((win.u - x0) / cell_mm).astype(np.float32)
        my = ((win.v - y0) / cell_mm).astype(np.float32)
        m = cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
        return m[..., None] * base

    return colour


def stray_objects(
    seed: int,
    count: int,
    kit: MarkerKit,
    keep_clear_mm: Sequence[tuple[float, float, float]],
    area_mm: tuple[float, float, float, float],
) -> list[dict[str, Any]]:
    """``count`` stray objects: discs, caps, bars and pens of other sizes and colours.

    Half of them take a colour within about 12 sRGB levels of a kit marker's (named
    in ``near_role``), the rest arbitrary colours. They keep ``keep_clear_mm``
    ((x, y, radius) circles: the markers and the wire) free. Sizes differ from the
    kit's discs: small (3-5 mm) or large (18-40 mm) discs, bars 4-8 mm wide.
    """
    rng = np.random.default_rng([seed, 0xC1])
    x0, y0, x1, y1 = area_mm
    out: list[dict[str, Any]] = []
    tries = 0
    while len(out) < count and tries < 2000:
        tries += 1
        shape = ["disc", "bar"][int(rng.integers(0, 2))]
        if shape == "disc":
            r = float(rng.uniform(1.5, 2.5) if rng.random() < 0.4 else rng.uniform(9.0, 20.0))
            size = (2 * r, 2 * r)
            reach = r
        else:
            size = (float(rng.uniform(30.0, 90.0)), float(rng.uniform(4.0, 8.0)))
            reach = float(np.hypot(*size)) / 2
        c = (float(rng.uniform(x0 + reach, x1 - reach)), float(rng.uniform(y0 + reach, y1 - reach)))
        if any(np.hypot(c[0] - kx, c[1] - ky) < kr + reach + 3.0 for kx, ky, kr in keep_clear_mm):
            continue
        if any(
            np.hypot(c[0] - o["centre_mm"][0], c[1] - o["centre_mm"][1]) < reach + o["reach_mm"]
            for o in out
        ):
            continue
        near = None
        if len(out) % 2 == 0:
            marker = kit.markers[int(rng.integers(0, len(kit.markers)))]
            srgb = np.clip(np.asarray(marker.srgb) + rng.integers(-12, 13, 3), 0, 255)
            near = marker.role
        else:
            srgb = rng.integers(20, 236, 3)
        out.append(
            {
                "shape": shape,
                "centre_mm": c,
                "size_mm": size,
                "angle_deg": float(rng.uniform(0.0, 180.0)),
                "srgb": [int(v) for v in srgb],
                "near_role": near,
                "reach_mm": reach,
            }
        )
    return out


def stray_layers(objects: list[dict[str, Any]]) -> list[Layer]:
    """Flat layers painting :func:`stray_objects` on the plane."""
    layers = []
    for o in objects:
        c, (sx, sy), ang = o["centre_mm"], o["size_mm"], o["angle_deg"]
        col = srgb8_to_linear(o["srgb"])
        if o["shape"] == "disc":
            layers.append(
                Layer(
                    circle_bbox(c, sx / 2 + 0.5),
                    lambda w, c=c, r=sx / 2: sdf_alpha(sdf_circle(w.u, w.v, c, r)),
                    col,
                )
            )
        else:
            reach = o["reach_mm"] + 0.5
            layers.append(
                Layer(
                    (c[0] - reach, c[1] - reach, c[0] + reach, c[1] + reach),
                    lambda w, c=c, h=(sx / 2, sy / 2), a=ang: sdf_alpha(
                        sdf_rect(w.u, w.v, c, h, a)
                    ),
                    col,
                )
            )
    return layers


def tool_shadow_layer(
    centre_mm: Sequence[float],
    angle_deg: float,
    width_mm: float,
    strength: float,
    *,
    length_mm: float = 120.0,
) -> Layer:
    """A tool's soft shadow: a band ``width_mm`` wide and ``length_mm`` long across ``centre_mm``."""
    d = np.array([np.cos(np.radians(angle_deg)), np.sin(np.radians(angle_deg))])
    half = length_mm / 2
    line = np.array([np.asarray(centre_mm) - half * d, np.asarray(centre_mm) + half * d])
    return Layer(
        polyline_bbox(line, width_mm / 2 + 5.0),
        lambda w: sdf_alpha(sdf_capsules(w.u, w.v, line, width_mm / 2, 4.0), 2.5),
        kind="shadow",
        strength=strength,
    )
