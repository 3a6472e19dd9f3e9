"""The held-out bender model against closed forms, and each effect's direction."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from benchmarks.heldout.bend_job import bend_job, parse_job
from benchmarks.heldout.bender_physics import (
    MACHINES,
    BenderRun,
    Effects,
    realised_springback_asymmetry,
    simulate_trials,
)
from benchmarks.heldout.machine import parse_effects
from benchmarks.heldout.wire_section import MATERIALS, epp_moment_closed_form, section_table

ROOT = Path(__file__).resolve().parents[2]
DIWIRE = MACHINES["diwire"]
EPP = dataclasses.replace(DIWIRE, name="diwire-epp", material="epp_steel")
PLAN = [20.0, 45.0, 90.0, 130.0, -20.0, -45.0, -90.0, -130.0]


def _ei(machine) -> float:
    return (
        MATERIALS[machine.material].youngs_modulus_mpa
        * math.pi
        * (machine.wire_diameter_mm / 2) ** 4
        / 4
    )


def test_epp_section_matches_the_textbook_moment_and_springback():
    mat, a = MATERIALS["epp_steel"], 1.5
    table = section_table(mat, a, 1.0 / 3.0)
    ei = mat.youngs_modulus_mpa * math.pi * a**4 / 4
    for curv in (2e-3, 1e-2, 0.1, 1.0 / 3.0):
        closed = epp_moment_closed_form(mat, a, curv)
        assert float(table.moment(curv)) == pytest.approx(closed, rel=2e-3)
        # Elastic unloading (the surface stress change M a / I stays under 2 sigma_y).
        assert float(table.residual(curv)) == pytest.approx(curv - closed / ei, rel=2e-3)
    # The fully plastic limit 4 sigma_y a^3 / 3.
    assert float(table.moment(1.0 / 3.0)) == pytest.approx(4 * 280.0 * a**3 / 3, rel=3e-3)


def test_small_elastic_bend_springs_back_fully():
    dead = DIWIRE.dead_angle_deg()
    for cmd in (dead + 0.05, -(dead + 0.05)):
        done = BenderRun(DIWIRE).execute(cmd)
        assert done.contact and abs(done.loaded_deg) > 0.01
        assert abs(done.unloaded_deg) < 1e-6
    # A cantilever's tip slope is 3/2 of its chord's: the loaded leg vs the rigid leg.
    run = BenderRun(DIWIRE)
    res, _ = run._at(1, dead + 0.05, run._table(1))
    assert res.loaded_deg == pytest.approx(1.5 * res.chord_deg, rel=1e-3)


def test_perfectly_plastic_springback_is_the_beam_formula():
    """Springback = M_p / EI * (wrapped arc + lever / 2) for a wire wrapped on the die."""
    run = BenderRun(EPP)
    table = run._table(1)
    a_d = EPP.die_radius_mm + EPP.wire_diameter_mm / 2
    m_die = epp_moment_closed_form(MATERIALS["epp_steel"], 1.5, 1.0 / a_d)
    for head in (45.0, 90.0, 130.0):
        res, _ = run._at(1, head, table)
        assert res.wrap_deg > 5.0
        expected = m_die / _ei(EPP) * (a_d * math.radians(res.wrap_deg) + res.lever_mm / 2)
        assert res.loaded_deg - res.unloaded_deg == pytest.approx(math.degrees(expected), rel=0.01)


def test_no_effect_run_is_mirror_symmetric_and_deterministic():
    rows = simulate_trials(PLAN, "diwire", Effects(), 0.0, 0)
    for plus, minus in zip(rows[:4], rows[4:], strict=True):
        assert plus.loaded_bend_deg == pytest.approx(-minus.loaded_bend_deg, abs=1e-9)
        assert plus.unloaded_bend_deg == pytest.approx(-minus.unloaded_bend_deg, abs=1e-9)
    sb = [r.loaded_bend_deg - r.unloaded_bend_deg for r in rows[:4]]
    assert all(0.3 < s < 3.0 for s in sb) and sb == sorted(sb)  # grows with the bend
    a = simulate_trials(PLAN, "diwire", Effects(), 0.05, 7)
    b = simulate_trials(PLAN, "diwire", Effects(), 0.05, 7)
    c = simulate_trials(PLAN, "diwire", Effects(), 0.05, 8)
    assert [r.loaded_bend_deg for r in a] == [r.loaded_bend_deg for r in b]
    assert [r.loaded_bend_deg for r in a] != [r.loaded_bend_deg for r in c]
    err = np.array([x.loaded_bend_deg - y.loaded_bend_deg for x, y in zip(a, rows, strict=True)])
    assert 0.0 < np.abs(err).max() < 0.05 * 5


def _heads(effects: Effects, plan=PLAN) -> np.ndarray:
    return np.array([r.truth.head_deg for r in simulate_trials(plan, DIWIRE, effects)])


def test_drive_effects_follow_their_contract():
    cmd = np.array(PLAN)
    np.testing.assert_allclose(
        np.abs(_heads(Effects(backlash_deg=1.2))), np.abs(cmd) - 1.2, atol=1e-9
    )
    np.testing.assert_allclose(_heads(Effects(offset_deg=0.8)), cmd + 0.8, atol=1e-9)
    np.testing.assert_allclose(_heads(Effects(scale=0.03)), cmd * 1.03, atol=1e-9)
    # Compliance: the loaded head lags by k T, T the pin torque (N m) at the lagged head.
    rows = simulate_trials(PLAN, DIWIRE, Effects(compliance_deg_per_nm=0.6))
    for r in rows:
        lag = np.sign(r.commanded_pin_deg) * (r.commanded_pin_deg - r.truth.head_deg)
        assert lag == pytest.approx(0.6 * r.truth.torque_nm, abs=1e-6) and lag > 0.5
    nominal = simulate_trials(PLAN, DIWIRE, Effects())
    for r, n in zip(rows, nominal, strict=True):
        assert abs(r.unloaded_bend_deg) < abs(n.unloaded_bend_deg)


def test_drift_closes_a_run_of_bends_like_a_helix():
    plan = [60.0] * 12
    rows = simulate_trials(plan, DIWIRE, Effects(drift_deg=0.2))
    bends = np.array([r.unloaded_bend_deg for r in rows])
    assert np.all(np.diff(bends) <= 1e-9) and bends[0] - bends[-1] > 1.5
    lost = 60.0 - np.array([r.truth.head_deg for r in rows])
    # Whole head steps: within one step of the continuous loss k d.
    np.testing.assert_allclose(lost, 0.2 * np.arange(1, 13), atol=DIWIRE.head_step_deg / 2 + 1e-9)
    # A bend the other way gains the loss back (the zero walked against the load).
    back = simulate_trials([60.0] * 6 + [-60.0], DIWIRE, Effects(drift_deg=0.2))
    assert abs(back[-1].truth.head_deg) > 60.0


def test_springback_asymmetry_and_camera_tilt_and_axis_offset():
    alpha = realised_springback_asymmetry(DIWIRE, Effects(springback_asymmetry=0.2), PLAN)
    assert alpha == pytest.approx(0.2, abs=0.03)
    tilt = simulate_trials(PLAN, DIWIRE, Effects(camera_tilt_deg=20.0))
    true = simulate_trials(PLAN, DIWIRE, Effects())
    for t, n in zip(tilt, true, strict=True):
        expected = math.degrees(
            math.atan(math.tan(math.radians(n.unloaded_bend_deg)) * math.cos(math.radians(20)))
        )
        if abs(n.unloaded_bend_deg) > 90:
            expected += math.copysign(180.0, n.unloaded_bend_deg)
        assert t.unloaded_bend_deg == pytest.approx(expected, abs=1e-9)
        assert t.truth.unloaded_deg == n.truth.unloaded_deg  # the wire is not changed
    # Head axis 0.3 mm to +y: CCW and CW differ with the sign of cos(theta).
    off = simulate_trials([25.0, -25.0, 150.0, -150.0], DIWIRE, Effects(axis_offset_mm=0.3))
    small = abs(off[0].unloaded_bend_deg) - abs(off[1].unloaded_bend_deg)
    large = abs(off[2].unloaded_bend_deg) - abs(off[3].unloaded_bend_deg)
    assert abs(small) > 0.5 and abs(large) > 0.5 and small * large < 0


def test_outside_catalogue_mechanisms_act():
    base = simulate_trials(PLAN, DIWIRE, Effects())
    for spec in (
        "coil_set=0.5",
        "die_radius_error=0.5",
        "orbit_eccentricity=0.3",
        "gear_runout=0.5",
    ):
        rows = simulate_trials(PLAN, DIWIRE, parse_effects([spec]))
        diff = max(
            abs(r.unloaded_bend_deg - b.unloaded_bend_deg) for r, b in zip(rows, base, strict=True)
        )
        assert diff > 0.1, spec
    # Step loss only on the bends loaded near the die-wrapping torque.
    rows = simulate_trials(
        [20.0, 20.0, 90.0, 20.0], DIWIRE, Effects(step_loss_deg=0.72, step_loss_torque_share=0.95)
    )
    assert [abs(r.truth.slipped_deg) for r in rows] == pytest.approx([0.0, 0.0, 0.72, 0.0])
    # Warming: the springback of one bend repeated shrinks over the run.
    rows = simulate_trials([90.0, -90.0] * 12, DIWIRE, Effects(thermal_softening=0.3))
    sb = [abs(r.loaded_bend_deg - r.unloaded_bend_deg) for r in rows]
    assert sb[-1] < 0.85 * sb[0]


def test_bend_job_vertices_carry_the_true_bends(tmp_path):
    job = "\n".join(
        [
            "N1 G21 G90 (test)",
            "N2 G0 Z0",
            "N3 G0 X0",
            "N4 G91 G1 Y30 F3000",
            "N5 G90 G1 X-54.585 F6000",
            "N6 G0 X0",
            "N7 G91 G1 Y28.284 F3000",
            "N8 G90 G0 Z180",
            "N9 G0 Z0",
            "N10 G90 G1 X54.585 F6000",
            "N11 G0 X0",
            "N12 G91 G1 Y30 F3000",
            "N13 (end)",
        ]
    )
    assert [s.kind for s in parse_job(job)] == ["feed", "bend", "feed", "bend", "feed"]
    part = bend_job(job, "diwire", Effects())
    trials = simulate_trials([-54.585, 54.585], DIWIRE, Effects())
    np.testing.assert_allclose(part.bend_deg, [t.truth.bend_deg for t in trials], atol=1e-9)
    seg = np.diff(part.vertices_mm, axis=0)
    heading = np.degrees(np.arctan2(seg[:, 1], seg[:, 0]))
    np.testing.assert_allclose(np.diff(heading), -part.bend_deg, atol=1e-3)
    assert heading[0] == pytest.approx(0.0, abs=1e-6)
    length = np.sum(np.hypot(*np.diff(part.centreline_mm, axis=0).T))
    assert length == pytest.approx(88.284, abs=1e-6)
    slipped = bend_job(job, "diwire", Effects(feed_slip=0.05), seed=4)
    length = np.sum(np.hypot(*np.diff(slipped.centreline_mm, axis=0).T))
    # Three feeds, each short by 5 % +- 1.25 % of itself.
    assert length == pytest.approx(0.95 * 88.284, abs=4 * 0.0125 * 30 * math.sqrt(3))
    again = bend_job(job, "diwire", Effects(feed_slip=0.05), seed=4)
    other = bend_job(job, "diwire", Effects(feed_slip=0.05), seed=5)
    assert np.array_equal(again.centreline_mm, slipped.centreline_mm)
    assert not np.array_equal(other.centreline_mm, slipped.centreline_mm)
    with pytest.raises(ValueError, match="beyond"):
        bend_job("G91 G1 Y20\nG90 G1 X175\n", "diwire")
    with pytest.raises(ValueError, match="line 2"):
        parse_job("G21\nG91 G1 Y-5\n")


def test_cli_writes_trials_and_truth_and_refuses_bad_input(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,commanded_pin_deg\n1,30\n2,-60\n", encoding="utf-8")
    out = tmp_path / "trials.csv"
    cmd = [
        sys.executable,
        "-m",
        "benchmarks.heldout.bender_physics",
        str(plan),
        "--effect",
        "offset=1",
        "-o",
        str(out),
    ]
    done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=False)
    assert done.returncode == 0, done.stderr
    header = out.read_text(encoding="utf-8").splitlines()[0]
    assert header == "trial,commanded_pin_deg,loaded_bend_deg,unloaded_bend_deg,measured_pin_deg"
    truth = json.loads((tmp_path / "trials.truth.json").read_text(encoding="utf-8"))
    assert truth["effects"] == {"offset": 1.0} and truth["catalogue_causes"] == ["offset"]
    assert truth["trials"][0]["head_deg"] == pytest.approx(31.0)
    bad = [
        sys.executable,
        "-m",
        "benchmarks.heldout.bender_physics",
        str(plan),
        "--effect",
        "warp=1",
        "-o",
        str(out),
    ]
    done = subprocess.run(bad, cwd=ROOT, capture_output=True, text=True, check=False)
    assert (
        done.returncode == 2
        and "warp" in done.stderr
        and len(done.stderr.strip().splitlines()) == 1
    )


def _imports(path: Path) -> set[str]:
    import ast

    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_the_model_and_the_code_under_test_stay_apart():
    own = ["bender_physics", "bend_job", "machine", "mechanics", "wire_section"]
    for name in own:
        found = _imports(ROOT / "benchmarks" / "heldout" / f"{name}.py")
        assert not [n for n in found if n.split(".")[0] in ("cvmeasure", "cvmeasure_datasets")], (
            name
        )
    for tree in ("cvmeasure", "datasets"):
        for path in (ROOT / tree).rglob("*.py"):
            if "benchmarks" not in path.read_text(encoding="utf-8"):
                continue  # cannot import it; skip the parse
            assert not [n for n in _imports(path) if n.startswith("benchmarks")], path
