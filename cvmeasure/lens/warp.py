"""Board warp: a calibration board that is not quite flat, solved with the lens (issue 16).

The board's corners are moved out of their plane by mrcal's two-parameter parabolic
bow (``calobject_warp``, mrcal's ``ref_calibration_object``)::

    z_mm = warp_x_mm * 4 xr (1 - xr) + warp_y_mm * 4 yr (1 - yr)

with ``xr``, ``yr`` the corner's position across the board's corner grid (0 at the first
corner, 1 at the last), so ``warp_x_mm`` is how far the middle of the board stands out of
the plane of its left and right edges (board frame, +z as the board frame's z axis).
:func:`refine_board_warp` refines OpenCV's solution (intrinsics, distortion, every pose)
together with the two warp values by ``scipy.optimize.least_squares`` with analytic
Jacobians from ``cv2.projectPoints``; :func:`warp_test` says whether the data show a warp
(its chi-square against its covariance, the same Jacobian as
:func:`~cvmeasure.lens.uncertainty.parameter_covariance`).

References
----------
D. Kogan, mrcal documentation, "Formulation: board deformation"
(https://mrcal.secretsauce.net/formulation.html).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix
from scipy.special import chdtrc

from cvmeasure.camera_model import CameraModel
from cvmeasure.lens.detect import BoardDetection

__all__ = [
    "BoardWarp",
    "WarpTest",
    "board_extent_mm",
    "warp_z_mm",
    "warped_object_mm",
    "refine_board_warp",
    "warp_test",
    "WARP_SIGNIFICANT_P",
]

#: The data show a warp when its chi-square (2 dof) rejects a flat board at this
#: false-alarm probability (3 sigma, the model choice's threshold).
WARP_SIGNIFICANT_P = 0.0027


@dataclass(frozen=True)
class BoardWarp:
    """A solved board warp: mrcal's two-parameter bow, mm, with its covariance (mm^2).

    ``extent_mm`` is ((x_min, x_max), (y_min, y_max)) of the corner grid it is relative to.
    """

    warp_mm: tuple[float, float]
    covariance_mm2: np.ndarray
    extent_mm: tuple[tuple[float, float], tuple[float, float]]

    @property
    def sigma_mm(self) -> tuple[float, float]:
        sd = np.sqrt(np.clip(np.diag(self.covariance_mm2), 0.0, None))
        return float(sd[0]), float(sd[1])

    def to_dict(self) -> dict[str, Any]:
        return {
            "what": "board bow out of its plane at the middle of the corner grid, mm "
            "(mrcal's calobject_warp: z = wx 4 xr (1 - xr) + wy 4 yr (1 - yr))",
            "warp_mm": list(self.warp_mm),
            "sigma_mm": list(self.sigma_mm),
            "extent_mm": [list(e) for e in self.extent_mm],
        }


@dataclass(frozen=True)
class WarpTest:
    """Does a warp fit show a board that is not flat? (chi-square of the warp, 2 dof)."""

    warp: BoardWarp
    chi2: float
    p: float
    z_towards_camera: bool = True  # the board frame's +z points towards the camera

    @property
    def significant(self) -> bool:
        return self.p < WARP_SIGNIFICANT_P

    def text(self, verdict: str | None = None) -> str:
        """One line, the same for a board described transposed: each side's bow (its length
        in mm), towards or away from the camera, longest side first; ``verdict`` replaces
        this test's own ("the board is not flat" / "flat within noise")."""
        (wx, wy), (sx, sy) = self.warp.warp_mm, self.warp.sigma_mm
        sides = []
        for w, s, (lo, hi) in zip((wx, wy), (sx, sy), self.warp.extent_mm, strict=True):
            towards = (w > 0) == self.z_towards_camera
            where = "towards the camera" if towards else "away from it"
            sides.append(
                (
                    hi - lo,
                    abs(w),
                    f"{abs(w):.4f} +- {s:.4f} mm {where} along the {hi - lo:.0f} mm side",
                )
            )
        sides.sort(key=lambda t: (-t[0], -t[1]))
        return (
            "board warp (the middle out of the plane of the edges): "
            + ", ".join(t[2] for t in sides)
            + f" (chi-square p {self.p:.2g}: "
            + (
                verdict
                if verdict is not None
                else ("the board is not flat" if self.significant else "flat within noise")
            )
            + ")"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            **self.warp.to_dict(),
            "chi2": self.chi2,
            "p": self.p,
            "significant": self.significant,
        }


def board_extent_mm(
    detections: Sequence[BoardDetection],
) -> tuple[tuple[float, float], tuple[float, float]]:
    """((x_min, x_max), (y_min, y_max)) of every corner seen in any view, board mm.

    The warp is relative to the corner grid; over a calibration set every corner is seen
    in some view, so this is the board's grid (a board described transposed swaps x, y).
    """
    pts = np.concatenate([np.asarray(d.object_mm, dtype=np.float64)[:, :2] for d in detections])
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    return (float(lo[0]), float(hi[0])), (float(lo[1]), float(hi[1]))


def _basis(object_mm: np.ndarray, extent_mm) -> np.ndarray:
    """(N, 2) d z / d warp: 4 r (1 - r) along x and along y."""
    out = np.empty((len(object_mm), 2))
    for a in range(2):
        lo, hi = extent_mm[a]
        r = (object_mm[:, a] - lo) / (hi - lo) if hi > lo else np.zeros(len(object_mm))
        out[:, a] = 4.0 * r * (1.0 - r)
    return out


def warp_z_mm(object_mm: np.ndarray, extent_mm, warp_mm: Sequence[float]) -> np.ndarray:
    """Out-of-plane offset (N,) of board corners (N, 3) under a warp, mm."""
    return _basis(np.asarray(object_mm, dtype=np.float64), extent_mm) @ np.asarray(warp_mm, float)


def warped_object_mm(object_mm: np.ndarray, extent_mm, warp_mm: Sequence[float]) -> np.ndarray:
    """Board corners (N, 3) with the warp's out-of-plane offset added to z, mm."""
    obj = np.array(object_mm, dtype=np.float64).reshape(-1, 3)
    obj[:, 2] += warp_z_mm(obj, extent_mm, warp_mm)
    return obj


def gauss_markov_covariance(residuals: np.ndarray, jacobian: Any) -> tuple[np.ndarray, float, int]:
    """sigma^2 (J^T J)^-1 with sigma^2 = |r|^2 / (rows - columns), J dense or sparse,
    columns scaled to unit norm for the inverse; returns (covariance, sigma^2 px^2, dof)."""
    jtj = jacobian.T @ jacobian
    jtj = jtj.toarray() if hasattr(jtj, "toarray") else np.asarray(jtj)
    dof = max(jacobian.shape[0] - jacobian.shape[1], 1)
    sigma2 = float(residuals @ residuals) / dof
    scale = np.sqrt(np.diag(jtj))
    scale[scale == 0] = 1.0
    return (
        np.linalg.pinv(jtj / np.outer(scale, scale)) / np.outer(scale, scale) * sigma2,
        sigma2,
        dof,
    )


def _project(obj, rvec, tvec, k, dist):
    proj, jac = cv2.projectPoints(obj.reshape(-1, 1, 3), rvec, tvec, k, dist)
    return proj.reshape(-1, 2), jac  # jac columns: r(3) t(3) fx fy cx cy dist(14)


def warp_jacobian(
    camera, detections, rvecs, tvecs, n_intrinsics: int, extent_mm, warp_mm
) -> tuple[np.ndarray, Any]:
    """Residuals (observed - projected, px, flattened) and the projection's sparse (CSR)
    Jacobian over [free intrinsics, 6 per view (rvec, tvec mm), warp x, warp y]."""
    n_v = len(detections)
    n_dist = camera.dist_coeffs.size
    n_cols = n_intrinsics + 6 * n_v + 2
    vals, cols, res = [], [], []
    for v, (det, rv, tv) in enumerate(zip(detections, rvecs, tvecs, strict=True)):
        obj = warped_object_mm(det.object_mm, extent_mm, warp_mm)
        proj, jac = _project(obj, rv, tv, camera.camera_matrix, camera.dist_coeffs)
        res.append((det.corners_px - proj).ravel())
        intr = np.concatenate([jac[:, 6:10], jac[:, 10 : 10 + n_dist]], axis=1)[:, :n_intrinsics]
        # a corner moved along the board's z moves in the camera by R[:, 2]: d proj / d z
        # is the translation Jacobian times that column
        rot, _ = cv2.Rodrigues(np.asarray(rv, dtype=np.float64))
        dz = jac[:, 3:6] @ rot[:, 2]  # (2N,)
        basis = np.repeat(_basis(obj, extent_mm), 2, axis=0)  # rows x0 y0 x1 y1 ...
        vals.append(np.concatenate([intr, jac[:, :6], dz[:, None] * basis], axis=1))
        c = np.concatenate(
            [
                np.arange(n_intrinsics),
                n_intrinsics + 6 * v + np.arange(6),
                [n_cols - 2, n_cols - 1],
            ]
        )
        cols.append(np.broadcast_to(c, (jac.shape[0], c.size)))
    data = np.concatenate(vals)
    idx = np.concatenate(cols)
    n_rows, width = data.shape
    jac_all = csr_matrix(
        (data.ravel(), idx.ravel(), np.arange(0, n_rows * width + 1, width)),
        shape=(n_rows, n_cols),
    )
    return np.concatenate(res), jac_all


def refine_board_warp(
    result,
    *,
    extent_mm: tuple[tuple[float, float], tuple[float, float]] | None = None,
):
    """Refine a solved calibration with mrcal's two-parameter board warp.

    ``result`` is a :class:`~cvmeasure.lens.solve.CalibrationResult` (its corners,
    its model's free intrinsics and its poses are the start); intrinsics, distortion,
    poses and the warp are solved together by ``scipy.optimize.least_squares`` (sparse
    analytic Jacobian). Returns the same result with the refined camera, poses, RMS,
    standard deviations (sigma^2 (J^T J)^-1 over all parameters, warp included) and
    ``board_warp`` set.
    """
    dets = result.detections
    extent = extent_mm or board_extent_mm(dets)
    n_i = len(result.std_devs)
    base = result.camera
    x0 = np.concatenate(
        [[base.fx, base.fy, *base.principal_point_px], base.dist_coeffs[: n_i - 4]]
        + [np.concatenate([v.rvec, v.tvec_mm]) for v in result.views]
        + [np.zeros(2)]
    )
    cache: dict[str, Any] = {}

    def evaluate(x):
        if cache.get("x") is None or not np.array_equal(cache["x"], x):
            cam, rv, tv, w = _unpack_warp_params(x, base, n_i, len(dets))
            cache["x"] = x.copy()
            cache["r"], cache["j"] = warp_jacobian(cam, dets, rv, tv, n_i, extent, w)
        return cache["r"], cache["j"]

    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)  # bit-identical runs (see solve._solve)
    try:
        x = _solve_warp(evaluate, x0)
        r, j = evaluate(x)
    finally:
        cv2.setNumThreads(threads)
    return _warped_result(result, x, r, j, extent)


def _unpack_warp_params(x: np.ndarray, base, n_i: int, n_v: int):
    """(camera, rvecs, tvecs, warp) from the parameter vector [free intrinsics, 6 per view,
    warp x, warp y]; distortion coefficients beyond the free ones stay ``base``'s."""
    k = np.array([[x[0], 0.0, x[2]], [0.0, x[1], x[3]], [0.0, 0.0, 1.0]])
    dist = base.dist_coeffs.copy()
    dist[: n_i - 4] = x[4:n_i]
    cam = CameraModel(base.image_size_px, k, dist)
    rv = [x[n_i + 6 * v : n_i + 6 * v + 3] for v in range(n_v)]
    tv = [x[n_i + 6 * v + 3 : n_i + 6 * v + 6] for v in range(n_v)]
    return cam, rv, tv, x[-2:]


def _solve_warp(evaluate, x0: np.ndarray) -> np.ndarray:
    """Least squares from ``x0`` (trust region, then up to 5 Gauss-Newton steps);
    ``evaluate(x)`` gives (observed - projected residuals, their sparse Jacobian)."""
    # x_scale: columns are scaled by the Jacobian's norms, so the step is well posed
    # for focal lengths (1e3 px), distortion (1e-1) and warps (1e-2 mm) alike
    sol = least_squares(
        lambda x: -evaluate(x)[0],  # projected - observed
        x0,
        jac=lambda x: evaluate(x)[1],
        method="trf",
        tr_solver="lsmr",
        x_scale="jac",
        xtol=1e-12,
        ftol=1e-12,
        gtol=1e-12,
        max_nfev=50,
    )
    x = sol.x
    # Gauss-Newton polish on the normal equations (the solve starts at OpenCV's flat
    # optimum, so a few exact steps converge where the iterative solver stops short)
    for _ in range(5):
        r, j = evaluate(x)
        jtj = (j.T @ j).toarray()
        scale = np.sqrt(np.diag(jtj))
        scale[scale == 0] = 1.0
        step = np.linalg.solve(jtj / np.outer(scale, scale), (j.T @ r) / scale) / scale
        x_new = x + step
        r_new, _ = evaluate(x_new)
        if r_new @ r_new > r @ r:
            break
        x = x_new
        if r @ r - r_new @ r_new < 1e-12 * (r @ r):
            break
    return x


def _warped_result(result, x: np.ndarray, r: np.ndarray, j, extent):
    """``result`` with the solution ``x`` (residuals ``r``, Jacobian ``j``): camera, poses,
    per-view and overall RMS, standard deviations and the board warp with its covariance."""
    dets = result.detections
    names = tuple(result.std_devs)
    n_i = len(names)
    cam, rv, tv, w = _unpack_warp_params(x, result.camera, n_i, len(dets))
    cov = gauss_markov_covariance(r, j)[0]
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    warp = BoardWarp((float(w[0]), float(w[1])), cov[-2:, -2:].copy(), extent)
    rr = r.reshape(-1, 2)
    views = []
    for v, view in enumerate(result.views):
        # per-view RMS from the refined residuals
        start = sum(d.corner_count for d in dets[:v])
        e = rr[start : start + dets[v].corner_count]
        views.append(
            replace(
                view,
                rms_px=float(np.sqrt(np.mean(np.sum(e**2, axis=1)))),
                rvec=rv[v].copy(),
                tvec_mm=tv[v].copy(),
            )
        )
    return replace(
        result,
        camera=cam,
        rms_px=float(np.sqrt(r @ r / (r.size / 2))),
        std_devs={n: float(s) for n, s in zip(names, sd[:n_i], strict=True)},
        views=tuple(views),
        board_warp=warp,
    )


def warp_test(warp: BoardWarp, result=None) -> WarpTest:
    """Chi-square of the warp against its covariance (2 dof): does the data show one?
    With the solved ``result`` the text says which way the board bows (towards the camera
    or away, the same for a board described transposed)."""
    w = np.asarray(warp.warp_mm)
    c2 = float(w @ np.linalg.pinv(warp.covariance_mm2) @ w)
    towards = True
    if result is not None and result.views:
        view, det = result.views[0], result.detections[0]
        rot, _ = cv2.Rodrigues(np.asarray(view.rvec, dtype=np.float64))
        centre = rot @ np.asarray(det.object_mm, dtype=np.float64).mean(axis=0) + view.tvec_mm
        towards = bool(rot[:, 2] @ centre < 0)  # +z points back at the camera at the origin
    # chi-square sf (scipy.stats's own ufunc); a rounding-negative c2 is 0, as stats had it
    return WarpTest(warp, c2, float(chdtrc(2, max(c2, 0.0))), towards)
