"""Serial faults: `cvmeasure bend` + `--resume` against a controller on a pty (issue 43).

Each run streams a 2,000-line bending job (feed, bend, return, with ducks) with
``cvmeasure bend`` as a process, with one fault injected (stall, no ack, XOFF, error
status, dropped byte, garbled byte, port gone) at a random line. After a stop the run
resumes the way an operator would: ``cvmeasure bend JOB --port ... --resume`` (with
``--force`` only after a stop that says the part must be checked, and counted so); a
resume that refuses is a refusal, not a retry. The controller's truth log (what the
machine executed, move by move, with the share of each move that ran) is then scored
against the job:

* **run twice**: a line whose executed shares add up to more than one move;
* **lost**: a line that never ran while the run says it finished (exit 0);
* **out of order**: a line that started after a later line had started;
* a move belongs to the job line whose planned path it lies on (the same way round),
  whatever N word it carried: a dropped digit that made ``N1631`` read ``N161`` ran
  line 1631's motion, not line 161 again. A move on no job line's path is a
  **foreign move** (a corrupted line ran a motion the job lacks): counted on its own,
  it makes a finished run a wrong part unless the operator was asked to check it;
* **silent wrong part**: exit 0 with a lost, doubled or out-of-order line and no warning;
* every stop must say its line and reason (one stderr line with ``N<number>``).

Controller models: ``heldout`` (written from TinyG's documentation apart from this
project's code; used when ``benchmarks/heldout`` is present) and ``double`` (the
project's own :class:`~cvmeasure.testing.double.FakeTinyG`, in its two ``sr.line``
modes, through ``sim://``-less pty access).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import random
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from benchmarks import Metric, Table, finish

SECTION = "Serial faults: streaming, stops and resumes against controller models"

EXE = str(Path(sys.executable).with_name("cvmeasure"))
KINDS = ("stall", "noack", "xoff", "error", "drop", "garble", "gone")
MAX_RESUMES = 4


def make_job(n_lines: int, seed: int) -> list[str]:
    """A bending job of ``n_lines`` numbered lines: feeds, bends and returns, some ducks."""
    rng = random.Random(seed)
    lines = ["G21 G90", "G0 Z0", "G0 X0"]
    while len(lines) < n_lines - 1:
        feed = rng.uniform(8.0, 30.0)
        pin = rng.choice([-1, 1]) * rng.uniform(15.0, 80.0)
        lines += [f"G91 G1 Y{feed:.3f} F3000", "G90", f"G1 X{pin:.3f} F6000", "G0 X0"]
        if rng.random() < 0.1:
            lines += ["G0 Z180", "G0 Z0"]
    lines = lines[: n_lines - 1] + ["M2"]
    return [f"N{i} {t}" for i, t in enumerate(lines, start=1)]


@dataclass
class RunResult:
    model: str
    fault: str
    exits: list[int] = field(default_factory=list)
    stderr: list[str] = field(default_factory=list)
    forced: bool = False
    asked: int = 0
    refused: bool = False
    finished: bool = False
    twice: list[int] = field(default_factory=list)
    lost: list[int] = field(default_factory=list)
    out_of_order: list[int] = field(default_factory=list)
    #: moves on no job line's path (a corrupted block ran a motion the job lacks)
    foreign: list[int] = field(default_factory=list)
    stops_unclear: int = 0
    stops: int = 0
    warned: bool = False
    seconds: float = 0.0

    @property
    def silent_wrong(self) -> bool:
        wrong = bool(self.twice or self.lost or self.out_of_order or self.foreign)
        return self.finished and wrong and not (self.warned or self.forced)

    @property
    def foreign_unchecked(self) -> bool:
        """A foreign move ran and the run went on without the part being checked."""
        return bool(self.foreign) and not (self.forced or self.refused)


def planned_ends(job: list[str]) -> dict[int, tuple[tuple[float, ...], tuple[float, ...]]]:
    """Each line's move as (start, end) positions, axes x y z a."""
    pos = {"X": 0.0, "Y": 0.0, "Z": 0.0, "A": 0.0}
    relative = False
    out = {}
    for text in job:
        words = text.upper().split()
        start = tuple(pos.values())
        relative = (relative or "G91" in words) and "G90" not in words
        for w in words[1:]:
            if w[:1] in pos:
                pos[w[:1]] = pos[w[:1]] + float(w[1:]) if relative else float(w[1:])
        out[int(words[0][1:])] = (start, tuple(pos.values()))
    return out


def planned_lengths(job: list[str]) -> dict[int, float]:
    """Length of each line's move (its own small G-code reader: G90/G91, X Y Z A words)."""
    pos = {"X": 0.0, "Y": 0.0, "Z": 0.0, "A": 0.0}
    relative = False
    out: dict[int, float] = {}
    for text in job:
        words = text.upper().split()
        number = int(words[0][1:])
        if "G91" in words:
            relative = True
        if "G90" in words:
            relative = False
        moved = 0.0
        for w in words[1:]:
            axis = w[:1]
            if axis in pos:
                value = float(w[1:])
                new = pos[axis] + value if relative else value
                moved += (new - pos[axis]) ** 2
                pos[axis] = new
        out[number] = moved**0.5
    return out


def score(job: list[str], executed: list[tuple[int, float]]) -> tuple[list, list, list]:
    """(lines run twice, lines never run, lines out of order) from (line, distance moved).

    A line's moves (a cut one and the move that completed it) must add up to its
    planned length: more is a second run, less a line lost.
    """
    lengths = planned_lengths(job)
    moved: Counter[int] = Counter()
    order: list[int] = []
    for line, distance in executed:
        moved[line] += distance
        if distance > 1e-6:
            order.append(line)
    twice = sorted(n for n, d in moved.items() if d > lengths.get(n, 0.0) + 1e-2)
    lost = sorted(n for n, length in lengths.items() if length > 1e-6 and moved[n] < length - 1e-2)
    return twice, lost, _out_of_order(order)


def _out_of_order(order: list[int]) -> list[int]:
    out, high = [], -1
    for n in order:
        if n < high:
            out.append(n)
        high = max(high, n)
    return sorted(set(out))


def _bend(job: Path, port: str, extra: list[str], env: dict[str, str]) -> tuple[int, str]:
    proc = subprocess.run(
        [EXE, "bend", str(job), "--port", port, "--quiet", "--stall-timeout-s", "2", *extra],
        capture_output=True,
        timeout=600,
        env=env,
    )
    return proc.returncode, proc.stderr.decode("utf-8", "replace")


_ASKED = re.compile(r"--from-line N(\d+) if they were not or --from-line N(\d+) if they were")


def _operate(run: RunResult, job_path: Path, port_of, env: dict[str, str], inspect=None) -> None:
    """Bend, then resume after each stop as an operator would, until done or refused.

    ``--force`` once a message asks for the part to be checked (the operator looked and
    said go; counted), ``--from-line`` when a resume asks which lines were made:
    ``inspect(first, last)`` is the operator looking at the part (were lines first..last-1
    made?); without it the run ends refused.
    """
    extra: list[str] = []
    waited = 0
    for _ in range(MAX_RESUMES + 1 + 20):
        code, err = _bend(job_path, port_of(), extra, env)
        run.exits.append(code)
        run.stderr.append(err.strip())
        if "warning" in err.lower():
            run.warned = True
        if code == 0:
            run.finished = True
            return
        lines = [ln for ln in err.splitlines() if ln.strip()]
        force = ["--force"] if run.forced else []
        # a stop reads "job stopped (<reason>) at line N..."; a refused resume that names
        # the stopped job ("the job stopped after ...; check the part") is no new stop
        if "job stopped (" in err:
            run.stops += 1
            if len(lines) != 1 or (" at line N" not in err and "unknown line" not in err):
                run.stops_unclear += 1
            if "--force" in err and "check" in err:
                run.forced = True
                force = ["--force"]
            extra = ["--resume", *force]
            time.sleep(0.3)
            continue
        if "no such serial port" in err and waited < 20:
            waited += 1  # the port is not back yet: the operator waits for it
            time.sleep(0.5)
            continue
        asked = _ASKED.search(err)
        if asked and inspect is not None:
            first, last = int(asked.group(1)), int(asked.group(2))
            run.asked += 1
            made = inspect(first, last)
            extra = ["--resume", *force, "--from-line", str(last if made else first)]
            continue
        if "--force" in err and "check" in err and not run.forced:
            run.forced = True
            extra = ["--resume", "--force"]
            continue
        run.refused = True
        return
    run.refused = True


def _made(job: list[str], executed: list[tuple[int, dict, dict]], first: int, last: int) -> bool:
    """Did the machine make lines first..last-1 (looked at as moves, whatever their labels)?"""
    ends = planned_ends(job)
    for n in range(first, last):
        if n not in ends or ends[n][0] == ends[n][1]:
            continue
        start, end = ends[n]
        if not any(
            _near(a, start) and _near(b, end) or (label == n and _near(b, end))
            for label, a, b in executed
        ):
            return False
    return True


def _xyza(p: dict) -> tuple[float, ...]:
    return tuple(float(p.get(a, 0.0)) for a in "xyza")


def _on(p: tuple[float, ...], seg: tuple[tuple[float, ...], tuple[float, ...]]) -> bool:
    a, b = seg
    return abs(math.dist(a, p) + math.dist(p, b) - math.dist(a, b)) <= 0.01


def _near(p: dict, q: tuple[float, ...]) -> bool:
    return all(abs(float(p.get(a, 0.0)) - v) <= 0.01 for a, v in zip("xyza", q, strict=True))


def run_heldout(job: list[str], fault: str, work: Path, env: dict[str, str]) -> RunResult:
    from benchmarks.heldout.tinyg_controller import TinyGController
    from benchmarks.heldout.tinyg_faults import parse_fault

    run = RunResult("heldout", fault)
    job_path = work / "job.nc"
    job_path.write_text("\n".join(job) + "\n")
    link = work / "tty"
    t0 = time.perf_counter()
    with TinyGController(faults=[parse_fault(fault)], link=link) as board:

        def inspect(first: int, last: int) -> bool:
            moves = [(e.line, e.start, e.end) for e in board.truth().executed]
            return _made(job, moves, first, last)

        _operate(run, job_path, lambda: str(link), env, inspect)
        board.wait_idle(timeout_s=30)
        truth = board.truth()
    run.seconds = time.perf_counter() - t0
    # a truth entry's end is where the move stopped: its distance is what ran; a move
    # is the job line whose planned path it lies on, whatever N word it carried
    executed, run.foreign = attribute_moves(job, [(e.line, e.start, e.end) for e in truth.executed])
    run.twice, run.lost, run.out_of_order = score(job, executed)
    if not run.finished:
        run.lost = []  # a refused run finished nothing: nothing is claimed done
    if run.twice or run.lost or run.out_of_order:
        _keep_evidence(run, work, truth.to_json())
    return run


def _keep_evidence(run: RunResult, work: Path, truth: dict) -> None:
    """A failed run's journal and truth log, kept for a look (under the temp folder)."""
    keep = Path(tempfile.gettempdir()) / "cvm_serial_failures" / run.fault.replace(":", "_")
    keep.mkdir(parents=True, exist_ok=True)
    journal = work / "job.nc.journal.jsonl"
    if journal.exists():
        (keep / "journal.jsonl").write_text(journal.read_text())
    (keep / "truth.json").write_text(json.dumps(truth))
    (keep / "stderr.txt").write_text("\n---\n".join(run.stderr))


_DOUBLE_FAULTS = {
    "stall": "stall",
    "drop": "drop_byte",
    "garble": "malformed_reply",
    "error": "error_status",
    "gone": "vanish",
}


def run_double(
    job: list[str], fault: str, work: Path, env: dict[str, str], line_report: str
) -> RunResult:
    from cvmeasure.testing.double import FakeTinyG, Fault

    kind, _, rest = fault.partition("@")
    at, _, arg = rest.partition(":")
    run = RunResult(f"double-{line_report}", fault)
    job_path = work / "job.nc"
    job_path.write_text("\n".join(job) + "\n")
    # the double counts every line it receives: 13 setup commands come before N1
    faults = [
        Fault(
            _DOUBLE_FAULTS[kind],
            int(at) + 14,
            duration_s=float(arg or 3.0),
            byte_index=3 if kind == "drop" else 0,
        )
    ]
    t0 = time.perf_counter()
    with FakeTinyG(speedup=100.0, faults=faults, line_report=line_report) as board:

        def port() -> str:
            if board.vanished:
                board.reconnect()
            return board.port

        def inspect(first: int, last: int) -> bool:
            moved: Counter[int] = Counter()
            for n, d in attribute_moves(job, board.executed_moves())[0]:
                moved[n] += d
            lengths = planned_lengths(job)
            return all(
                moved[n] >= lengths[n] - 1e-2
                for n in range(first, last)
                if lengths.get(n, 0.0) > 1e-6
            )

        _operate(run, job_path, port, env, inspect)
        time.sleep(0.2)
        moves = board.executed_moves()
    run.seconds = time.perf_counter() - t0
    executed, run.foreign = attribute_moves(job, moves)
    run.twice, run.lost, run.out_of_order = score(job, executed)
    if not run.finished:
        run.lost = []
    return run


def attribute_moves(
    job: list[str], moves: list[tuple[int | None, dict, dict]]
) -> tuple[list[tuple[int, float]], list[int]]:
    """(job line, distance) for each move the machine made, and the foreign moves' labels.

    A move belongs to the job line whose planned path holds it, the same way round:
    its own label's line first, else the line nearest the last one attributed (a
    corrupted N word can name any line). A move on no job line's path is foreign: a
    corrupted block ran a motion the job does not have. Foreign moves are left out of
    the (line, distance) list: they are counted on their own, not as a labelled line.
    """
    ends = planned_ends(job)
    order = sorted(ends)
    out: list[tuple[int, float]] = []
    foreign: list[int] = []
    prev = order[0]
    for label, start, end in moves:
        p, q = _xyza(start), _xyza(end)
        distance = math.dist(p, q)
        n = -1 if label is None else int(label)
        if distance <= 1e-6:
            continue
        found = n if n in ends and _along(p, q, ends[n]) else None
        if found is None:
            near = sorted(order, key=lambda m: abs(m - prev))
            found = next((m for m in near if _along(p, q, ends[m])), None)
        if found is None:
            foreign.append(n)
            continue
        out.append((found, distance))
        prev = found
    return out, foreign


def _along(p: tuple[float, ...], q: tuple[float, ...], seg) -> bool:
    """Both ends on the planned segment and the move the same way round."""
    a, b = seg
    same_way = sum((y - x) * (d - c) for x, y, c, d in zip(p, q, a, b, strict=True)) > 0
    return same_way and _on(p, seg) and _on(q, seg)


def fault_plan(n_runs: int, n_lines: int, seed: int, kinds: tuple[str, ...] = KINDS) -> list[str]:
    rng = random.Random(seed)
    out = []
    for i in range(n_runs):
        kind = kinds[i % len(kinds)]
        line = rng.randrange(50, n_lines - 50)
        arg = {"stall": ":6", "xoff": ":3", "gone": ":1.5"}.get(kind, "")
        out.append(f"{kind}@{line}{arg}")
    return out


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.serial_faults", description=__doc__)
    p.add_argument("--quick", action="store_true", help="7 runs of 400-line jobs per model")
    p.add_argument("--runs", type=int, help="fault runs per model (default 63; quick 7)")
    p.add_argument("--lines", type=int, help="lines per job (default 2000; quick 400)")
    p.add_argument("--models", default="heldout,double-parsed", help="comma-separated models")
    p.add_argument("--faults", help="comma-separated fault specs instead of the random plan")
    args = p.parse_args(argv)
    n_runs = args.runs or (7 if args.quick else 63)
    n_lines = args.lines or (400 if args.quick else 2000)
    env = dict(os.environ)
    results: list[RunResult] = []
    models = [m for m in args.models.split(",") if m]
    heldout = Path(__file__).with_name("heldout").is_dir()
    for model in models:
        if model == "heldout" and not heldout:
            print("no benchmarks/heldout: skipping the held-out controller")
            continue
        kinds = KINDS if model == "heldout" else tuple(_DOUBLE_FAULTS)
        plan = args.faults.split(",") if args.faults else fault_plan(n_runs, n_lines, 43, kinds)
        for i, fault in enumerate(plan):
            job = make_job(n_lines, seed=i)
            with tempfile.TemporaryDirectory(prefix="cvm_serial_") as tmp:
                if model == "heldout":
                    r = run_heldout(job, fault, Path(tmp), env)
                else:
                    kind = fault.partition("@")[0]
                    if kind not in _DOUBLE_FAULTS:
                        continue
                    r = run_double(job, fault, Path(tmp), env, model.partition("-")[2])
            results.append(r)
            print(
                f"{model:14s} {fault:16s} exits {r.exits} twice {r.twice[:5]} lost {r.lost[:5]} "
                f"order {r.out_of_order[:5]} forced {r.forced} refused {r.refused} "
                f"{r.seconds:.1f}s | {r.stderr[0][:110] if r.stderr else ''}",
                flush=True,
            )
    return _report(results, argv, args.quick, n_lines)


def _report(results: list[RunResult], argv: list[str] | None, quick: bool, n_lines: int) -> dict:
    metrics = []
    rows = []
    for model in sorted({r.model for r in results}):
        rs = [r for r in results if r.model == model]
        twice = sum(len(r.twice) for r in rs)
        lost = sum(len(r.lost) for r in rs)
        order = sum(len(r.out_of_order) for r in rs)
        silent = sum(r.silent_wrong for r in rs)
        unclear = sum(r.stops_unclear for r in rs)
        finished = sum(r.finished for r in rs)
        foreign = sum(len(r.foreign) for r in rs)
        unchecked = sum(r.foreign_unchecked for r in rs)
        metrics += [
            Metric(
                f"{model}: fault runs of {n_lines}-line jobs",
                len(rs),
                "",
                target=">= 60",
                met=len(rs) >= 60,
            ),
            Metric(f"{model}: lines run twice", twice, "", target="= 0", met=twice == 0),
            Metric(f"{model}: lines lost", lost, "", target="= 0", met=lost == 0),
            Metric(f"{model}: lines out of order", order, "", target="= 0", met=order == 0),
            Metric(f"{model}: silent wrong parts", silent, "", target="= 0", met=silent == 0),
            Metric(
                f"{model}: corrupted lines run as a motion the job lacks (moves on no line's path)",
                foreign,
                "",
                target=None,
                met=None,
            ),
            Metric(
                f"{model}: runs going on after such a move without the part checked",
                unchecked,
                "",
                target="= 0",
                met=unchecked == 0,
            ),
            Metric(
                f"{model}: stops without their line and reason",
                unclear,
                "",
                target="= 0",
                met=unclear == 0,
            ),
            Metric(
                f"{model}: runs finished (the rest refused, naming the check)",
                finished,
                "",
                target=None,
                met=None,
            ),
            Metric(
                f"{model}: runs the operator was asked which lines ran (--from-line)",
                sum(r.asked > 0 for r in rs),
                "",
                target=None,
                met=None,
            ),
            Metric(
                f"{model}: runs the operator forced after checking the part (--force)",
                sum(r.forced for r in rs),
                "",
                target=None,
                met=None,
            ),
        ]
        for r in rs:
            rows.append(
                [
                    model,
                    r.fault,
                    " ".join(map(str, r.exits)),
                    r.forced,
                    r.refused,
                    len(r.twice),
                    len(r.lost),
                    len(r.out_of_order),
                    len(r.foreign),
                    (r.stderr[-1] if r.stderr else "")[:140],
                ]
            )
    return finish(
        __file__,
        SECTION,
        argv,
        quick=quick,
        metrics=metrics,
        tables=[
            Table(
                "runs",
                [
                    "model",
                    "fault",
                    "exits",
                    "forced",
                    "refused",
                    "twice",
                    "lost",
                    "out of order",
                    "foreign moves",
                    "last stderr line",
                ],
                rows,
            )
        ],
        notes=[
            "each run: `cvmeasure bend` as a process, then `--resume` after each stop "
            f"(at most {MAX_RESUMES}); `--force` only where a stop asks for the part to be checked",
            "lost lines are counted on finished runs only: a refused resume claims nothing done",
        ],
        # a stop message's form can depend on timing (what the board ran before the stop):
        # every stderr of such a run, to read without running it again
        extra={
            "unclear_stop_runs": [
                {"model": r.model, "fault": r.fault, "exits": r.exits, "stderr": r.stderr}
                for r in results
                if r.stops_unclear
            ]
        },
    )


if __name__ == "__main__":
    main()
