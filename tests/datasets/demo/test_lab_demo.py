"""The photo lab's demo step."""

from __future__ import annotations

import json
from pathlib import Path

from cvmeasure_datasets.demo.lab import demo_step


def test_demo_step_checks_its_photos(tmp_path):
    section = demo_step(tmp_path, seed=3)
    assert section.title == "synthetic photo lab"
    assert section.rows and all(row.ok for row in section.rows), [r.to_dict() for r in section.rows]
    truths = [f for f in section.files if f.endswith(".truth.json")]
    assert len(truths) == 3
    for f in truths:
        assert "camera" in json.loads(Path(f).read_text())
