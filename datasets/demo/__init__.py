"""The end-to-end demo (``cvmeasure demo``): every stage on rendered data with exact truth.

Each stage has a ``demo_step(out_dir, *, seed) -> DemoSection`` in a module of
this package (:data:`DEMO_STAGES`); :func:`run_demo` runs them in order and
:func:`format_sections` prints one table of measured against true values.
The demo lives in the photo lab, not in the stages: no measuring stage
imports the renderer.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from pathlib import Path

from cvmeasure_datasets.demo import (
    calibration,
    diagnose,
    lab,
    markers,
    part,
    session,
    streaming,
)
from cvmeasure_datasets.demo.report import DemoRow, DemoSection, format_sections

__all__ = ["DemoRow", "DemoSection", "DEMO_STAGES", "run_demo", "format_sections"]

DemoStep = Callable[..., DemoSection]

#: (title, step) of each stage, in the order the demo runs them.
DEMO_STAGES: tuple[tuple[str, DemoStep], ...] = (
    ("synthetic photo lab", lab.demo_step),
    ("lens calibration", calibration.demo_step),
    ("bender photos", markers.demo_step),
    ("finished part", part.demo_step),
    ("diagnosis", diagnose.demo_step),
    ("bender streaming", streaming.demo_step),
    ("calibration session", session.demo_step),
)


def run_demo(
    out_dir: Path,
    *,
    seed: int = 7,
    stages: tuple[tuple[str, DemoStep], ...] = DEMO_STAGES,
    progress: Callable[[str], None] | None = None,
) -> list[DemoSection]:
    """Run every stage in order; return their sections (with the seconds each took)."""
    out_dir.mkdir(parents=True, exist_ok=True)
    sections = []
    for title, step in stages:
        if progress:
            progress(f"running {title} ...")
        t0 = time.perf_counter()
        section = step(out_dir, seed=seed)
        section.seconds = time.perf_counter() - t0
        sections.append(section)
    return sections
