"""A small, exact board renderer for calibration tests (pinhole + OpenCV distortion).

Every output pixel is traced back: distorted pixel -> undistorted ray -> board
plane -> board texture (rendered by OpenCV at ``texture_px_per_mm``), with
supersampling for anti-aliasing. Ground truth is the camera and pose passed in.
"""

from __future__ import annotations

import cv2
import numpy as np

from cvmeasure.board import CharucoBoardSpec, ChessboardSpec
from cvmeasure.camera_model import CameraModel

__all__ = ["board_texture", "render_view", "look_at_pose", "random_poses", "synthetic_detections"]


def board_texture(board, px_per_mm: float) -> np.ndarray:
    """The board's printed face, uint8, 1 texture px = 1 / px_per_mm mm, with a white margin."""
    w_mm, h_mm = board.size_mm
    if isinstance(board, CharucoBoardSpec):
        size = (round(w_mm * px_per_mm), round(h_mm * px_per_mm))
        return board.cv_board().generateImage(size, marginSize=0, borderBits=1)
    assert isinstance(board, ChessboardSpec)
    sq = board.square_mm * px_per_mm
    ys, xs = np.mgrid[0 : round(h_mm * px_per_mm), 0 : round(w_mm * px_per_mm)]
    return np.where(((xs // sq).astype(int) + (ys // sq).astype(int)) % 2 == 0, 0, 255).astype(
        np.uint8
    )


def render_view(
    board,
    camera: CameraModel,
    rvec: np.ndarray,
    tvec_mm: np.ndarray,
    *,
    supersample: int = 2,
    noise_sigma: float = 0.0,
    seed: int = 0,
    texture_px_per_mm: float = 8.0,
) -> np.ndarray:
    """Render the board seen by ``camera`` at pose (rvec, tvec: camera <- board); grey uint8."""
    w, h = camera.image_size_px
    tex = board_texture(board, texture_px_per_mm)
    s = supersample
    step = 4  # the ray map is smooth: trace a coarse grid, interpolate the rest
    gw, gh = w * s // step + 2, h * s // step + 2
    us, vs = np.meshgrid(
        (np.arange(gw) * step + 0.5) / s - 0.5, (np.arange(gh) * step + 0.5) / s - 0.5
    )
    pix = np.column_stack((us.ravel(), vs.ravel())).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 30, 1e-10)
    norm = cv2.undistortPoints(
        pix, camera.camera_matrix, camera.dist_coeffs, criteria=crit
    ).reshape(-1, 2)
    rot, _ = cv2.Rodrigues(np.asarray(rvec, dtype=np.float64))
    t = np.asarray(tvec_mm, dtype=np.float64).ravel()
    # Ray d = (x, y, 1); board point X = R^T (l d - t) with z = 0 -> solve l.
    rt = rot.T
    d = np.column_stack((norm, np.ones(len(norm))))
    lam = (rt[2] @ t) / (d @ rt[2])
    pts = (lam[:, None] * d - t) @ rt.T
    coarse = np.stack(
        (pts[:, 0] * texture_px_per_mm - 0.5, pts[:, 1] * texture_px_per_mm - 0.5, lam), axis=-1
    ).reshape(gh, gw, 3)
    # Fine sample (i, j) sits at coarse coordinate (i / step, j / step).
    fy, fx = np.mgrid[0 : h * s, 0 : w * s].astype(np.float32) / step
    fine = cv2.remap(coarse.astype(np.float32), fx, fy, cv2.INTER_LINEAR)
    mx, my, lam_f = fine[..., 0], fine[..., 1], fine[..., 2]
    padded = cv2.copyMakeBorder(tex, 40, 40, 40, 40, cv2.BORDER_CONSTANT, value=255)
    img = cv2.remap(
        padded, mx + 40, my + 40, cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=200
    )
    img = img.astype(np.float32)
    img[lam_f <= 0] = 200
    if s > 1:
        img = cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA)
    img = 30 + img * (190 / 255)
    if noise_sigma > 0:
        img = img + np.random.default_rng(seed).normal(0, noise_sigma, img.shape)
    return np.clip(img + 0.5, 0, 255).astype(np.uint8)


def look_at_pose(
    board,
    distance_mm: float,
    tilt_x_deg: float,
    tilt_y_deg: float,
    shift_mm: tuple[float, float] = (0.0, 0.0),
    roll_deg: float = 0.0,
):
    """Pose (rvec, tvec) of a board whose centre sits at ``distance_mm`` on the axis, tilted."""
    w_mm, h_mm = board.size_mm
    rx, _ = cv2.Rodrigues(np.array([np.radians(tilt_x_deg), 0, 0]))
    ry, _ = cv2.Rodrigues(np.array([0, np.radians(tilt_y_deg), 0]))
    rz, _ = cv2.Rodrigues(np.array([0, 0, np.radians(roll_deg)]))
    rot = rz @ ry @ rx
    centre = np.array([w_mm / 2, h_mm / 2, 0.0])
    t = np.array([shift_mm[0], shift_mm[1], distance_mm]) - rot @ centre
    rvec, _ = cv2.Rodrigues(rot)
    return rvec.ravel(), t


def random_poses(
    board,
    n: int,
    seed: int,
    *,
    distance_mm: float,
    max_tilt_deg: float = 40.0,
    shift_frac: float = 0.25,
):
    """``n`` varied poses (rvec, tvec) with seeded tilts, rolls and shifts."""
    rng = np.random.default_rng(seed)
    w_mm, h_mm = board.size_mm
    out = []
    for _ in range(n):
        tx, ty = rng.uniform(-max_tilt_deg, max_tilt_deg, 2)
        sx, sy = rng.uniform(-shift_frac, shift_frac, 2) * np.array([w_mm, h_mm])
        out.append(
            look_at_pose(
                board, distance_mm * rng.uniform(0.85, 1.15), tx, ty, (sx, sy), rng.uniform(-20, 20)
            )
        )
    return out


def synthetic_detections(board, camera: CameraModel, poses, noise_px: float, rng, *, size=None):
    """Exact corner projections plus Gaussian noise, as BoardDetection objects (no rendering)."""
    from cvmeasure.lens.detect import BoardDetection

    obj = board.corners_mm()
    ids = np.arange(len(obj))
    out = []
    for k, (rvec, tvec) in enumerate(poses):
        proj, _ = cv2.projectPoints(obj, rvec, tvec, camera.camera_matrix, camera.dist_coeffs)
        pts = proj.reshape(-1, 2) + rng.normal(0.0, noise_px, (len(obj), 2))
        out.append(
            BoardDetection(f"view{k:02d}", size or camera.image_size_px, pts, ids, obj.copy())
        )
    return out
