"""``cvmeasure gcode`` and ``cvmeasure bend`` through cvmeasure.cli.main, exit codes included."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import ezdxf
import numpy as np
import pytest

from cvmeasure.cli import main
from cvmeasure.fileio import read_jsonl
from cvmeasure.sim import pin_command_for_angle
from cvmeasure.testing.double import FakeTinyG, Fault

HALF_SVG = (
    '<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="300mm" viewBox="0 0 300 300">'
    '<path d="M 150 50 A 100 100 0 0 1 150 250" fill="none" stroke="black"/></svg>'
)


@pytest.fixture
def half_gcode(tmp_path, capsys):
    svg = tmp_path / "half.svg"
    svg.write_text(HALF_SVG)
    out = tmp_path / "half.gcode"
    assert main(["gcode", str(svg), "-o", str(out), "--divisions", "20", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    return out, summary


def test_gcode_from_svg_uses_the_simulation_inverse(half_gcode):
    out, summary = half_gcode
    assert summary["bends"] == 19
    steps = summary["bend_list"]
    np.testing.assert_allclose(
        [s["feed_mm"] for s in steps], 200 * np.sin(np.radians(4.5)), atol=1e-6
    )
    bends = np.array([s["bend_deg"] for s in steps[:-1]])
    np.testing.assert_allclose(np.abs(bends), 9.0, atol=1e-6)
    np.testing.assert_allclose(summary["pin_deg"], pin_command_for_angle(bends), atol=1e-9)
    lines = out.read_text().splitlines()
    first = next(i for i, line in enumerate(lines) if not line.startswith(";"))
    assert lines[0].startswith("; cvmeasure") and lines[first].startswith("N1 G21 G90")
    # the header keeps the division of the arc (printed too) and the polygon bent
    assert any(line.startswith("; curve divided:") for line in lines[:first])
    assert any(line.startswith("; plan ") for line in lines[:first])


def test_gcode_with_a_calibration_json(tmp_path, capsys):
    from cvmeasure.contracts import TrialTable
    from cvmeasure.material.bender_calibration import fit_calibration, save_calibration
    from cvmeasure.sim import simulate

    angles = [5, 10, 15, 20, 30, 45, 60, 75, 90, 110, 130]
    cmds = np.concatenate(
        [
            pin_command_for_angle(np.array(angles, float)),
            -pin_command_for_angle(np.array(angles, float)),
        ]
    )
    res = simulate(cmds)
    rows = [
        {"trial": i + 1, "commanded_pin_deg": c, "loaded_bend_deg": l, "unloaded_bend_deg": u}
        for i, (c, l, u) in enumerate(
            zip(cmds, res.loaded_bend_deg, res.unloaded_bend_deg, strict=True)
        )
    ]
    cal = fit_calibration(TrialTable.from_rows(rows), model="linear")
    save_calibration(tmp_path / "cal.json", cal)
    svg = tmp_path / "half.svg"
    svg.write_text(HALF_SVG)
    out = tmp_path / "job.gcode"
    args = [
        "gcode",
        str(svg),
        "-o",
        str(out),
        "--divisions",
        "20",
        "--material",
        str(tmp_path / "cal.json"),
        "--json",
    ]
    assert main(args) == 0
    summary = json.loads(capsys.readouterr().out)
    final = simulate(np.array(summary["pin_deg"])).unloaded_bend_deg
    np.testing.assert_allclose(np.abs(final), 9.0, atol=0.05)  # interpolated, not exact


def test_bend_to_the_sim_double(half_gcode, capsys):
    out, _ = half_gcode
    assert main(["bend", str(out), "--port", "sim://?speedup=300", "--quiet", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["executed_line"] == result["lines_total"] == 62
    assert read_jsonl(out.with_name("half.gcode.journal.jsonl"))[-1]["event"] == "done"


def test_bend_progress_piped_is_whole_lines(half_gcode, capsys):
    """Piped (not a terminal), progress comes as whole lines, no carriage returns."""
    out, _ = half_gcode
    assert main(["bend", str(out), "--port", "sim://?speedup=300"]) == 0
    err = capsys.readouterr().err
    assert "\r" not in err
    lines = err.splitlines()
    assert lines and all(line.startswith("sent ") for line in lines)
    assert lines[-1].startswith("sent 62/62, executing N")


def test_bend_stops_on_a_vanished_port_and_resumes(half_gcode, capsys):
    out, _ = half_gcode
    with FakeTinyG(speedup=100.0, faults=[Fault("vanish", 40)]) as board:
        assert main(["bend", str(out), "--port", board.port, "--quiet"]) == 1
        err = capsys.readouterr().err
        assert "job stopped (port_gone) at line N" in err and "--resume" in err
        port = board.reconnect()
        assert main(["bend", str(out), "--port", port, "--resume", "--quiet"]) == 0
        completed, _ = board.executed_lines()
        assert completed == list(range(0, 63))
        assert "resumed at line" in capsys.readouterr().out


def test_bend_missing_port_is_exit_2_naming_it(half_gcode, capsys):
    out, _ = half_gcode
    assert main(["bend", str(out), "--port", "/dev/ttyNOPE0"]) == 2
    assert capsys.readouterr().err.strip() == "cvmeasure bend: /dev/ttyNOPE0: no such serial port"


def test_bend_bad_job_and_missing_journal_are_exit_2(tmp_path, capsys):
    job = tmp_path / "bad.gcode"
    job.write_text("G21\nG1 X5 F100 ! now\n")
    assert main(["bend", str(job), "--port", "sim://"]) == 2
    assert "bad.gcode: line 2" in capsys.readouterr().err
    job.write_text("G21\n")
    assert main(["bend", str(job), "--port", "sim://", "--resume"]) == 2
    assert "no journal to resume from" in capsys.readouterr().err
    assert main(["bend", str(tmp_path / "none.gcode"), "--port", "sim://"]) == 2
    assert "G-code file not found" in capsys.readouterr().err


def test_gcode_bad_designs_are_exit_2_and_write_nothing(tmp_path, capsys):
    out = tmp_path / "job.gcode"
    closed = tmp_path / "sq.svg"
    closed.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" viewBox="0 0 100 100">'
        '<rect id="r1" x="10" y="10" width="50" height="50"/></svg>'
    )
    assert main(["gcode", str(closed), "-o", str(out)]) == 2
    assert "closed shape" in capsys.readouterr().err
    doc = ezdxf.new(units=4)  # millimetres
    doc.modelspace().add_lwpolyline([(0, 0), (30, 0), (30, 8), (60, 8)])
    short = tmp_path / "short.dxf"
    doc.saveas(short)
    assert main(["gcode", str(short), "-o", str(out)]) == 2
    assert "short.dxf: segment 2" in capsys.readouterr().err
    doc = ezdxf.new(units=4)  # millimetres
    doc.modelspace().add_lwpolyline([(0, 0), (30, 0), (0, 5)])
    sharp = tmp_path / "sharp.dxf"
    doc.saveas(sharp)
    assert main(["gcode", str(sharp), "-o", str(out)]) == 2
    assert "at most 135 deg" in capsys.readouterr().err
    text = tmp_path / "t.svg"
    text.write_text('<svg xmlns="http://www.w3.org/2000/svg"><text x="1" y="1">hi</text></svg>')
    assert main(["gcode", str(text), "-o", str(out)]) == 2
    assert "t.svg" in capsys.readouterr().err
    cal = tmp_path / "cal.json"
    cal.write_text("{not json")
    half = tmp_path / "half.svg"
    half.write_text(HALF_SVG)
    assert main(["gcode", str(half), "-o", str(out), "--material", str(cal)]) == 2
    assert "cal.json" in capsys.readouterr().err
    assert not out.exists()


def test_from_line_takes_the_line_as_the_refusal_names_it(half_gcode):
    """A refused resume says `--from-line N4`; typed as shown, the word reaches the check."""
    out, _ = half_gcode
    exe = str(Path(sys.executable).with_name("cvmeasure"))

    def bend(*extra: str) -> subprocess.CompletedProcess:
        argv = [exe, "bend", str(out), "--port", "sim://?speedup=300", "--quiet", *extra]
        return subprocess.run(argv, capture_output=True, text=True, timeout=120)

    assert bend().returncode == 0
    # the journal says done and sim:// is a fresh machine at home: N20 is checked and refused
    proc = bend("--resume", "--from-line", "N20")
    assert proc.returncode == 2
    assert proc.stderr.startswith("cvmeasure bend: --from-line: N20 is not where the job can")
    proc = bend("--resume", "--from-line", "X20")
    assert proc.returncode == 2 and len(proc.stderr.splitlines()) == 1
    assert "--from-line: must be a line number such as N1837 (or 1837), got 'X20'" in proc.stderr
