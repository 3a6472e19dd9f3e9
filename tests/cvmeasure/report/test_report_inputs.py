"""``cvmeasure report`` on what a user has: a session log, a calibration JSON, results with
targets; the wrong kind of file refused by naming its kind (issue 42, issue 38)."""

from __future__ import annotations

import json

import html5lib

from cvmeasure.cli import main
from cvmeasure.report import build_report
from cvmeasure.report.html import column_name, verdict


def _session(tmp_path):
    out = tmp_path / "cal.json"
    args = ["session", "--simulate", "-o", str(out), "--angles", "10,30", "--scale", "0.2"]
    assert main([*args, "--quiet", "--json"]) == 0
    return out, tmp_path / "cal_session" / "session.jsonl"


def test_report_of_a_session_log_and_of_its_calibration(tmp_path, capsys):
    cal, log = _session(tmp_path)
    capsys.readouterr()
    page = tmp_path / "log.html"
    assert main(["report", str(log), "-o", str(page), "--quiet"]) == 0
    text = page.read_text()
    html5lib.HTMLParser(strict=True).parse(text)
    assert "photo not found" not in text  # each photo found beside the log
    assert text.count("<img class=thumb") == 8  # 4 bends x loaded, unloaded
    assert "heights_not_applied" in text and "id=warnings" in text  # every photo's warning
    assert "bend angle (deg)" in text and "&plusmn;" in text
    page = tmp_path / "cal.html"
    assert main(["report", str(cal), "-o", str(page), "--quiet"]) == 0
    text = page.read_text()
    assert "Springback curves" in text and "heights_not_applied" in text


def test_report_refuses_a_file_of_another_kind_by_naming_it(tmp_path, capsys):
    camera = tmp_path / "camera.json"
    lens = {"camera_matrix": [[1, 0, 0], [0, 1, 0], [0, 0, 1]], "dist_coeffs": []}
    camera.write_text(json.dumps(lens, indent=2))
    assert main(["report", str(camera), "-o", str(tmp_path / "r.html")]) == 2
    err = capsys.readouterr().err
    assert "camera.json: this is a camera JSON" in err and "not results" in err
    assert not (tmp_path / "r.html").exists()


def test_columns_name_their_units_and_verdicts_weigh_the_uncertainty():
    assert column_name("unloaded_bend_deg") == "unloaded bend, the part's (deg)"
    rec = {
        "trial": "1",
        "target_deg": 90.0,
        "unloaded_bend_deg": 90.3,
        "uncertainty_deg": {"unloaded_bend_deg": 0.05},
    }
    assert verdict(rec, 0.5, None)[0] == "within"  # 0.3 + 2 x 0.05 <= 0.5
    assert verdict(rec, 0.35, None)[0] == "undecided"  # 0.35 lies within 2 sigma of 0.3
    assert verdict(rec, 0.15, None)[0] == "out"  # 0.3 - 0.1 > 0.15
    assert verdict({"comparison": {"deviation": {"max_mm": 1.4}}}, None, 1.0)[0] == "out"
    assert verdict({"pin_angle_deg": 3.0}, 0.5, 1.0) is None
    text = build_report([rec], thumbnails=False, tolerance_deg=0.5)
    assert "90.3000 &plusmn; 0.0500" in text and ">within<" in text
    assert "verdict within" in text


def test_report_refuses_results_whose_last_line_is_cut(tmp_path, capsys):
    whole = '{"photo": "a.jpg", "pin_angle_deg": 1.0}\n'
    cut = tmp_path / "cut.jsonl"
    cut.write_text(whole + '{"photo": "b.jpg", "pin_an')
    page = tmp_path / "cut.html"
    assert main(["report", str(cut), "-o", str(page), "--quiet"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cut.jsonl" in err[0] and "last line is cut" in err[0]
    assert not page.exists()
    # a whole last line without its newline is a complete file, not a cut one
    cut.write_text(whole + '{"photo": "b.jpg", "pin_angle_deg": 2.0}')
    assert main(["report", str(cut), "-o", str(page), "--quiet"]) == 0
