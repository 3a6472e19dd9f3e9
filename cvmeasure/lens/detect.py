"""Board corner detection: ChArUco (CharucoDetector) and plain chessboards.

Every detector returns a :class:`BoardDetection` -- a failed detection is a
value with ``ok`` false and a ``reason`` a user can act on, never an exception.
Corners are in image pixels (OpenCV convention, centre of the top-left pixel at
(0, 0)); object points are in the board frame, in mm (spec ``Frames``).

Notes
-----
* ChArUco boards with an even number of rows differ between OpenCV < 4.6
  ("legacy") and later layouts, and the wrong setting finds 0 corners. When
  that happens the other layout is tried and the detection says so.
* Chessboard corners are refined with ``cornerSubPix`` with a half-window of
  about 15 % of the corner spacing: larger windows take in neighbouring edges
  and bias the focal length (an 11x11 half-window on 32 px squares moves f by
  about 7 sigma on OpenCV's own sample set).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from cvmeasure.board import BoardSpec, CharucoBoardSpec, ChessboardSpec

__all__ = [
    "BoardDetection",
    "MIN_CORNERS",
    "detect_board",
    "detect_charuco",
    "detect_chessboard",
    "subpix_half_window_px",
    "verify_chessboard",
]

#: Fewest corners a view needs to be used (a homography needs 4; 6 leaves slack).
MIN_CORNERS = 6

#: Longest image side at which chessboards are searched (larger photos are
#: searched at reduced size, then refined at full size).
_CHESSBOARD_SEARCH_PX = 1600


@dataclass(frozen=True)
class BoardDetection:
    """The board corners found in one photo.

    Attributes
    ----------
    source : str
        The photo (file name) the corners came from.
    image_size_px : (width, height)
    corners_px : ndarray of shape (N, 2), float64
        Sub-pixel corner positions, image pixels.
    ids : ndarray of shape (N,), int
        Corner ids (ChArUco ids; row-major index for chessboards).
    object_mm : ndarray of shape (N, 3), float64
        The same corners in the board frame, mm (z = 0).
    markers_found : int
        ArUco markers seen (ChArUco only; 0 for chessboards).
    legacy_pattern : bool or None
        The ChArUco layout that matched (None for chessboards).
    reason : str
        Empty when ``ok``; otherwise why the photo cannot be used.
    notes : tuple of str
        Things the user should know (e.g. the board JSON has the wrong layout).
    """

    source: str
    image_size_px: tuple[int, int]
    corners_px: np.ndarray
    ids: np.ndarray
    object_mm: np.ndarray
    markers_found: int = 0
    legacy_pattern: bool | None = None
    reason: str = ""
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def ok(self) -> bool:
        return not self.reason

    @property
    def corner_count(self) -> int:
        return int(self.corners_px.shape[0])

    def to_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "image_size": list(self.image_size_px),
            "ok": self.ok,
            "reason": self.reason,
            "corner_count": self.corner_count,
            "markers_found": self.markers_found,
            "legacy_pattern": self.legacy_pattern,
            "notes": list(self.notes),
            "ids": self.ids.tolist(),
            "corners_px": np.round(self.corners_px, 4).tolist(),
        }

    def subset(self, keep: np.ndarray) -> BoardDetection:
        """The same detection with only the corners where ``keep`` is true."""
        keep = np.asarray(keep, dtype=bool)
        return BoardDetection(
            self.source,
            self.image_size_px,
            self.corners_px[keep],
            self.ids[keep],
            self.object_mm[keep],
            self.markers_found,
            self.legacy_pattern,
            self.reason,
            self.notes,
        )


def _empty(source: str, size: tuple[int, int], reason: str, **kw: Any) -> BoardDetection:
    return BoardDetection(
        source,
        size,
        np.zeros((0, 2)),
        np.zeros(0, dtype=int),
        np.zeros((0, 3)),
        reason=reason,
        **kw,
    )


def _as_gray(image: np.ndarray) -> np.ndarray:
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    if img.dtype != np.uint8:
        img = np.clip(img.astype(np.float32) / float(np.iinfo(img.dtype).max) * 255 + 0.5, 0, 255)
        img = img.astype(np.uint8)
    return np.ascontiguousarray(img)


def subpix_half_window_px(corners_px: np.ndarray, grid_shape: tuple[int, int]) -> int:
    """The ``cornerSubPix`` half-window for a corner grid: ~15 % of the spacing, 2..10 px.

    ``grid_shape`` is (columns, rows) of the row-major ``corners_px`` (N, 2).
    """
    nx, ny = grid_shape
    grid = np.asarray(corners_px, dtype=np.float64).reshape(ny, nx, 2)
    dx = np.linalg.norm(np.diff(grid, axis=1), axis=2).ravel()
    dy = np.linalg.norm(np.diff(grid, axis=0), axis=2).ravel()
    spacing = float(np.min([np.median(dx), np.median(dy)]))
    return int(np.clip(np.floor(0.15 * spacing), 2, 10))


#: A chessboard's squares must alternate dark/light in at least this share of squares.
_MIN_PARITY_SHARE = 0.9
#: A plain square's grey levels (10th to 90th percentile of its middle half) span less
#: than this share of the dark/light contrast (a ChArUco marker spans most of it).
_MAX_SQUARE_SPREAD = 0.35
#: Largest departure of a corner from the homography of its 4x4 neighbourhood, as a share
#: of the smallest spacing there (lens distortion bends a grid only slowly: on the
#: real sets at most 0.16, 45 deg tilts included; two corners swapped: 1.1).
_MAX_GRID_BEND = 0.35


def _grid_bend(grid: np.ndarray) -> float:
    """Worst corner offset from the homography of its 4x4 window of a (rows, cols, 2) grid,
    over that window's smallest corner spacing."""
    ny, nx = grid.shape[:2]
    wy, wx = min(4, ny), min(4, nx)
    if wy * wx < 5:
        return 0.0
    ideal = np.array([[i, j] for j in range(wy) for i in range(wx)], dtype=np.float64)
    worst = 0.0
    for y0 in range(ny - wy + 1):
        for x0 in range(nx - wx + 1):
            win = grid[y0 : y0 + wy, x0 : x0 + wx]
            pts = win.reshape(-1, 2)
            hom, _ = cv2.findHomography(ideal, pts, 0)
            if hom is None:
                return float("inf")
            fit = cv2.perspectiveTransform(ideal.reshape(-1, 1, 2), hom).reshape(-1, 2)
            step = min(
                float(np.min(np.linalg.norm(np.diff(win, axis=a), axis=2)))
                if win.shape[a] > 1
                else np.inf
                for a in (0, 1)
            )
            worst = max(worst, float(np.max(np.linalg.norm(fit - pts, axis=1))) / max(step, 1e-9))
    return worst


def verify_chessboard(gray: np.ndarray, corners_px: np.ndarray, grid_shape: tuple[int, int]) -> str:
    """Why these corners are not a plain chessboard's, or "" when they are.

    Checks the geometry (every corner of the row-major (N, 2) ``corners_px`` within
    35 % of the local spacing of the homography of its 4x4 neighbourhood) and the
    squares between the corners (the middle half of each square is plain and the
    squares alternate dark/light, at least 90 % of them plain, so a ChArUco board or a
    pattern with markers in its light squares is not taken for a chessboard).
    ``grid_shape`` is (columns, rows) of inner corners.
    """
    nx, ny = grid_shape
    grid = np.asarray(corners_px, dtype=np.float64).reshape(ny, nx, 2)
    spacing = [np.linalg.norm(np.diff(grid, axis=axis), axis=2) for axis in (0, 1)]
    if _grid_bend(grid) > _MAX_GRID_BEND:
        return "the corners found do not form a regular grid (not this chessboard)"
    if min(float(np.min(s)) for s in spacing) < 2.0:
        return "the corners found are closer than 2 px (not this chessboard)"
    if nx < 2 or ny < 2:
        return ""
    # the middle half of each square between four corners, 5x5 bilinear samples
    uv = np.linspace(0.25, 0.75, 5)
    u, v = np.meshgrid(uv, uv)
    u, v = u.ravel()[None, None, :, None], v.ravel()[None, None, :, None]
    c00, c10 = grid[:-1, :-1, None, :], grid[:-1, 1:, None, :]
    c01, c11 = grid[1:, :-1, None, :], grid[1:, 1:, None, :]
    pts = (1 - u) * (1 - v) * c00 + u * (1 - v) * c10 + (1 - u) * v * c01 + u * v * c11
    h, w = gray.shape
    xs = np.clip(np.rint(pts[..., 0]).astype(int), 0, w - 1)
    ys = np.clip(np.rint(pts[..., 1]).astype(int), 0, h - 1)
    samples = gray[ys, xs].astype(np.float64)  # (ny-1, nx-1, 25)
    means = np.median(samples, axis=2)
    threshold = float(np.median(means))
    parity = (np.add.outer(np.arange(ny - 1), np.arange(nx - 1)) % 2).astype(bool)
    light = means > threshold
    share = max(float(np.mean(light == parity)), float(np.mean(light != parity)))
    contrast = (
        float(np.median(means[light])) - float(np.median(means[~light]))
        if (light.any() and (~light).any())
        else 0.0
    )
    if share < _MIN_PARITY_SHARE or contrast < 10.0:
        return (
            f"the squares between the corners do not alternate dark/light ({100 * share:.0f} % "
            "do): not a plain chessboard"
        )
    spread = np.percentile(samples, 90, axis=2) - np.percentile(samples, 10, axis=2)
    plain = float(np.mean(spread < _MAX_SQUARE_SPREAD * contrast))
    if plain < _MIN_PARITY_SHARE:
        return (
            f"only {100 * plain:.0f} % of the squares between the corners are plain: not a "
            "plain chessboard (a ChArUco board, or another pattern with marks in its squares?)"
        )
    return ""


def detect_chessboard(
    image: np.ndarray, board: ChessboardSpec, *, source: str = "image"
) -> BoardDetection:
    """Find and refine the inner corners of a plain chessboard.

    Parameters
    ----------
    image : ndarray (H, W) or (H, W, 3), uint8 or uint16
    board : ChessboardSpec
    source : str
        Name used in the result and its reasons.
    """
    gray = _as_gray(image)
    h, w = gray.shape
    size = (w, h)
    pattern = (board.inner_x, board.inner_y)
    scale = min(1.0, _CHESSBOARD_SEARCH_PX / max(w, h))
    search = (
        gray
        if scale == 1.0
        else cv2.resize(gray, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    )
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    found, corners = cv2.findChessboardCorners(search, pattern, flags=flags)
    if not found:
        # the fallback finds boards where the classic detector gives up, and also false
        # ones (in a ChArUco board, a pattern of tiles): used only when verified
        found, corners = cv2.findChessboardCornersSB(search, pattern)
    if not found or corners is None:
        return _empty(
            source,
            size,
            f"no {board.inner_x}x{board.inner_y} chessboard found (wrong board, board cut off, or blurred)",
        )
    problem = verify_chessboard(search, corners.reshape(-1, 2), pattern)
    if problem:
        return _empty(
            source, size, f"{board.inner_x}x{board.inner_y} chessboard rejected: {problem}"
        )
    corners = corners.reshape(-1, 2).astype(np.float64)
    if scale != 1.0:
        corners = (corners + 0.5) / scale - 0.5
    half = subpix_half_window_px(corners, pattern)
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 30, 0.01)
    refined = cv2.cornerSubPix(
        gray, corners.astype(np.float32).reshape(-1, 1, 2), (half, half), (-1, -1), crit
    )
    ids = np.arange(board.corner_count)
    return BoardDetection(
        source, size, refined.reshape(-1, 2).astype(np.float64), ids, board.corners_mm()
    )


def _charuco_once(gray: np.ndarray, board: CharucoBoardSpec, legacy: bool):
    cv_board = board.cv_board()
    cv_board.setLegacyPattern(legacy)
    detector = cv2.aruco.CharucoDetector(cv_board)
    ch_corners, ch_ids, _marker_corners, marker_ids = detector.detectBoard(gray)
    n_markers = 0 if marker_ids is None else len(marker_ids)
    if ch_ids is None or len(ch_ids) == 0:
        return None, None, n_markers, marker_ids
    ids = np.asarray(ch_ids, dtype=int).ravel()
    corners = np.asarray(ch_corners, dtype=np.float64).reshape(-1, 2)
    return corners, ids, n_markers, marker_ids


def detect_charuco(
    image: np.ndarray,
    board: CharucoBoardSpec,
    *,
    source: str = "image",
    min_corners: int = MIN_CORNERS,
    try_other_layout: bool = True,
) -> BoardDetection:
    """Find the ChArUco corners of ``board`` (OpenCV 5 ``CharucoDetector``).

    When the board JSON's layout finds markers but no corners and the board
    has an even number of rows, the other (legacy/new) layout is tried; a
    match is used and noted, so a wrong ``legacy_pattern`` never fails silently.
    """
    gray = _as_gray(image)
    h, w = gray.shape
    size = (w, h)
    legacy = bool(board.legacy_pattern)
    corners, ids, n_markers, marker_ids = _charuco_once(gray, board, legacy)
    notes: tuple[str, ...] = ()
    if corners is None and n_markers > 0 and try_other_layout and board.squares_y % 2 == 0:
        corners2, ids2, n2, _ = _charuco_once(gray, board, not legacy)
        if corners2 is not None:
            corners, ids, n_markers, legacy = corners2, ids2, n2, not legacy
            notes = (
                f"the board only matched with legacy_pattern={str(legacy).lower()}: "
                f'set "legacy_pattern": {str(legacy).lower()} in the board JSON',
            )
    if corners is None:
        if n_markers == 0:
            reason = "no ChArUco board found (no ArUco markers of the board's dictionary)"
        else:
            valid = int(np.sum(np.asarray(marker_ids).ravel() < len(board.cv_board().getIds())))
            if valid == 0:
                reason = (
                    f"{n_markers} ArUco markers found but none belongs to this board "
                    "(wrong board, dictionary or size?)"
                )
            else:
                hint = (
                    " (try legacy_pattern)"
                    if board.squares_y % 2 == 0 and not try_other_layout
                    else ""
                )
                reason = (
                    f"{n_markers} markers found but no ChArUco corners could be interpolated{hint}"
                )
        return _empty(source, size, reason, markers_found=n_markers, legacy_pattern=legacy)
    obj = board.corners_mm()[ids]
    det = BoardDetection(source, size, corners, ids, obj, n_markers, legacy, "", notes)
    if det.corner_count < min_corners:
        return BoardDetection(
            source,
            size,
            corners,
            ids,
            obj,
            n_markers,
            legacy,
            f"too few corners ({det.corner_count} < {min_corners})",
            notes,
        )
    return det


def detect_board(
    image: np.ndarray,
    board: BoardSpec,
    *,
    source: str = "image",
    min_corners: int = MIN_CORNERS,
) -> BoardDetection:
    """Detect ``board`` (ChArUco or chessboard) in a photo; see the type-specific functions."""
    if isinstance(board, CharucoBoardSpec):
        return detect_charuco(image, board, source=source, min_corners=min_corners)
    if isinstance(board, ChessboardSpec):
        return detect_chessboard(image, board, source=source)
    raise TypeError(f"unsupported board spec {type(board).__name__}")
