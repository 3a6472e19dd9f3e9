"""The part stage's demo step: the seed's half circle against its design."""

from __future__ import annotations

import json
from pathlib import Path

from cvmeasure_datasets.demo.part import demo_step


def test_demo_step_meets_its_tolerances(tmp_path):
    section = demo_step(tmp_path, seed=7)
    checked = [row for row in section.rows if row.tolerance is not None]
    assert len(checked) >= 5
    failed = [(r.quantity, r.measured, r.true) for r in checked if not r.ok]
    assert not failed
    names = {Path(f).name for f in section.files}
    assert {"half-circle.json", "half-circle-overlay.png", "half-circle-deviation.png"} <= names
    result = json.loads((tmp_path / "part" / "half-circle.json").read_text())
    assert result["divisions"] == 20 and len(result["vertex_bend_deg"]) == 19
    # the seed's methods are reported beside ours, without a tolerance
    seed_rows = [r for r in section.rows if "seed" in r.quantity and "radius" in r.quantity]
    assert len(seed_rows) == 2 and all(r.tolerance is None for r in seed_rows)
