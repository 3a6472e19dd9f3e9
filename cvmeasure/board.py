"""Calibration board specifications (spec ``board JSON``) and their OpenCV objects.

Board frame: OpenCV's object coordinates, origin at the board's outer top-left
chessboard corner, x along ``squares_x``, y along ``squares_y``, z = 0, in mm.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from typing import Any, Literal

import cv2
import numpy as np

from cvmeasure.errors import InputError
from cvmeasure.fileio import read_json

__all__ = [
    "CharucoBoardSpec",
    "ChessboardSpec",
    "BoardSpec",
    "DEFAULT_BOARD",
    "SHEET_MARGIN_MM",
    "SHEET_FOOTER_MM",
    "SHEET_RULER_MM",
    "SHEET_FOOTER_WIDTH_MM",
    "printed_footer_mm",
    "board_from_dict",
    "load_board",
]


@dataclass(frozen=True)
class CharucoBoardSpec:
    """A ChArUco board: squares, sizes in mm, ArUco dictionary name."""

    squares_x: int
    squares_y: int
    square_mm: float
    marker_mm: float
    dictionary: str = "DICT_5X5_100"
    legacy_pattern: bool = False
    type: Literal["charuco"] = "charuco"

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        if not self.legacy_pattern:
            out.pop("legacy_pattern")
        return {"type": out.pop("type"), **out}

    @property
    def corner_count(self) -> int:
        return (self.squares_x - 1) * (self.squares_y - 1)

    @property
    def size_mm(self) -> tuple[float, float]:
        return self.squares_x * self.square_mm, self.squares_y * self.square_mm

    def cv_dictionary(self):
        return cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, self.dictionary))

    def cv_board(self):
        """The ``cv2.aruco.CharucoBoard`` (lengths in mm)."""

        board = cv2.aruco.CharucoBoard(
            (self.squares_x, self.squares_y), self.square_mm, self.marker_mm, self.cv_dictionary()
        )
        board.setLegacyPattern(bool(self.legacy_pattern))
        return board

    def corners_mm(self) -> np.ndarray:
        """Inner chessboard corners (N, 3) in the board frame, in OpenCV's id order."""
        return np.asarray(self.cv_board().getChessboardCorners(), dtype=np.float64).reshape(-1, 3)


@dataclass(frozen=True)
class ChessboardSpec:
    """A plain chessboard, counted by inner corners."""

    inner_x: int
    inner_y: int
    square_mm: float
    type: Literal["chessboard"] = "chessboard"

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        return {"type": out.pop("type"), **out}

    @property
    def corner_count(self) -> int:
        return self.inner_x * self.inner_y

    @property
    def size_mm(self) -> tuple[float, float]:
        return (self.inner_x + 1) * self.square_mm, (self.inner_y + 1) * self.square_mm

    def corners_mm(self) -> np.ndarray:
        """Inner corners (N, 3), row by row as findChessboardCorners orders them.

        Origin here is the first inner corner plus one square, so that the
        board frame matches a ChArUco board's (outer top-left corner at 0).
        """
        xs, ys = np.meshgrid(np.arange(1, self.inner_x + 1), np.arange(1, self.inner_y + 1))
        pts = np.column_stack((xs.ravel(), ys.ravel(), np.zeros(xs.size))) * self.square_mm
        pts[:, 2] = 0.0
        return pts


BoardSpec = CharucoBoardSpec | ChessboardSpec

#: Most squares along one side, and the largest square, a board JSON may describe (a
#: 2 m board of 100 squares; more is a typo, and would take gigabytes to draw).
MAX_SQUARES_PER_SIDE = 100
MAX_SQUARE_MM = 500.0


def _check_size(source: Any, squares: tuple[int, int], square_mm: float) -> None:
    if max(squares) > MAX_SQUARES_PER_SIDE:
        raise InputError(
            source, f"{squares[0]} x {squares[1]} squares: at most {MAX_SQUARES_PER_SIDE} a side"
        )
    if not (0 < square_mm <= MAX_SQUARE_MM) or not math.isfinite(square_mm):
        raise InputError(source, f"square_mm {square_mm:g} must be in (0, {MAX_SQUARE_MM:g}]")


def board_from_dict(data: Any, *, source: str = "board JSON") -> BoardSpec:
    """Validate a board JSON object and build its spec; InputError on schema errors."""
    if not isinstance(data, dict):
        raise InputError(source, "board JSON must be an object")
    kind = data.get("type")
    try:
        if kind == "charuco":
            spec = CharucoBoardSpec(
                squares_x=int(data["squares_x"]),
                squares_y=int(data["squares_y"]),
                square_mm=float(data["square_mm"]),
                marker_mm=float(data["marker_mm"]),
                dictionary=str(data.get("dictionary", "DICT_5X5_100")),
                legacy_pattern=bool(data.get("legacy_pattern", False)),
            )
            if not hasattr(cv2.aruco, spec.dictionary):
                raise InputError(source, f"unknown ArUco dictionary {spec.dictionary!r}")
            if spec.squares_x < 2 or spec.squares_y < 2:
                raise InputError(source, "a ChArUco board needs at least 2x2 squares")
            _check_size(source, (spec.squares_x, spec.squares_y), spec.square_mm)
            if not 0 < spec.marker_mm < spec.square_mm:
                raise InputError(source, "marker_mm must be positive and smaller than square_mm")
            return spec
        if kind == "chessboard":
            spec2 = ChessboardSpec(
                inner_x=int(data["inner_x"]),
                inner_y=int(data["inner_y"]),
                square_mm=float(data["square_mm"]),
            )
            if spec2.inner_x < 2 or spec2.inner_y < 2 or spec2.square_mm <= 0:
                raise InputError(
                    source, "a chessboard needs >= 2x2 inner corners and square_mm > 0"
                )
            _check_size(source, (spec2.inner_x + 1, spec2.inner_y + 1), spec2.square_mm)
            return spec2
    except KeyError as exc:
        raise InputError(source, f"board JSON lacks {exc.args[0]!r}") from None
    except (TypeError, ValueError) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(source, f"board JSON has a malformed value: {exc}") from None
    raise InputError(source, f"board type must be 'charuco' or 'chessboard', got {kind!r}")


def load_board(path: str | os.PathLike[str]) -> BoardSpec:
    """Read a board JSON file (spec)."""
    return board_from_dict(read_json(path, what="board JSON"), source=str(path))


#: The spec's example board (14 x 10 squares of 20 mm, 15 mm markers, DICT_5X5_100;
#: 280 x 200 mm, prints on A3): what ``cvmeasure targets charuco`` draws without ``--board``.
DEFAULT_BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0, "DICT_5X5_100")


#: Blank margin around what ``cvmeasure targets charuco`` prints (mm).
SHEET_MARGIN_MM = 15.0

#: Below the board the printed sheet holds its print-check ruler and the board JSON as
#: text, within this far of the board's lower edge (mm).
SHEET_FOOTER_MM = 42.0

#: Length of the printed print-check ruler (mm).
SHEET_RULER_MM = 100.0

#: Width of the ruler and its caption beside it (mm): the footer is at least this wide.
SHEET_FOOTER_WIDTH_MM = 145.0


def printed_footer_mm(board: BoardSpec) -> tuple[float, float, float, float]:
    """Where the sheet printed by ``cvmeasure targets charuco`` carries its ruler and
    text: (x0, y0, x1, y1) in the board frame, mm.

    The footer starts under the board's left edge (or, on a board narrower than the
    ruler and its caption, centred under it) and runs to the board's right edge or the
    caption's end, whichever is further; the part's wire search leaves it out with the
    board (a ruler 0.2 mm thick with its ticks is a thin line as long as a part).

    Examples
    --------
    >>> printed_footer_mm(DEFAULT_BOARD)
    (0.0, 200.0, 280.0, 242.0)
    """
    w_mm, h_mm = board.size_mm
    needed = SHEET_FOOTER_WIDTH_MM
    x0 = min(0.0, 0.5 * (w_mm - needed))
    return (x0, h_mm, max(w_mm, x0 + needed), h_mm + SHEET_FOOTER_MM)
