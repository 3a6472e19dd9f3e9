"""Score a streamed job against the held-out controller's truth log, by what physically ran.

The job's expected motion is worked out with the controller's own G-code model on a fresh
machine (which lines move, and what each does to its named axes), not with the streamer's
code. Lines are compared by motion, not by text, so a streamer may finish an interrupted
absolute move with a line of its own (same number, same target) without penalty.

* *ran twice*: the line moved again after it had once run to its end, or a relative move
  moved more than its length in total;
* *lost*: the line should have moved and never completed, although a later line of the
  job moved (or the streamer said the job is finished);
* *out of order*: the line moved after a later line of the job had moved;
* *corrupted*: a move ran under the line's number that is not the job's (another target,
  another length, an axis the line does not name, a number the job does not move under),
  which is what a dropped or garbled byte that reaches the planner does.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from benchmarks.heldout.tinyg_gcode import AXES, ModelState, parse_block, plan_move
from benchmarks.heldout.tinyg_machine import MachineConfig
from benchmarks.heldout.tinyg_truth import Executed, TruthLog

__all__ = ["ExpectedJob", "JobMove", "JobScore", "expected_job", "score_job"]

_TOL_MM = 1e-3


@dataclass(frozen=True)
class JobMove:
    """One moving line of the job: the axes it names, with their target (absolute) or
    displacement (relative), mm (X = pin deg)."""

    line: int
    relative: bool
    named: dict[str, float]


@dataclass(frozen=True)
class ExpectedJob:
    """What a clean run of the job does on the controller model."""

    text_by_line: dict[int, str]
    moves: dict[int, JobMove]
    moving_lines: list[int]
    total_feed_mm: float


@dataclass
class JobScore:
    """Lines run twice, lost, out of order and corrupted; the wire-feed error (mm).

    The feed error is the wire actually fed (the sum of every executed Y displacement,
    so a reboot zeroing the board's coordinates neither hides nor fakes one) minus the
    job's total feed; it is only scored for a job said to be finished.
    """

    ran_twice: list[int] = field(default_factory=list)
    lost: list[int] = field(default_factory=list)
    out_of_order: list[int] = field(default_factory=list)
    corrupted: list[int] = field(default_factory=list)
    feed_error_mm: float | None = None


def expected_job(gcode: str, config: MachineConfig | None = None) -> ExpectedJob:
    """Run the job's lines through the G-code model of a freshly booted controller."""
    cfg = config or MachineConfig()
    model = ModelState()
    texts: dict[int, str] = {}
    moves: dict[int, JobMove] = {}
    for raw in gcode.splitlines():
        block = parse_block(raw)
        if block.status or block.line_number is None:
            continue
        texts[block.line_number] = raw.strip()
        status, move = plan_move(block, model, raw.strip(), cfg.vmax_mm_min, cfg.min_move_s)
        if status == 0 and move is not None and move.kind == "move":
            named = [a for a in AXES if a.upper() in block.words]
            if model.absolute:
                values = {a: move.target[a] for a in named}
            else:
                values = {a: move.target[a] - move.start[a] for a in named}
            moves[move.line] = JobMove(move.line, not model.absolute, values)
    feed = sum(m.named.get("y", 0.0) for m in moves.values() if m.relative)
    return ExpectedJob(texts, moves, list(moves), feed)


def _delta(rec: Executed, axis: str) -> float:
    return rec.end[axis] - rec.start[axis]


def _moves_unnamed_axis(rec: Executed, move: JobMove) -> bool:
    return any(abs(_delta(rec, a)) > _TOL_MM for a in AXES if a not in move.named)


def _judge_line(move: JobMove, recs: list[Executed], out: JobScore) -> bool:
    """Score one job line's executions; True when it completed as the job says."""
    n = move.line
    if any(_moves_unnamed_axis(r, move) for r in recs):
        out.corrupted.append(n)
    done = [i for i, r in enumerate(recs) if r.how == "done"]
    if done and done[0] < len(recs) - 1:
        out.ran_twice.append(n)
    if move.relative:
        total = {a: sum(_delta(r, a) for r in recs) for a in move.named}
        over = any(
            abs(total[a]) > abs(v) + _TOL_MM and total[a] * v > 0 for a, v in move.named.items()
        )
        if over and len(recs) > 1 and n not in out.ran_twice:
            out.ran_twice.append(n)
        complete = all(abs(total[a] - v) <= _TOL_MM for a, v in move.named.items())
        # one execution of the wrong length is a corrupted line, not a repeat
        if done and not complete and (len(recs) == 1 or not over) and n not in out.corrupted:
            out.corrupted.append(n)
        return complete or over
    hits = [recs[i] for i in done]
    wrong = [r for r in hits if any(abs(r.end[a] - v) > _TOL_MM for a, v in move.named.items())]
    if wrong and n not in out.corrupted:
        out.corrupted.append(n)
    return len(wrong) < len(hits)


def score_job(job: ExpectedJob, truth: TruthLog, finished: bool) -> JobScore:
    """Compare what ran with the job.

    Parameters
    ----------
    finished
        Whether the streamer said the job is done (exit 0): then every moving line must
        have run, and the wire fed must be the job's.
    """
    out = JobScore()
    by_line: dict[int, list[Executed]] = {}
    max_line = 0
    for rec in truth.executed:
        if rec.fraction <= 1e-9:
            continue
        if rec.line < max_line and rec.line not in out.out_of_order:
            out.out_of_order.append(rec.line)
        max_line = max(max_line, rec.line)
        by_line.setdefault(rec.line, []).append(rec)
        if rec.line not in job.moves and rec.line not in out.corrupted:
            out.corrupted.append(rec.line)
    completed = {
        n for n, recs in by_line.items() if n in job.moves and _judge_line(job.moves[n], recs, out)
    }
    reached = max(by_line, default=0)  # a later line that moved at all skipped the gap
    out.lost = [
        n
        for n in job.moving_lines
        if n not in completed and n not in out.corrupted and (finished or n < reached)
    ]
    if finished:
        fed = sum(_delta(rec, "y") for rec in truth.executed)
        out.feed_error_mm = abs(fed - job.total_feed_mm)
    for lines in (out.ran_twice, out.corrupted, out.out_of_order):
        lines.sort()
    return out
