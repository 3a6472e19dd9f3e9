"""Printable boards: exact scale, the right layout, the CLI."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest

from cvmeasure.board import board_from_dict
from cvmeasure.cli import main
from cvmeasure.lens.detect import detect_board
from cvmeasure_calib_targets.charuco import (
    board_black_rects_mm,
    render_board_sheet,
    sheet_layout,
    write_board_sheet,
)

CORNER_ATOL_PX = 0.25  # rendered at 100-200 dpi; measured error ~0.1 px

BOARD = {
    "type": "charuco",
    "squares_x": 7,
    "squares_y": 5,
    "square_mm": 20.0,
    "marker_mm": 15.0,
    "dictionary": "DICT_5X5_100",
}


@pytest.mark.parametrize("dpi", [100.0, 150.0])
def test_png_corners_sit_at_exact_scale(dpi):
    board = board_from_dict(BOARD)
    img = cv2.imdecode(np.frombuffer(render_board_sheet(board, "png", dpi=dpi), np.uint8), 0)
    det = detect_board(img, board)
    assert det.corner_count == board.corner_count
    px_per_mm = dpi / 25.4
    origin = np.asarray(sheet_layout(board).board_origin_mm)
    expected = (det.object_mm[:, :2] + origin) * px_per_mm - 0.5
    assert np.max(np.abs(det.corners_px - expected)) < CORNER_ATOL_PX
    # Corner spacing = square_mm at that dpi.
    grid = det.corners_px[np.argsort(det.ids)].reshape(4, 6, 2)
    spacing = np.linalg.norm(np.diff(grid, axis=1), axis=2)
    assert np.mean(spacing) == pytest.approx(20.0 * px_per_mm, rel=2e-3)


def test_legacy_layout_sheet_detects_only_as_legacy():
    spec = dict(BOARD, squares_y=6, legacy_pattern=True)
    board = board_from_dict(spec)
    img = cv2.imdecode(np.frombuffer(render_board_sheet(board, "png", dpi=100), np.uint8), 0)
    det = detect_board(img, board)
    assert det.ok and det.legacy_pattern is True and not det.notes
    wrong = board_from_dict(dict(BOARD, squares_y=6))  # JSON says new layout
    det2 = detect_board(img, wrong)
    assert det2.ok and det2.legacy_pattern is True
    assert "legacy_pattern" in det2.notes[0]


def test_chessboard_sheet():
    board = board_from_dict({"type": "chessboard", "inner_x": 6, "inner_y": 4, "square_mm": 15.0})
    rects = board_black_rects_mm(board)
    assert len(rects) == 18  # half of the 7x5 squares, rounded up
    img = cv2.imdecode(np.frombuffer(render_board_sheet(board, "png", dpi=120), np.uint8), 0)
    det = detect_board(img, board)
    assert det.ok
    origin = np.asarray(sheet_layout(board).board_origin_mm)
    expected = (det.object_mm[:, :2] + origin) * (120 / 25.4) - 0.5
    err = np.linalg.norm(det.corners_px - expected, axis=1)
    flipped = np.linalg.norm(det.corners_px[::-1] - expected, axis=1)  # 180-degree ambiguity
    assert min(err.max(), flipped.max()) < CORNER_ATOL_PX


def test_vector_formats_have_page_size_and_board_json(tmp_path):
    board = board_from_dict(BOARD)
    svg = write_board_sheet(board, tmp_path / "b.svg").read_text()
    w, h = sheet_layout(board).page_mm
    sw, sh = (float(re.search(rf'{k}="([0-9.]+)pt"', svg).group(1)) for k in ("width", "height"))
    assert sw * 25.4 / 72 == pytest.approx(w, abs=0.01)
    assert sh * 25.4 / 72 == pytest.approx(h, abs=0.01)
    assert "DICT_5X5_100" in svg  # the board JSON is on the sheet
    pdf = write_board_sheet(board, tmp_path / "b.pdf").read_bytes()
    assert pdf.startswith(b"%PDF")
    # The PDF MediaBox is the page in points (1 pt = 25.4/72 mm).
    box = pdf.split(b"/MediaBox")[1].split(b"]")[0].strip(b" [").split()
    assert float(box[2]) * 25.4 / 72 == pytest.approx(w, abs=0.01)
    assert float(box[3]) * 25.4 / 72 == pytest.approx(h, abs=0.01)


def test_page_too_small_and_named_pages():
    board = board_from_dict(dict(BOARD, squares_x=14, squares_y=10))  # 280 x 200 mm
    with pytest.raises(ValueError, match="too small"):
        sheet_layout(board, page="a4")
    layout = sheet_layout(board, page="a3")
    assert layout.page_mm == (420.0, 297.0)  # turned to landscape to fit


def test_cli_targets_charuco(tmp_path, capsys):
    bj = tmp_path / "board.json"
    bj.write_text(json.dumps(BOARD))
    out = tmp_path / "board.png"
    assert main(["targets", "charuco", "--board", str(bj), "-o", str(out), "--dpi", "100"]) == 0
    img = cv2.imread(str(out), cv2.IMREAD_GRAYSCALE)
    assert detect_board(img, board_from_dict(BOARD)).corner_count == 24
    assert (
        main(
            [
                "targets",
                "charuco",
                "--board",
                str(bj),
                "-o",
                str(tmp_path / "b.pdf"),
                "--page",
                "a4",
            ]
        )
        == 0
    )
    assert (tmp_path / "b.pdf").read_bytes().startswith(b"%PDF")
    # Bad input: exit 2 and one line naming the file.
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    capsys.readouterr()
    assert main(["targets", "charuco", "--board", str(bad), "-o", str(tmp_path / "x.pdf")]) == 2
    err = capsys.readouterr().err
    assert "bad.json" in err and err.count("\n") == 1
    assert main(["targets", "charuco", "--board", str(bj), "-o", str(tmp_path / "x.gif")]) == 2
    big = tmp_path / "big.json"
    big.write_text(json.dumps(dict(BOARD, square_mm=60.0, marker_mm=45.0)))
    assert (
        main(
            [
                "targets",
                "charuco",
                "--board",
                str(big),
                "-o",
                str(tmp_path / "y.pdf"),
                "--page",
                "a4",
            ]
        )
        == 2
    )
    assert not (tmp_path / "x.pdf").exists() and not (tmp_path / "y.pdf").exists()


def test_cli_targets_markers(capsys, tmp_path):
    assert main(["targets", "markers", "--format", "json"]) == 0
    kit = json.loads(capsys.readouterr().out)
    assert {m["role"] for m in kit["markers"]} == {"origin", "axis", "pin", "wire_a", "wire_b"}
    # The sheet itself comes from cvmeasure_calib_targets.markers through the hook.
    assert main(["targets", "markers", "-o", str(tmp_path / "kit.pdf")]) == 0
    assert (tmp_path / "kit.pdf").read_bytes().startswith(b"%PDF")
    capsys.readouterr()
    assert main(["targets", "markers", "-o", str(tmp_path / "kit.gif")]) == 2
    assert "kit.gif" in capsys.readouterr().err


def test_oversized_boards_and_resolutions_are_refused_before_drawing(tmp_path, capsys):
    from cvmeasure.cli import main

    huge = tmp_path / "huge.json"
    huge.write_text(
        '{"type": "charuco", "squares_x": 5000, "squares_y": 5000, "square_mm": 20,'
        ' "marker_mm": 15, "dictionary": "DICT_5X5_100"}'
    )
    assert main(["targets", "charuco", "--board", str(huge), "-o", str(tmp_path / "b.pdf")]) == 2
    assert "at most 100 a side" in capsys.readouterr().err
    out = str(tmp_path / "b.png")
    assert main(["targets", "charuco", "-o", out, "--dpi", "100000"]) == 2
    assert "--dpi: must be in (0, 1200]" in capsys.readouterr().err
    big = tmp_path / "big.json"
    big.write_text(
        '{"type": "charuco", "squares_x": 100, "squares_y": 70, "square_mm": 20,'
        ' "marker_mm": 15, "dictionary": "DICT_6X6_1000"}'
    )
    assert main(["targets", "charuco", "--board", str(big), "-o", out, "--dpi", "1200"]) == 2
    assert "MP; at most 150 MP" in capsys.readouterr().err
    assert not (tmp_path / "b.png").exists()
