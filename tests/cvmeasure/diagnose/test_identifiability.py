"""Confounded causes are reported with the experiment that separates them."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import Cause, diagnose
from cvmeasure.diagnose.identify import check_identifiability, signature, similarity
from cvmeasure.sim import SimParams
from cvmeasure_datasets.trials import hidden_case


def test_one_direction_confounds_backlash_and_offset():
    case = hidden_case(3, effect="backlash", n_trials=30, both_directions=False)
    result = diagnose(case.trials)
    assert result.cause.primary in ("backlash", "offset")
    pair = {i.causes[1]: i for i in result.identifiability}
    other = "offset" if result.cause.primary == "backlash" else "backlash"
    assert not pair[other].separable
    assert pair[other].similarity > 0.999
    assert "reverse bends" in result.recommended_experiment


def test_without_loaded_angles_springback_asymmetry_needs_the_loaded_photo():
    case = hidden_case(4, effect="springback_asymmetry", n_trials=40, loaded=False)
    result = diagnose(case.trials)
    assert result.cause != Cause.none()
    confounded = [i for i in result.identifiability if not i.separable]
    assert confounded, "asymmetric springback is confounded with a machine cause here"
    assert "loaded angle" in result.recommended_experiment


def test_both_directions_with_loaded_angles_separate_the_catalogue():
    cmd = np.linspace(15.0, 150.0, 24) * np.where(np.arange(24) % 2, 1.0, -1.0)
    design = TrialTable.from_arrays(cmd, np.zeros(24), np.zeros(24))
    for item in check_identifiability(
        design, SimParams(), "backlash", ["offset", "scale", "drift", "axis_offset"]
    ):
        assert item.separable, item


def test_similarity_is_scale_free_and_projects_nuisance():
    a = np.array([1.0, 2.0, 3.0])
    assert similarity(a, -2 * a, np.array([0.0, 0.0, 1.0])) == pytest.approx(1.0)
    assert similarity(a, np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.0, 1.0])) == pytest.approx(0.0)
    design = TrialTable.from_arrays([40.0, -40.0], [0.0, 0.0], [0.0, 0.0])
    sig = signature(design, SimParams(), "offset")
    assert sig.shape == (4,) and sig[0] > 0 and sig[1] > 0  # +c turns both directions ccw
