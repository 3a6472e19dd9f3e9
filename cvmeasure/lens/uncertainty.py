"""How far the solved lens can be trusted: projection uncertainty and cross-validation.

* :func:`parameter_covariance` -- covariance of every solved parameter
  (intrinsics and the 6 pose parameters of each view) from the solve's
  Jacobian, scaled by the residual variance (Gauss-Markov).
* :func:`view_clustered_covariance` -- the same, allowing for errors the corners of one
  view share (the larger, direction by direction, of the formal covariance and the
  view-clustered sandwich): what :func:`~cvmeasure.lens.pipeline.calibrate_detections`
  states.
* :func:`projection_uncertainty` -- propagates a covariance to the pixel a
  fixed 3-D point projects to, across a grid over the image, as mrcal does
  ("mean-pcam": the point is carried through every view's board frame, so pose
  uncertainty counts too). This is *sampling* error: with the view-clustered
  covariance it includes errors shared within a view, but not a bias every view shares
  (lens model too simple, board not flat).
* :func:`projection_diff` -- how far two camera models disagree on where a ray
  lands, optionally after the rotation that best aligns them.
* :func:`cross_validate` -- calibrates two halves of the views separately and
  compares them. A diff well above the two halves' combined uncertainty means
  model error; it is the first number a user should look at.

References
----------
D. Kogan, mrcal documentation, "Projection uncertainty" and "Cross-validation"
(https://mrcal.secretsauce.net/uncertainty.html).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from scipy.optimize import least_squares
from scipy.special import chdtrc

from cvmeasure.camera_model import CameraModel
from cvmeasure.errors import InputError
from cvmeasure.lens.detect import BoardDetection
from cvmeasure.lens.solve import CalibrationResult, calibrate_views
from cvmeasure.lens.warp import gauss_markov_covariance, warp_jacobian

__all__ = [
    "ParameterCovariance",
    "ProjectionUncertainty",
    "ProjectionDiff",
    "CrossValidation",
    "parameter_covariance",
    "view_clustered_covariance",
    "view_shared_error_p",
    "SHARED_ERROR_SIGNIFICANT_P",
    "projection_uncertainty",
    "projection_diff",
    "cross_validate",
    "image_grid_px",
    "central_mask",
]


def image_grid_px(image_size_px: tuple[int, int], grid: tuple[int, int] = (24, 16)) -> np.ndarray:
    """Pixel centres of a (nx, ny) grid spanning the whole image, (ny*nx, 2), row-major."""
    w, h = image_size_px
    xs = np.linspace(0.0, w - 1.0, grid[0])
    ys = np.linspace(0.0, h - 1.0, grid[1])
    gx, gy = np.meshgrid(xs, ys)
    return np.column_stack((gx.ravel(), gy.ravel()))


def central_mask(points_px: np.ndarray, size: tuple[int, int], frac: float = 0.6) -> np.ndarray:
    """True for points (N, 2) px inside the central ``frac`` of the image in x and in y."""
    w, h = size
    dx = np.abs(points_px[:, 0] - (w - 1) / 2) / w
    dy = np.abs(points_px[:, 1] - (h - 1) / 2) / h
    return (dx <= frac / 2 + 1e-9) & (dy <= frac / 2 + 1e-9)


_central_mask = central_mask


@dataclass(frozen=True)
class ParameterCovariance:
    """Covariance of the solved parameters.

    Parameters are ordered: the free intrinsics (``names[:n_intrinsics]``),
    then rvec (3) and tvec (3, mm) of each view.
    """

    names: tuple[str, ...]
    n_intrinsics: int
    covariance: np.ndarray
    residual_sigma_px: float
    dof: int

    def std_devs(self) -> dict[str, float]:
        sd = np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))
        return {n: float(s) for n, s in zip(self.names[: self.n_intrinsics], sd, strict=False)}


def _view_jacobian(camera: CameraModel, det: BoardDetection, rvec, tvec):
    proj, jac = cv2.projectPoints(
        det.object_mm.reshape(-1, 1, 3), rvec, tvec, camera.camera_matrix, camera.dist_coeffs
    )
    return proj.reshape(-1, 2), jac  # jac columns: r(3) t(3) fx fy cx cy dist(k)


def _residuals_and_jacobian(result: CalibrationResult) -> tuple[np.ndarray, Any, int]:
    """Residuals (observed - projected, px, flattened view by view), the projection's
    Jacobian over [free intrinsics, 6 per view, and the 2 warp terms when the result has a
    board warp] (dense, or sparse with a warp), and the number of warp columns (0 or 2)."""
    cam = result.camera
    n_i = len(result.std_devs)
    n_v = len(result.views)
    if result.board_warp is not None:
        w = result.board_warp
        r, jac_w = warp_jacobian(
            cam,
            result.detections,
            [v.rvec for v in result.views],
            [v.tvec_mm for v in result.views],
            n_i,
            w.extent_mm,
            w.warp_mm,
        )
        return r, jac_w, 2
    n_dist = cam.dist_coeffs.size
    blocks = []
    res = []
    for k, (det, view) in enumerate(zip(result.detections, result.views, strict=True)):
        proj, jac = _view_jacobian(cam, det, view.rvec, view.tvec_mm)
        res.append((det.corners_px - proj).ravel())
        full = np.zeros((jac.shape[0], n_i + 6 * n_v))
        intr = np.concatenate([jac[:, 6:10], jac[:, 10 : 10 + n_dist]], axis=1)
        full[:, :n_i] = intr[:, :n_i]
        full[:, n_i + 6 * k : n_i + 6 * k + 6] = jac[:, :6]
        blocks.append(full)
    return np.concatenate(res), np.concatenate(blocks), 0


def _covariance_names(result: CalibrationResult) -> tuple[str, ...]:
    return tuple(result.std_devs) + tuple(
        f"view{k}_{q}"
        for k in range(len(result.views))
        for q in ("rx", "ry", "rz", "tx", "ty", "tz")
    )


def _marginal(
    result: CalibrationResult, cov: np.ndarray, n_warp: int, sigma2: float, dof: int
) -> ParameterCovariance:
    """The intrinsics' and poses' block of ``cov`` (the warp's ``n_warp`` last rows out)."""
    keep = cov.shape[0] - n_warp
    return ParameterCovariance(
        _covariance_names(result),
        len(result.std_devs),
        cov[:keep, :keep],
        float(np.sqrt(sigma2)),
        dof,
    )


def parameter_covariance(result: CalibrationResult) -> ParameterCovariance:
    """Covariance of intrinsics and poses: sigma^2 (J^T J)^-1 with sigma^2 = |r|^2 / (2N - P).

    With a board warp (``result.board_warp``) the corners are the warped board's and the
    warp's two parameters are solved too: the covariance returned is the intrinsics' and
    poses' marginal (their uncertainty includes the warp's).
    """
    r, jac, n_warp = _residuals_and_jacobian(result)
    cov, sigma2, dof = gauss_markov_covariance(r, jac)
    return _marginal(result, cov, n_warp, sigma2, dof)


#: The view-clustered sandwich replaces the formal covariance when the corners' errors
#: shared within views are significant at this false-alarm probability (3 sigma, the
#: model choice's and the board warp's threshold).
SHARED_ERROR_SIGNIFICANT_P = 0.0027


def _view_scores(r: np.ndarray, jac: Any, rows: np.ndarray) -> tuple[np.ndarray, list]:
    """Each view's score J_v^T r_v (G, P) and its dense Jacobian rows."""
    blocks = [jac[a:b] for a, b in zip(rows[:-1], rows[1:], strict=True)]
    blocks = [b.toarray() if hasattr(b, "toarray") else np.asarray(b) for b in blocks]
    scores = np.stack([b.T @ r[a:e] for b, a, e in zip(blocks, rows[:-1], rows[1:], strict=True)])
    return scores, blocks


def _shared_error_p(
    scores: np.ndarray, blocks: list, bread: np.ndarray, sigma2: float, shared: np.ndarray
) -> float:
    """p of the view-clustered scores' size if every corner's error were independent.

    The statistic is the trace of the sandwich whitened by the formal covariance,
    ``T = sum_v s_v^T B s_v / sigma^2`` (s_v = J_v^T r_v; only the columns every view
    shares, ``shared``, carry a score: a view's own pose columns are zero at the optimum).
    Under independent noise the scores are Gaussian with
    ``cov(s_v, s_w) = sigma^2 (delta_vw C_v - C_v B C_w)``, C_v = J_v^T J_v, so T is a
    weighted sum of chi-squares; its p is Satterthwaite's (a scaled chi-square with T's
    mean and variance).
    """
    b_ss = bread[np.ix_(shared, shared)]
    c_rows = np.concatenate([(blk[:, shared].T @ blk) for blk in blocks])  # (G q, P)
    q = shared.size
    g = len(blocks)
    x = -(c_rows @ bread @ c_rows.T)
    for v in range(g):
        sl = slice(v * q, (v + 1) * q)
        x[sl, sl] += c_rows[sl][:, shared]
    kx = np.concatenate([b_ss @ x[v * q : (v + 1) * q] for v in range(g)])
    mean = float(np.trace(kx))
    var = 2.0 * float(np.sum(kx * kx.T))
    if mean <= 0 or var <= 0:
        return 1.0
    t = float(sum(s[shared] @ b_ss @ s[shared] for s in scores)) / sigma2
    scale = var / (2.0 * mean)
    # the chi-square sf (scipy.stats's own ufunc; importing scipy.stats costs start-up)
    return float(chdtrc(2.0 * mean * mean / var, t / scale))


def _scores_and_p(result, r, jac, n_warp, bread, sigma2) -> tuple[np.ndarray, float]:
    rows = np.cumsum([0] + [2 * d.corner_count for d in result.detections])
    scores, blocks = _view_scores(r, jac, rows)
    n_i = len(result.std_devs)
    n_p = bread.shape[0]
    shared = np.r_[np.arange(n_i), np.arange(n_p - n_warp, n_p)]
    return scores, _shared_error_p(scores, blocks, bread, sigma2, shared)


def view_shared_error_p(result: CalibrationResult) -> float:
    """p of the views' scores if every corner's error were independent with one variance:
    small when the corners of a view share errors that move the lens (the test
    :func:`view_clustered_covariance` runs)."""
    r, jac, n_warp = _residuals_and_jacobian(result)
    formal, sigma2, _ = gauss_markov_covariance(r, jac)
    return _scores_and_p(result, r, jac, n_warp, formal / sigma2, sigma2)[1]


def view_clustered_covariance(result: CalibrationResult) -> ParameterCovariance:
    """The solve's covariance allowing for errors shared by the corners of one view.

    :func:`parameter_covariance` assumes every corner's error independent with one
    variance. Real corners share errors within a view (blur, lighting, the detector's
    bias, lens-model error along the view's path through the image): on PhotonVision's
    123-view LifeCam set the view-clustered sandwich estimate of sigma(fx, fy, cx, cy)
    is 3-5x the formal one, and a delete-a-group jackknife over the views agrees (3.5-4.7x).
    The sandwich (Liang-Zeger, clustered by view, with the G / (G - 1) small-sample
    factor) is::

        B (sum_v J_v^T r_v r_v^T J_v) B,   B = (J^T J)^-1

    It is noisy with few views. When the views' scores are larger than independent
    corner errors explain (:func:`view_shared_error_p` below ``SHARED_ERROR_SIGNIFICANT_P``),
    the covariance returned is, in every direction of parameter space, the larger of the
    formal variance and the sandwich's: with F the formal covariance and S the sandwich,
    ``F^1/2 U max(L, 1) U^T F^1/2`` where ``U L U^T`` is ``F^-1/2 S F^-1/2`` (invariant to
    the parameters' units). Otherwise it is the formal covariance: the larger of an exact
    variance and a noisy estimate of the same variance overstates it (the sandwich's
    noise, kept in every direction where it came out high).

    References
    ----------
    K.-Y. Liang, S. L. Zeger, "Longitudinal data analysis using generalized linear
    models", Biometrika 73(1), 1986.
    """
    r, jac, n_warp = _residuals_and_jacobian(result)
    formal, sigma2, dof = gauss_markov_covariance(r, jac)
    bread = formal / sigma2
    scores, p = _scores_and_p(result, r, jac, n_warp, bread, sigma2)
    if p >= SHARED_ERROR_SIGNIFICANT_P:
        return _marginal(result, formal, n_warp, sigma2, dof)
    groups = scores.shape[0]
    sandwich = bread @ (scores.T @ scores) @ bread * (groups / max(groups - 1, 1))
    # whiten by the formal covariance (columns scaled to unit variance first, for conditioning)
    scale = np.sqrt(np.clip(np.diag(formal), 1e-300, None))
    f_s = formal / np.outer(scale, scale)
    s_s = sandwich / np.outer(scale, scale)
    evals, evecs = np.linalg.eigh(f_s)
    evals = np.clip(evals, evals.max() * 1e-15, None)
    half = evecs * np.sqrt(evals)
    inv_half = evecs / np.sqrt(evals)
    lam, u = np.linalg.eigh(inv_half.T @ s_s @ inv_half)
    root = half @ u
    cov_s = (root * np.maximum(lam, 1.0)) @ root.T
    cov = cov_s * np.outer(scale, scale)
    return _marginal(result, cov, n_warp, sigma2, dof)


def _unpack(params: np.ndarray, base: CameraModel, n_i: int):
    k = np.array([[params[0], 0, params[2]], [0, params[1], params[3]], [0, 0, 1.0]])
    dist = base.dist_coeffs.copy()
    dist[: n_i - 4] = params[4:n_i]
    return k, dist


def _mean_pcam_projection(
    params, base, n_i, n_v, board_pts, at_infinity: bool = False
) -> np.ndarray:
    """Project points given in every view's board frame, averaged in the camera frame
    (``at_infinity``: directions, rotated only)."""
    k, dist = _unpack(params, base, n_i)
    cam_pts = np.zeros(board_pts.shape[1:])
    for v in range(n_v):
        rv = params[n_i + 6 * v : n_i + 6 * v + 3]
        tv = params[n_i + 6 * v + 3 : n_i + 6 * v + 6]
        rot, _ = cv2.Rodrigues(rv)
        cam_pts += board_pts[v] @ rot.T + (0.0 if at_infinity else tv)
    cam_pts /= n_v
    img, _ = cv2.projectPoints(cam_pts.reshape(-1, 1, 3), np.zeros(3), np.zeros(3), k, dist)
    return img.reshape(-1, 2)


@dataclass(frozen=True)
class ProjectionUncertainty:
    """One-sigma projection uncertainty across the image.

    Attributes
    ----------
    grid_px : ndarray (M, 2)
        Pixels where it was evaluated.
    sigma_px : ndarray (M,)
        Worst-direction standard deviation of the projected pixel, px.
    distance_mm : float
        Range of the 3-D points (by default the median distance to the middle of the
        corners each view saw: independent of where the board's origin is); inf for
        directions (points at infinity).
    total_px : ndarray (M,) or None
        RMS length of the 2-D pixel error (square root of the covariance's trace), px.
    """

    grid_px: np.ndarray
    grid_shape: tuple[int, int]
    sigma_px: np.ndarray
    distance_mm: float
    image_size_px: tuple[int, int]
    total_px: np.ndarray | None = None

    @property
    def median_px(self) -> float:
        return float(np.median(self.sigma_px))

    @property
    def p95_px(self) -> float:
        return float(np.percentile(self.sigma_px, 95))

    @property
    def max_px(self) -> float:
        return float(np.max(self.sigma_px))

    @property
    def centre_px(self) -> float:
        w, h = self.image_size_px
        d = np.linalg.norm(self.grid_px - [(w - 1) / 2, (h - 1) / 2], axis=1)
        return float(self.sigma_px[np.argmin(d)])

    @property
    def central_p95_px(self) -> float:
        mask = _central_mask(self.grid_px, self.image_size_px)
        return float(np.percentile(self.sigma_px[mask], 95))

    def to_dict(self, *, with_grid: bool = True) -> dict[str, Any]:
        out: dict[str, Any] = {
            "what": "1-sigma worst-direction pixel uncertainty of a projected point, "
            "from the corners' errors (with calibrate's covariance, including errors shared "
            "within a view; not a bias every view shares)",
            "distance_mm": self.distance_mm,
            "centre_px": self.centre_px,
            "median_px": self.median_px,
            "central_60pct_p95_px": self.central_p95_px,
            "p95_px": self.p95_px,
            "max_px": self.max_px,
        }
        if with_grid:
            out["grid_shape"] = list(self.grid_shape)
            out["sigma_px_grid"] = np.round(
                self.sigma_px.reshape(self.grid_shape[1], self.grid_shape[0]), 4
            ).tolist()
        return out


def projection_uncertainty(
    result: CalibrationResult,
    *,
    grid: tuple[int, int] = (24, 16),
    distance_mm: float | None = None,
    covariance: ParameterCovariance | None = None,
    at_infinity: bool = False,
    fit_rotation: bool = False,
) -> ProjectionUncertainty:
    """Projection uncertainty across the image (mrcal-style, "mean-pcam").

    For each grid pixel the point at ``distance_mm`` along its ray is expressed
    in every view's board frame; a perturbed solution maps it back through each
    perturbed pose, averages, and projects with the perturbed intrinsics. The
    gradient of that pixel with respect to all parameters, with the parameter
    covariance, gives the 2x2 pixel covariance; its worst-direction sigma is
    reported. ``at_infinity`` propagates directions instead (mrcal's "at infinity":
    poses rotate them, their translations drop out): the uncertainty of where a far
    point lands, the one to compare with a projection diff at infinity, as
    :func:`cross_validate` does. At the boards' range a focal-length error is largely
    offset by the poses' distances; at infinity it is not. ``fit_rotation`` (with
    ``at_infinity``) leaves out what a rotation fitted over the central 60 % absorbs,
    as :func:`projection_diff` does: the frame's orientation is not a property of the lens.
    """
    cov = covariance or parameter_covariance(result)
    cam = result.camera
    n_i = cov.n_intrinsics
    n_v = len(result.views)
    if distance_mm is None:
        # the distance to the middle of the corners each view saw, not to the board's
        # origin corner: the same physical board described transposed gives the same range
        centres = []
        for view, det in zip(result.views, result.detections, strict=True):
            rot, _ = cv2.Rodrigues(view.rvec)
            middle = np.asarray(det.object_mm, dtype=np.float64).reshape(-1, 3).mean(axis=0)
            centres.append(float(np.linalg.norm(rot @ middle + view.tvec_mm)))
        distance_mm = float(np.median(centres))
    pts_px = image_grid_px(cam.image_size_px, grid)
    rays = np.column_stack((cam.normalized(pts_px), np.ones(len(pts_px))))
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    p_cam = rays * distance_mm
    board_pts = np.empty((n_v, len(p_cam), 3))
    params = np.concatenate(
        [[cam.fx, cam.fy, *cam.principal_point_px], cam.dist_coeffs[: n_i - 4]]
        + [np.concatenate([v.rvec, v.tvec_mm]) for v in result.views]
    )
    for v, view in enumerate(result.views):
        rot, _ = cv2.Rodrigues(view.rvec)
        board_pts[v] = (rays if at_infinity else p_cam - view.tvec_mm) @ rot  # R^T (p - t)
    grad = np.empty((len(p_cam), 2, params.size))
    sd = np.sqrt(np.clip(np.diag(cov.covariance), 1e-30, None))
    for j in range(params.size):
        h = sd[j] * 1e-2
        up = params.copy()
        dn = params.copy()
        up[j] += h
        dn[j] -= h
        grad[:, :, j] = (
            _mean_pcam_projection(up, cam, n_i, n_v, board_pts, at_infinity)
            - _mean_pcam_projection(dn, cam, n_i, n_v, board_pts, at_infinity)
        ) / (2 * h)
    if fit_rotation:
        if not at_infinity:
            raise ValueError("fit_rotation needs at_infinity")
        grad = _without_fitted_rotation(cam, rays, pts_px, grad)
    var_q = np.einsum("mij,jk,mlk->mil", grad, cov.covariance, grad)
    worst = np.sqrt(np.clip(np.linalg.eigvalsh(var_q)[:, -1], 0.0, None))
    total = np.sqrt(np.clip(np.trace(var_q, axis1=1, axis2=2), 0.0, None))
    return ProjectionUncertainty(
        pts_px,
        tuple(grid),
        worst,
        float("inf") if at_infinity else float(distance_mm),
        cam.image_size_px,
        total,
    )


def _without_fitted_rotation(
    camera: CameraModel, rays: np.ndarray, pts_px: np.ndarray, grad: np.ndarray
) -> np.ndarray:
    """The (M, 2, P) gradient of projected rays less what a least-squares rotation over the
    central 60 % (linearised :func:`projection_diff`) takes out of it."""
    h = 1e-6
    jr = np.stack(
        [
            (_project_rays(camera, rays, h * e) - _project_rays(camera, rays, -h * e)) / (2 * h)
            for e in np.eye(3)
        ],
        axis=-1,
    )  # (M, 2, 3)
    mask = _central_mask(pts_px, camera.image_size_px)
    jc = jr[mask].reshape(-1, 3)
    gc = grad[mask].reshape(-1, grad.shape[2])
    theta = np.linalg.lstsq(jc, gc, rcond=None)[0]  # (3, P): rotation each parameter implies
    return grad - np.einsum("mik,kp->mip", jr, theta)


@dataclass(frozen=True)
class ProjectionDiff:
    """Where two camera models send the same ray apart, across the image, px."""

    grid_px: np.ndarray
    grid_shape: tuple[int, int]
    diff_px: np.ndarray
    image_size_px: tuple[int, int]
    rotation_deg: float

    @property
    def rms_px(self) -> float:
        return float(np.sqrt(np.mean(self.diff_px**2)))

    @property
    def central_rms_px(self) -> float:
        mask = _central_mask(self.grid_px, self.image_size_px)
        return float(np.sqrt(np.mean(self.diff_px[mask] ** 2)))

    @property
    def p95_px(self) -> float:
        return float(np.percentile(self.diff_px, 95))

    @property
    def max_px(self) -> float:
        return float(np.max(self.diff_px))

    def to_dict(self, *, with_grid: bool = False) -> dict[str, Any]:
        out: dict[str, Any] = {
            "central_60pct_rms_px": self.central_rms_px,
            "rms_px": self.rms_px,
            "p95_px": self.p95_px,
            "max_px": self.max_px,
            "fitted_rotation_deg": self.rotation_deg,
        }
        if with_grid:
            out["grid_shape"] = list(self.grid_shape)
            out["diff_px_grid"] = np.round(
                self.diff_px.reshape(self.grid_shape[1], self.grid_shape[0]), 4
            ).tolist()
        return out


def _project_rays(camera: CameraModel, rays: np.ndarray, rvec: np.ndarray) -> np.ndarray:
    img, _ = cv2.projectPoints(
        rays.reshape(-1, 1, 3), rvec, np.zeros(3), camera.camera_matrix, camera.dist_coeffs
    )
    return img.reshape(-1, 2)


def projection_diff(
    camera_a: CameraModel,
    camera_b: CameraModel,
    *,
    grid: tuple[int, int] = (24, 16),
    fit_rotation: bool = True,
) -> ProjectionDiff:
    """Pixel distance between where A and B project the same ray (at infinity).

    Each grid pixel is unprojected with A and projected with B. With
    ``fit_rotation`` the rotation of B's frame that best aligns the two over
    the central 60 % of the image is removed first (the frame of a camera is
    only known up to what its poses absorb; mrcal's "implied transform").
    """
    if tuple(camera_a.image_size_px) != tuple(camera_b.image_size_px):
        raise ValueError("the two camera models have different image sizes")
    pts = image_grid_px(camera_a.image_size_px, grid)
    rays = np.column_stack((camera_a.normalized(pts), np.ones(len(pts))))
    rvec = np.zeros(3)
    if fit_rotation:
        mask = _central_mask(pts, camera_a.image_size_px)

        def resid(rv: np.ndarray) -> np.ndarray:
            return (_project_rays(camera_b, rays[mask], rv) - pts[mask]).ravel()

        rvec = least_squares(resid, np.zeros(3), x_scale=1e-3).x
    diff = np.linalg.norm(_project_rays(camera_b, rays, rvec) - pts, axis=1)
    return ProjectionDiff(
        pts, tuple(grid), diff, camera_a.image_size_px, float(np.degrees(np.linalg.norm(rvec)))
    )


@dataclass(frozen=True)
class CrossValidation:
    """Two independent calibrations from the even and odd views, compared."""

    diff: ProjectionDiff
    views: tuple[int, int]
    focal_px: tuple[float, float]
    expected_px: float
    ratio: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "what": "even/odd halves calibrated separately; projection difference "
            "after the best-fit rotation (mrcal-style)",
            "views": list(self.views),
            "fx_px": list(self.focal_px),
            **self.diff.to_dict(),
            "expected_from_uncertainty_px": self.expected_px,
            "ratio_to_expected": self.ratio,
        }


def cross_validate(
    detections: Sequence[BoardDetection],
    image_size_px: tuple[int, int],
    *,
    model: str = "5",
    grid: tuple[int, int] = (24, 16),
    board_warp: bool = False,
    board_extent_mm: tuple[tuple[float, float], tuple[float, float]] | None = None,
) -> CrossValidation | None:
    """Calibrate even and odd views separately and compare them (each half with a board
    warp relative to ``board_extent_mm`` when ``board_warp``).

    Returns None when either half has fewer than 3 usable views. ``ratio`` is
    the central-60 % RMS diff over the combined central projection uncertainty
    of the halves; ~1-2 is what noise explains, far above means model error.
    """
    usable = [d for d in detections if d.ok]
    halves = (usable[0::2], usable[1::2])
    if min(len(h) for h in halves) < 3:
        return None
    try:
        res = [
            calibrate_views(
                h,
                image_size_px,
                model=model,  # type: ignore[arg-type]
                board_warp=board_warp,
                board_extent_mm=board_extent_mm,
            )
            for h in halves
        ]
    except InputError:
        return None
    diff = projection_diff(res[0].camera, res[1].camera, grid=grid, fit_rotation=True)
    # the diff is at infinity after a fitted rotation: so is the expectation (at the
    # boards' range it was 5x too small on renders whose lens is exactly the fitted model,
    # at infinity with the rotation 3x too large), and it is the RMS length of a 2-D error
    # (trace), not the worst direction
    unc = [projection_uncertainty(r, grid=grid, at_infinity=True, fit_rotation=True) for r in res]
    mask = _central_mask(diff.grid_px, diff.image_size_px)
    expected = float(
        np.sqrt(np.mean(unc[0].total_px[mask] ** 2) + np.mean(unc[1].total_px[mask] ** 2))
    )
    ratio = diff.central_rms_px / expected if expected > 0 else float("inf")
    return CrossValidation(
        diff,
        (len(res[0].views), len(res[1].views)),
        (res[0].camera.fx, res[1].camera.fx),
        expected,
        float(ratio),
    )
