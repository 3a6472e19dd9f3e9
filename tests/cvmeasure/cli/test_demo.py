"""``cvmeasure demo``, the README's first command, run as a user runs it."""

import json
import subprocess
import sys


def test_demo_json_prints_every_section_and_meets_its_tolerances(tmp_path):
    """``--json`` prints the sections (it raised on numpy booleans); every row within tolerance."""
    proc = subprocess.run(
        [sys.executable, "-m", "cvmeasure", "demo", "--json", "-o", str(tmp_path / "out")],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    sections = json.loads(proc.stdout)
    assert len(sections) >= 6
    rows = [row for section in sections for row in section["rows"]]
    assert len(rows) >= 30
    for row in rows:
        if row["ok"] is not None:
            # each row states its own tolerance: |measured - true| within it
            assert row["ok"] is True, row
            assert abs(row["error"]) <= row["tolerance"], row
    written = json.loads((tmp_path / "out" / "demo.json").read_text())
    assert written["sections"] == sections
