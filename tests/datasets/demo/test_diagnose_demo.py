"""The diagnosis demo step: hidden backlash found and recovered."""

from __future__ import annotations

from cvmeasure_datasets.demo.diagnose import demo_step


def test_demo_step_finds_hidden_backlash(tmp_path):
    section = demo_step(tmp_path, seed=7)
    assert section.title == "diagnosis"
    by_name = {r.quantity: r for r in section.rows}
    assert by_name["cause named is backlash (1 = yes)"].measured == 1.0
    assert all(r.ok is not False for r in section.rows), [r.to_dict() for r in section.rows]
    assert by_name["held-out RMSE gain"].measured > 70.0
    for name in ("diagnosis_trials.csv", "diagnosis.json", "diagnosis_residuals.png"):
        assert (tmp_path / name).stat().st_size > 0
