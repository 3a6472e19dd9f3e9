"""The calibration JSON: modes, fitting from trials, validated load/save."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cvmeasure.contracts import TrialTable
from cvmeasure.driver.session import nominal_pin_for_loaded_deg
from cvmeasure.errors import InputError
from cvmeasure.fileio import write_csv_rows
from cvmeasure.material.bender_calibration import (
    FORMAT,
    MODES,
    BenderCalibration,
    calibration_plan,
    fit_calibration,
    load_calibration,
    read_trials_csv,
    save_calibration,
)
from cvmeasure.sim import simulate


def trials(angles, noise_deg=0.0, seed=0):
    """Calibration bends of the simulated bender (both directions) with seeded camera noise."""
    rng = np.random.default_rng(seed)
    pins = [nominal_pin_for_loaded_deg(a, d) for d in ("ccw", "cw") for a in angles]
    bends = simulate(pins)
    noise = rng.normal(0.0, noise_deg, (2, len(pins)))
    return np.array(pins), bends.loaded_bend_deg + noise[0], bends.unloaded_bend_deg + noise[1]


def final_deg(pin_deg):
    """What the simulated bender really makes of a pin command (deg)."""
    return float(simulate([pin_deg]).unloaded_bend_deg[0])


def trial_rows(angles=MODES["standard"], noise_deg=0.01, seed=1):
    pin, loaded, unloaded = trials(angles, noise_deg=noise_deg, seed=seed)
    targets = list(angles) * 2
    return [
        {
            "trial": i + 1,
            "commanded_pin_deg": p,
            "loaded_bend_deg": lo,
            "unloaded_bend_deg": un,
            "target_deg": t,
            "loaded_uncertainty_deg": 0.01,
            "unloaded_uncertainty_deg": 0.01,
        }
        for i, (p, lo, un, t) in enumerate(zip(pin, loaded, unloaded, targets, strict=True))
    ]


def test_modes_and_plan():
    assert MODES["quick"] == (10, 20, 45, 75, 110)
    assert len(MODES["standard"]) == 11
    assert set(MODES["standard"]) < set(MODES["high"]) and min(MODES["high"]) == 2.5
    plan = calibration_plan("quick")
    assert len(plan) == 10
    assert plan[0] == ("ccw", 10.0) and plan[-1] == ("cw", 110.0)
    with pytest.raises(ValueError, match="unknown mode"):
        calibration_plan("slow")


def test_round_trip_keeps_samples_models_and_compensation(tmp_path):
    samples = TrialTable.from_rows(trial_rows())
    cal = fit_calibration(samples, model="pchip", name="steel-3mm")
    assert cal.mode == "standard"
    path = save_calibration(tmp_path / "cal.json", cal)
    d = json.loads(path.read_text())
    assert d["format"] == FORMAT
    assert len(d["samples"]["ccw"]) == 11 and len(d["samples"]["cw"]) == 11
    s0 = d["samples"]["cw"][0]
    assert s0["springback_deg"] == pytest.approx(-(s0["loaded_bend_deg"] - s0["unloaded_bend_deg"]))
    assert s0["uncertainty_deg"]["springback_deg"] == pytest.approx(np.hypot(0.01, 0.01))
    assert set(d["scores"]) == {"linear", "cubic", "pchip", "physical"}
    again = load_calibration(path)
    assert isinstance(again, BenderCalibration)
    assert again.samples == cal.samples
    for target in (9.0, -9.0, 44.4, -101.0):
        assert again.compensate(target) == pytest.approx(cal.compensate(target), abs=1e-12)
        final = final_deg(again.compensate(target))
        assert final == pytest.approx(target, abs=0.1)


def test_refit_changes_model_not_samples():
    cal = fit_calibration(TrialTable.from_rows(trial_rows()), model="linear")
    cubic = cal.refit("cubic")
    assert cubic.model == "cubic" and cubic.samples == cal.samples
    assert cubic.compensation.springback["ccw"].coef != ()


def test_read_trials_csv(tmp_path):
    rows = trial_rows()
    path = write_csv_rows(tmp_path / "t.csv", rows, list(rows[0]))
    samples = read_trials_csv(path)
    assert len(samples) == 22 and samples[11].direction == "cw"
    assert samples[3].target_deg == 20.0
    bad = dict(rows[0], loaded_bend_deg="abc")
    path = write_csv_rows(tmp_path / "bad.csv", [bad], list(rows[0]))
    with pytest.raises(
        InputError, match=r"bad\.csv: line 2: loaded_bend_deg 'abc' is not a number"
    ):
        read_trials_csv(path)


@pytest.mark.parametrize(
    ("mutate", "message"),
    [
        (lambda d: d.update(format="other/1"), "format is 'other/1'"),
        (lambda d: d.pop("samples"), "missing key 'samples'"),
        (
            lambda d: d["samples"]["ccw"][2].update(loaded_bend_deg="x"),
            r"samples\.ccw\[2\]\.loaded_bend_deg",
        ),
        (
            lambda d: d["samples"]["cw"][0].update(loaded_bend_deg=5.0),
            "sign does not match direction cw",
        ),
        (lambda d: d["samples"]["ccw"][1].update(springback_deg=9.0), "does not equal sign"),
        (lambda d: d["springback"]["ccw"].update(model="spline"), "unknown model 'spline'"),
        (lambda d: d["springback"]["cw"]["final_deg"].pop(), "differ in length"),
        (lambda d: d["motion"].clear(), "motion: no fitted curve"),
        (lambda d: d.update(mode="turbo"), "unknown mode 'turbo'"),
    ],
)
def test_schema_errors_name_the_file_and_key(tmp_path, mutate, message):
    d = fit_calibration(TrialTable.from_rows(trial_rows())).to_dict()
    mutate(d)
    path = tmp_path / "broken.json"
    path.write_text(json.dumps(d))
    with pytest.raises(InputError, match=rf"broken\.json: .*{message}"):
        load_calibration(path)


def test_corrupt_and_missing_files(tmp_path):
    path = tmp_path / "cal.json"
    path.write_text('{"format": "diwire-material/1",')
    with pytest.raises(InputError, match=r"cal\.json: corrupt calibration JSON"):
        load_calibration(path)
    with pytest.raises(InputError, match="not found"):
        load_calibration(tmp_path / "none.json")


def test_fit_cli_writes_calibration_and_plot(tmp_path, capsys):
    from cvmeasure.cli import main

    rows = trial_rows()
    trials_csv = write_csv_rows(tmp_path / "trials.csv", rows, list(rows[0]))
    out, plot = tmp_path / "cal.json", tmp_path / "fit.png"
    code = main(
        ["fit", str(trials_csv), "--model", "pchip", "-o", str(out), "--plot", str(plot), "--json"]
    )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["model"] == "pchip" and summary["bends"] == 22
    assert summary["scores"]["linear"]["ccw"]["loao_rmse_deg"] < 0.05
    cal = load_calibration(out)
    final = final_deg(cal.compensate(-9.0))
    assert final == pytest.approx(-9.0, abs=0.1)
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_fit_cli_bad_input_exit_2(tmp_path, capsys):
    from cvmeasure.cli import main

    out = tmp_path / "cal.json"
    bad = tmp_path / "bad.csv"
    bad.write_text("trial,commanded_pin_deg,loaded_bend_deg\n1,20,18\n")
    assert main(["fit", str(bad), "-o", str(out)]) == 2
    assert "bad.csv: missing column(s) unloaded_bend_deg" in capsys.readouterr().err
    few = write_csv_rows(
        tmp_path / "few.csv", trial_rows(angles=(10, 20, 45)), list(trial_rows()[0])
    )
    assert main(["fit", str(few), "--model", "cubic", "-o", str(out)]) == 2
    assert "few.csv: cubic springback needs at least 4 distinct angles" in capsys.readouterr().err
    assert not out.exists()
