"""Production tracking: control charts, Cp/Cpk and drift alarms on runs with known truth."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cvmeasure.cli import main
from cvmeasure.part.track import bends_from_records, track_bends

DESIGN = np.array([9.0, 9.0, 3.48, -3.48, 20.0])


def run(parts=30, sigma=0.05, seed=0, drift_from=None, drift_per_part=0.0, shift=0.0):
    rng = np.random.default_rng(seed)
    x = DESIGN + 0.1 + rng.normal(0.0, sigma, (parts, DESIGN.size))
    if drift_from is not None:
        steps = np.clip(np.arange(parts) - drift_from + 1, 0, None)
        x[:, 0] += drift_per_part * steps
        x[drift_from:, 1] += shift
    return x


def test_in_control_run_capability_matches_the_truth():
    x = run(parts=60, seed=1)
    res = track_bends(x, DESIGN)
    for c in res.charts:
        assert c.sigma_deg == pytest.approx(0.05, rel=0.3)
        tol = min(1.0, 0.1 * abs(c.design_deg))
        assert c.tolerance_deg == pytest.approx(tol)
        assert c.cp == pytest.approx(2 * tol / (6 * 0.05), rel=0.3)
        assert c.cpk == pytest.approx((tol - 0.1) / (3 * 0.05), rel=0.3, abs=0.1)
    # the 3.48 deg vertices have a 0.348 deg tolerance: the worst Cpk
    assert res.worst_cpk == pytest.approx(min(c.cpk for c in res.charts[2:4]))
    alarmed = [c.vertex for c in res.charts if any(a["rule"].startswith("WE1") for a in c.alarms)]
    assert len(alarmed) <= 1  # 300 in-control points: ~1 false 3-sigma point expected


def test_drift_and_step_raise_the_alarm_after_they_start():
    x = run(seed=2, drift_from=15, drift_per_part=0.03, shift=0.25)
    res = track_bends(x, DESIGN)
    assert res.alarm
    drift, step = res.charts[0], res.charts[1]
    assert drift.alarms and 15 <= drift.first_alarm_part <= 25
    assert step.alarms and 15 <= step.first_alarm_part <= 22
    assert all(a["side"] == "high" for a in drift.alarms)


def test_too_few_parts_and_bad_shapes():
    with pytest.raises(ValueError, match="at least 3"):
        track_bends(run(parts=2), DESIGN)
    with pytest.raises(ValueError, match="do not fit"):
        track_bends(run(parts=5), DESIGN[:3])


def records(x, design=DESIGN):
    return [
        {
            "photo": f"part_{i:02d}.jpg",
            "comparison": {
                "bends": {"design_bend_deg": design.tolist(), "measured_bend_deg": row.tolist()}
            },
        }
        for i, row in enumerate(x)
    ]


def test_records_and_cli_json(tmp_path, capsys):
    x = run(seed=3, drift_from=10, drift_per_part=0.05)
    recs = records(x) + [{"photo": "machine.jpg", "kind": "machine"}]
    names, design, measured = bends_from_records(recs)
    assert names[0] == "part_00.jpg" and measured.shape == (30, 5)
    path = tmp_path / "results.jsonl"
    path.write_text("".join(json.dumps(r) + "\n" for r in recs))
    svg = tmp_path / "d.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
        'viewBox="0 0 100 100"><polyline points="0,0 20,0 40,5"/></svg>'
    )
    out = tmp_path / "track.json"
    html = tmp_path / "track.html"
    argv = ["track", str(path), "--design", str(svg), "-o", str(out), "--html", str(html)]
    assert main([*argv, "--json"]) == 0
    printed = json.loads(capsys.readouterr().out)
    assert printed["alarm"] and 0 in printed["alarmed_vertices"]
    assert json.loads(out.read_text())["charts"][0]["vertex"] == 0
    assert "<img" in html.read_text()
    # too few parts: exit 2 naming the file
    short = tmp_path / "short.jsonl"
    short.write_text("".join(json.dumps(r) + "\n" for r in records(x[:2])))
    assert main(["track", str(short), "--design", str(svg)]) == 2
    assert "short.jsonl" in capsys.readouterr().err


def test_html_report_has_the_tracking_section():
    from cvmeasure.report.html import build_report

    page = build_report(records(run(seed=4)), thumbnails=False)
    assert "Production tracking" in page and "data:image/png;base64," in page
    assert "Production tracking" not in build_report(records(run(seed=4))[:2], thumbnails=False)
