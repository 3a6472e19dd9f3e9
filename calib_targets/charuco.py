"""Printable ChArUco boards and chessboards at exact physical scale (PDF, SVG, PNG).

The sheet holds the board, its board JSON (so a photo can always be matched to
the geometry that was printed) and a 100 mm print-check ruler: print at 100 %
("actual size") and check the ruler with a real one before calibrating.

Frames: everything is laid out in mm on the page; the board frame (spec) is the
page frame shifted by :attr:`SheetLayout.board_origin_mm`.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cvmeasure.board import (
    SHEET_FOOTER_MM,
    SHEET_FOOTER_WIDTH_MM,
    SHEET_MARGIN_MM,
    SHEET_RULER_MM,
    BoardSpec,
    CharucoBoardSpec,
    ChessboardSpec,
    printed_footer_mm,
)
from cvmeasure_calib_targets.sheet import SheetFormat, figure_bytes, sheet_format

__all__ = [
    "SheetFormat",
    "SheetLayout",
    "PAGE_SIZES_MM",
    "board_black_rects_mm",
    "sheet_layout",
    "render_board_sheet",
    "write_board_sheet",
]


#: Named paper sizes (portrait width, height) in mm.
PAGE_SIZES_MM: dict[str, tuple[float, float]] = {
    "a4": (210.0, 297.0),
    "a3": (297.0, 420.0),
    "letter": (215.9, 279.4),
    "tabloid": (279.4, 431.8),
}

_INCH_MM = 25.4


def board_black_rects_mm(board: BoardSpec) -> np.ndarray:
    """Every black area of the board as rectangles (M, 4): x, y, width, height in board mm.

    ChArUco: the black chessboard squares plus the black cells of each ArUco
    marker (taken from OpenCV's board object, so legacy layouts come out right).
    Chessboard: the black squares, the outer top-left one black.
    """
    rects: list[tuple[float, float, float, float]] = []
    if isinstance(board, ChessboardSpec):
        s = board.square_mm
        for j in range(board.inner_y + 1):
            for i in range(board.inner_x + 1):
                if (i + j) % 2 == 0:
                    rects.append((i * s, j * s, s, s))
        return np.asarray(rects, dtype=np.float64)
    if not isinstance(board, CharucoBoardSpec):
        raise TypeError(f"unsupported board spec {type(board).__name__}")
    cv_board = board.cv_board()
    dictionary = board.cv_dictionary()
    s = board.square_mm
    obj = [np.asarray(p, dtype=np.float64).reshape(4, 3) for p in cv_board.getObjPoints()]
    ids = np.asarray(cv_board.getIds()).ravel()
    centres = np.array([p[:, :2].mean(axis=0) for p in obj])
    with_marker = {(int(c[0] // s), int(c[1] // s)) for c in centres}
    for j in range(board.squares_y):
        for i in range(board.squares_x):
            if (i, j) not in with_marker:
                rects.append((i * s, j * s, s, s))
    cells = dictionary.markerSize + 2
    for corners, marker_id in zip(obj, ids, strict=True):
        x0, y0 = corners[:, 0].min(), corners[:, 1].min()
        size = corners[:, 0].max() - x0
        cell = size / cells
        bits = dictionary.generateImageMarker(int(marker_id), cells, borderBits=1)
        for r in range(cells):
            c = 0
            while c < cells:  # merge runs of black cells in a row
                if bits[r, c] == 0:
                    start = c
                    while c < cells and bits[r, c] == 0:
                        c += 1
                    rects.append((x0 + start * cell, y0 + r * cell, (c - start) * cell, cell))
                else:
                    c += 1
    return np.asarray(rects, dtype=np.float64)


@dataclass(frozen=True)
class SheetLayout:
    """Where things go on the page, mm from the page's top-left corner."""

    page_mm: tuple[float, float]
    board_origin_mm: tuple[float, float]
    board_size_mm: tuple[float, float]
    ruler_origin_mm: tuple[float, float]
    ruler_mm: float


def sheet_layout(board: BoardSpec, *, page: str | tuple[float, float] | None = None) -> SheetLayout:
    """Lay out board, ruler and text; ``page`` a name of :data:`PAGE_SIZES_MM`, (w, h) mm,
    or None for a page just large enough. Raises ValueError when the board does not fit."""
    bw, bh = board.size_mm
    need_w = max(bw, SHEET_FOOTER_WIDTH_MM) + 2 * SHEET_MARGIN_MM
    need_h = bh + 2 * SHEET_MARGIN_MM + SHEET_FOOTER_MM
    if page is None:
        pw, ph = need_w, need_h
    else:
        if isinstance(page, str):
            if page.lower() not in PAGE_SIZES_MM:
                raise ValueError(f"unknown page {page!r}; choose one of {list(PAGE_SIZES_MM)}")
            pw, ph = PAGE_SIZES_MM[page.lower()]
        else:
            pw, ph = (float(v) for v in page)
        if (need_w > pw or need_h > ph) and need_w <= ph and need_h <= pw:
            pw, ph = ph, pw  # landscape
        if need_w > pw or need_h > ph:
            raise ValueError(
                f"a {bw:g}x{bh:g} mm board needs a {need_w:.0f}x{need_h:.0f} mm page; "
                f"{pw:g}x{ph:g} mm is too small"
            )
    ox = (pw - bw) / 2
    oy = SHEET_MARGIN_MM + max(0.0, (ph - need_h) / 2)
    # under the board's left edge (printed_footer_mm: where the wire search leaves it out),
    # not the page's: on a page wider than needed it would lie beside the board
    ruler = (ox + printed_footer_mm(board)[0], oy + bh + 12.0)
    return SheetLayout((pw, ph), (ox, oy), (bw, bh), ruler, SHEET_RULER_MM)


def render_board_sheet(
    board: BoardSpec,
    fmt: SheetFormat,
    *,
    dpi: float = 300.0,
    page: str | tuple[float, float] | None = None,
) -> bytes:
    """The printable sheet as bytes: board at exact scale, board JSON text, 100 mm ruler.

    Drawn with matplotlib on a figure whose size in inches is the page size, so
    1 mm on the page is 1 mm on paper when printed at 100 %; ``dpi`` sets the
    PNG resolution (and is stored in the PNG).
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure
    from matplotlib.patches import Rectangle

    layout = sheet_layout(board, page=page)
    pw, ph = layout.page_mm
    if fmt == "png":  # whole pixels, or the renderer crops a fraction and shifts everything
        pw = np.ceil(pw * dpi / _INCH_MM - 1e-9) * _INCH_MM / dpi
        ph = np.ceil(ph * dpi / _INCH_MM - 1e-9) * _INCH_MM / dpi
    fig = Figure(figsize=(pw / _INCH_MM, ph / _INCH_MM))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0.0, pw)
    ax.set_ylim(ph, 0.0)
    ax.set_axis_off()
    ox, oy = layout.board_origin_mm
    for x, y, w, h in board_black_rects_mm(board):
        ax.add_patch(
            Rectangle(
                (ox + x, oy + y), w, h, facecolor="black", edgecolor="none", linewidth=0, snap=False
            )
        )
    rx, ry = layout.ruler_origin_mm
    ax.plot([rx, rx + layout.ruler_mm], [ry, ry], color="black", linewidth=0.6)
    for mm in range(int(layout.ruler_mm) + 1):
        tick = 4.0 if mm % 10 == 0 else (2.5 if mm % 5 == 0 else 1.5)
        ax.plot([rx + mm, rx + mm], [ry, ry - tick], color="black", linewidth=0.3)
        if mm % 10 == 0:
            ax.text(rx + mm, ry - 4.8, str(mm), fontsize=5, ha="center", va="bottom")
    ax.text(
        rx + layout.ruler_mm + 3.0,
        ry,
        "mm  print at 100 % (actual size);\nthis ruler must measure 100 mm",
        fontsize=5.5,
        va="center",
    )
    text = json.dumps(board.to_dict(), separators=(", ", ": "))
    ax.text(rx, ry + 6.0, f"board JSON: {text}", fontsize=5.5, va="top", family="monospace")
    w_mm, h_mm = board.size_mm
    ax.text(
        rx,
        ry + 11.0,
        f"board {w_mm:g} x {h_mm:g} mm, square {board.square_mm:g} mm -- cvmeasure targets",
        fontsize=5.5,
        va="top",
    )
    return figure_bytes(fig, fmt, dpi=dpi)


def write_board_sheet(
    board: BoardSpec,
    path: str | os.PathLike[str],
    fmt: SheetFormat | None = None,
    *,
    dpi: float = 300.0,
    page: str | tuple[float, float] | None = None,
) -> Path:
    """Write the sheet atomically; the format comes from ``fmt`` or the file suffix."""
    from cvmeasure.fileio import atomic_write_bytes

    path = Path(path)
    return atomic_write_bytes(
        path, render_board_sheet(board, sheet_format(path, fmt), dpi=dpi, page=page)
    )  # type: ignore[arg-type]
