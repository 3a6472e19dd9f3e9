"""Wire segmentation on synthetic images: dark and light sheets, spurs, broad strips."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cvmeasure.part.segment import gray_float, longest_skeleton_path, segment_wire


def _scene(sheet: str, *, strip: bool = False, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """A 3 px wide arc of a wire on a sheet (and optionally a broad dark strip)."""
    rng = np.random.default_rng(seed)
    level = 210 if sheet == "light" else 40
    img = np.full((300, 400), level, dtype=np.float64)
    if strip:  # a 25 px gap between board and sheet: broader than any wire
        img[:, 20:45] = 90
    t = np.radians(np.linspace(200, 340, 400))
    axis = np.column_stack((200 + 150 * np.cos(t), 250 + 150 * np.sin(t)))
    wire = np.zeros_like(img, dtype=np.uint8)
    cv2.polylines(wire, [np.round(axis * 16).astype(np.int32)], False, 255, 3, cv2.LINE_AA, 4)
    alpha = wire / 255.0
    img = img * (1 - alpha) + 150.0 * alpha  # steel grey: darker than light, brighter than dark
    img += rng.normal(0, 1.5, img.shape)
    bgr = cv2.cvtColor(np.clip(img, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)
    return bgr, axis


@pytest.mark.parametrize("sheet", ["dark", "light"])
def test_wire_found_on_both_sheets(sheet):
    bgr, axis = _scene(sheet, strip=True)
    wm = segment_wire(bgr, max_wire_width_px=10, min_length_px=40)
    assert wm is not None
    assert wm.sheet == sheet
    assert 2.0 < wm.width_px < 8.0  # rough: the anti-aliased fringe counts
    # the path runs along the arc, end to end, not along the broad strip
    d = np.min(np.hypot(*(wm.path_px[:, None, :] - axis[None]).transpose(2, 0, 1)), axis=1)
    assert np.max(d) < 2.0
    length = np.sum(np.hypot(*np.diff(axis, axis=0).T))
    assert wm.length_px == pytest.approx(length, rel=0.08)  # pixel staircase: a little long
    assert wm.to_dict()["area_px"] == int(wm.mask.sum())


def test_nothing_thin_means_no_wire():
    bgr = np.full((200, 300, 3), 200, dtype=np.uint8)
    bgr[:, :150] = 60  # a step edge, no line
    assert segment_wire(bgr, max_wire_width_px=10, min_length_px=40) is None


def test_excluded_pixels_are_not_searched():
    bgr, _ = _scene("dark")
    exclude = np.ones(bgr.shape[:2], dtype=bool)
    assert segment_wire(bgr, exclude=exclude, max_wire_width_px=10, min_length_px=40) is None


def test_longest_path_drops_spurs():
    skel = np.zeros((50, 80), dtype=bool)
    skel[25, 5:75] = True  # the wire
    skel[10:25, 40] = True  # a spur
    path = longest_skeleton_path(skel)
    assert {tuple(path[0]), tuple(path[-1])} == {(5.0, 25.0), (74.0, 25.0)}
    assert len(path) == 70


def test_gray_float_scales_16_bit():
    img16 = np.full((4, 4, 3), 65535, dtype=np.uint16)
    assert np.allclose(gray_float(img16), 255.0)


def test_grainy_margin_around_the_board_is_not_the_wire():
    """A bright, grainy sheet margin around the left-out board (its speckle has a long
    skeleton) is no wire: filled it is far wider than one; the thin arc is chosen."""
    rng = np.random.default_rng(3)
    bgr, axis = _scene("dark", seed=1)
    below = 40.0 + rng.normal(0, 1.5, (160, 400))  # more of the dark sheet, for the board
    gray = np.vstack((bgr[..., 0].astype(np.float64), below))
    gray[320:450, 20:380] = 200.0 + rng.normal(0, 10.0, (130, 360))  # the board's grainy sheet
    exclude = np.zeros(gray.shape, dtype=bool)
    exclude[340:430, 40:360] = True  # the board itself, left out; its margin is not
    bgr = cv2.cvtColor(np.clip(gray, 0, 255).astype(np.uint8), cv2.COLOR_GRAY2BGR)
    wm = segment_wire(bgr, exclude=exclude, max_wire_width_px=10, min_length_px=40)
    assert wm is not None
    d = np.min(np.hypot(*(wm.path_px[:, None, :] - axis[None]).transpose(2, 0, 1)), axis=1)
    assert np.max(d) < 2.0
