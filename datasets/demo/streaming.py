"""Demo step: a half circle from design to G-code to the TinyG double, through a fault.

The seed paper's half circle (R 100 mm, 20 chords, 9 degree bends) becomes
G-code with the simulation's compensation, is streamed over a real
pseudo-terminal to :class:`~cvmeasure.testing.double.FakeTinyG`, whose USB port
vanishes part-way; the job is resumed from its journal, and the wire the
double bent (simulated) is compared with the design.
"""

from __future__ import annotations

from collections import Counter
from pathlib import Path

import numpy as np

from cvmeasure_datasets.demo.report import DemoRow, DemoSection

__all__ = ["demo_step"]


def demo_step(out_dir: Path, *, seed: int = 7) -> DemoSection:
    """Run the streaming demo; write the G-code and its journal under ``out_dir``."""
    from cvmeasure.design import arc_points_mm, bend_angles_deg
    from cvmeasure.driver.stream import JobStopped, StreamConfig, stream_job
    from cvmeasure.driver.transport import open_link
    from cvmeasure.fileio import atomic_write_text
    from cvmeasure.gcode import design_job
    from cvmeasure.testing.double import FakeTinyG, Fault

    rng = np.random.default_rng(seed)
    design = arc_points_mm((0.0, 0.0), 100.0, 90.0, 180.0, chords=20)
    job = design_job(design, source="half-circle R100 x 20")
    gcode = atomic_write_text(Path(out_dir) / "half_circle.gcode", job.text())
    journal = Path(out_dir) / "half_circle.gcode.journal.jsonl"
    journal.unlink(missing_ok=True)
    fault_line = int(rng.integers(25, 60))
    config = StreamConfig(stall_timeout_s=1.0)
    section = DemoSection("bender streaming (G-code -> TinyG double)")
    with FakeTinyG(speedup=200.0, faults=[Fault("vanish", fault_line)]) as board:
        stop_line = None
        link = open_link(board.port)
        try:
            stream_job(link, job.lines, journal=journal, config=config)
        except JobStopped as exc:
            stop_line = exc.stop.line_number
        finally:
            link.close()
        if board.vanished:
            board.reconnect()
        with open_link(board.port) as link:
            stream_job(link, job.lines, journal=journal, resume=True, config=config)
        completed, _ = board.executed_lines()
        shape = board.wire_shape_mm()
        stats = board.stats
    counts = Counter(n for n in completed if n is not None)
    expected = range(0, len(job.lines) + 1)
    lost = sum(1 for n in expected if counts[n] == 0)
    repeated = sum(c - 1 for c in counts.values() if c > 1)
    bent = bend_angles_deg(shape)
    wanted = bend_angles_deg(design)
    section.rows += [
        DemoRow("lines in the job", len(job.lines), None, "lines"),
        DemoRow("lines lost after port loss + resume", lost, 0, "lines", 0),
        DemoRow("lines executed twice", repeated, 0, "lines", 0),
        DemoRow("RX buffer bytes dropped", stats.rx_dropped_bytes, 0, "bytes", 0),
        DemoRow("segment bend, mean (simulated wire)", float(np.mean(bent)), 9.0, "deg", 0.01),
        DemoRow(
            "segment bend, worst error", float(np.max(np.abs(bent - wanted))), 0.0, "deg", 0.01
        ),
        DemoRow(
            "wire fed", float(board.machine_state().feed_mm), job.bends.total_feed_mm, "mm", 0.01
        ),
    ]
    section.notes.append(
        f"the port vanished after board line {fault_line}; the stop was journalled at "
        f"N{stop_line} and the job resumed from the board's own line and position"
    )
    section.files += [str(gcode), str(journal)]
    return section
