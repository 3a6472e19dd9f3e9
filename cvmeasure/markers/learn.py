"""Learning a kit's colours from a reference photo (``cvmeasure markers learn``).

The markers are found with the kit's nominal colours, then each disc's pixels
(inside 70 % of its fitted radius, full resolution) are white-balanced on the
white rings and summarised: the mean becomes the kit's ``srgb`` (the printed
colour as it really came out, under D65), the spread becomes ``lab_sigma`` /
``rgb_sigma`` (inflated for light and print variation across photos). The
result is a kit JSON of the spec, which ``measure --kit`` then uses.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cvmeasure.imageio import to_bgr8
from cvmeasure.kit import ROLES, MarkerKit
from cvmeasure.markers.colour import (
    ColourSpace,
    WhiteEstimate,
    bgr8_to_space,
    kit_colour_model,
)
from cvmeasure.markers.detect import find_markers
from cvmeasure.markers.measure import MarkerNotFoundError, refine_candidate

__all__ = ["LearntKit", "learn_kit", "SIGMA_INFLATION", "SIGMA_FLOOR"]

#: Learnt spreads are multiplied by this (one photo under-represents other photos' light).
SIGMA_INFLATION = 2.0
#: Smallest learnt spread per channel: L*, a*, b* and 8-bit sRGB.
SIGMA_FLOOR = {"lab": (6.0, 4.0, 4.0), "rgb": (8.0, 8.0, 8.0)}


@dataclass(frozen=True)
class LearntKit:
    """The learnt kit and, per role, how far the learnt colour is from the nominal one (Delta E76)."""

    kit: MarkerKit
    delta_e: dict[str, float]
    n_pixels: dict[str, int]
    white_srgb8: tuple[float, float, float]

    def to_dict(self) -> dict[str, Any]:
        return {
            "kit": self.kit.to_dict(),
            "delta_e": {r: round(v, 2) for r, v in self.delta_e.items()},
            "n_pixels": self.n_pixels,
            "white_srgb8": [round(v, 2) for v in self.white_srgb8],
        }


def learn_kit(
    bgr: np.ndarray,
    kit: MarkerKit,
    *,
    space: ColourSpace = "lab",
    source: str = "photo",
    name: str | None = None,
) -> LearntKit:
    """Learn the colours of ``kit``'s markers from one reference photo.

    Parameters
    ----------
    bgr : ndarray (H, W, 3), uint8 or uint16, the reference photo (all five markers visible).
    kit : the nominal kit (sizes and roles are kept; colours are learnt).
    space : colour space used to find the markers with the nominal colours.
    source : what errors name.
    name : the learnt kit's name (default ``<kit name>-learnt``).

    Raises
    ------
    MarkerNotFoundError
        A marker is missing or ambiguous in the reference photo.
    """
    img = np.asarray(bgr)
    bgr8 = to_bgr8(img)
    search = find_markers(bgr8, kit, kit_colour_model(kit, space))
    failures = dict(search.failures)
    fits = {}
    for role in ROLES:
        if role in search.found:
            spec = kit.by_role(role)
            got = refine_candidate(bgr8, search.found[role], spec.ring_mm / spec.diameter_mm)
            if isinstance(got, str):
                failures[role] = got
            else:
                fits[role] = got
    if failures:
        raise MarkerNotFoundError(source, {r: failures[r] for r in ROLES if r in failures}, kit)
    rings = np.array([e.ring_bgr for _, e in fits.values()])
    b, g, r = np.median(rings, axis=0)
    white = WhiteEstimate((float(r), float(g), float(b)), len(rings), 0.0)
    h, w = bgr8.shape[:2]
    markers, delta_e, n_pixels = [], {}, {}
    for spec in kit.markers:
        fit, _ = fits[spec.role]
        cx, cy = fit.centre
        rr = 0.7 * fit.radius
        x0, x1 = max(0, int(cx - rr)), min(w, int(cx + rr) + 2)
        y0, y1 = max(0, int(cy - rr)), min(h, int(cy + rr) + 2)
        yy, xx = np.mgrid[y0:y1, x0:x1]
        inside = np.hypot(xx - cx, yy - cy) <= rr
        pixels = bgr8[y0:y1, x0:x1][inside]
        lab = bgr8_to_space(pixels, "lab", white)
        rgb = bgr8_to_space(pixels, "rgb", white)
        mean_rgb = np.clip(np.round(rgb.mean(axis=0)), 0, 255).astype(int)
        lab_sigma = np.maximum(lab.std(axis=0) * SIGMA_INFLATION, SIGMA_FLOOR["lab"])
        rgb_sigma = np.maximum(rgb.std(axis=0) * SIGMA_INFLATION, SIGMA_FLOOR["rgb"])
        learnt = replace(
            spec,
            srgb=tuple(int(v) for v in mean_rgb),
            lab_sigma=tuple(round(float(v), 2) for v in lab_sigma),
            rgb_sigma=tuple(round(float(v), 2) for v in rgb_sigma),
        )
        markers.append(learnt)
        delta_e[spec.role] = float(np.linalg.norm(learnt.lab_d65 - spec.lab_d65))
        n_pixels[spec.role] = int(inside.sum())
    new_kit = replace(kit, name=name or f"{kit.name}-learnt", markers=tuple(markers))
    return LearntKit(new_kit, delta_e, n_pixels, white.srgb8)
