"""The held-out renders' budget: each render's CPU time kept beside the cache, each set's
total, and the whole set's only when every set's cost is known (no render, no Mitsuba)."""

from __future__ import annotations

import math
import time
from pathlib import Path

import pytest

from benchmarks import mitsuba_markers as mm
from benchmarks.mitsuba_parts import _whole_set_budget


def _busy_render(out: Path, cpu_s: float) -> Path:
    """A stand-in render: spends ``cpu_s`` of CPU unless its output is cached."""
    if not out.exists():
        t0 = time.process_time()
        while time.process_time() - t0 < cpu_s:
            sum(i * i for i in range(1000))
        out.write_text("render")
    return out


def test_a_cached_render_is_counted_at_the_cost_it_had(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr(mm, "_RENDERED", [])
    first = mm._timed(tmp_path, "part", _busy_render, tmp_path / "a.jpg", 1.2)
    assert first == tmp_path / "a.jpg"
    spent = mm._RENDERED[-1][1]
    assert spent == pytest.approx(1.2, abs=0.3)
    mm._timed(tmp_path, "part", _busy_render, tmp_path / "a.jpg", 1.2)  # cached now
    assert mm._RENDERED[-1][1] == spent
    assert mm._render_cpu_h(("part",)) == pytest.approx(2 * spent / 3600.0, rel=1e-6)


def test_the_whole_set_is_known_only_when_every_set_is(tmp_path: Path) -> None:
    cpu_h, missing = mm.whole_set_cpu_h(tmp_path)
    assert math.isnan(cpu_h) and missing == list(mm.RENDER_SETS)
    for i, name in enumerate(mm.RENDER_SETS[:-1]):
        mm.record_render_set(tmp_path, name, 0.3 + i, renders=10)
    metric = _whole_set_budget(tmp_path)
    assert mm.RENDER_SETS[-1] in metric.name and metric.met is False
    mm.record_render_set(tmp_path, mm.RENDER_SETS[-1], 0.2, renders=40)
    cpu_h, missing = mm.whole_set_cpu_h(tmp_path)
    assert missing == [] and cpu_h == pytest.approx(0.3 + 1.3 + 0.2)
    metric = _whole_set_budget(tmp_path)
    assert metric.value == pytest.approx(0.9) and metric.met is True
    mm.record_render_set(tmp_path, mm.RENDER_SETS[0], 1.5, renders=10)  # rendered again
    assert _whole_set_budget(tmp_path).met is False
