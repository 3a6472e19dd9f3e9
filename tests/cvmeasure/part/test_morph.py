"""The local dilations give exactly ``cv2.dilate``'s pixels (random masks, fixed seeds)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cvmeasure.part.morph import dilate_local, dilated_at


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize("size", [3, 9, 21])
def test_dilate_local_equals_full_dilation(seed: int, size: int) -> None:
    rng = np.random.default_rng(seed)
    mask = np.zeros((120, 170), dtype=np.uint8)
    # a thin random stroke that touches an image edge (the clipped box)
    pts = np.cumsum(rng.normal(0, 3, (60, 2)), axis=0) + [5, 60]
    cv2.polylines(mask, [np.round(pts).astype(np.int32)], False, 1, 2)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    assert np.array_equal(dilate_local(mask, kernel), cv2.dilate(mask, kernel))
    as_bool = dilate_local(mask.astype(bool), kernel)
    assert as_bool.dtype == bool
    assert np.array_equal(as_bool, cv2.dilate(mask, kernel).astype(bool))


def test_dilate_local_of_an_empty_mask_is_empty() -> None:
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (7, 7))
    assert not dilate_local(np.zeros((30, 40), dtype=np.uint8), kernel).any()


@pytest.mark.parametrize("seed", [3, 4])
def test_dilated_at_equals_full_dilation_at_points(seed: int) -> None:
    rng = np.random.default_rng(seed)
    mask = np.zeros((200, 300), dtype=np.uint8)
    cv2.fillPoly(mask, [np.array([[40, 30], [180, 50], [150, 160], [60, 140]], np.int32)], 1)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (31, 31))
    full = cv2.dilate(mask, kernel).astype(bool)
    pts = np.column_stack((rng.integers(-5, 305, 400), rng.integers(-5, 205, 400)))
    inside = (pts[:, 0] >= 0) & (pts[:, 0] < 300) & (pts[:, 1] >= 0) & (pts[:, 1] < 200)
    want = np.zeros(len(pts), dtype=bool)
    want[inside] = full[pts[inside, 1], pts[inside, 0]]
    got = dilated_at(mask.astype(bool), kernel, pts)
    assert np.array_equal(got, want)
    assert 20 < want.sum() < 380  # both answers are tested
