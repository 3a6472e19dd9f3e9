"""The independent physical model: independent of the fitted simulation, physically sane."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from cvmeasure.sim import simulate
from cvmeasure_datasets import physical_bender as pb


def test_it_does_not_use_the_simulation_it_judges():
    tree = ast.parse(Path(pb.__file__).read_text())
    imported = {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module} | {
        a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names
    }
    assert not any(m.startswith("cvmeasure.sim") for m in imported), imported


def test_nominal_machine_is_near_the_simulation_but_not_the_same():
    cmd = np.array([20.0, 45.0, 75.0, 110.0, 140.0])
    phys, sim = pb.bend(cmd, pb.Machine()), simulate(cmd)
    diff_l = phys.loaded_deg - sim.loaded_bend_deg
    sb_phys = phys.loaded_deg - phys.unloaded_deg
    # the span's elastic bow adds 0.15-0.3 deg to the loaded angle; springback is within
    # 25 % (Voce hardening and a falling chord modulus instead of Swift and E)
    assert np.all((diff_l > 0.1) & (diff_l < 0.4))
    np.testing.assert_allclose(sb_phys, sim.springback_deg, rtol=0.25)
    assert np.ptp(sb_phys / sim.springback_deg) > 0.02  # a different shape, not a scale


def test_backlash_on_reversals_and_drift_shifting_home():
    m = pb.Machine()
    cmd = np.array([60.0, 60.0, -60.0, -60.0, 60.0])
    rev = pb.Hidden("backlash", {"backlash_deg": 1.0, "same_direction_share": 0.0})
    head = pb.bend(cmd, m, (rev,)).head_deg
    np.testing.assert_allclose(np.abs(head), [59.0, 60.0, 59.0, 60.0, 59.0])
    drift = pb.Hidden("drift", {"drift_deg_per_bend": 0.12, "quantum_deg": 0.06})
    head = pb.bend(cmd, m, (drift,)).head_deg
    # steps lost by ccw bends shift home clockwise: the next ccw bend is short, cw long
    assert head[1] < 60.0 and head[2] < -60.0
    assert np.allclose(np.round(np.abs(head) / 0.06) * 0.06, np.abs(head))  # whole quanta


def test_photos_of_one_bend_share_their_error():
    case = pb.physical_case(3, "none", plan="repeats", n_trials=600, noise_range_deg=(0.1, 0.1))
    truth = pb.bend(case.trials.commanded_pin_deg, case.machine)
    el = case.trials.loaded_bend_deg - truth.loaded_deg
    eu = case.trials.unloaded_bend_deg - truth.unloaded_deg
    assert np.std(el) == pytest.approx(0.1, rel=0.1)
    assert np.corrcoef(el, eu)[0, 1] == pytest.approx(case.shared_share, abs=0.1)


def test_plans():
    rng = np.random.default_rng(0)
    rep = pb.plan_commands(rng, "repeats", 60)
    assert np.unique(rep).size <= 20 and rep.size == 60
    sweep = pb.plan_commands(rng, "sweep", 10)
    assert np.all(np.diff(np.abs(sweep[::2])) > 0)
    assert np.all(sweep[::2] > 0) and np.all(sweep[1::2] < 0)
    with pytest.raises(ValueError, match="unknown plan"):
        pb.plan_commands(rng, "zigzag", 10)
