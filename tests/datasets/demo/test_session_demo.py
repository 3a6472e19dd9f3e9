"""The calibration-session demo step: a 6-bend session on the double, every row within tolerance."""

from __future__ import annotations

from pathlib import Path


def test_demo_step_meets_its_tolerances(tmp_path):
    from cvmeasure_datasets.demo import DEMO_STAGES
    from cvmeasure_datasets.demo.session import demo_step

    assert ("calibration session", demo_step) in DEMO_STAGES
    section = demo_step(tmp_path, seed=3)
    assert len(section.rows) == 3 and all(row.ok for row in section.rows)
    assert all(Path(f).exists() for f in section.files)
    assert "8." in section.notes[1]  # the uncalibrated half circle shows the backlash
