"""A part photo measured on blocks of pixels: the working image and the way back.

A wire many pixels wide (2-3 mm at 0.11 mm/px: 18-28 px) shows what a coarser photo
averages away: the lamp's reflections inside the polished tube, the grain of its
shadow, each pixel's noise. Averaging ``factor`` x ``factor`` blocks (OpenCV's
``INTER_AREA``, exact on whole blocks) brings it back to 9-14 px, where the edges are
looked for over the wire's own scale, and cuts the noise by ``factor``.

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

__all__ = ["downsample_photo", "photo_px", "in_photo_px"]


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
    scaled = plane.scaled(1.0 / factor)
    # the lens' uncertainty is read in pixels of the image the camera is for: carried to
    # the working pixels so that its figure in mm on the plate stays the photo's
    lens = plane.camera.lens_record or {}
    unc = (lens.get("projection_uncertainty") or {}).get("median_px")
    cv = (lens.get("cross_validation") or {}).get("central_60pct_rms_px")
    record = {}
    if unc is not None:
        record["projection_uncertainty"] = {"median_px": float(unc) / factor}
    if cv is not None:
        record["cross_validation"] = {"central_60pct_rms_px": float(cv) / factor}
    camera = replace(scaled.camera, lens_record=record)
    return small, replace(scaled, camera=camera)


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
        plane=PlaneSummary(plane.tilt_deg, plane.mm_per_px, plane.rms_px, plane.corner_count),
        wire=wire,
        downsample=factor,
    )
