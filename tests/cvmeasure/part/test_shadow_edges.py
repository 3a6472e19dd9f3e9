"""The shadow profiles read from the samples' box equal those read from the whole image."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cvmeasure.part.shadow_edges import _sample_box


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_remap_in_the_sample_box_equals_remap_on_the_whole_image(seed: int) -> None:
    rng = np.random.default_rng(seed)
    img = rng.uniform(0, 1, (90, 120)).astype(np.float32)
    # samples inside, across an edge and beyond it (read as NaN there either way)
    px = np.column_stack((rng.uniform(-3, 60, 500), rng.uniform(20, 92, 500))).astype(np.float32)
    x0, y0, x1, y1 = _sample_box(px, img.shape)
    assert (x0, y1) == (0, 90) and 0 < y0 and x1 < 120  # clipped where the samples leave
    whole = cv2.remap(
        img, px[:, 0].reshape(20, 25), px[:, 1].reshape(20, 25), cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan,
    )  # fmt: skip
    boxed = cv2.remap(
        img[y0:y1, x0:x1], (px[:, 0] - x0).reshape(20, 25), (px[:, 1] - y0).reshape(20, 25),
        cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=np.nan,
    )  # fmt: skip
    np.testing.assert_array_equal(boxed, whole)
    assert np.isnan(whole).any() and np.isfinite(whole).any()


def test_sample_box_without_finite_samples_is_the_whole_image() -> None:
    assert _sample_box(np.full((4, 2), np.nan), (30, 40)) == (0, 0, 40, 30)
