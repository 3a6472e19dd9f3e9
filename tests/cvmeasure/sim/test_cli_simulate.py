"""``cvmeasure simulate`` through the CLI entry point, including exit-2 paths."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cvmeasure.cli import main
from cvmeasure.fileio import read_csv_rows
from cvmeasure.sim import Effect, SimParams, params_to_json, simulate

COLUMNS = [
    "trial",
    "commanded_pin_deg",
    "pin_deg",
    "loaded_bend_deg",
    "unloaded_bend_deg",
    "springback_deg",
]


@pytest.fixture
def plan(tmp_path):
    path = tmp_path / "plan.csv"
    path.write_text("trial,commanded_pin_deg\nA,40\nB,-40\nC,90\nD,-120\n")
    return path


def _read(path):
    rows = read_csv_rows(path, required=COLUMNS)
    return {c: np.array([float(r[c]) for r in rows]) for c in COLUMNS[1:]}, rows


def test_simulate_writes_spec_columns(plan, tmp_path, capsys):
    out = tmp_path / "out.csv"
    assert main(["simulate", str(plan), "-o", str(out)]) == 0
    data, rows = _read(out)
    said = capsys.readouterr().out  # without --json, a one-line summary
    sb = simulate([40, -40, 90, -120]).springback_deg
    assert "4 bends simulated (effects: none" in said
    assert f"springback {min(sb):.3f} to {max(sb):.3f} deg" in said
    assert list(rows[0]) == COLUMNS
    assert [r["trial"] for r in rows] == ["A", "B", "C", "D"]
    ref = simulate([40, -40, 90, -120])
    np.testing.assert_allclose(data["loaded_bend_deg"], ref.loaded_bend_deg, atol=1e-6)
    np.testing.assert_allclose(data["springback_deg"], ref.springback_deg, atol=1e-6)


def test_effect_flag_and_params_file_agree(plan, tmp_path, capsys):
    out1, out2 = tmp_path / "o1.csv", tmp_path / "o2.csv"
    assert main(["simulate", str(plan), "--effect", "backlash=1.2", "-o", str(out1)]) == 0
    assert "effects: backlash=1.2" in capsys.readouterr().out
    params = tmp_path / "p.json"
    params_to_json(params, SimParams(), (Effect("backlash", 1.2),))
    assert main(["simulate", str(plan), "--params", str(params), "-o", str(out2), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["effects"] == [{"name": "backlash", "backlash_deg": 1.2}]
    d1, _ = _read(out1)
    d2, _ = _read(out2)
    np.testing.assert_allclose(d1["pin_deg"], [38.8, -38.8, 88.8, -118.8], atol=1e-6)
    np.testing.assert_allclose(d1["unloaded_bend_deg"], d2["unloaded_bend_deg"])


@pytest.mark.parametrize(
    ("content", "extra", "message"),
    [
        ("trial,pin\n1,3\n", [], "missing column"),
        ("trial,commanded_pin_deg\n1,abc\n", [], "not a number"),
        ("trial,commanded_pin_deg\n1,30\n", ["--effect", "wobble=1"], "unknown effect"),
        ("trial,commanded_pin_deg\n1,30\n", ["--effect", "backlash=-2"], "bounds"),
    ],
)
def test_bad_input_exit_2(tmp_path, capsys, content, extra, message):
    plan = tmp_path / "plan.csv"
    plan.write_text(content)
    out = tmp_path / "out.csv"
    assert main(["simulate", str(plan), "-o", str(out), *extra]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not out.exists()


def test_corrupt_params_exit_2(plan, tmp_path, capsys):
    params = tmp_path / "p.json"
    params.write_text('{"yield_mpa": 280,')
    assert (
        main(["simulate", str(plan), "--params", str(params), "-o", str(tmp_path / "o.csv")]) == 2
    )
    assert "p.json" in capsys.readouterr().err
    params.write_text('{"yield_mpa": "soft"}')
    assert (
        main(["simulate", str(plan), "--params", str(params), "-o", str(tmp_path / "o.csv")]) == 2
    )
    assert "must be a number" in capsys.readouterr().err
