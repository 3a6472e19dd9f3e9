import numpy as np
import pytest

from cvmeasure.board import CharucoBoardSpec, ChessboardSpec, board_from_dict, load_board
from cvmeasure.errors import InputError


def test_charuco_roundtrip_and_corners():
    spec = board_from_dict(
        {
            "type": "charuco",
            "squares_x": 14,
            "squares_y": 10,
            "square_mm": 20.0,
            "marker_mm": 15.0,
            "dictionary": "DICT_5X5_100",
        }
    )
    assert isinstance(spec, CharucoBoardSpec)
    assert spec.to_dict()["type"] == "charuco"
    corners = spec.corners_mm()
    assert corners.shape == (13 * 9, 3)
    np.testing.assert_allclose(corners[0], [20.0, 20.0, 0.0])
    np.testing.assert_allclose(corners[1], [40.0, 20.0, 0.0])


def test_chessboard_corners_follow_board_frame():
    spec = board_from_dict({"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_mm": 25.0})
    assert isinstance(spec, ChessboardSpec)
    c = spec.corners_mm()
    assert c.shape == (54, 3)
    np.testing.assert_allclose(c[0], [25, 25, 0])
    np.testing.assert_allclose(c[9], [25, 50, 0])


@pytest.mark.parametrize(
    "data, message",
    [
        ({"type": "circles"}, "board type"),
        ({"type": "charuco", "squares_x": 5}, "lacks"),
        (
            {"type": "charuco", "squares_x": 5, "squares_y": 7, "square_mm": 40, "marker_mm": 50},
            "marker_mm",
        ),
        (
            {
                "type": "charuco",
                "squares_x": 5,
                "squares_y": 7,
                "square_mm": 40,
                "marker_mm": 20,
                "dictionary": "DICT_NOPE",
            },
            "dictionary",
        ),
    ],
)
def test_bad_board_json(tmp_path, data, message):
    import json

    p = tmp_path / "board.json"
    p.write_text(json.dumps(data))
    with pytest.raises(InputError, match=message):
        load_board(p)
