"""The closed loop's stability figures separate a loop that settles from one that walks."""

from __future__ import annotations

import pytest

from benchmarks.closed_loop import _stability

TARGET = [10.0, -5.0]


def _run(errors):
    """Per-part records of executed bends ``TARGET + error`` (deg)."""
    return [
        {"made_deg": [t + e for t, e in zip(TARGET, err, strict=True)], "true_err_deg": list(err)}
        for err in errors
    ]


def test_a_third_correction_that_removes_an_error_is_not_a_walk():
    # part 2 still 0.08 off at vertex 0; the next correction fixes it, then nothing moves
    run = _run([(0.4, 0.3), (0.1, 0.0), (0.08, 0.0), (0.01, 0.0), (0.01, 0.0), (0.01, 0.0)])
    change, worse, walk = _stability([run])
    assert change == pytest.approx(0.07)
    assert worse == pytest.approx(0.0)
    assert walk == pytest.approx(0.0)


def test_a_loop_that_chases_noise_shows_in_every_figure():
    run = _run([(0.4, 0.3), (0.1, 0.0), (0.0, 0.0), (0.06, 0.0), (-0.06, 0.0), (0.06, 0.0)])
    change, worse, walk = _stability([run])
    assert change == pytest.approx(0.06)
    assert worse == pytest.approx(0.06)
    assert walk == pytest.approx(0.12)


def test_runs_without_further_parts_are_left_out():
    assert _stability([_run([(0.4, 0.3), (0.1, 0.0), (0.0, 0.0)])]) == (0.0, 0.0, 0.0)
