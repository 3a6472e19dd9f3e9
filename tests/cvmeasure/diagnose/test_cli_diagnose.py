"""``cvmeasure diagnose`` through the CLI entry point, including exit-2 paths."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cvmeasure.cli import main
from cvmeasure.fileio import write_csv_rows
from cvmeasure.sim import Effect, params_from_json, simulate
from cvmeasure_datasets import physical_bender as pb
from cvmeasure_datasets.trials import measure_trials, random_plan

COLUMNS = ("trial", "commanded_pin_deg", "loaded_bend_deg", "unloaded_bend_deg", "part")


@pytest.fixture(scope="module")
def offset_trials(tmp_path_factory):
    rng = np.random.default_rng(41)
    cmd = random_plan(rng, 40)
    trials = measure_trials(cmd, (Effect("offset", -1.5),), 0.05, rng)
    path = tmp_path_factory.mktemp("diag") / "trials.csv"
    write_csv_rows(path, trials.rows(), COLUMNS)
    return path


def test_diagnose_json_plot_and_extended_params(offset_trials, tmp_path, capsys):
    plot, saved = tmp_path / "res.png", tmp_path / "ext.json"
    argv = ["diagnose", str(offset_trials), "--json", "--plot", str(plot)]
    assert main([*argv, "--save-params", str(saved)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cause"] == "offset"
    assert out["params"]["offset_deg"] == pytest.approx(-1.5, abs=0.05)
    lo, hi = out["intervals"]["offset_deg"]
    assert lo < out["params"]["offset_deg"] < hi
    assert out["extended_rmse_deg"] < 0.2 * out["baseline_rmse_deg"]
    assert {c["cause"] for c in out["candidates"]} >= {"backlash", "offset", "scale", "drift"}
    assert all("cv_rmse_deg" in c for c in out["candidates"])
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # the saved extended model carries the named effect and simulates like the truth
    params, effects = params_from_json(saved)
    assert [e.name for e in effects] == ["offset"]
    ref = simulate([60.0, -60.0], effects=[Effect("offset", -1.5)])
    got = simulate([60.0, -60.0], params, effects)
    np.testing.assert_allclose(got.unloaded_bend_deg, ref.unloaded_bend_deg, atol=0.1)
    # diagnosing again with the extended model finds nothing more
    assert main(["diagnose", str(offset_trials), "--params", str(saved), "--json"]) == 0
    again = json.loads(capsys.readouterr().out)
    assert again["cause"] == "none"


def test_measured_pin_column_is_read(tmp_path, capsys):
    rng = np.random.default_rng(45)
    trials = measure_trials(random_plan(rng, 30), (Effect("scale", 0.03),), 0.05, rng, pin=True)
    path = tmp_path / "t.csv"
    write_csv_rows(path, trials.rows(), (*COLUMNS, "measured_pin_deg"))
    assert main(["diagnose", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cause"] == "scale"
    assert out["params"]["scale"] == pytest.approx(0.03, abs=0.002)
    text = path.read_text().splitlines()
    text[3] = text[3].rsplit(",", 1)[0] + ",north"
    path.write_text("\n".join(text) + "\n")
    assert main(["diagnose", str(path)]) == 2
    assert "measured_pin_deg" in capsys.readouterr().err


def test_diagnose_text_summary(offset_trials, capsys):
    assert main(["diagnose", str(offset_trials)]) == 0
    text = capsys.readouterr().out
    assert text.startswith("cause: offset") and "held-out RMSE" in text


def test_a_follow_up_asked_for_without_a_tie_is_said_not_written(offset_trials, tmp_path, capsys):
    plan = tmp_path / "follow-up.csv"
    assert main(["diagnose", str(offset_trials), "--follow-up-csv", str(plan)]) == 0
    text = capsys.readouterr().out
    assert text.startswith("cause: offset") and not plan.exists()
    assert text.rstrip().endswith(
        f"no follow-up plan written to {plan}: no tie between catalogue causes to separate"
    )


def test_unloaded_only_trials_are_accepted(tmp_path, capsys):
    rng = np.random.default_rng(43)
    trials = measure_trials(
        random_plan(rng, 30), (Effect("backlash", 2.0),), 0.05, rng, loaded=False
    )
    path = tmp_path / "t.csv"
    write_csv_rows(path, trials.rows(), COLUMNS)
    assert "\n1," in path.read_text() and ",," in path.read_text()  # empty loaded cells
    assert main(["diagnose", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cause"] != "none"
    assert any("loaded" in n for n in out["notes"])


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("trial,commanded_pin_deg,loaded_bend_deg\n1,3,3\n", "missing column"),
        ("trial,commanded_pin_deg,loaded_bend_deg,unloaded_bend_deg\n1,x,3,3\n", "not a number"),
        ("trial,commanded_pin_deg,loaded_bend_deg,unloaded_bend_deg\n1,30,,\n", "neither"),
        ("trial,commanded_pin_deg,loaded_bend_deg,unloaded_bend_deg\n1,30,20,19\n", "at least"),
        ("trial,commanded_pin_deg,loaded_bend_deg,unloaded_bend_deg\n", "no trials"),
    ],
)
def test_bad_trials_exit_2(tmp_path, capsys, content, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    saved = tmp_path / "ext.json"
    assert main(["diagnose", str(path), "--json", "--save-params", str(saved)]) == 2
    err = capsys.readouterr().err.strip()
    assert "bad.csv" in err and message in err and len(err.splitlines()) == 1
    assert not saved.exists()


def test_missing_file_and_bad_params_exit_2(offset_trials, tmp_path, capsys):
    assert main(["diagnose", str(tmp_path / "nope.csv")]) == 2
    assert "nope.csv" in capsys.readouterr().err
    params = tmp_path / "p.json"
    params.write_text('{"effects": [{"name": "wobble"}]}')
    assert main(["diagnose", str(offset_trials), "--params", str(params)]) == 2
    assert "unknown effect" in capsys.readouterr().err


@pytest.mark.parametrize("noise", ["0", "0.05"])
def test_simulate_then_diagnose_round_trip(tmp_path, capsys, noise):
    rng = np.random.default_rng(47)
    plan = tmp_path / "plan.csv"
    cmds = random_plan(rng, 30)
    write_csv_rows(
        plan,
        [{"trial": i + 1, "commanded_pin_deg": float(c)} for i, c in enumerate(cmds)],
        ("trial", "commanded_pin_deg"),
    )
    trials = tmp_path / "trials.csv"
    argv = ["simulate", str(plan), "--effect", "drift=0.04", "-o", str(trials)]
    assert main([*argv, "--noise-deg", noise, "--seed", "3"]) == 0
    assert "30 bends simulated" in capsys.readouterr().out
    assert main(["diagnose", str(trials), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["cause"] == "drift"
    assert out["params"]["drift_deg_per_bend"] == pytest.approx(0.04, abs=0.002)
    if noise == "0":  # exact data: recovered to the CSV's rounding
        assert out["params"]["drift_deg_per_bend"] == pytest.approx(0.04, abs=1e-6)
        # and exact null data names nothing (rounding error is not a cause)
        assert main(["simulate", str(plan), "-o", str(trials)]) == 0
        capsys.readouterr()
        assert main(["diagnose", str(trials), "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["cause"] == "none"


def test_simulate_bad_noise_exit_2(tmp_path, capsys):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,commanded_pin_deg\n1,30\n")
    with pytest.raises(SystemExit) as info:  # refused by the parser, one line
        main(["simulate", str(plan), "--noise-deg", "-1", "-o", str(tmp_path / "o.csv")])
    assert info.value.code == 2
    assert "--noise-deg" in capsys.readouterr().err


def test_max_causes_option(tmp_path, capsys):
    rng = np.random.default_rng(49)
    effects = (Effect("offset", 1.0), Effect("drift", 0.03))
    trials = measure_trials(random_plan(rng, 40), effects, 0.05, rng)
    path = tmp_path / "t.csv"
    write_csv_rows(path, trials.rows(), COLUMNS)
    assert main(["diagnose", str(path), "--json"]) == 0
    assert set(json.loads(capsys.readouterr().out)["causes"]) == {"offset", "drift"}
    assert main(["diagnose", str(path), "--json", "--max-causes", "1"]) == 0
    assert len(json.loads(capsys.readouterr().out)["causes"]) == 1


def test_cli_json_is_the_library_result(offset_trials, capsys):
    # the CLI (lazy imports, its garbage-collector settings) prints what diagnose() returns,
    # byte for byte
    from cvmeasure.contracts import TrialTable
    from cvmeasure.diagnose import diagnose
    from cvmeasure.fileio import to_jsonable

    assert main(["diagnose", str(offset_trials), "--json"]) == 0
    printed = capsys.readouterr().out
    expected = to_jsonable(diagnose(TrialTable.read_csv(offset_trials)).to_dict())
    assert printed == json.dumps(expected, indent=2) + "\n"


def test_text_summary_of_a_tilt_about_another_axis(tmp_path, capsys):
    # a camera tilted about an axis the fit picks from its grid of forms: the axis is a
    # parameter without an interval, and the text summary once stopped on it (KeyError)
    case = pb.physical_case(426, ("camera_tilt", "scale"), plan="random", n_trials=60)
    path = case.trials.write_csv(tmp_path / "t.csv")
    saved = tmp_path / "ext.json"
    assert main(["diagnose", str(path), "--save-params", str(saved)]) == 0
    text = capsys.readouterr().out
    assert text.splitlines()[0] == "cause: camera_tilt", text
    axis = [ln for ln in text.splitlines() if ln.strip().startswith("tilt_axis_deg =")]
    assert len(axis) == 1 and "no interval" in axis[0], text
    tilt = [ln for ln in text.splitlines() if ln.strip().startswith("tilt_deg =")]
    assert len(tilt) == 1 and "95 % interval" in tilt[0], text
    # the hidden scale (-2.3 %) is not asked for: on this plan the tilt's axis, fitted
    # off the grid, takes it up (a tilt about -40..-60 deg with a scale of 0..-1.7 % fit
    # alike, 0.080-0.083 deg rms at 0.076 deg of noise)
    assert saved.exists()
