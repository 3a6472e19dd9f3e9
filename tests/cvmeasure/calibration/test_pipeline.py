"""The whole calibration from corner sets: invariance, model choice, rejection."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from _calib_synth import random_poses, synthetic_detections

from cvmeasure.board import board_from_dict
from cvmeasure.calibration.pipeline import calibrate_detections


def _printed(report) -> list[str]:
    """The numbers ``cvmeasure calibrate`` prints, at the precision it prints them."""
    s = report.summary()
    cv = report.cross_validation
    out = [f"{s['rms_px']:.4f}", f"{s['corners_used']}", f"{s['views_used']}"]
    out += [f"{s[k]:.3f}" for k in ("fx", "fy", "cx", "cy")]
    out += [f"{v:.3f}" for v in s["std_devs"].values()]
    out += [f"{report.uncertainty.centre_px:.3f}", f"{report.uncertainty.p95_px:.3f}"]
    out += [f"{report.uncertainty.max_px:.3f}", f"{cv.diff.central_rms_px:.3f}", f"{cv.ratio:.1f}"]
    return out


def test_a_board_described_transposed_prints_the_same_numbers(true_camera):
    """inner_x/inner_y swapped: every corner's board coordinates swap and the detector
    lists them in another order; the printed results must not change in any digit."""
    board = board_from_dict({"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_mm": 25.0})
    rng = np.random.default_rng(3)
    dets = synthetic_detections(
        board, true_camera, random_poses(board, 12, 5, distance_mm=500.0), 0.15, rng
    )
    order = np.random.default_rng(1).permutation(dets[0].corner_count)
    swapped = [
        replace(
            d,
            object_mm=d.object_mm[order][:, [1, 0, 2]],
            corners_px=d.corners_px[order],
            ids=d.ids[order],
        )
        for d in dets
    ]
    a = calibrate_detections(dets, true_camera.image_size_px)
    b = calibrate_detections(swapped, true_camera.image_size_px)
    assert _printed(b) == _printed(a)
    assert b.uncertainty.distance_mm == pytest.approx(a.uncertainty.distance_mm, rel=1e-9)
