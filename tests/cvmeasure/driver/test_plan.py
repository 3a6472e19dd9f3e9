"""The session's plan: every catalogue cause identifiable, the calibration unchanged by order."""

from __future__ import annotations

import dataclasses
from collections import Counter

import numpy as np
import pytest

from cvmeasure.contracts import Trial
from cvmeasure.driver.plan import diagnosis_plan, swept_plan
from cvmeasure.driver.session import SessionConfig, nominal_pin_for_loaded_deg
from cvmeasure.material.bender_calibration import MODES, fit_calibration
from cvmeasure.sim import simulate


@pytest.mark.parametrize("mode", list(MODES))
def test_every_angle_twice_each_way_after_reversals_and_not(mode):
    plan = SessionConfig(mode=mode).plan()
    angles = MODES[mode]
    assert len(plan) == 4 * len(angles)
    assert Counter(plan) == {(d, a): 2 for d in ("ccw", "cw") for a in angles}
    after_reversal = [i > 0 and plan[i - 1][0] != d for i, (d, _) in enumerate(plan)]
    # a sixth to a quarter of the bends follow a reversal (a backlash lost on reversals),
    # the rest a bend the same way, in runs of 4 and more (a drift shifting home walks)
    assert 0.12 < np.mean(after_reversal[1:]) < 0.4
    runs, run = [], 1
    for i in range(1, len(plan)):
        run = 1 if after_reversal[i] else run + 1
        runs.append(run)
    assert max(runs) >= min(4, len(angles)) and max(runs) <= 8
    # the angle does not follow the bend index (a drift or a warm-up would take its shape)
    a = np.array([x for _, x in plan])
    assert abs(np.corrcoef(a, np.arange(a.size))[0, 1]) < 0.2
    # the repeats of a bend are apart (n or 3 n bends: drift shows as their difference)
    gaps = [j - i for i in range(len(plan)) for j in range(i + 1, len(plan)) if plan[i] == plan[j]]
    assert np.median(gaps) >= len(angles)


def test_custom_angles_keep_the_listed_sweep():
    assert SessionConfig(mode="custom", angles_deg=(5.0, 20.0)).plan() == swept_plan((5.0, 20.0))
    with pytest.raises(ValueError, match="unknown mode"):
        SessionConfig(mode="slow").plan()


def _samples(plan, noise_deg=0.05, seed=3):
    rng = np.random.default_rng(seed)
    pins = np.array([round(nominal_pin_for_loaded_deg(a, d), 3) for d, a in plan])
    sim = simulate(pins)
    loaded = sim.loaded_bend_deg + rng.normal(0, noise_deg, pins.size)
    unloaded = sim.unloaded_bend_deg + rng.normal(0, noise_deg, pins.size)
    return [
        Trial(str(i + 1), float(p), float(lo), float(un), target_deg=a)
        for i, (p, lo, un, (_, a)) in enumerate(zip(pins, loaded, unloaded, plan, strict=True))
    ]


@pytest.mark.parametrize("model", ["linear", "pchip"])
def test_calibration_fit_unchanged_by_the_order(model):
    # the same bends in the session's order and sorted as the former sweep (ccw rising,
    # then cw): the same compensation to rounding
    samples = _samples(diagnosis_plan(MODES["standard"]))
    swept = sorted(samples, key=lambda t: (t.commanded_pin_deg < 0, abs(t.commanded_pin_deg)))
    swept = [dataclasses.replace(t, trial=str(i + 1)) for i, t in enumerate(swept)]
    a = fit_calibration(samples, model=model)
    b = fit_calibration(swept, model=model)
    for target in (-120.0, -40.0, -8.0, 8.0, 40.0, 120.0):
        assert a.compensate(target) == pytest.approx(b.compensate(target), abs=1e-9)
    # and the compensation bends the simulated machine within 0.1 deg
    for target in (-40.0, 8.0, 100.0):
        assert simulate([a.compensate(target)]).unloaded_bend_deg[0] == pytest.approx(
            target, abs=0.1
        )


def test_report_figure_with_repeated_bends():
    # repeats are averaged into one angle per curve, so the lowest single bend can lie
    # below the curve's domain: the report drew it over the raw range and refused
    from cvmeasure.driver.session_report import calibration_figure_png

    calibration = fit_calibration(_samples(diagnosis_plan(MODES["quick"]), seed=4))
    assert calibration_figure_png(calibration)[:8] == b"\x89PNG\r\n\x1a\n"
