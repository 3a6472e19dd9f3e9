"""Lens calibration, honest uncertainty, image coverage and the affine plane check.

Stages (each a module of pure functions returning frozen result dataclasses):

* :mod:`~cvmeasure.lens.detect` -- ChArUco / chessboard corners;
* :mod:`~cvmeasure.lens.solve` -- ``calibrateCameraExtended`` with a
  distortion-model choice and iterative rejection of bad corners and views;
* :mod:`~cvmeasure.lens.uncertainty` -- projection uncertainty across
  the image (mrcal-style) and the cross-validation difference of two halves;
* :mod:`~cvmeasure.lens.coverage` -- image coverage, tilt variety, and
  what photos to add;
* :mod:`~cvmeasure.lens.plane` -- plane tilt, scale, the affine verdict
  and the rectifying homography to board millimetres;
* :mod:`~cvmeasure.lens.pipeline` -- all of the above for a set of photos,
  and the camera JSON record.

The names load on first use (PEP 562, ``docs/design/imports.md``): a bender photo's
measurement uses only :mod:`~cvmeasure.lens.plane` and must not pay for the calibration
solver's SciPy.
"""

from __future__ import annotations

from cvmeasure._lazy import lazy_names

#: Each public name and the module that defines it.
_NAMES = {
    "Coverage": "cvmeasure.lens.coverage",
    "image_coverage": "cvmeasure.lens.coverage",
    "BoardDetection": "cvmeasure.lens.detect",
    "detect_board": "cvmeasure.lens.detect",
    "CalibrationReport": "cvmeasure.lens.pipeline",
    "calibrate_detections": "cvmeasure.lens.pipeline",
    "detect_photos": "cvmeasure.lens.pipeline",
    "PlaneModel": "cvmeasure.lens.plane",
    "estimate_plane": "cvmeasure.lens.plane",
    "fit_plane": "cvmeasure.lens.plane",
    "rectify_image": "cvmeasure.lens.plane",
    "CalibrationResult": "cvmeasure.lens.solve",
    "calibrate_views": "cvmeasure.lens.solve",
    "CrossValidation": "cvmeasure.lens.uncertainty",
    "ProjectionDiff": "cvmeasure.lens.uncertainty",
    "ProjectionUncertainty": "cvmeasure.lens.uncertainty",
    "cross_validate": "cvmeasure.lens.uncertainty",
    "projection_diff": "cvmeasure.lens.uncertainty",
    "projection_uncertainty": "cvmeasure.lens.uncertainty",
}

__all__ = [
    "BoardDetection",
    "detect_board",
    "detect_photos",
    "CalibrationResult",
    "calibrate_views",
    "CalibrationReport",
    "calibrate_detections",
    "Coverage",
    "image_coverage",
    "ProjectionUncertainty",
    "projection_uncertainty",
    "ProjectionDiff",
    "projection_diff",
    "CrossValidation",
    "cross_validate",
    "PlaneModel",
    "estimate_plane",
    "fit_plane",
    "rectify_image",
]


__getattr__, __dir__ = lazy_names(__name__, globals(), _NAMES)
