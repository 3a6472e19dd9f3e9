"""The runnable examples in docs/examples/ run and measure what they rendered.

Each example is run as a user runs it (its ``main``), into a temporary folder; the
measured values are checked against the photo lab's ground truth.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[2] / "docs" / "examples"


def _load(name: str):
    spec = importlib.util.spec_from_file_location(name, EXAMPLES / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_measure_with_the_api(tmp_path, capsys):
    rows = _load("measure_with_the_api").main(["-o", str(tmp_path), "--scale", "0.5"])
    # Half-size photos: the tolerances are the README's headline accuracies, widened for
    # the half resolution (no lens calibration or plane in a 10-line example).
    tolerance = {
        "bend angle (deg)": 0.05,
        "pin angle (deg)": 0.05,
        "part radius (mm)": 0.1,
        "part arc angle (deg)": 0.3,
        "worst vertex bend error vs design (deg)": 0.1,
        "G-code bends": 0.0,
    }
    for name, (measured, true) in rows.items():
        assert abs(measured - true) <= tolerance[name], name
    for out in ("part.json", "half-circle.gcode"):
        assert (tmp_path / out).stat().st_size > 0
    assert "part radius (mm)" in capsys.readouterr().out
