"""Design corpus: every design file as operators export it through `cvmeasure gcode` (issue 36).

The corpus (``tests/cvmeasure/data/designs``: Inkscape px and mm documents, Illustrator
pt, plain SVG in in/cm/pt and without units, LibreCAD/QCAD/ezdxf DXF in mm, cm, inches,
metres and without units; arcs, Beziers, splines, bulges, lines out of order, gaps,
closed shapes, self-contact, too-short segments) with the outcome each file's
construction gives (``expected.json``, written by ``make_corpus.py`` without cvmeasure).
Each file is run as an operator runs it: ``cvmeasure gcode FILE -o JOB --json``, a
process with the defaults. Scored: the outcome (bent as drawn, or refused with exit 2,
one stderr line naming the element and the number, nothing written), and whether a
design was changed without a refusal or a printed table.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks import Metric, Table, finish

SECTION = "Design corpus: designs as operators export them, through cvmeasure gcode"
CORPUS = Path(__file__).resolve().parents[1] / "tests" / "cvmeasure" / "data" / "designs"


def _run(args: list[str]) -> tuple[int, str, str]:
    proc = subprocess.run(
        [sys.executable, "-m", "cvmeasure", *args], capture_output=True, text=True, check=False
    )
    return proc.returncode, proc.stdout, proc.stderr


def _as_drawn(want: dict, feeds: np.ndarray, turns: np.ndarray) -> bool:
    if "chords_mm" not in want:
        return False
    c, t = np.asarray(want["chords_mm"]), np.asarray(want["turns_deg"])
    for cc, tt in ((c, t), (c[::-1], -t[::-1])):
        if len(cc) == len(feeds) and np.allclose(feeds, cc, atol=0.01):
            if np.allclose(turns, tt, atol=0.01):
                return True
    return False


def score(name: str, want: dict, folder: Path) -> dict:
    """Run one design through the CLI and score it against its expected outcome."""
    out = folder / f"{name}.gcode"
    code, stdout, stderr = _run(["gcode", str(CORPUS / name), "-o", str(out), "--json"])
    row = {"design": name, "expected": want["outcome"], "exit": code}
    if want["outcome"] == "refused":
        words = all(w in stderr for w in want["message"])
        one_line = stderr.count("\n") == 1
        row.update(
            ok=code == 2 and words and one_line and not out.exists(),
            silent=code == 0,
            detail=stderr.strip().split(f"{name}: ", 1)[-1][:90],
        )
        return row
    if code != 0:
        row.update(ok=False, silent=False, detail=stderr.strip()[:90])
        return row
    job = json.loads(stdout)
    steps = job["bend_list"]
    feeds = np.array([s["feed_mm"] for s in steps])
    turns = -np.array([s["bend_deg"] for s in steps[:-1]])
    changes = [c["what"] for c in job["plan"]["changes"]]
    header = out.read_text(encoding="utf-8")
    kept = all(f"; {c}:" in header for c in changes)
    drawn = _as_drawn(want, feeds, turns)
    expected_changes = sorted(changes) == sorted(want["changes"])
    row.update(
        ok=(drawn or "chords_mm" not in want) and expected_changes and kept,
        silent=not drawn and not (changes and kept),
        detail=f"{len(turns)} bends; " + (", ".join(changes) if changes else "as drawn"),
    )
    return row


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.design_corpus", description=__doc__)
    p.add_argument("--quick", action="store_true", help="the same (the corpus is small)")
    args = p.parse_args(argv)
    expected = json.loads((CORPUS / "expected.json").read_text(encoding="utf-8"))
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        rows = [score(name, want, Path(tmp)) for name, want in sorted(expected.items())]
    seconds = time.perf_counter() - t0
    n = len(rows)
    right = sum(r["ok"] for r in rows)
    silent = sum(r["silent"] for r in rows)
    refused = [r for r in rows if r["expected"] == "refused"]
    metrics = [
        Metric("designs in the corpus", n, "", target=">= 30", met=n >= 30),
        Metric(
            "outcome as expected (bends/feeds as drawn or the stated change; refusal "
            "naming element and number)",
            right,
            f"of {n}",
            target=f"{n}",
            met=right == n,
        ),  # fmt: skip
        Metric(
            "designs changed without a refusal or a printed table",
            silent,
            "",
            target="0",
            met=silent == 0,
        ),  # fmt: skip
        Metric(
            "refusals: exit 2, one line, nothing written",
            sum(r["ok"] for r in refused),
            f"of {len(refused)}",
            target=f"{len(refused)}",
            met=all(r["ok"] for r in refused),
        ),  # fmt: skip
        Metric("wall time (one cvmeasure process per design)", seconds, "s"),
    ]
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[
            Table(
                "every design: expected outcome, exit code, what cvmeasure gcode said",
                ["design", "expected", "exit", "ok", "detail"],
                [[r["design"], r["expected"], r["exit"], r["ok"], r["detail"]] for r in rows],
            )
        ],
        notes=[
            "expected outcomes come from each file's construction (make_corpus.py, no "
            "cvmeasure code): chords and turns of polylines, chord count and length of arcs "
            "divided into the most chords >= 12 mm, or the words a refusal must contain",
        ],
    )


if __name__ == "__main__":
    main()
