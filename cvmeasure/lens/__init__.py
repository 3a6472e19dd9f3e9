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
"""

from cvmeasure.lens.coverage import Coverage, image_coverage
from cvmeasure.lens.detect import BoardDetection, detect_board
from cvmeasure.lens.pipeline import CalibrationReport, calibrate_detections, detect_photos
from cvmeasure.lens.plane import PlaneModel, estimate_plane, fit_plane, rectify_image
from cvmeasure.lens.solve import CalibrationResult, calibrate_views
from cvmeasure.lens.uncertainty import (
    CrossValidation,
    ProjectionDiff,
    ProjectionUncertainty,
    cross_validate,
    projection_diff,
    projection_uncertainty,
)

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
