"""The streaming demo step: a port loss mid-job, resumed, every row within tolerance."""

from __future__ import annotations

from cvmeasure_datasets.demo.streaming import demo_step


def test_streaming_demo_rows_are_within_tolerance(tmp_path):
    section = demo_step(tmp_path, seed=3)
    checked = [r for r in section.rows if r.tolerance is not None]
    assert len(checked) == 6
    assert all(r.ok for r in checked), [r.to_dict() for r in checked if not r.ok]
    assert (tmp_path / "half_circle.gcode").is_file()
    assert "resumed" in section.notes[0]
