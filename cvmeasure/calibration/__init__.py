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
  and the rectifying homography to board millimetres.
"""

from cvmeasure.calibration.detect import BoardDetection, detect_board
from cvmeasure.calibration.plane import PlaneFit, estimate_plane, fit_plane, rectify_image
from cvmeasure.calibration.solve import CalibrationResult, calibrate_views

__all__ = [
    "BoardDetection",
    "detect_board",
    "CalibrationResult",
    "calibrate_views",
    "PlaneFit",
    "estimate_plane",
    "fit_plane",
    "rectify_image",
]
