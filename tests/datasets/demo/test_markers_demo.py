"""The demo step of the bender photos."""

from __future__ import annotations

from pathlib import Path

import pytest

pytest.importorskip("cvmeasure_datasets.bender")


def test_demo_step_measures_the_pair_within_tolerance(tmp_path):
    from cvmeasure_datasets.demo.markers import demo_step

    section = demo_step(tmp_path, seed=7)
    assert [r.quantity for r in section.rows] == [
        "pin angle, loaded",
        "bend angle, loaded",
        "bend angle, unloaded",
        "springback",
    ]
    assert all(r.ok for r in section.rows), [r.to_dict() for r in section.rows]
    assert all(Path(f).is_file() for f in section.files)
    assert any("seed paper's method" in n for n in section.notes)
