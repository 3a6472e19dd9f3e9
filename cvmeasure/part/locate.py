"""The wire located on the plate: the board's plane, the wire's mask and its centreline in mm.

:func:`measure_centreline_mm` finds the plane (from the board in the photo, or a plane
measured before), segments the wire with the board left out, measures its sub-pixel
centreline and maps it to board millimetres on the plane of the wire's axis.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import cv2
import numpy as np

from cvmeasure.board import BoardSpec, printed_footer_mm
from cvmeasure.camera_model import CameraModel
from cvmeasure.contracts import PlaneModel
from cvmeasure.errors import InputError
from cvmeasure.lens.plane import estimate_plane
from cvmeasure.part.centreline import SYMMETRIC_WIRE_MAX, Centreline, measure_centreline
from cvmeasure.part.ends import EndShape
from cvmeasure.part.resolution import coarse_line_hint
from cvmeasure.part.segment import WireMask, gray_float, wire_candidates

__all__ = [
    "MAX_WIRE_MM",
    "MIN_WIRE_MM",
    "MIN_COVERAGE",
    "MAX_ASYMMETRY",
    "BOARD_MARGIN_MM",
    "board_exclusion",
    "measure_centreline_mm",
    "axis_height_for",
    "outline_mm",
]


#: Widest wire looked for (mm): 1/4 inch with margin; sets the filters' sizes.
MAX_WIRE_MM = 7.0

#: Shortest wire accepted as a part (mm).
MIN_WIRE_MM = 15.0

#: Least share of a candidate's cross-profiles that must have a symmetric centre.
MIN_COVERAGE = 0.5

#: Largest remaining asymmetry (relative to the profile's variance) of a round
#: wire's cross-profiles: rendered wires give 0.001-0.08 (0.25-1x size, both
#: sheets), thin lines on a cluttered real desk 0.27-0.84.
MAX_ASYMMETRY = SYMMETRIC_WIRE_MAX

#: Margin around the board left out of the wire search (mm).
BOARD_MARGIN_MM = 4.0


def board_exclusion(board: BoardSpec, plane: PlaneModel, shape: tuple[int, int]) -> np.ndarray:
    """True (H, W) on the board and on its printed sheet's footer (ruler and text below
    it, :func:`printed_footer_mm`), each grown by ``BOARD_MARGIN_MM``."""
    w_mm, h_mm = board.size_mm
    mask = _rect_mask(plane, shape, (0.0, 0.0, w_mm, h_mm))
    return mask | _rect_mask(plane, shape, printed_footer_mm(board))


def _rect_mask(
    plane: PlaneModel, shape: tuple[int, int], rect_mm: tuple[float, float, float, float]
) -> np.ndarray:
    """True (H, W) inside a board-frame rectangle (x0, y0, x1, y1) grown by the margin."""
    m = BOARD_MARGIN_MM
    s = np.linspace(0.0, 1.0, 25)
    x0, y0, x1, y1 = rect_mm[0] - m, rect_mm[1] - m, rect_mm[2] + m, rect_mm[3] + m
    outline = np.vstack(
        (
            np.column_stack((x0 + (x1 - x0) * s, np.full_like(s, y0))),
            np.column_stack((np.full_like(s, x1), y0 + (y1 - y0) * s)),
            np.column_stack((x1 - (x1 - x0) * s, np.full_like(s, y1))),
            np.column_stack((np.full_like(s, x0), y1 - (y1 - y0) * s)),
        )
    )
    px = plane.plane_to_image_px(outline)
    mask = np.zeros(shape, dtype=np.uint8)
    cv2.fillPoly(mask, [np.round(px).astype(np.int32)], 1)
    return mask.astype(bool)


def measure_centreline_mm(
    image: np.ndarray,
    board: BoardSpec | None,
    camera: CameraModel | None,
    *,
    axis_height_mm: float | None = None,
    end_shape: EndShape = "round",
    source: str = "photo",
    wire_diameter_mm: float | None = None,
    plane: PlaneModel | None = None,
) -> tuple[Any, WireMask, Centreline, np.ndarray]:
    """Board plane, wire mask, pixel centreline and centreline in board mm of one photo.

    ``axis_height_mm`` is how far the wire's axis lies above the board's
    plane, towards the camera (see :func:`measure_part`). With ``wire_diameter_mm``
    the centreline lies between the wire's silhouette edges. ``plane`` (e.g. from
    ``cvmeasure plane``) replaces the board's plane in the photo; ``board`` is then
    only left out of the wire search (None: nothing is).

    Raises
    ------
    InputError
        No board (named by the calibration stage), or no wire beside it.
    """
    if plane is None:
        if board is None or camera is None:
            raise ValueError("need a plane, or a board and a camera")
        plane = estimate_plane(image, board, camera, source=source)
    height = axis_height_for(axis_height_mm, wire_diameter_mm)
    mm_per_px = plane.mm_per_px
    exclude = None if board is None else board_exclusion(board, plane, image.shape[:2])
    candidates = wire_candidates(
        image,
        exclude=exclude,
        max_wire_width_px=MAX_WIRE_MM / mm_per_px,
        min_length_px=MIN_WIRE_MM / mm_per_px,
    )
    if not candidates:
        raise InputError(source, "no wire found beside the board")
    # the longest thin line whose profiles are a wire's: a longer one can be an edge of the
    # board's sheet, a grainy strip as thin as a wire and not round across. Only for a wire
    # of known diameter, whose profiles are tested between edges its width apart: without
    # it a cluttered desk's shorter lines pass the symmetry test alone
    # Of those, the one that is a wire's along the longest stretch (its length times the
    # share of its profiles with a wire's centre): a texture line on a printed sheet can be
    # longer than the wire and pass along half its length (cork: 453 px, 57 %, beside the
    # wire's 300 px, 100 %). Candidates come longest first, so none shorter than the best
    # stretch can win and the search stops there.
    errors: list[InputError] = []
    best: tuple[float, WireMask, Centreline] | None = None
    for wire in candidates if wire_diameter_mm is not None else candidates[:1]:
        if best is not None and wire.length_px <= best[0]:
            break
        try:
            centre = _wire_centreline(
                image, wire, plane, height, end_shape, wire_diameter_mm, source
            )
        except InputError as exc:
            errors.append(exc)
            continue
        stretch = wire.length_px * min(1.0, centre.coverage)
        if best is None or stretch > best[0]:
            if best is not None:
                errors.append(InputError(source, _outranked(best[1], best[2])))
            best = (stretch, replace(wire, passed_over=tuple(e.problem for e in errors)), centre)
    if best is None:
        raise errors[0]
    _, wire, centre = best
    return plane, wire, centre, plane.image_to_plane_mm(centre.points_px, height_mm=height)


def _outranked(wire: WireMask, centre: Centreline) -> str:
    """Why a longer line that passed was not taken for the wire."""
    return (
        f"a longer thin line, {wire.length_px:.0f} px, looks like a round wire along only "
        f"{100 * centre.coverage:.0f} % of it, a shorter stretch than the wire measured"
    )


def _wire_centreline(
    image: np.ndarray,
    wire: WireMask,
    plane: PlaneModel,
    height: float,
    end_shape: EndShape,
    wire_diameter_mm: float | None,
    source: str,
) -> Centreline:
    """The centreline of one candidate line, or InputError saying why it is no wire."""
    width_px = None
    if wire_diameter_mm is not None:
        # the diameter over the local scale at the axis' height, about the wire's middle
        mid = wire.path_px[len(wire.path_px) // 2]
        probe = plane.image_to_plane_mm(mid + np.array([[0, 0], [1, 0], [0, 1]]), height_mm=height)
        scale = float(
            np.sqrt(abs(np.linalg.det(np.vstack((probe[1] - probe[0], probe[2] - probe[0])))))
        )
        width_px = wire_diameter_mm / scale
    try:
        centre = measure_centreline(
            gray_float(image),
            wire.path_px,
            width_guess_px=wire.width_px,
            end_shape=end_shape,
            wire_width_px=width_px,
        )
    except ValueError as exc:
        raise InputError(source, f"the wire's centreline could not be measured ({exc})") from None
    if centre.coverage < MIN_COVERAGE or not centre.round_profile:
        problem = (
            f"no wire found beside the board (the longest thin line, {wire.length_px:.0f} px, "
            f"has a round wire's symmetric profile along {100 * centre.coverage:.0f} % of it, "
            f"asymmetry {centre.asymmetry:.2f} > {MAX_ASYMMETRY})"
            if not centre.round_profile
            else f"no wire found beside the board (the longest thin line, "
            f"{wire.length_px:.0f} px, looks like a round wire along only "
            f"{100 * centre.coverage:.0f} % of it)"
        )
        if centre.edges_refused is not None:
            # why its silhouette edges did not say wire either
            problem = f"{problem[:-1]}; {centre.edges_refused})"
        hint = coarse_line_hint(centre.half_width_px, plane.mm_per_px, wire.sheet, wire_diameter_mm)
        raise InputError(source, problem + hint)
    return centre


def axis_height_for(axis_height_mm: float | None, wire_diameter_mm: float | None) -> float:
    """The axis' height above the plate: as given; else the radius of a known wire; else 0."""
    if axis_height_mm is not None:
        return float(axis_height_mm)
    return 0.0 if wire_diameter_mm is None else 0.5 * float(wire_diameter_mm)


def outline_mm(image: np.ndarray, wire: WireMask, plane: PlaneModel) -> np.ndarray:
    """The wire's outer contour at full resolution, board mm (the seed's input).

    Pixels near the mask that differ from the background by more than half the
    wire's contrast (a seed-style binary threshold, so a dark shadow joins in
    as it did in the paper); the largest such region's outer contour.
    """
    near = max(3, int(round(0.5 * wire.width_px)) | 1)
    # all of it within the wire's box grown by the dilation and the closing (the same
    # pixels as on the whole photo: nothing outside it can join)
    ys, xs = np.nonzero(wire.mask.any(axis=1))[0], np.nonzero(wire.mask.any(axis=0))[0]
    grow = near // 2 + 2
    h, w = wire.mask.shape
    y0, y1 = max(0, int(ys[0]) - grow), min(h, int(ys[-1]) + grow + 1)
    x0, x1 = max(0, int(xs[0]) - grow), min(w, int(xs[-1]) + grow + 1)
    mask = wire.mask[y0:y1, x0:x1].astype(np.uint8)
    gray = gray_float(image[y0:y1, x0:x1])
    band = cv2.dilate(mask, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (near, near))).astype(bool)
    level = max(wire.threshold, 0.5 * wire.contrast)
    binary = (band & (np.abs(gray - wire.background_level) > level)).astype(np.uint8)
    count, labels, stats, _ = cv2.connectedComponentsWithStats(binary, connectivity=8)
    if count > 1:
        biggest = 1 + int(np.argmax(stats[1:, cv2.CC_STAT_AREA]))
        binary = (labels == biggest).astype(np.uint8)
    else:
        binary = mask
    binary = cv2.morphologyEx(binary, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    contours, _ = cv2.findContours(
        binary, cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE, offset=(x0, y0)
    )
    pts = np.vstack([c.reshape(-1, 2) for c in contours]).astype(np.float64)
    return plane.image_to_plane_mm(pts)
