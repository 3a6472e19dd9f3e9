"""The whole calibration: photos -> corners -> solve -> uncertainty, coverage, cross-check.

:func:`calibrate_detections` is pure (corner sets in, a report out);
:func:`detect_photos` is the only function here that reads files.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np
from scipy.special import fdtrc

from cvmeasure.board import BoardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.errors import InputError
from cvmeasure.imageio import read_photo
from cvmeasure.lens.coverage import Coverage, image_coverage
from cvmeasure.lens.detect import BoardDetection, detect_board
from cvmeasure.lens.solve import (
    DISTORTION_MODELS,
    CalibrationResult,
    DistortionModel,
    calibrate_views,
    view_residuals_px,
)
from cvmeasure.lens.uncertainty import (
    CrossValidation,
    ProjectionUncertainty,
    central_mask,
    cross_validate,
    projection_diff,
    projection_uncertainty,
    view_clustered_covariance,
)
from cvmeasure.lens.warp import board_extent_mm
from cvmeasure.lens.warp_decision import decide_board_warp
from cvmeasure.warning import StageWarning

__all__ = [
    "CalibrationReport",
    "calibrate_detections",
    "detect_photos",
    "CROSS_VALIDATION_RATIO_LIMIT",
    "AUTO_MODELS",
    "choose_model",
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
    warnings: tuple[StageWarning, ...]
    model_choice: dict[str, Any] | None = None
    board_warp: dict[str, Any] | None = None

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
            "warnings": [w.to_json() for w in self.warnings],
            "model_choice": self.model_choice,
            "board_warp": self.board_warp,
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
            "model": self.result.model,
            "model_choice": self.model_choice,
            "board_warp": self.board_warp,
            "warnings": [w.to_json() for w in self.warnings],
        }


#: A distortion coefficient beyond this magnitude means the model is not determined by
#: the views (a rational fit on clean renders reached k3 = -156).
ILL_CONDITIONED_COEFF = 10.0
#: A projection uncertainty beyond this many image sizes means nothing.
ILL_CONDITIONED_UNCERTAINTY = 10.0
#: OpenCV's distortion coefficient order.
DIST_NAMES = ("k1", "k2", "p1", "p2", "k3", "k4", "k5", "k6", "s1", "s2", "s3", "s4", "tx", "ty")


#: Models ``auto`` tries, simplest first.
AUTO_MODELS = ("1", "2", "5", "rational")


def _held_out(
    detections: Sequence[BoardDetection], image_size_px: tuple[int, int], model: str
) -> dict[str, Any] | None:
    """Residuals of corners in views left out of the fit (even fits odd and back), split
    into the central 60 % of the image and the rest.

    Each left-out view's pose is solved (PnP) with the other half's intrinsics fixed, so
    the residual holds model error as well as noise. Returns per held-out view the sums
    of squared residuals (px^2) and corner counts in the centre and at the edge (arrays,
    parallel), or None when a half has fewer than 3 views or a fit fails.
    """
    halves = (list(detections[0::2]), list(detections[1::2]))
    if min(len(h) for h in halves) < 3:
        return None
    rows = []
    for fit, test in ((halves[0], halves[1]), (halves[1], halves[0])):
        try:
            cam = calibrate_views(fit, image_size_px, model=model).camera  # type: ignore[arg-type]
        except InputError:
            return None
        for det in test:
            obj = det.object_mm.reshape(-1, 1, 3)
            img = det.corners_px.reshape(-1, 1, 2)
            ok, rvec, tvec = cv2.solvePnP(obj, img, cam.camera_matrix, cam.dist_coeffs)
            if not ok:
                continue
            rvec, tvec = cv2.solvePnPRefineLM(
                obj, img, cam.camera_matrix, cam.dist_coeffs, rvec, tvec
            )
            sq = np.sum(view_residuals_px(cam, det, rvec.ravel(), tvec.ravel()) ** 2, axis=1)
            centre = central_mask(det.corners_px, image_size_px)
            rows.append((sq[centre].sum(), centre.sum(), sq[~centre].sum(), (~centre).sum()))
    if not rows:
        return None
    arr = np.asarray(rows, dtype=np.float64)
    return {
        "sq_centre": arr[:, 0],
        "n_centre": arr[:, 1],
        "sq_edge": arr[:, 2],
        "n_edge": arr[:, 3],
    }


def _whole_image_terms(held: dict[str, Any]) -> np.ndarray:
    """Per held-out view, its share of the whole-image held-out mean square (px^2 per
    coordinate): the centre's and the edge's mean squares weigh half each, so the edge,
    where the operator's parts lie too, counts as much as the centre however few corners
    it has. Their sum is the whole-image held-out mean square."""
    n_c, n_e = held["n_centre"].sum(), held["n_edge"].sum()
    regions = [(held["sq_centre"], n_c), (held["sq_edge"], n_e)]
    regions = [(sq, n) for sq, n in regions if n > 0]
    return sum(sq / (2.0 * n * len(regions)) for sq, n in regions)


def _held_out_summary(held: dict[str, Any]) -> dict[str, Any]:
    n_c, n_e = held["n_centre"].sum(), held["n_edge"].sum()
    return {
        "held_out_rms_px": float(np.sqrt(np.sum(_whole_image_terms(held)))),
        "held_out_centre_rms_px": float(np.sqrt(held["sq_centre"].sum() / (2 * n_c)))
        if n_c
        else None,
        "held_out_edge_rms_px": float(np.sqrt(held["sq_edge"].sum() / (2 * n_e))) if n_e else None,
        "residuals": int(2 * (n_c + n_e)),
    }


def _paired_z(worse: dict[str, Any], better: dict[str, Any]) -> float:
    """How many standard errors ``worse``'s whole-image held-out mean square is above
    ``better``'s: the views are the same, so the difference is judged view by view (its
    standard error from the spread of the per-view differences)."""
    d = _whole_image_terms(worse) - _whole_image_terms(better)
    if d.size < 2:
        return 0.0
    se = float(np.sqrt(d.size * np.var(d, ddof=1)))
    return float(np.sum(d) / se) if se > 0 else (np.inf if np.sum(d) > 0 else 0.0)


#: A model's whole-image held-out mean square is worse than another's beyond noise when
#: it is higher by more than this many standard errors of the view-by-view difference.
HELD_OUT_WORSE_Z = 2.0

#: A richer model's fit is better than the simpler one's when the nested F-test rejects
#: the simpler model at this false-alarm probability (3 sigma, two-sided).
SIGNIFICANT_P = 0.0027


def _full_fit(
    detections: Sequence[BoardDetection], image_size_px: tuple[int, int], model: str
) -> dict[str, Any] | None:
    """Fit ``model`` on every corner (no rejection, so all models see the same corners):
    residual sum of squares (px^2), residual and parameter counts, coefficients and their
    standard deviations; None when the solve fails."""
    try:
        res = calibrate_views(
            detections,
            image_size_px,
            model=model,  # type: ignore[arg-type]
            reject_outliers=False,
        )
    except InputError:
        return None
    n = 2 * res.corner_count
    return {
        "ssr_px2": float(res.rms_px) ** 2 * n,
        "n": n,
        "params": len(res.std_devs) + 6 * len(res.views),
        "camera": res.camera,
        "coeffs": {
            k: float(v)
            for k, v in zip(DIST_NAMES, res.camera.dist_coeffs, strict=False)
            if k in res.std_devs
        },
        "std_devs": dict(res.std_devs),
    }


def _richer_supported(simple: dict[str, Any], rich: dict[str, Any]) -> dict[str, Any]:
    """Is the richer model's fit (``rich``) significantly better than ``simple``'s?

    Its extra coefficients are significant when the nested-model F-test on the residual
    sums of squares (same corners) rejects the simpler model at :data:`SIGNIFICANT_P`;
    each extra coefficient's |value| / sigma is reported as evidence. A richer model
    that is ill-conditioned (a coefficient beyond
    :data:`ILL_CONDITIONED_COEFF`) or whose whole-image held-out mean square is worse
    than the simpler one's by more than :data:`HELD_OUT_WORSE_Z` standard errors
    (:func:`_paired_z`) is never supported.
    """
    sf, rf = simple["fit"], rich["fit"]
    extra = [k for k in rf["coeffs"] if k not in sf["coeffs"]]
    t = {
        k: abs(rf["coeffs"][k]) / rf["std_devs"][k] if rf["std_devs"][k] > 0 else 0.0 for k in extra
    }
    dq = rf["params"] - sf["params"]
    dof = rf["n"] - rf["params"]
    f_stat = max(sf["ssr_px2"] - rf["ssr_px2"], 0.0) / dq / (rf["ssr_px2"] / dof)
    p = float(fdtrc(dq, dof, f_stat))  # the F distribution's sf, no scipy.stats
    ill = any(abs(v) > ILL_CONDITIONED_COEFF for v in rf["coeffs"].values())
    held_worse = False
    if simple.get("held") is not None and rich.get("held") is not None:
        held_worse = _paired_z(rich["held"], simple["held"]) > HELD_OUT_WORSE_Z
    # the F-test decides: OpenCV's coefficient sigmas of an ill-conditioned model are
    # tiny (rational fits on clean renders showed k3 at 5e6 sigma), so |value| / sigma
    # is evidence only
    significant = p < SIGNIFICANT_P
    return {
        "over": simple["model"],
        "extra_coefficient_sigmas": {k: round(v, 2) for k, v in t.items()},
        "f_test_p": p,
        "ill_conditioned": ill,
        "held_out_worse": held_worse,
        "supported": bool(significant and not ill and not held_worse),
    }


def choose_model(
    detections: Sequence[BoardDetection], image_size_px: tuple[int, int]
) -> tuple[str, dict[str, Any]]:
    """The simplest model no richer one beats, judged over the whole image.

    Every candidate of :data:`AUTO_MODELS` is fitted on the corners and views model 5's
    outlier rejection keeps (:func:`_full_fit`), and on the even views with the odd ones'
    corners predicted (pose by PnP, intrinsics fixed), and back (:func:`_held_out`). The
    held-out error is taken over the whole image: the centre (central 60 %) and the edge
    weigh half each. Starting from the simplest, a richer model replaces the choice when
    its extra coefficients are significant (nested F-test, p < 0.0027) and it is neither
    ill-conditioned nor worse held out over the whole image (:func:`_paired_z` >
    :data:`HELD_OUT_WORSE_Z`): a model that fits the centre and strays at the edge loses
    there. If the choice is still worse held out than the best candidate beyond noise,
    the simplest candidate that is not is taken. (The held-out error alone cannot tell k1
    from k1 k2 p1 p2 k3 at 922x614 with 12 views; the F-test can.) Returns the model and
    the evidence (JSON-ready): every candidate's held-out RMS (whole image, centre,
    edge), the test against the one before, why the choice, and the next-best model with
    how far it would move the image corners. With too few views, ``"5"`` is returned and
    the evidence says why.
    """
    if len(detections) < 6:
        return "5", {
            "rule": "too few views to choose a model (need 6 or more); model 5 is used",
            "candidates": [],
        }

    # every candidate is judged on the same corners: those model 5's rejection keeps
    # (an outlier corner would inflate every model's residuals alike and hide the gain)
    try:
        detections = list(calibrate_views(detections, image_size_px, model="5").detections)
    except InputError:
        pass
    evidence: list[dict[str, Any]] = []
    for m in AUTO_MODELS:
        fit = _full_fit(detections, image_size_px, m)
        if fit is None:
            continue
        held = _held_out(detections, image_size_px, m)
        evidence.append(
            {
                "model": m,
                "fit": fit,
                "held": held,
                **(_held_out_summary(held) if held is not None else {"held_out_rms_px": None}),
            }
        )
    if not evidence:
        return "5", {
            "rule": "no candidate model could be fitted; model 5 is used",
            "candidates": [],
        }
    chosen = evidence[0]
    why = f"model {chosen['model']} is the simplest candidate"
    for e in evidence[1:]:
        e["test"] = _richer_supported(chosen, e)
        if e["test"]["supported"]:
            why = (
                f"model {e['model']} fits significantly better than {chosen['model']} "
                f"(F-test p {e['test']['f_test_p']:.2g}) and is no worse held out over the "
                "whole image"
            )
            chosen = e
    chosen, why = _no_worse_than_best(evidence, chosen, why)
    next_best = _next_best(evidence, chosen)
    for e in evidence:
        fit = e.pop("fit")
        e.pop("held")
        e.pop("camera", None)
        e["fit_rms_px"] = float(np.sqrt(fit["ssr_px2"] / fit["n"]))
    helds = [e["held_out_rms_px"] for e in evidence if e["held_out_rms_px"] is not None]
    return chosen["model"], {
        "rule": "simplest model no richer one beats: a richer model replaces the choice "
        "when the nested F-test on the fit residuals (same corners) gives p < 0.0027, "
        "unless it is ill-conditioned or worse held out over the whole image (fit on even "
        "views, tested on odd, and back; centre and edge weigh half each; worse by more "
        f"than {HELD_OUT_WORSE_Z:g} standard errors of the view-by-view difference); a "
        "choice worse held out than the best candidate gives way to the simplest that is not",
        "chosen": chosen["model"],
        "why": why,
        "best_held_out_rms_px": min(helds) if helds else None,
        "next_best": next_best,
        "candidates": evidence,
    }


def _no_worse_than_best(
    evidence: list[dict[str, Any]], chosen: dict[str, Any], why: str
) -> tuple[dict[str, Any], str]:
    """``chosen`` and ``why``, unless ``chosen`` is worse held out over the whole image than
    the best well-conditioned candidate beyond noise (:func:`_paired_z` >
    :data:`HELD_OUT_WORSE_Z`): then the simplest candidate that is not, and why."""
    usable = [
        e
        for e in evidence
        if e["held"] is not None
        and not any(abs(v) > ILL_CONDITIONED_COEFF for v in e["fit"]["coeffs"].values())
    ]
    best = min(usable, key=lambda e: e["held_out_rms_px"], default=None)
    if best is None or chosen["held"] is None:
        return chosen, why
    z = _paired_z(chosen["held"], best["held"])
    if z <= HELD_OUT_WORSE_Z:
        return chosen, why
    adequate = next(e for e in usable if _paired_z(e["held"], best["held"]) <= HELD_OUT_WORSE_Z)
    why = (
        f"model {chosen['model']} is worse held out over the whole image than model "
        f"{best['model']} ({z:.1f} standard errors); model {adequate['model']} is the "
        "simplest that is not"
    )
    return adequate, why


def _next_best(evidence: list[dict[str, Any]], chosen: dict[str, Any]) -> dict[str, Any] | None:
    """The candidate with the lowest whole-image held-out error other than ``chosen``
    (ill-conditioned ones excluded), and how far it would move the image: at the four
    image corners (largest) and RMS over the image, after the best-fit rotation, px."""
    others = [
        e
        for e in evidence
        if e is not chosen
        and e.get("held_out_rms_px") is not None
        and not any(abs(v) > ILL_CONDITIONED_COEFF for v in e["fit"]["coeffs"].values())
    ]
    if not others:
        return None
    other = min(others, key=lambda e: e["held_out_rms_px"])
    diff = projection_diff(chosen["fit"]["camera"], other["fit"]["camera"])
    w, h = diff.image_size_px
    corners = [
        float(diff.diff_px[i])
        for i, (x, y) in enumerate(diff.grid_px)
        if x in (0.0, w - 1.0) and y in (0.0, h - 1.0)
    ]
    return {
        "model": other["model"],
        "held_out_rms_px": other["held_out_rms_px"],
        "image_corner_change_px": max(corners),
        "whole_image_change_rms_px": diff.rms_px,
    }


#: The next richer model :func:`richer_model_test` tries for each model.
_NEXT_RICHER = {"1": "2", "2": "5", "5": "rational"}


def richer_model_test(
    detections: Sequence[BoardDetection], image_size_px: tuple[int, int], model: str
) -> dict[str, Any] | None:
    """Does the next richer model (1 -> 2 -> 5 -> rational) fit the same corners
    significantly better? The nested F-test of :func:`_richer_supported` (p < 0.0027, and
    not ill-conditioned). This sees model error the cross-validation cannot: both halves of
    the views share a too-simple model's bias, so their difference hides it (issue 16: model
    1 on a k1 k2 lens, 27 px off the true lens in the corners, halves ratio 0.6). None for
    models with no richer candidate or when a fit fails."""
    richer = _NEXT_RICHER.get(model)
    if richer is None:
        return None
    fits = [_full_fit(detections, image_size_px, m) for m in (model, richer)]
    if fits[0] is None or fits[1] is None:
        return None
    return _richer_supported({"model": model, "fit": fits[0]}, {"model": richer, "fit": fits[1]})


def model_choice_text(choice: dict[str, Any]) -> str:
    """One line of evidence for a :func:`choose_model` choice: the model and why; per
    candidate its whole-image held-out RMS (centre / edge, px) and, for richer ones, the
    largest extra coefficient in sigmas and the F-test p; what the next-best model would
    change at the image corners."""
    parts = []
    for e in choice.get("candidates", []):
        held = e.get("held_out_rms_px")
        text = f"{e['model']}:"
        if held is not None:
            text = f"{e['model']}: held-out {held:.4f} px"
            c, g = e.get("held_out_centre_rms_px"), e.get("held_out_edge_rms_px")
            if c is not None and g is not None:
                text += f" (centre {c:.4f}, edge {g:.4f})"
        test = e.get("test")
        if test:
            t = max(test["extra_coefficient_sigmas"].values(), default=0.0)
            text += (
                f", vs {test['over']} extra coeff {t:.1f} sigma, F-test p {test['f_test_p']:.2g}"
            )
            if test["ill_conditioned"]:
                text += ", ill-conditioned"
            if test["held_out_worse"]:
                text += ", worse held out"
        parts.append(text)
    line = f"model {choice.get('chosen', '5')} chosen"
    if choice.get("why"):
        line += f": {choice['why']}"
    line += " (" + ("; ".join(parts) or choice["rule"]) + ")"
    nb = choice.get("next_best")
    if nb:
        line += (
            f"; the next best, model {nb['model']}, would move the image corners by up to "
            f"{nb['image_corner_change_px']:.2f} px ({nb['whole_image_change_rms_px']:.2f} px "
            "RMS over the image)"
        )
    return line


def calibrate_detections(
    detections: Sequence[BoardDetection],
    image_size_px: tuple[int, int],
    *,
    model: DistortionModel | str = "5",
    reject_outliers: bool = True,
    cross_check: bool = True,
    source: str = "calibration photos",
    board_warp: str = "auto",
) -> CalibrationReport:
    """Solve, then measure projection uncertainty, coverage and the cross-validation diff.

    Raises :class:`~cvmeasure.errors.InputError` (naming ``source``) when too
    few views are usable. ``model="auto"`` picks it with :func:`choose_model`.
    ``board_warp``: ``"auto"`` solves mrcal's two-parameter board warp with the lens
    (:mod:`cvmeasure.lens.warp`) and keeps it only when the lens model's extension
    still sees the bow, every group of views does, and it moves the lens beyond noise
    (:func:`~cvmeasure.lens.warp_decision.decide_board_warp`), ``"on"`` always keeps it, ``"off"``
    never solves it; the report's ``board_warp`` says which, with the warp in mm and its
    sigma. The cross-validation's halves are solved the same way. With ``cross_check`` and
    a model given (not ``"auto"``), :func:`richer_model_test` also asks whether the next
    richer model fits the same corners significantly better, and warns if so.
    """
    if board_warp not in ("auto", "on", "off"):
        raise ValueError(f"board_warp must be auto, on or off, not {board_warp!r}")
    choice = None
    if model == "auto":
        usable = [d for d in detections if d.ok]
        model, choice = choose_model(usable, image_size_px)
    result = calibrate_views(
        detections, image_size_px, model=model, reject_outliers=reject_outliers, source=source
    )
    warp_info = None
    extent = None
    if board_warp != "off":
        extent = board_extent_mm(result.detections)
        result, decision = decide_board_warp(result, mode=board_warp, extent_mm=extent)
        warp_info = decision.to_dict()
    use_warp = result.board_warp is not None
    # the stated sigmas allow for errors shared by a view's corners when the views show them
    # (the formal ones alone put a real set's published cy 4.1 sigma away; the
    # view-clustered ones, 1.4)
    param_cov = view_clustered_covariance(result)
    result = replace(result, std_devs=param_cov.std_devs())
    unc = projection_uncertainty(result, covariance=param_cov)
    coverage = image_coverage(
        result.detections, result.image_size_px, [v.rvec for v in result.views]
    )
    cv = (
        cross_validate(
            result.detections,
            result.image_size_px,
            model=model,
            board_warp=use_warp,
            board_extent_mm=extent,
        )
        if cross_check
        else None
    )
    warnings: list[StageWarning] = []
    for det in detections:
        warnings.extend(StageWarning("calib_board_layout", n, det.source) for n in det.notes)
    warnings += _model_error_warnings(result, model, cv, cross_check=cross_check and choice is None)
    if cv is None and cross_check:
        warnings.append(
            StageWarning(
                "calib_no_cross_validation",
                "too few views to cross-validate two halves (need 6 or more)",
            )
        )
    warnings += _solve_quality_warnings(result, unc, coverage)
    return CalibrationReport(result, unc, coverage, cv, tuple(warnings), choice, warp_info)


def _model_error_warnings(
    result: CalibrationResult, model: str, cv: CrossValidation | None, *, cross_check: bool
) -> list[StageWarning]:
    """Model error seen two ways: with ``cross_check`` (a model given, not chosen), the
    next richer model fitting the same corners significantly better; the two halves of the
    views disagreeing beyond noise (``cv``)."""
    out: list[StageWarning] = []
    richer = (
        richer_model_test(result.detections, result.image_size_px, model) if cross_check else None
    )
    if richer is not None and richer["supported"]:
        t = max(richer["extra_coefficient_sigmas"].values(), default=0.0)
        out.append(
            StageWarning(
                "calib_model_too_simple",
                f"model {model} is too simple for these views: model {_NEXT_RICHER[model]} fits "
                f"the same corners significantly better (F-test p {richer['f_test_p']:.2g}, "
                f"extra coefficient {t:.1f} sigma); the halves check cannot see this (both "
                "halves share the bias): use --model auto or a richer model",
            )
        )
    if cv is not None and cv.ratio > CROSS_VALIDATION_RATIO_LIMIT:
        out.append(
            StageWarning(
                "calib_halves_disagree",
                f"the two halves of the views disagree by {cv.diff.central_rms_px:.2f} px in the "
                f"image centre, {cv.ratio:.1f}x what corner noise explains: model error (lens "
                "model too simple, board not flat, focus or zoom changed between photos); the "
                "reported standard deviations understate the real uncertainty",
            )
        )
    return out


def _solve_quality_warnings(
    result: CalibrationResult, unc: ProjectionUncertainty, coverage: Coverage
) -> list[StageWarning]:
    """What the solve itself shows: a poorly determined focal length, the coverage's
    warnings, an ill-conditioned model, corners dropped and photos skipped."""
    out: list[StageWarning] = []
    rel_f = result.std_devs["fx"] / result.camera.fx
    if rel_f > _FOCAL_SIGMA_WARN:
        out.append(
            StageWarning(
                "calib_focal_uncertain",
                f"the focal length is poorly determined (1 sigma {100 * rel_f:.2f} % of f): add "
                "photos with the board tilted 30-45 deg and closer to the camera",
            )
        )
    out.extend(coverage.warnings)
    big = {
        name: float(v)
        for name, v in zip(DIST_NAMES, result.camera.dist_coeffs, strict=False)
        if abs(float(v)) > ILL_CONDITIONED_COEFF
    }
    size = float(max(result.image_size_px))
    if big or not unc.max_px <= ILL_CONDITIONED_UNCERTAINTY * size:
        coeffs = ", ".join(f"{k} {v:+.3g}" for k, v in big.items())
        out.append(
            StageWarning(
                "calib_ill_conditioned",
                f"the {result.model} distortion model is ill-conditioned on these views"
                + (f" (coefficients {coeffs})" if coeffs else "")
                + (
                    f"; its projection uncertainty exceeds {ILL_CONDITIONED_UNCERTAINTY:g}x the "
                    "image size and means nothing"
                    if not unc.max_px <= ILL_CONDITIONED_UNCERTAINTY * size
                    else ""
                )
                + ": use a simpler model (--model 5) or add photos with the board in the corners",
            )
        )
    if result.corners_rejected:
        out.append(
            StageWarning(
                "calib_corners_dropped",
                f"{result.corners_rejected} outlier corner(s) dropped from the views used "
                "(residual more than 4 robust sigmas off its board neighbours' median)",
            )
        )
    if result.rejected:
        out.append(
            StageWarning(
                "calib_views_skipped",
                f"{len(result.rejected)} photo(s) skipped; see views_rejected",
            )
        )
    return out


def detect_photos(
    paths: Sequence[str | os.PathLike[str]],
    board: BoardSpec,
    *,
    progress: Callable[[str], None] | None = None,
) -> list[BoardDetection]:
    """Read every photo (JPEG/PNG/TIFF/RAW) and detect the board; unreadable files raise InputError."""
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
