"""A part photo measured on blocks of pixels: the working image and the way back.

A wire many pixels wide (2-3 mm at 0.11 mm/px: 18-28 px) shows what a coarser photo
averages away: the lamp's reflections inside the polished tube, the grain of its
shadow, each pixel's noise. Averaging ``factor`` x ``factor`` blocks (OpenCV's
``INTER_AREA``, exact on whole blocks) brings it back to 9-14 px, where the edges are
looked for over the wire's own scale, and cuts the noise by ``factor``.

What it costs, on the project's own photo lab (round wires 19 px wide at 0.157 mm/px,
measured over 2 x 2 blocks): the rules that tell a cap's outline from a dark fleck just
beyond it, or read the lift from the cast shadow's edge, were written at the photo's own
pixels and lose it (ends 7-10 px out beside a fleck; the shadow's lift refused, only
bounded), and the stated sigmas whose terms are counted in pixels (an end's outline, the
centreline's offset) double. So it is asked for (``cvmeasure part --downsample``), not
the default.

Pixel frames: the pixel-centre convention. A working pixel ``x`` covers photo pixels
``k x .. k x + k - 1``, so its centre lies at ``k x + (k - 1) / 2`` in the photo
(:func:`photo_px`). The board plane is found on the photo itself and rescaled
(:meth:`cvmeasure.plane_model.PlaneModel.scaled`), its lens uncertainty carried in mm.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from cvmeasure.contracts import PlaneModel
from cvmeasure.part.result import PartMeasurement, PlaneSummary

__all__ = ["WORKING_WIRE_PX", "auto_downsample", "downsample_photo", "photo_px", "in_photo_px"]

#: The wire's width (px) the working image is brought nearest to (by whole blocks): the
#: width the part measurement is developed and tested at (7-11 px at 0.28 mm/px). On the
#: 28 full-size Mitsuba photos (0.11 mm/px) the 2 and 3 mm wires measured best over 2 x 2
#: blocks (9 and 14 px: 18 on target, their stated sigmas holding) and worse over 3 x 3
#: (6 and 9 px: 14) or on the photo's own pixels (18 and 28 px: 13); the same scenes
#: rendered again on another machine: 16 over 2 x 2 blocks against 15, the stated sigmas
#: holding on all over the blocks only.
WORKING_WIRE_PX = 12.0


def auto_downsample(mm_per_px: float, wire_diameter_mm: float | None) -> int:
    """The block size that brings the wire nearest :data:`WORKING_WIRE_PX` wide (>= 1).

    1 without the wire's diameter: the profiles' centre of symmetry is then measured,
    which was not tested on pixel blocks.

    >>> auto_downsample(0.11, 2.0), auto_downsample(0.11, 3.0), auto_downsample(0.28, 3.0)
    (2, 2, 1)
    """
    if wire_diameter_mm is None:
        return 1
    return max(1, round(wire_diameter_mm / mm_per_px / WORKING_WIRE_PX))


def downsample_photo(
    image: np.ndarray, plane: PlaneModel, factor: int
) -> tuple[np.ndarray, PlaneModel]:
    """The photo averaged over ``factor`` x ``factor`` blocks, and its plane.

    The last rows and columns short of a whole block are left out (at most
    ``factor - 1`` px at the far edges), so every working pixel is one block's mean.
    """
    h, w = image.shape[:2]
    hk, wk = h // factor, w // factor
    small = cv2.resize(image[: hk * factor, : wk * factor], (wk, hk), interpolation=cv2.INTER_AREA)
    # the lens' uncertainty goes with the camera, in working pixels: its figure in mm on
    # the plate stays the photo's (:meth:`cvmeasure.camera_model.CameraModel.scaled`)
    return small, plane.scaled(1.0 / factor)


def photo_px(points_px: np.ndarray, factor: int) -> np.ndarray:
    """Working-image pixels (..., 2) -> the photo's pixels (pixel-centre convention)."""
    return (np.asarray(points_px, dtype=np.float64) + 0.5) * factor - 0.5


def in_photo_px(m: PartMeasurement, factor: int, plane: PlaneModel) -> PartMeasurement:
    """A measurement made on the working image, its pixel figures in the photo's.

    ``plane`` is the photo's own (its scale and corner RMS are reported); millimetres,
    degrees and the warnings' wording are left as measured.
    """
    w = m.wire
    wire = replace(
        w,
        width_px=w.width_px * factor,
        length_px=w.length_px * factor,
        area_px=int(w.area_px * factor * factor),
        edge_width_px=None if w.edge_width_px is None else w.edge_width_px * factor,
        half_width_px=w.half_width_px * factor,
        rho_px=w.rho_px * factor,
        ends_px=photo_px(np.asarray(w.ends_px), factor).tolist(),
        end_uncertainty_px=[float(u) * factor for u in w.end_uncertainty_px],
    )
    return replace(
        m,
        centreline_px=photo_px(m.centreline_px, factor),
        vertices_px=None if m.vertices_px is None else photo_px(m.vertices_px, factor),
        plane=PlaneSummary.of(plane),
        wire=wire,
        downsample=factor,
    )
