"""Lens calibration, honest uncertainty, image coverage and the affine plane check.

Stages (each a module of pure functions returning frozen result dataclasses):

* :mod:`~cvmeasure.calibration.detect` -- ChArUco / chessboard corners;
* :mod:`~cvmeasure.calibration.solve` -- ``calibrateCameraExtended`` with a
  distortion-model choice and iterative rejection of bad corners and views;
* :mod:`~cvmeasure.calibration.uncertainty` -- projection uncertainty across
  the image (mrcal-style) and the cross-validation difference of two halves;
* :mod:`~cvmeasure.calibration.coverage` -- image coverage, tilt variety, and
  what photos to add;
* :mod:`~cvmeasure.calibration.plane` -- plane tilt, scale, the affine verdict
  and the rectifying homography to board millimetres;
* :mod:`~cvmeasure.calibration.pipeline` -- all of the above for a set of photos,
  and the camera JSON record.
"""

from cvmeasure.calibration.coverage import Coverage, image_coverage
from cvmeasure.calibration.detect import BoardDetection, detect_board
from cvmeasure.calibration.pipeline import CalibrationReport, calibrate_detections, detect_photos
from cvmeasure.calibration.plane import PlaneModel, estimate_plane, fit_plane, rectify_image
from cvmeasure.calibration.solve import CalibrationResult, calibrate_views
from cvmeasure.calibration.uncertainty import (
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
