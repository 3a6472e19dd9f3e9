"""Printable calibration targets at exact physical scale: ChArUco boards and marker-kit sheets."""

from cvmeasure_calib_targets.charuco import (
    PAGE_SIZES_MM,
    SheetLayout,
    board_black_rects_mm,
    render_board_sheet,
    sheet_layout,
    write_board_sheet,
)

__all__ = [
    "PAGE_SIZES_MM",
    "SheetLayout",
    "board_black_rects_mm",
    "render_board_sheet",
    "sheet_layout",
    "write_board_sheet",
]
