"""The README's CLI table, walked end to end as a new user would, on rendered photos.

One journey through every command a user meets (targets, render, calibrate, plane,
measure, part with an SVG design, gcode, bend, session, fit, simulate, diagnose,
batch, report, agreement), each output feeding the next, every figure checked
against the renders' ground truth or the simulation's hidden cause with a stated
tolerance, and the messages a user reads checked for what they must say.
Renders are at 0.25 scale (1152 x 768) to keep the walk under a minute.
"""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from cvmeasure.cli import main

SCALE = "0.25"


def _cli(capsys, *args: object) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def _truth(photo: Path) -> dict:
    return json.loads(photo.with_suffix(".truth.json").read_text())


def _arc_svg(path: Path, radius_mm: float, arc_deg: float) -> None:
    """An SVG design: one circular arc of ``radius_mm`` over ``arc_deg``, in mm."""
    a = math.radians(arc_deg)
    x0, y0 = 150.0 - radius_mm, 150.0
    x1, y1 = 150.0 - radius_mm * math.cos(a), 150.0 - radius_mm * math.sin(a)
    large = 1 if arc_deg > 180 else 0
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="300mm" '
        'viewBox="0 0 300 300">'
        f'<path d="M {x0:.6f} {y0:.6f} A {radius_mm} {radius_mm} 0 {large} 1 {x1:.6f} {y1:.6f}" '
        'fill="none" stroke="black"/></svg>'
    )


@pytest.mark.slow
def test_readme_cli_table_end_to_end(tmp_path, capsys):
    # -- targets: a printable board (its board JSON comes with it) and the kit JSON
    code, out, _ = _cli(capsys, "targets", "charuco", "-o", tmp_path / "board.svg", "--page", "a3")
    assert code == 0 and "280 x 200 mm board" in out
    board = tmp_path / "board.board.json"
    code, _, _ = _cli(capsys, "targets", "markers", "--format", "json", "-o", tmp_path / "kit.json")
    assert code == 0
    kit = tmp_path / "kit.json"

    # -- render calibration views and calibrate the lens from them
    views = tmp_path / "views"
    code, out, _ = _cli(capsys, "render", "board", "--count", 10, "--scale", SCALE, "-o", views)
    assert code == 0 and out.count("wrote") == 10
    camera = tmp_path / "camera.json"
    photos = sorted(views.glob("*.jpg"))
    code, out, _ = _cli(capsys, "calibrate", *photos, "--board", board, "-o", camera, "--json")
    assert code == 0
    true_k = np.array(_truth(photos[0])["camera"]["camera_matrix"])
    cal = json.loads(camera.read_text())
    fx = np.array(cal["camera_matrix"])[0, 0]
    assert fx == pytest.approx(true_k[0, 0], rel=0.01)  # 1 % at 1152 px and 10 views

    # -- the plane check on one view: tilt against the render's pose
    code, out, _ = _cli(capsys, "plane", photos[0], "--board", board, "--camera", camera, "--json")
    assert code == 0
    plane = json.loads(out)
    assert plane["tilt_deg"] == pytest.approx(_truth(photos[0])["pose"]["tilt_deg"], abs=0.5)

    # -- bender photos: one bend loaded and unloaded, measured and paired
    bender = tmp_path / "bender"
    for name, bend in (("loaded", 47.5), ("unloaded", 45.0)):
        code, _, _ = _cli(
            capsys,
            "render",
            "bender",
            "--pin-deg",
            70,
            "--bend-deg",
            bend,
            "--name",
            name,
            "--scale",
            SCALE,
            "-o",
            bender,
            "--seed",
            3,
        )
        assert code == 0
    code, _, _ = _cli(
        capsys,
        "render",
        "bender",
        "--pin-deg",
        -60,
        "--bend-deg",
        -30,
        "--name",
        "cw",
        "--scale",
        SCALE,
        "-o",
        bender,
        "--seed",
        4,
    )
    assert code == 0
    loaded, unloaded = bender / "loaded.jpg", bender / "unloaded.jpg"
    code, out, _ = _cli(capsys, "measure", loaded, "--kit", kit, "--camera", camera, "--json")
    assert code == 0
    record = json.loads(out.splitlines()[0])
    assert record["bend_angle_deg"] == pytest.approx(_truth(loaded)["bend_angle_deg"], abs=0.1)
    # `render bender` stands the discs at the kit's heights; without a plane pose the heights
    # are not applied, and the record says so with a bound that must hold the pin's error.
    codes = {w["code"] for w in record["warnings"]}
    assert "heights_not_applied" in codes
    pin_error_deg = abs(record["pin_angle_deg"] - _truth(loaded)["pin_angle_deg"])
    assert pin_error_deg <= (
        record["height_bound_deg"]["pin_angle_deg"] + 2 * record["uncertainty_deg"]["pin_angle_deg"]
    )
    code, out, _ = _cli(
        capsys, "measure", "--pair", loaded, unloaded, "--kit", kit, "--camera", camera, "--json"
    )
    assert code == 0
    pair = json.loads(out.splitlines()[-1])
    assert pair["springback_deg"] == pytest.approx(2.5, abs=0.1)

    # -- a finished part beside the board, against its SVG design
    design = tmp_path / "design.svg"
    _arc_svg(design, 80.0, 120.0)
    parts = tmp_path / "part"
    code, _, _ = _cli(capsys, "render", "part", "--arc", 80, 120, 8, "--scale", SCALE, "-o", parts)
    assert code == 0
    code, out, _ = _cli(
        capsys,
        "part",
        parts / "part.jpg",
        "--board",
        board,
        "--camera",
        camera,
        "--divisions",
        8,
        "--design",
        design,
        "--json",
    )
    assert code == 0
    part = json.loads(out)
    assert part["radius_mm"] == pytest.approx(80.0, rel=0.02)  # 2 % at 1152 px
    assert part["arc_angle_deg"] == pytest.approx(120.0, abs=1.5)

    # -- the design as G-code, bent on the simulated bender
    job = tmp_path / "job.gcode"
    code, _, _ = _cli(capsys, "gcode", design, "-o", job)
    assert code == 0 and "G1" in job.read_text()
    code, out, _ = _cli(capsys, "bend", job, "--port", "sim://?speedup=300", "--quiet", "--json")
    assert code == 0
    streamed = json.loads(out)
    assert streamed["executed_line"] == streamed["lines_total"]

    # -- a calibration session on the double, then a refit of its trials
    cal_json = tmp_path / "cal.json"
    code, _, _ = _cli(
        capsys, "session", "--simulate", "-o", cal_json, "--angles", "5,20,60", "--quiet"
    )
    assert code == 0 and json.loads(cal_json.read_text())["format"] == "diwire-material/1"
    trials = tmp_path / "cal_session" / "trials.csv"
    code, _, _ = _cli(capsys, "fit", trials, "--model", "linear", "-o", tmp_path / "cal2.json")
    assert code == 0 and (tmp_path / "cal2.json").is_file()

    # -- simulate a machine with a hidden backlash; the diagnosis names it
    plan = tmp_path / "plan.csv"
    commands = [s * a for a in (20, 35, 50, 65, 80, 95) for s in (1, -1)] * 4
    with plan.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["trial", "commanded_pin_deg"])
        w.writerows((i + 1, c) for i, c in enumerate(commands))
    simulated = tmp_path / "sim.csv"
    code, _, _ = _cli(
        capsys,
        "simulate",
        plan,
        "--effect",
        "backlash=0.8",
        "--noise-deg",
        0.03,
        "--seed",
        1,
        "-o",
        simulated,
    )
    assert code == 0
    code, out, _ = _cli(capsys, "diagnose", simulated, "--json")
    assert code == 0
    diagnosis = json.loads(out)
    assert diagnosis["cause"] == "backlash"
    assert diagnosis["params"]["backlash_deg"] == pytest.approx(0.8, abs=0.1)
    assert diagnosis["extended_rmse_deg"] < diagnosis["baseline_rmse_deg"]

    # -- batch every bender photo, report them, compare with manual readings
    results = tmp_path / "results.jsonl"
    code, _, _ = _cli(
        capsys, "batch", bender, "--kit", kit, "--camera", camera, "--workers", 1, "-o", results
    )
    assert code == 0
    records = [json.loads(line) for line in results.read_text().splitlines()]
    assert len(records) == 3 and all(r["ok"] for r in records)
    for r in records:
        assert r["bend_angle_deg"] == pytest.approx(
            _truth(Path(r["photo"]))["bend_angle_deg"], abs=0.1
        )
    report = tmp_path / "report.html"
    code, _, _ = _cli(capsys, "report", results, "-o", report, "--quiet")
    assert code == 0 and "<html" in report.read_text()[:200].lower()
    manual = tmp_path / "manual.csv"
    with manual.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["photo", "bend_angle_deg"])
        for photo in (loaded, unloaded, bender / "cw.jpg"):
            w.writerow([photo.name, round(_truth(photo)["bend_angle_deg"], 1)])
    code, out, _ = _cli(capsys, "agreement", manual, results, "--json")
    assert code == 0
    agreement = json.loads(out)
    assert agreement["tolerance"]["n_within"] == agreement["tolerance"]["n_pairs"] == 3
    assert agreement["tolerance"]["verdict"] == "within tolerance"
