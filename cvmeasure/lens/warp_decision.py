"""Whether to keep a board warp: a bow the lens model's own extension does not explain.

A warp solved with a lens model that is too simple absorbs the lens's error (a real set
with model 2 found a 0.11 mm "bow" at chi-square p 7.5e-07 and moved fx by 3.3 sigma; a
flat solve was 0.2 sigma off the published value). So ``--board-warp auto`` keeps the warp
only when all of these hold:

1. **The lens model's extension still sees it.** The warp is solved with the next richer
   model (1 -> 2 -> 5 -> rational -> thin prism) on the same corners, and its chi-square
   (2 dof, formal covariance) rejects a flat board at p < 0.0027.
2. **Every part of the views sees it.** The views are split into up to 10 groups; the
   warp is solved again (extension model) with each group left out, and the spread of
   those solutions (delete-a-group jackknife) is the warp's covariance. Hotelling's T^2
   with that covariance, F(2, g - 2), rejects a flat board at p < 0.0027. Real corners
   carry errors shared within a view (blur, detector bias, model error) that the formal
   covariance, which assumes independent corners, does not hold.
3. **It matters to the lens.** The warp moves some of fx, fy, cx, cy by more than one of
   its sigmas (the flat solve's). A bow that changes nothing beyond noise is not worth two
   parameters that can absorb something else.

References
----------
B. Efron, C. Stein, "The jackknife estimate of variance", Ann. Statist. 9(3), 1981.
H. Hotelling, "The generalization of Student's ratio", Ann. Math. Statist. 2(3), 1931.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.special import fdtrc

from cvmeasure.errors import InputError
from cvmeasure.lens.solve import CalibrationResult, calibrate_views
from cvmeasure.lens.warp import (
    WARP_SIGNIFICANT_P,
    WarpTest,
    refine_board_warp,
    warp_test,
)

__all__ = ["WarpDecision", "decide_board_warp", "EXTENSION_MODEL", "LENS_SHIFT_SIGMAS"]

#: The lens model's own extension, the model the warp is tested with.
EXTENSION_MODEL = {
    "1": "2",
    "2": "5",
    "5": "rational",
    "8": "thin-prism",
    "rational": "thin-prism",
    "thin-prism": "thin-prism",
}

#: The warp matters when it moves fx, fy, cx or cy by more than this many sigmas.
LENS_SHIFT_SIGMAS = 1.0

#: Most view groups the jackknife leaves out one at a time.
_JACKKNIFE_GROUPS = 10
#: Fewest views the jackknife needs (F(2, g - 2) needs g >= 3; 6 gives it some power).
_JACKKNIFE_MIN_VIEWS = 6


@dataclass(frozen=True)
class WarpDecision:
    """A board warp solved with the lens, and whether it is kept, with the evidence.

    ``own`` is the warp test with the solve's model (``model``); ``extension_model`` and
    ``extension_p`` the formal test with its extension; ``jackknife_p`` the test with
    the jackknife covariance over ``jackknife_groups`` view groups (None when not run);
    ``lens_shift_sigma`` the largest move of fx, fy, cx, cy the warp causes, in sigmas.
    """

    mode: str
    model: str
    used: bool
    own: WarpTest
    extension_model: str
    extension_p: float | None
    jackknife_p: float | None
    jackknife_groups: int
    lens_shift_sigma: float
    reason: str

    def text(self) -> str:
        seen = "the board is not flat" if self.own.significant else "flat within noise"
        verdict = f"{seen} with model {self.model} alone"
        return self.own.text(verdict) + (": kept: " if self.used else ": not kept: ") + self.reason

    def to_dict(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "used": self.used,
            **self.own.to_dict(),
            "extension_model": self.extension_model,
            "extension_p": self.extension_p,
            "jackknife_p": self.jackknife_p,
            "jackknife_groups": self.jackknife_groups,
            "lens_shift_sigma": self.lens_shift_sigma,
            "reason": self.reason,
            "text": self.text(),
        }


def _jackknife_p(result: CalibrationResult, extent_mm, warp_mm: np.ndarray) -> tuple[float, int]:
    """Hotelling's T^2 of ``warp_mm`` against the delete-a-group jackknife covariance of
    the warp (views in up to 10 groups, every k-th view in one group); (p, groups).

    Each group's solve starts from ``result`` (the flat solve on every view) with the
    group's views left out, so it needs a few Gauss-Newton steps, not a new calibration.
    """
    dets = result.detections
    groups = min(len(dets), _JACKKNIFE_GROUPS)
    warps = []
    for g in range(groups):
        keep = [i for i in range(len(dets)) if i % groups != g]
        sub = replace(
            result,
            views=tuple(result.views[i] for i in keep),
            detections=tuple(dets[i] for i in keep),
        )
        warps.append(refine_board_warp(sub, extent_mm=extent_mm).board_warp.warp_mm)
    w = np.asarray(warps)
    dev = w - w.mean(axis=0)
    cov = (groups - 1) / groups * dev.T @ dev
    t2 = float(warp_mm @ np.linalg.pinv(cov) @ warp_mm)
    f_stat = (groups - 2) / (2.0 * (groups - 1)) * t2
    # the F distribution's sf (scipy.stats's own ufunc); a rounding-negative t2 is 0
    return float(fdtrc(2, groups - 2, max(f_stat, 0.0))), groups


def _lens_shift_sigma(flat: CalibrationResult, warped: CalibrationResult) -> float:
    a, b = flat.camera, warped.camera
    moves = {
        "fx": b.fx - a.fx,
        "fy": b.fy - a.fy,
        "cx": b.principal_point_px[0] - a.principal_point_px[0],
        "cy": b.principal_point_px[1] - a.principal_point_px[1],
    }
    return float(max(abs(v) / flat.std_devs[k] for k, v in moves.items() if flat.std_devs[k] > 0))


def decide_board_warp(
    result: CalibrationResult,
    *,
    mode: str,
    extent_mm: tuple[tuple[float, float], tuple[float, float]],
) -> tuple[CalibrationResult, WarpDecision]:
    """Solve the board warp with ``result``'s lens and decide whether to keep it.

    ``mode`` ``"on"`` keeps it, ``"auto"`` keeps it when the three tests of the module
    docstring pass. Returns the result to use (warped or ``result`` itself) and the
    decision.
    """
    warped = refine_board_warp(result, extent_mm=extent_mm)
    own = warp_test(warped.board_warp, warped)
    shift = _lens_shift_sigma(result, warped)
    ext_model = EXTENSION_MODEL.get(result.model, result.model)
    if mode == "on":
        decision = WarpDecision(
            mode, result.model, True, own, ext_model, None, None, 0, shift, "--board-warp on"
        )
        return warped, decision
    ext_p: float | None = None
    jk_p: float | None = None
    groups = 0
    try:
        ext = calibrate_views(
            result.detections,
            result.image_size_px,
            model=ext_model,  # type: ignore[arg-type]
            reject_outliers=False,
        )
        ext_warped = refine_board_warp(ext, extent_mm=extent_mm)
        ext_test = warp_test(ext_warped.board_warp, ext_warped)
        ext_p = ext_test.p
        if ext_test.significant and len(result.detections) >= _JACKKNIFE_MIN_VIEWS:
            jk_p, groups = _jackknife_p(ext, extent_mm, np.asarray(ext_warped.board_warp.warp_mm))
    except InputError:
        pass
    if ext_p is None or ext_p >= WARP_SIGNIFICANT_P:
        reason = (
            f"with the lens model's extension (model {ext_model}) the board is flat within "
            f"noise (chi-square p {ext_p:.2g})"
            if ext_p is not None
            else f"the extension model {ext_model} could not be solved"
        )
        used = False
    elif jk_p is None:
        reason = f"too few views (< {_JACKKNIFE_MIN_VIEWS}) to check the bow across them"
        used = False
    elif jk_p >= WARP_SIGNIFICANT_P:
        reason = (
            f"model {ext_model} sees it (p {ext_p:.2g}) but the views disagree on it "
            f"(jackknife over {groups} view groups: p {jk_p:.2g})"
        )
        used = False
    elif shift <= LENS_SHIFT_SIGMAS:
        reason = (
            f"a bow model {ext_model} and every view group see (p {ext_p:.2g}, jackknife "
            f"p {jk_p:.2g}), but it moves fx, fy, cx, cy by at most {shift:.2f} sigma"
        )
        used = False
    else:
        reason = (
            f"a bow the lens model's extension (model {ext_model}) does not explain: "
            f"p {ext_p:.2g}, jackknife over {groups} view groups p {jk_p:.2g}; it moves the "
            f"lens by {shift:.1f} sigma"
        )
        used = True
    decision = WarpDecision(
        mode, result.model, used, own, ext_model, ext_p, jk_p, groups, shift, reason
    )
    return (warped if used else result), decision
