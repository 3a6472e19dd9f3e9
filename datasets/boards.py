"""Calibration boards (ChArUco and chessboard) as anti-aliased layers, and board views.

The board lies in the plane z = 0 of the board frame (OpenCV's object frame:
origin at the outer top-left chessboard corner, x along ``squares_x``, y along
``squares_y``, mm) on white paper with a one-square margin.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from cvmeasure.board import BoardSpec, CharucoBoardSpec, ChessboardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure_datasets.lighting import Lighting, srgb8_to_linear
from cvmeasure_datasets.optics import Pose, project_frame_points
from cvmeasure_datasets.photo import RenderedPhoto, render_scene, resolve_camera
from cvmeasure_datasets.raster import Layer, Window, box_coverage, sdf_alpha, sdf_rect

__all__ = ["board_layers", "board_truth", "render_board_view", "random_board_poses"]

_PAPER = (238, 238, 234)
_INK = (24, 24, 26)
_TABLE = (92, 88, 84)


def _squares(board: BoardSpec) -> tuple[int, int, float]:
    if isinstance(board, CharucoBoardSpec):
        return board.squares_x, board.squares_y, board.square_mm
    if isinstance(board, ChessboardSpec):
        return board.inner_x + 1, board.inner_y + 1, board.square_mm
    raise TypeError(f"unknown board spec {type(board).__name__}")


def _square_wave(coord_mm: np.ndarray, gx: np.ndarray, gy: np.ndarray, square_mm: float, n: int):
    """Box-filtered +-1 wave, +1 in even squares, with lines only inside the board.

    ``(gx, gy)`` is the pixel gradient of ``coord_mm`` (mm per pixel).
    """
    k = np.clip(np.round(coord_mm / square_mm), 1, n - 1)
    d_px = (coord_mm - k * square_mm) / np.maximum(np.hypot(gx, gy), 1e-12)
    sign = 1.0 - 2.0 * np.mod(k, 2)
    # coverage of the side beyond the line (the square k), mapped to -1..1
    return sign * (2.0 * box_coverage(-d_px, gx, gy) - 1.0)


def _checker_alpha(board: BoardSpec, first_black_parity: int):
    sx, sy, s = _squares(board)
    width, height = sx * s, sy * s
    sigma = 1.0 if first_black_parity == 0 else -1.0

    def alpha(win: Window) -> np.ndarray:
        du_dx, du_dy, dv_dx, dv_dy = win.jacobian()
        su = _square_wave(win.u, du_dx, du_dy, s, sx)
        sv = _square_wave(win.v, dv_dx, dv_dy, s, sy)
        inside = sdf_alpha(sdf_rect(win.u, win.v, (width / 2, height / 2), (width / 2, height / 2)))
        return 0.5 * (1.0 + sigma * su * sv) * inside

    return alpha


def _sharp_index(pos: np.ndarray, cells_per_px: np.ndarray) -> np.ndarray:
    """Sample index along one axis for a box-filtered lookup of unit cells ("sharp bilinear")."""
    j = np.floor(pos - 0.5)
    t = np.clip((pos - (j + 1.0)) / np.maximum(cells_per_px, 1e-9) + 0.5, 0.0, 1.0)
    return j + t


def _marker_alpha(bits_white: np.ndarray, x0_mm: float, y0_mm: float, cell_mm: float):
    """Ink coverage of one ArUco marker whose padded bit grid starts one cell before (x0, y0)."""
    from scipy.ndimage import map_coordinates

    ink = 1.0 - bits_white.astype(np.float64)

    def alpha(win: Window) -> np.ndarray:
        du_dx, du_dy, dv_dx, dv_dy = win.jacobian()
        a = (win.u - x0_mm) / cell_mm + 1.0
        b = (win.v - y0_mm) / cell_mm + 1.0
        ca = _sharp_index(a, np.hypot(du_dx, du_dy) / cell_mm)
        cb = _sharp_index(b, np.hypot(dv_dx, dv_dy) / cell_mm)
        return map_coordinates(ink, [cb, ca], order=1, mode="nearest")

    return alpha


def board_layers(board: BoardSpec) -> list[Layer]:
    """Paper, checker and (for ChArUco) marker layers of a board, in the board frame."""
    import cv2

    sx, sy, s = _squares(board)
    width, height = sx * s, sy * s
    paper = srgb8_to_linear(_PAPER)
    ink = srgb8_to_linear(_INK)
    layers = [
        Layer(
            (-s - 1, -s - 1, width + s + 1, height + s + 1),
            lambda w: sdf_alpha(
                sdf_rect(w.u, w.v, (width / 2, height / 2), (width / 2 + s, height / 2 + s))
            ),
            paper,
        )
    ]
    parity = 0
    markers: list[Layer] = []
    if isinstance(board, CharucoBoardSpec):
        cv_board = board.cv_board()
        dictionary = board.cv_dictionary()
        n = dictionary.markerSize
        obj = cv_board.getObjPoints()
        ids = np.asarray(cv_board.getIds()).ravel()
        first = np.asarray(obj[0]).reshape(-1, 3)[:, :2].mean(axis=0)
        parity = 1 - int(np.floor(first[0] / s) + np.floor(first[1] / s)) % 2
        cell = board.marker_mm / (n + 2)
        for corners, marker_id in zip(obj, ids, strict=True):
            c = np.asarray(corners).reshape(-1, 3)[:, :2]
            x0, y0 = float(c[:, 0].min()), float(c[:, 1].min())
            bits = cv2.aruco.generateImageMarker(dictionary, int(marker_id), n + 2, borderBits=1)
            padded = np.pad(bits > 127, 1, constant_values=True)
            markers.append(
                Layer(
                    (
                        x0 - cell,
                        y0 - cell,
                        x0 + board.marker_mm + cell,
                        y0 + board.marker_mm + cell,
                    ),
                    _marker_alpha(padded, x0, y0, cell),
                    ink,
                )
            )
    layers.append(
        Layer((-1.0, -1.0, width + 1.0, height + 1.0), _checker_alpha(board, parity), ink)
    )
    return layers + markers


def board_truth(
    board: BoardSpec, camera: CameraModel, rot: np.ndarray, t_mm: np.ndarray
) -> dict[str, Any]:
    """Board spec, inner corners in mm and their exact (distorted) image positions."""
    corners_mm = board.corners_mm()
    corners_px = project_frame_points(camera, rot, t_mm, corners_mm)
    w, h = camera.image_size_px
    inside = (
        (corners_px[:, 0] >= 0)
        & (corners_px[:, 0] <= w - 1)
        & (corners_px[:, 1] >= 0)
        & (corners_px[:, 1] <= h - 1)
    )
    return {
        "board": board.to_dict(),
        "corner_ids": list(range(len(corners_mm))),
        "corners_mm": corners_mm.tolist(),
        "corners_px": corners_px.tolist(),
        "corners_in_image": inside.tolist(),
    }


def table_layer() -> Layer:
    """The grey table every board-plane scene (board views, part photos) lies on."""
    return Layer(None, None, srgb8_to_linear(_TABLE))


def render_board_view(
    *,
    board: BoardSpec,
    camera: CameraModel | None = None,
    pose: Pose | None = None,
    lighting: Lighting | None = None,
    seed: int = 0,
    scale: float = 1.0,
    image_size_px: tuple[int, int] | None = None,
    linear: bool = False,
) -> RenderedPhoto:
    """Render a calibration view of ``board``.

    ``pose`` is in the board frame (default: straight on, centred, the board
    filling about 70 % of the width). Truth: camera, pose, board and the exact
    image position (``corners_px``, distorted, OpenCV id order) of every inner
    corner, with ``corners_in_image``.
    """
    cam = resolve_camera(camera, scale, image_size_px)
    sx, sy, s = _squares(board)
    if pose is None:
        dist = cam.fx * sx * s / (0.7 * cam.image_size_px[0])
        pose = Pose(distance_mm=dist, offset_mm=(sx * s / 2, sy * s / 2))
    rot, t_mm = pose.extrinsics("board")
    truth = {"kind": "board_view", **board_truth(board, cam, rot, t_mm)}
    return render_scene(
        [table_layer(), *board_layers(board)],
        frame="board",
        camera=cam,
        pose=pose,
        lighting=lighting,
        seed=seed,
        scale=1.0,
        linear=linear,
        truth=truth,
    )


def random_board_poses(
    n: int,
    seed: int,
    *,
    board: BoardSpec | None = None,
    camera: CameraModel | None = None,
    max_tilt_deg: float = 40.0,
) -> list[Pose]:
    """``n`` varied board poses that make a good calibration set.

    The first view is nearly fronto-parallel; the others are tilted 15 to
    ``max_tilt_deg`` towards evenly spread directions, yawed up to +-25 degrees,
    at distances where the board fills 60-90 % of the image width, and aimed
    off-centre so corners reach the image edges (where distortion shows). Every
    pose keeps the whole board (plus its paper margin) inside the image.
    """
    board = board if board is not None else CharucoBoardSpec(14, 10, 20.0, 15.0)
    cam = camera if camera is not None else resolve_camera(None, 1.0)
    rng = np.random.default_rng([seed, 0xCA1])
    sx, sy, s = _squares(board)
    width, height = sx * s, sy * s
    outline = np.array(
        [
            [-s / 2, -s / 2],
            [width + s / 2, -s / 2],
            [width + s / 2, height + s / 2],
            [-s / 2, height + s / 2],
        ]
    )
    w, h = cam.image_size_px
    margin = 0.02 * w
    poses: list[Pose] = []
    directions = rng.permutation(np.linspace(0.0, 360.0, max(n - 1, 1), endpoint=False))
    attempts = 0
    while len(poses) < n:
        attempts += 1
        if attempts > 200 * n:
            raise RuntimeError("could not place the board in the image; try a smaller board")
        i = len(poses)
        fill = rng.uniform(0.6, 0.9)
        dist = cam.fx * width / (fill * w)
        if i == 0:
            tilt, direction = rng.uniform(0.0, 4.0), rng.uniform(0.0, 360.0)
        else:
            tilt = rng.uniform(15.0, max_tilt_deg)
            direction = directions[(i - 1) % len(directions)] + rng.uniform(-15.0, 15.0)
        offset = (
            width / 2 + rng.uniform(-0.25, 0.25) * width * (1 - fill),
            height / 2 + rng.uniform(-0.25, 0.25) * height * (1 - fill),
        )
        pose = Pose(
            tilt_deg=float(tilt),
            tilt_direction_deg=float(direction),
            yaw_deg=float(rng.uniform(-25.0, 25.0)),
            distance_mm=float(dist),
            offset_mm=offset,
        )
        rot, t_mm = pose.extrinsics("board")
        px = project_frame_points(cam, rot, t_mm, outline)
        if (
            px[:, 0].min() > margin
            and px[:, 1].min() > margin
            and px[:, 0].max() < w - 1 - margin
            and px[:, 1].max() < h - 1 - margin
        ):
            poses.append(pose)
    return poses
