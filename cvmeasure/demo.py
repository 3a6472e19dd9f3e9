"""The end-to-end demo: every stage that exists, on embedded (rendered) data.

Each stage contributes a ``demo_step(out_dir, *, seed) -> DemoSection`` in the
module listed in :data:`DEMO_STAGES`; the demo runs them in order and prints
one table of measured against true values.
"""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["DemoRow", "DemoSection", "DEMO_STAGES", "run_demo", "format_sections"]


@dataclass(frozen=True)
class DemoRow:
    """One measured quantity beside its ground truth."""

    quantity: str
    measured: float
    true: float | None
    unit: str
    tolerance: float | None = None

    @property
    def error(self) -> float | None:
        return None if self.true is None else self.measured - self.true

    @property
    def ok(self) -> bool | None:
        if self.tolerance is None or self.error is None:
            return None
        return abs(self.error) <= self.tolerance

    def to_dict(self) -> dict[str, Any]:
        return {
            "quantity": self.quantity,
            "measured": self.measured,
            "true": self.true,
            "error": self.error,
            "unit": self.unit,
            "tolerance": self.tolerance,
            "ok": self.ok,
        }


@dataclass
class DemoSection:
    """What one stage of the demo measured, and the files it wrote."""

    title: str
    rows: list[DemoRow] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "title": self.title,
            "rows": [r.to_dict() for r in self.rows],
            "files": self.files,
            "notes": self.notes,
            "seconds": round(self.seconds, 3),
        }


#: (title, module) of each stage, in the order the demo runs them.
DEMO_STAGES: tuple[tuple[str, str], ...] = (
    ("synthetic photo lab", "datasets.demo"),
    ("lens calibration", "cvmeasure.calibration.demo"),
    ("bender photos", "cvmeasure.markers.demo"),
    ("finished part", "cvmeasure.part.demo"),
    ("diagnosis", "cvmeasure.diagnose.demo"),
    ("bender streaming", "cvmeasure.driver.streaming_demo"),
    ("calibration session", "cvmeasure.driver.session_demo"),
)


def _load_step(module_name: str) -> Callable[..., DemoSection] | None:
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name is not None and module_name.startswith(exc.name):
            return None
        raise
    return getattr(module, "demo_step", None)


def run_demo(
    out_dir: Path,
    *,
    seed: int = 7,
    stages: tuple[tuple[str, str], ...] = DEMO_STAGES,
    progress: Callable[[str], None] | None = None,
) -> list[DemoSection]:
    """Run every available stage; return their sections (stages not built are skipped)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    sections = []
    for title, module_name in stages:
        step = _load_step(module_name)
        if step is None:
            continue
        if progress:
            progress(f"running {title} ...")
        t0 = time.perf_counter()
        section = step(out_dir, seed=seed)
        section.seconds = time.perf_counter() - t0
        sections.append(section)
    return sections


def _fmt(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.6g}"


def format_sections(sections: list[DemoSection]) -> str:
    """A readable plain-text table of every section."""
    lines: list[str] = []
    for s in sections:
        lines.append(f"== {s.title}  ({s.seconds:.1f} s)")
        lines.append(
            f"  {'quantity':<38} {'measured':>11} {'true':>11} {'error':>11} {'unit':<6} ok"
        )
        for r in s.rows:
            ok = {True: "yes", False: "NO", None: ""}[r.ok]
            lines.append(
                f"  {r.quantity:<38} {_fmt(r.measured):>11} {_fmt(r.true):>11} {_fmt(r.error):>11} {r.unit:<6} {ok}"
            )
        for note in s.notes:
            lines.append(f"  note: {note}")
        for f in s.files:
            lines.append(f"  wrote {f}")
    return "\n".join(lines)
