"""The calibration stage of ``cvmeasure demo`` meets its own tolerances."""

from __future__ import annotations

import json

from cvmeasure.camera_model import load_camera
from cvmeasure_datasets.demo.calibration import demo_step


def test_demo_step_meets_its_tolerances(tmp_path):
    section = demo_step(tmp_path, seed=7)
    rows = {r.quantity: r for r in section.rows}
    assert {"focal length fx", "principal point cx", "plane tilt (one photo)"} <= set(rows)
    failed = [r.quantity for r in section.rows if r.ok is False]
    assert not failed, failed
    assert abs(rows["focal length fx"].error) <= 1e-3 * rows["focal length fx"].true
    assert abs(rows["plane tilt (one photo)"].error) <= 0.05
    cam = load_camera(tmp_path / "calibration" / "camera.json")
    assert cam.lens_record["cross_validation"] is not None
    assert json.loads((tmp_path / "calibration" / "plane.json").read_text())["tilt_deg"] > 2.9
