"""Image coverage and pose variety of a calibration, and what photos to add.

A lens model is only known where corners were seen: the corners of the image
are where distortion is largest and where poorly covered calibrations go wrong.
Focal length is only separable from distance when boards are tilted (mrcal's
guidance: tilts up to about 45 degrees, about both axes).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np

from cvmeasure.lens.detect import BoardDetection
from cvmeasure.warning import StageWarning

__all__ = ["Coverage", "image_coverage", "EDGE_BAND", "MIN_GOOD_TILT_DEG", "RECOMMENDED_VIEWS"]

#: Width of the band along each image edge that should hold corners, as a fraction of the side.
EDGE_BAND = 0.1
#: Largest tilt (deg) below which the tilt variety is reported as too small.
MIN_GOOD_TILT_DEG = 20.0
#: Views recommended for a trustworthy solve.
RECOMMENDED_VIEWS = 12

_EDGES = ("left", "right", "top", "bottom")


@dataclass(frozen=True)
class Coverage:
    """Where the corners fell and how varied the poses were.

    Attributes
    ----------
    cells : (nx, ny)
        The grid the image was divided into.
    counts : ndarray (ny, nx), int
        Corners seen in each cell, over all views.
    covered_fraction : float
        Share of cells with at least one corner.
    edge_gap_frac : dict of str -> float
        Distance from each image edge to the nearest corner, as a fraction of
        the image width (left/right) or height (top/bottom).
    tilt_deg : tuple of float
        Tilt of each view (board normal vs optical axis).
    tilt_x_deg, tilt_y_deg : tuple of float
        Each view's tilt split into rotation about the image x and y axes.
    warnings : tuple of str
        What is weak and which photos would fix it.
    """

    cells: tuple[int, int]
    counts: np.ndarray
    covered_fraction: float
    edge_gap_frac: dict[str, float]
    tilt_deg: tuple[float, ...]
    tilt_x_deg: tuple[float, ...]
    tilt_y_deg: tuple[float, ...]
    view_count: int
    warnings: tuple[StageWarning, ...]

    def to_dict(self) -> dict[str, Any]:
        return {
            "cells": list(self.cells),
            "corner_counts": self.counts.tolist(),
            "covered_fraction": self.covered_fraction,
            "edge_gap_frac": dict(self.edge_gap_frac),
            "tilt_deg": {
                "min": min(self.tilt_deg, default=0.0),
                "median": float(np.median(self.tilt_deg)) if self.tilt_deg else 0.0,
                "max": max(self.tilt_deg, default=0.0),
                "max_about_x": max((abs(t) for t in self.tilt_x_deg), default=0.0),
                "max_about_y": max((abs(t) for t in self.tilt_y_deg), default=0.0),
            },
            "view_count": self.view_count,
            "warnings": [w.to_json() for w in self.warnings],
        }


def _tilt_components(rvec: np.ndarray) -> tuple[float, float, float]:
    rot, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64).reshape(3, 1))
    n = rot[:, 2] * np.sign(rot[2, 2] or 1.0)
    tilt = float(np.degrees(np.arccos(np.clip(n[2], -1.0, 1.0))))
    about_x = float(np.degrees(np.arctan2(-n[1], n[2])))  # rotation about the image x axis
    about_y = float(np.degrees(np.arctan2(n[0], n[2])))  # rotation about the image y axis
    return tilt, about_x, about_y


def image_coverage(
    detections: Sequence[BoardDetection],
    image_size_px: tuple[int, int],
    rvecs: Sequence[np.ndarray] = (),
    *,
    cells: tuple[int, int] = (6, 4),
) -> Coverage:
    """Measure image coverage and pose variety; word warnings with the photos to add.

    Parameters
    ----------
    detections : the corner sets used by the solve.
    image_size_px : (width, height)
    rvecs : the views' board rotations (camera <- board), for tilt variety.
    cells : (nx, ny) grid for the occupancy count.
    """
    w, h = image_size_px
    nx, ny = cells
    pts = np.concatenate([d.corners_px for d in detections]) if detections else np.zeros((0, 2))
    counts = np.zeros((ny, nx), dtype=int)
    if len(pts):
        ix = np.clip((pts[:, 0] + 0.5) / w * nx, 0, nx - 1).astype(int)
        iy = np.clip((pts[:, 1] + 0.5) / h * ny, 0, ny - 1).astype(int)
        np.add.at(counts, (iy, ix), 1)
    covered = float(np.mean(counts > 0))
    if len(pts):
        gaps = {
            "left": float(pts[:, 0].min() / w),
            "right": float((w - 1 - pts[:, 0].max()) / w),
            "top": float(pts[:, 1].min() / h),
            "bottom": float((h - 1 - pts[:, 1].max()) / h),
        }
    else:
        gaps = dict.fromkeys(_EDGES, 1.0)
    comps = [_tilt_components(r) for r in rvecs]
    tilts = tuple(c[0] for c in comps)
    tx = tuple(c[1] for c in comps)
    ty = tuple(c[2] for c in comps)
    warnings: list[StageWarning] = []
    for edge in _EDGES:
        if gaps[edge] > EDGE_BAND:
            warnings.append(
                StageWarning(
                    "calib_edge_uncovered",
                    f"no corners within {EDGE_BAND:.0%} of the {edge} edge (nearest at "
                    f"{gaps[edge]:.0%}): add photos with the board reaching the {edge} edge",
                    f"{edge} edge",
                )
            )
    if covered < 0.75:
        empty = np.argwhere(counts == 0)
        names = sorted({_region_name(c, r, nx, ny) for r, c in empty})
        warnings.append(
            StageWarning(
                "calib_coverage_low",
                f"corners cover only {covered:.0%} of the image ({int((counts > 0).sum())} of "
                f"{nx * ny} cells): add photos filling the {', '.join(names)}",
            )
        )
    if comps:
        if max(tilts) < MIN_GOOD_TILT_DEG:
            warnings.append(
                StageWarning(
                    "calib_tilt_low",
                    f"the board is never tilted more than {max(tilts):.0f} deg: add photos "
                    "tilted 30-45 deg (focal length and distance cannot be told apart otherwise)",
                )
            )
        else:
            if max(abs(t) for t in tx) < MIN_GOOD_TILT_DEG:
                warnings.append(
                    StageWarning(
                        "calib_tilt_axis_missing",
                        "no view is tilted about the horizontal axis: add photos with the top "
                        "or bottom edge of the board turned 30-45 deg away from the camera",
                        "horizontal axis",
                    )
                )
            if max(abs(t) for t in ty) < MIN_GOOD_TILT_DEG:
                warnings.append(
                    StageWarning(
                        "calib_tilt_axis_missing",
                        "no view is tilted about the vertical axis: add photos with the left or "
                        "right edge of the board turned 30-45 deg away from the camera",
                        "vertical axis",
                    )
                )
    if len(detections) < RECOMMENDED_VIEWS:
        warnings.append(
            StageWarning(
                "calib_few_views",
                f"only {len(detections)} views: {RECOMMENDED_VIEWS}-30 are recommended for a "
                "trustworthy solve",
            )
        )
    return Coverage(
        (nx, ny), counts, covered, gaps, tilts, tx, ty, len(detections), tuple(warnings)
    )


def _region_name(col: int, row: int, nx: int, ny: int) -> str:
    horiz = "left" if col < nx / 3 else ("right" if col >= 2 * nx / 3 else "centre")
    vert = "top" if row < ny / 3 else ("bottom" if row >= 2 * ny / 3 else "middle")
    if horiz == "centre" and vert == "middle":
        return "image centre"
    if vert == "middle":
        return f"{horiz} side"
    if horiz == "centre":
        return f"{vert} middle"
    return f"{vert}-{horiz} corner"
