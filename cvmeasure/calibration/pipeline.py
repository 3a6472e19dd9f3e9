"""The whole calibration: photos -> corners -> solve -> uncertainty, coverage, cross-check.

:func:`calibrate_detections` is pure (corner sets in, a report out);
:func:`detect_photos` is the only function here that reads files.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.calibration.coverage import Coverage, image_coverage
from cvmeasure.calibration.detect import BoardDetection, detect_board
from cvmeasure.calibration.solve import (
    DISTORTION_MODELS,
    CalibrationResult,
    DistortionModel,
    calibrate_views,
)
from cvmeasure.calibration.uncertainty import (
    CrossValidation,
    ProjectionUncertainty,
    cross_validate,
    projection_uncertainty,
)
from cvmeasure.camera import CameraModel

__all__ = [
    "CalibrationReport",
    "calibrate_detections",
    "detect_photos",
    "CROSS_VALIDATION_RATIO_LIMIT",
]

#: Relative 1-sigma focal-length uncertainty above which a warning is given.
_FOCAL_SIGMA_WARN = 0.005

#: Cross-validation diff above this many times what noise explains is reported as model error.
CROSS_VALIDATION_RATIO_LIMIT = 3.0


@dataclass(frozen=True)
class CalibrationReport:
    """A solved camera with everything needed to judge it."""

    result: CalibrationResult
    uncertainty: ProjectionUncertainty
    coverage: Coverage
    cross_validation: CrossValidation | None
    warnings: tuple[str, ...]

    @property
    def camera(self) -> CameraModel:
        return self.result.camera

    def calibration_record(
        self,
        board: BoardSpec,
        *,
        provenance: dict[str, Any] | None = None,
        detections: Sequence[BoardDetection] = (),
    ) -> dict[str, Any]:
        """The ``calibration`` part of the camera JSON (spec), JSON-ready."""
        res = self.result
        record: dict[str, Any] = {
            "rms_px": res.rms_px,
            "model": res.model,
            "model_description": DISTORTION_MODELS[res.model][0],
            "opencv_flags": res.flags,
            "std_devs": dict(res.std_devs),
            "per_view_errors_px": [v.rms_px for v in res.views],
            "views_used": [v.to_dict() for v in res.views],
            "views_rejected": [r.to_dict() for r in res.rejected],
            "corner_count": res.corner_count,
            "rejection_rounds": res.rounds,
            "cross_validation": (
                self.cross_validation.to_dict() if self.cross_validation else None
            ),
            "projection_uncertainty": self.uncertainty.to_dict(),
            "coverage": self.coverage.to_dict(),
            "warnings": list(self.warnings),
            "board": board.to_dict(),
            "observations": [
                {
                    "source": d.source,
                    "ids": d.ids.tolist(),
                    "corners_px": np.round(d.corners_px, 4).tolist(),
                }
                for d in (detections or res.detections)
                if d.ok
            ],
        }
        if provenance is not None:
            record["provenance"] = provenance
        return record

    def camera_model(
        self, board: BoardSpec, *, provenance: dict[str, Any] | None = None
    ) -> CameraModel:
        """The camera with its calibration record attached (ready for ``save_camera``)."""
        cam = self.result.camera
        return CameraModel(
            cam.image_size_px,
            cam.camera_matrix,
            cam.dist_coeffs,
            self.calibration_record(board, provenance=provenance),
        )

    def summary(self) -> dict[str, Any]:
        """The numbers a user looks at first."""
        cam = self.camera
        cv = self.cross_validation
        return {
            "cross_validation_central_rms_px": cv.diff.central_rms_px if cv else None,
            "cross_validation_ratio": cv.ratio if cv else None,
            "rms_px": self.result.rms_px,
            "fx": cam.fx,
            "fy": cam.fy,
            "cx": cam.principal_point_px[0],
            "cy": cam.principal_point_px[1],
            "dist_coeffs": cam.dist_coeffs.tolist(),
            "std_devs": dict(self.result.std_devs),
            "projection_uncertainty_p95_px": self.uncertainty.p95_px,
            "views_used": len(self.result.views),
            "views_rejected": [r.to_dict() for r in self.result.rejected],
            "corners_used": self.result.corner_count,
            "corners_rejected": self.result.corners_rejected,
            "warnings": list(self.warnings),
        }


#: A distortion coefficient beyond this magnitude means the model is not determined by
#: the views (a rational fit on clean renders reached k3 = -156).
ILL_CONDITIONED_COEFF = 10.0
#: A projection uncertainty beyond this many image sizes means nothing.
ILL_CONDITIONED_UNCERTAINTY = 10.0
#: OpenCV's distortion coefficient order.
DIST_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty")


def calibrate_detections(
    detections: Sequence[BoardDetection],
    image_size_px: tuple[int, int],
    *,
    model: DistortionModel = "5",
    reject_outliers: bool = True,
    cross_check: bool = True,
    source: str = "calibration photos",
) -> CalibrationReport:
    """Solve, then measure projection uncertainty, coverage and the cross-validation diff.

    Raises :class:`~cvmeasure.errors.InputError` (naming ``source``) when too
    few views are usable.
    """
    result = calibrate_views(
        detections, image_size_px, model=model, reject_outliers=reject_outliers, source=source
    )
    unc = projection_uncertainty(result)
    cov = image_coverage(result.detections, result.image_size_px, [v.rvec for v in result.views])
    cv = (
        cross_validate(result.detections, result.image_size_px, model=model)
        if cross_check
        else None
    )
    warnings: list[str] = []
    for det in detections:
        warnings.extend(f"{det.source}: {n}" for n in det.notes)
    if cv is None and cross_check:
        warnings.append("too few views to cross-validate two halves (need 6 or more)")
    elif cv is not None and cv.ratio > CROSS_VALIDATION_RATIO_LIMIT:
        warnings.append(
            f"the two halves of the views disagree by {cv.diff.central_rms_px:.2f} px in the "
            f"image centre, {cv.ratio:.1f}x what corner noise explains: model error (lens model "
            "too simple, board not flat, focus or zoom changed between photos); the reported "
            "standard deviations understate the real uncertainty"
        )
    rel_f = result.std_devs["fx"] / result.camera.fx
    if rel_f > _FOCAL_SIGMA_WARN:
        warnings.append(
            f"the focal length is poorly determined (1 sigma {100 * rel_f:.2f} % of f): add "
            "photos with the board tilted 30-45 deg and closer to the camera"
        )
    warnings.extend(cov.warnings)
    big = {
        name: float(v)
        for name, v in zip(DIST_NAMES, result.camera.dist_coeffs, strict=False)
        if abs(float(v)) > ILL_CONDITIONED_COEFF
    }
    size = float(max(result.image_size_px))
    if big or not unc.max_px <= ILL_CONDITIONED_UNCERTAINTY * size:
        coeffs = ", ".join(f"{k} {v:+.3g}" for k, v in big.items())
        warnings.append(
            f"the {result.model} distortion model is ill-conditioned on these views"
            + (f" (coefficients {coeffs})" if coeffs else "")
            + (
                f"; its projection uncertainty exceeds {ILL_CONDITIONED_UNCERTAINTY:g}x the "
                "image size and means nothing"
                if not unc.max_px <= ILL_CONDITIONED_UNCERTAINTY * size
                else ""
            )
            + ": use a simpler model (--model 5) or add photos with the board in the corners"
        )
    if result.corners_rejected:
        warnings.append(
            f"{result.corners_rejected} outlier corner(s) dropped from the views used "
            "(residual beyond 4 robust sigmas)"
        )
    if result.rejected:
        warnings.append(f"{len(result.rejected)} photo(s) skipped; see views_rejected")
    return CalibrationReport(result, unc, cov, cv, tuple(warnings))


def detect_photos(
    paths: Sequence[str | os.PathLike[str]],
    board: BoardSpec,
    *,
    progress: Callable[[str], None] | None = None,
) -> list[BoardDetection]:
    """Read every photo (JPEG/PNG/TIFF/RAW) and detect the board; unreadable files raise InputError."""
    from cvmeasure.imageio import read_photo

    out = []
    for path in paths:
        photo = read_photo(path)
        det = detect_board(photo.gray8(), board, source=str(path))
        if progress:
            progress(
                f"{path}: {det.corner_count} corners" + (f" ({det.reason})" if det.reason else "")
            )
        out.append(det)
    return out
