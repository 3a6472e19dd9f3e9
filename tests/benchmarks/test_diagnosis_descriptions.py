"""Scoring two params descriptions of one machine, and the coverage sample: each helper on
made-up diagnoses whose answer is known."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.diagnosis_session import (
    CATALOGUE,
    COVERAGE_CAUSES,
    MODES_RUN,
    SEED0,
    _cases,
    _coverage_cases,
    coverage_table,
    description_agreement,
    description_cases,
    similar_params,
)
from cvmeasure.sim import SimParams, simulate


def said(cause, intervals, causes=None, tie=()):
    causes = [cause] if causes is None and cause != "none" else (causes or [])
    return {"cause": cause, "causes": causes, "tie": list(tie), "intervals": intervals}


def test_a_similar_machine_is_every_length_times_k_and_predicts_the_same():
    p = SimParams().replace(die_radius_mm=1.7, yield_mpa=300.0)
    q = similar_params(p, 0.5)
    assert q.wire_diameter_mm == 1.5 and q.die_radius_mm == pytest.approx(0.85)
    assert q.pin_orbit_mm == 6.0 and q.yield_mpa == 300.0 and q.approach_deg == p.approach_deg
    cmd = np.array([30.0, -60.0, 90.0, -120.0])
    np.testing.assert_allclose(simulate(cmd, p).loaded_bend_deg, simulate(cmd, q).loaded_bend_deg)


def test_intervals_compared_in_standard_errors_after_the_similarity_scaling():
    # a 95 % interval 0.2 .. 0.6 mm: sigma 0.4 / 3.92; twice the size reads 0.4 .. 1.2 mm
    a = said("axis_offset", {"axis_offset_mm": [0.2, 0.6]})
    assert description_agreement(a, said("axis_offset", {"axis_offset_mm": [0.4, 1.2]}), 2.0) == (
        True,
        0.0,
    )
    # unscaled, the same numbers are far apart
    same, worst = description_agreement(a, said("axis_offset", {"axis_offset_mm": [0.4, 1.2]}))
    assert same and worst == pytest.approx(0.6 / (0.4 / 3.92))
    # a compliance at half the size reads 8 times larger (the torque k^3): one endpoint
    # off by 0.02 deg/(N m) in the machine's own terms, 0.2 standard errors of 0.392 / 3.92
    b = said("compliance", {"compliance_deg_per_nm": [8 * 0.1, 8 * 0.512]})
    a = said("compliance", {"compliance_deg_per_nm": [0.1, 0.492]})
    assert description_agreement(a, b, 0.5)[1] == pytest.approx(0.2)


def test_a_different_name_or_tie_is_not_the_same_diagnosis():
    a = said("compliance", {"compliance_deg_per_nm": [0.1, 0.3]})
    tied = said("backlash", {}, causes=["backlash"], tie=["backlash", "compliance"])
    assert description_agreement(a, tied) == (False, None)
    assert description_agreement(said("none", {}), said("none", {})) == (True, None)
    assert not description_agreement(said("none", {}), said("offset", {"offset_deg": [1, 2]}))[0]


def test_the_coverage_sample_draws_new_machines_of_the_scored_causes_only():
    extra = _coverage_cases(2)
    assert len(extra) == 2 * len(COVERAGE_CAUSES) * len(MODES_RUN)
    assert {n for _, n, _ in extra} == set(COVERAGE_CAUSES) <= set(CATALOGUE)
    main_seeds = {s for _, s, _, _ in _cases(("sim", "physical"), 3)}
    assert len({s for s, _, _ in extra}) == len(extra) and not main_seeds & {s for s, _, _ in extra}
    assert min(main_seeds) == SEED0


def test_description_sessions_take_the_modes_in_turn():
    cases = description_cases(2)
    assert len(cases) == 2 * (len(CATALOGUE) + 1)
    for name in (*CATALOGUE, "none"):
        modes = [m for _, n, m in cases if n == name]
        assert len(set(modes)) == 2  # two modes per cause, not one mode twice


def test_the_coverage_table_names_each_miss_with_its_truth_and_interval():
    rows = [
        {"generator": "sim", "hidden": "offset", "mode": "quick", "covered": True, "truth": 1.0, "interval": [0.9, 1.1], "estimate": 1.0},
        {"generator": "sim", "hidden": "offset", "mode": "high", "covered": False, "truth": 1.5, "interval": [1.1, 1.3], "estimate": 1.2},
        {"generator": "sim", "hidden": "drift", "mode": "high", "covered": None, "truth": None, "interval": None},
    ]  # fmt: skip
    # errors 0 and 0.3 of sigmas 0.2 / 3.92: rms sqrt((0 + 5.88^2) / 2) = 4.16
    assert coverage_table(rows) == [
        ["sim", "offset", "offset_deg", 2, 50.0, 4.16, "high truth 1.5 in [1.1, 1.3]"]
    ]
