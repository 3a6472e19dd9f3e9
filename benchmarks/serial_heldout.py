"""Serial streaming against a held-out TinyG model: faults, the operator's resume, scored against the board's truth log (issue 43).

Jobs of 2,000 lines are written here in the bender's G-code dialect (``cvmeasure gcode``
refuses the 9 m of wire they would take); the quick run streams a job that ``cvmeasure
gcode`` made from a design of ours (a random open polyline). ``cvmeasure bend JOB --port PTY``
streams each to :mod:`benchmarks.heldout.tinyg_controller` (a TinyG model written from the
firmware's documentation, on a pseudo-terminal) with one fault injected. After a stop the
operator does what ``cvmeasure bend --help`` and the stop message say: re-run with
``--resume`` (at most twice more, and not again when a resume changed nothing); when asked
to check the part before ``--resume --force``, the operator checks it (against the truth
log) and either resumes with ``--force`` or scraps a bad part. The controller's truth log says which
lines really ran: lines run twice, lost, out of order, corrupted lines that reached the
planner, silent wrong parts (exit 0 but the executed sequence differs from the job), and
whether every stop was clean: a reason on stderr naming the line the board really stopped
at (the line in progress, or the next one after a completed line, when the streamer exited
or once the board settled), and no move started after the streamer left (except when the
port itself vanished and nobody could stop the board). A streamer still running after
45 s is killed, as an operator would, and counts as an unclean stop.
"""

from __future__ import annotations

import argparse
import math
import random
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import asdict, dataclass, field
from pathlib import Path

from benchmarks import Metric, Table, finish
from benchmarks.heldout.score import ExpectedJob, expected_job, score_job
from benchmarks.heldout.tinyg_controller import TinyGController
from benchmarks.heldout.tinyg_faults import FAULT_KINDS, Fault
from benchmarks.heldout.tinyg_machine import MachineConfig
from benchmarks.heldout.tinyg_truth import TruthLog

SECTION = "Serial streaming vs a held-out TinyG model (issue 43)"
CVMEASURE = str(Path(sys.executable).with_name("cvmeasure"))
SPEEDUP = 200.0  # machine seconds per real second: a 2,000-line job runs in ~5 s
MAX_ATTEMPTS = 3
GRACE_S = 0.5  # watch the board this long after the streamer exits
ATTEMPT_TIMEOUT_S = 45.0  # an operator kills a streamer silent for this long
HUNG = -9  # the exit code recorded for a streamer killed after ATTEMPT_TIMEOUT_S
_LINE = re.compile(r"\bN(\d+)\b")


@dataclass
class Attempt:
    """One ``cvmeasure bend`` process: its exit, its stderr verdict, and what the board did."""

    resume: bool
    force: bool
    rc: int
    seconds: float
    message: str
    named_line: int | None
    board_lines: list[int]
    moves_started_after_exit: list[int] = field(default_factory=list)

    @property
    def names_line_and_reason(self) -> bool:
        return self.rc != HUNG and self.named_line is not None and bool(self.message)

    @property
    def clean_stop(self) -> bool:
        """A reason, and the line the board really stopped at (``board_lines``)."""
        return self.names_line_and_reason and self.named_line in self.board_lines


@dataclass
class Run:
    """One job streamed with one fault, and its score."""

    design: str
    fault: str
    kind: str
    attempts: list[Attempt]
    finished: bool
    ran_twice: list[int]
    lost: list[int]
    out_of_order: list[int]
    corrupted: list[int]
    feed_error_mm: float | None
    fault_fired: bool
    scrapped: bool

    @property
    def silent_wrong(self) -> bool:
        return self.finished and bool(
            self.ran_twice
            or self.lost
            or self.out_of_order
            or self.corrupted
            or (self.feed_error_mm or 0.0) > 1e-3
        )

    def stops(self) -> list[Attempt]:
        """Attempts that stopped on a fault (exit 1) or hung; exit 2 is a refusal to start."""
        return [a for a in self.attempts if a.rc in (1, HUNG)]

    def unclean_stops(self) -> list[Attempt]:
        return [
            a
            for a in self.stops()
            if not a.clean_stop or (a.moves_started_after_exit and self.kind != "gone")
        ]


def write_job(path: Path, seed: int, min_lines: int) -> None:
    """A job in the bender's G-code dialect (docs/streaming.md, "Lines"), written here.

    ``cvmeasure gcode`` refuses a wire longer than 3 m, which caps its jobs near 1,200
    lines; the 2,000-line jobs are written in the same dialect: ``N1 G21 G90``, ``G0 Z0``,
    ``G0 X0``, then per bend a relative feed, the pin to its angle and back home, the pin
    ducked (``Z180`` then ``Z0``) when the bend direction changes, and an ``N`` end marker.
    Feeds 12-30 mm, pin angles 25-80 deg of either sign (fixed seed).
    """
    rng = random.Random(seed)
    lines = ["G21 G90 (heldout job)", "G0 Z0", "G0 X0"]
    side = 1
    while len(lines) < min_lines - 2:
        lines.append(f"G91 G1 Y{rng.uniform(12.0, 30.0):.3f} F3000")
        if rng.random() < 0.4:
            side = -side
            lines += ["G90 G0 Z180", "G0 Z0"]
        lines += [f"G90 G1 X{side * rng.uniform(25.0, 80.0):.3f} F6000", "G0 X0"]
    lines.append(f"G91 G1 Y{rng.uniform(12.0, 30.0):.3f} F3000")
    numbered = [f"N{i} {text}" for i, text in enumerate(lines, start=1)]
    numbered.append(f"N{len(lines) + 1} (end)")
    path.write_text(f"; heldout job, seed {seed}\n" + "\n".join(numbered) + "\n")


def write_design(path: Path, seed: int, segments: int) -> None:
    """An open zigzag polyline SVG: random segment lengths and turns (our own design)."""
    rng = random.Random(seed)
    pts = [(0.0, 0.0)]
    heading = 0.0
    for _ in range(segments):
        step = rng.uniform(14.0, 30.0)
        turn = math.radians(rng.uniform(15.0, 80.0))
        heading = turn if heading <= 0 else heading - turn  # zigzag: it never meets itself
        x, y = pts[-1]
        pts.append((x + step * math.cos(heading), y + step * math.sin(heading)))
    points = " ".join(f"{x:.3f},{y:.3f}" for x, y in pts)
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="4000mm" height="4000mm" '
        'viewBox="-2000 -2000 4000 4000">'
        f'<polyline points="{points}" fill="none" stroke="black"/></svg>\n'
    )


def make_job(workdir: Path, seed: int, size: int, source: str) -> Path:
    """The job: ``cvmeasure gcode`` on a design of ours (``size`` segments), or written
    in the dialect here (``size`` lines)."""
    job = workdir / f"job{seed}.nc"
    if source == "written":
        write_job(job, seed, size)
        return job
    svg = workdir / f"design{seed}.svg"
    write_design(svg, seed, size)
    subprocess.run([CVMEASURE, "gcode", str(svg), "-o", str(job)], check=True, capture_output=True)
    return job


def fault_plan(job: ExpectedJob, seed: int, variants: int) -> list[Fault]:
    """``variants`` faults of each kind at random lines of the job (fixed seed)."""
    rng = random.Random(seed)
    lines = sorted(job.text_by_line)
    pick = lambda: rng.choice(lines[40:-30])  # noqa: E731
    args: dict[str, list[float | None]] = {
        "stall": [2.0, 8.0, None],
        "noack": [None, None, None],
        "xoff": [2.0, 8.0, 8.0],
        "error": [130, 202, 108],
        "gone": [1.0, 3.0, 1.0],
    }
    faults = []
    for kind in FAULT_KINDS:
        for v in range(variants):
            n = pick()
            if kind in ("drop", "garble"):
                faults.append(
                    Fault(kind, line=n, arg=_byte_index(job.text_by_line[n], kind, v, rng))
                )
            else:
                faults.append(Fault(kind, line=n, arg=args[kind][v % 3]))
    return faults


def _byte_index(text: str, kind: str, variant: int, rng: random.Random) -> float:
    """Which byte of the line the fault hits: a digit of a value, the LF, 'N', an axis letter."""
    digits = [i for i, c in enumerate(text) if c.isdigit() and i > text.find(" ")]
    letters = [i for i, c in enumerate(text) if c in "XYZ"]
    if kind == "drop":
        choice = [-1, rng.choice(digits or [0]), 0][variant % 3]
    else:
        choice = [rng.choice(digits or [1]), rng.choice(letters or [1]), rng.randrange(len(text))][
            variant % 3
        ]
    return float(choice)


def _stop_lines(truth: TruthLog, t_exit: float, job: ExpectedJob) -> list[int]:
    """Lines a stop may name: the faulty line, where the board was when the streamer
    exited, and where it settled (the line in progress, or the one after a completed line)."""
    out: set[int] = {f["line"] for f in truth.faults if f["line"] is not None}
    at_exit = [e for e in truth.executed if e.t_start_s <= t_exit]
    for recs, t_done in ((at_exit, t_exit), (truth.executed, float("inf"))):
        if not recs:
            continue
        last = recs[-1]
        out.add(last.line)
        out.update(int(n) for n in _LINE.findall(last.text))  # a merged line names two
        if last.how == "done" and last.t_end_s <= t_done:
            out.add(last.line + 1)
            later = [n for n in job.moving_lines if n > last.line]
            if later:
                out.add(later[0])
    return sorted(out)


def _attempt(
    board: TinyGController, job_path: Path, job: ExpectedJob, resume: bool, force: bool
) -> Attempt:
    cmd = [CVMEASURE, "bend", str(job_path), "--port", board.port, "--quiet"]
    cmd += ["--force"] if force else []
    t0 = time.monotonic()
    try:
        proc = subprocess.run(
            cmd + (["--resume"] if resume else []),
            capture_output=True,
            text=True,
            timeout=ATTEMPT_TIMEOUT_S,
        )
        rc, stderr = proc.returncode, proc.stderr
    except subprocess.TimeoutExpired as exc:  # the operator gives up waiting and kills it
        err = exc.stderr.decode() if isinstance(exc.stderr, bytes) else (exc.stderr or "")
        rc, stderr = HUNG, err + f"\n(no exit after {ATTEMPT_TIMEOUT_S:g} s: killed)"
    t_exit = board.elapsed_s()
    time.sleep(GRACE_S)
    truth = board.truth()
    lines = stderr.strip().splitlines()
    message = " ".join(lines[-2:] if rc == HUNG else lines[-1:]) if rc else ""
    named = _LINE.search(message)
    return Attempt(
        resume,
        force,
        rc,
        round(time.monotonic() - t0, 2),
        message,
        int(named.group(1)) if named else None,
        _stop_lines(truth, t_exit, job),
        [e.line for e in truth.executed if e.t_start_s > t_exit],
    )


def _wait_for_port(path: Path, timeout_s: float = 10.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not path.exists() and time.monotonic() < deadline:
        time.sleep(0.05)


def stream_with_fault(job_path: Path, job: ExpectedJob, fault: Fault, design: str) -> Run:
    """Stream one job with one fault; resume after stops as the operator would; score it."""
    with tempfile.TemporaryDirectory(prefix="serial_heldout_") as tmp:
        local_job = Path(tmp) / job_path.name
        local_job.write_text(job_path.read_text())
        board = TinyGController([fault], MachineConfig(speedup=SPEEDUP), link=Path(tmp) / "tty")
        with board:
            time.sleep(0.1)
            attempts: list[Attempt] = []
            force = scrapped = False
            for i in range(MAX_ATTEMPTS):
                _wait_for_port(Path(board.port))  # an operator plugs the cable back first
                done_before = len(board.truth().executed)
                attempts.append(_attempt(board, local_job, job, resume=i > 0, force=force))
                if attempts[-1].rc == 0:
                    break
                if "--force" in attempts[-1].message:  # "check the part first": the operator
                    check = score_job(job, board.truth(), finished=False)  # looks at it
                    if check.corrupted or check.ran_twice or check.lost or check.out_of_order:
                        scrapped = True
                        break
                    force = True
                stuck = len(board.truth().executed) == done_before
                if i > 0 and stuck and attempts[-1].message == attempts[-2].message:
                    break  # the resume changed nothing: the operator stops here
            board.wait_idle(timeout_s=3.0)
            truth = board.truth()
    finished = attempts[-1].rc == 0
    score = score_job(job, truth, finished)
    return Run(
        design,
        fault.spec,
        fault.kind,
        attempts,
        finished,
        score.ran_twice,
        score.lost,
        score.out_of_order,
        score.corrupted,
        None if score.feed_error_mm is None else round(score.feed_error_mm, 4),
        bool(truth.faults),
        scrapped,
    )


def _kind_rows(runs: list[Run]) -> list[list[object]]:
    rows = []
    for kind in FAULT_KINDS:
        rs = [r for r in runs if r.kind == kind]
        stops = [a for r in rs for a in r.stops()]
        unclean = [a for r in rs for a in r.unclean_stops()]
        rows.append([
            kind, len(rs), sum(r.finished for r in rs), sum(r.scrapped for r in rs),
            sum(not r.finished and not r.scrapped for r in rs),
            sum(len(r.ran_twice) for r in rs), sum(len(r.lost) for r in rs),
            sum(len(r.out_of_order) for r in rs), sum(len(r.corrupted) for r in rs),
            sum(r.silent_wrong for r in rs), len(stops) - len(unclean), len(stops),
            sum(a.rc == 2 for r in rs for a in r.attempts),
        ])  # fmt: skip
    return rows


def _failure_rows(runs: list[Run]) -> list[list[object]]:
    rows = []
    for r in runs:
        bad = r.silent_wrong or r.ran_twice or r.lost or r.out_of_order or r.unclean_stops()
        if not bad:
            continue
        what = []
        for name in ("ran_twice", "lost", "out_of_order", "corrupted"):
            lines = getattr(r, name)
            if lines:
                what.append(f"{name} " + ",".join(f"N{n}" for n in lines[:6]))
        for a in r.unclean_stops():
            if a.rc == HUNG:
                why = "hung, killed"
            elif a.named_line is None:
                why = "no line named"
            elif not a.clean_stop:
                why = f"named N{a.named_line}, board at {a.board_lines}"
            else:
                why = f"moves after exit {a.moves_started_after_exit[:4]}"
            what.append(f"unclean stop ({why})")
        rcs = "/".join(str(a.rc) + ("f" if a.force else "") for a in r.attempts)
        last = r.attempts[-1].message[:160]
        rows.append([r.design, r.fault, rcs, "; ".join(what), last])
    return rows


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.serial_heldout", description=__doc__)
    p.add_argument("--quick", action="store_true", help="one short job, one fault of each kind")
    args = p.parse_args(argv)
    # (seed, size, source): the quick run keeps one job from the user's own `gcode`
    designs = (
        [(7, 100, "gcode")]
        if args.quick
        else [(7, 2000, "written"), (11, 2000, "written"), (23, 2000, "written")]
    )
    variants = 1 if args.quick else 3
    runs: list[Run] = []
    job_lines = []
    with tempfile.TemporaryDirectory(prefix="serial_heldout_jobs_") as tmp:
        for seed, size, source in designs:
            job_path = make_job(Path(tmp), seed, size, source)
            job = expected_job(job_path.read_text())
            job_lines.append(max(job.text_by_line))
            for fault in fault_plan(job, seed, variants):
                run = stream_with_fault(job_path, job, fault, f"job{seed}")
                print(f"{run.design} {run.fault}: rc {[a.rc for a in run.attempts]}, "
                      f"twice {run.ran_twice[:5]}, lost {run.lost[:5]}, "
                      f"order {run.out_of_order[:5]}, corrupted {run.corrupted[:5]}, "
                      f"feed err {run.feed_error_mm}; {run.attempts[-1].message[:200]}",
                      flush=True)  # fmt: skip
                runs.append(run)
    return _report(argv, args.quick, runs, job_lines)


def _report(argv, quick: bool, runs: list[Run], job_lines: list[int]) -> dict:
    stops = [a for r in runs for a in r.stops()]
    unclean = [a for r in runs for a in r.unclean_stops()]
    twice = sum(len(r.ran_twice) for r in runs)
    lost = sum(len(r.lost) for r in runs)
    order = sum(len(r.out_of_order) for r in runs)
    silent = sum(r.silent_wrong for r in runs)
    named = sum(a.names_line_and_reason for a in stops)
    metrics = [
        Metric(
            "fault runs of ~2,000-line jobs", len(runs), "runs", target=">= 60", met=len(runs) >= 60
        ),  # fmt: skip
        Metric.at_most("lines run twice", twice, "lines", 0),
        Metric.at_most("lines lost", lost, "lines", 0),
        Metric.at_most("lines out of order", order, "lines", 0),
        Metric.at_most("silent wrong parts (exit 0, sequence differs)", silent, "runs", 0),
        Metric(
            "stops clean: the board's or the faulty line, a reason, no move after",
            len(stops) - len(unclean),
            "stops",
            target=f"= {len(stops)} (all)",
            met=not unclean,
        ),  # fmt: skip
        Metric(
            "jobs finished after the operator's resumes", sum(r.finished for r in runs), "runs"
        ),  # fmt: skip
        Metric(
            "corrupted lines that reached the planner", sum(len(r.corrupted) for r in runs), "lines"
        ),  # fmt: skip
        Metric("stops naming a line and a reason (any line)", named, "stops"),
    ]
    kinds = Table(
        "per fault kind",
        ["fault", "runs", "finished", "scrapped", "stopped", "twice", "lost", "order", "corrupted",
         "silent wrong", "clean stops", "stops", "refusals"],
        _kind_rows(runs),
    )  # fmt: skip
    failures = Table(
        "runs that failed a target (job, fault, exit code per attempt (f = --force), what, "
        "last message)",
        ["job", "fault", "rcs", "what", "last message"],
        _failure_rows(runs),
    )
    counts = Counter(r.kind for r in runs)
    return finish(
        __file__,
        SECTION,
        argv,
        quick=quick,
        metrics=metrics,
        tables=[kinds, failures],
        notes=[
            f"jobs of {', '.join(map(str, job_lines))} lines; faults per kind {dict(counts)}; "
            f"controller speedup {SPEEDUP:g}x, 115,200 baud wire, TinyG 440 buffers",
            "the controller is benchmarks/heldout (written from TinyG's documentation, "
            "not from cvmeasure's streaming code); the streamer is run as the user runs it",
            "gone: the board keeps running its queue while the port is away, so moves after "
            "the streamer's exit do not make that stop unclean",
        ],
        extra={"runs": [{**asdict(r), "silent_wrong": r.silent_wrong} for r in runs]},
    )


if __name__ == "__main__":
    main()
