"""Where a stopped job continues: decided from what the board reports after the stop.

After a stop the board is asked for its line and position. TinyG's ``sr.line`` once
the machine is idle after a queue flush names the last line it *parsed* (flushed ones
included), so the line alone does not say what ran. What does:

* a lower bound: the last line the board reported while running or held (a line
  the machine had certainly started), and the line a fresh feedhold report named;
* an upper bound: the line the board reports now (nothing after it was parsed);
* the position: each line between the bounds is a candidate, kept when the
  position is where the job is after it, or on its move (a line cut short).

One candidate (or several that leave the same motions to do) decides the resume.
Candidates that disagree (the pin is home both before a bend and after its return)
leave the bend's completion uncertain: the resume refuses, naming the lines and
the check, until the operator says where to continue (``from_line``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cvmeasure.driver.job import JobLine
from cvmeasure.driver.protocol import AXES, track_positions
from cvmeasure.errors import DeviceError, InputError
from cvmeasure.fileio import read_jsonl

__all__ = [
    "ResumePlan",
    "ResumeEvidence",
    "plan_resume",
    "locate_resume",
    "journal_evidence",
]

#: Planned positions compared to tell two resumes apart (the motions each leaves to do).
_COMPARE_MOVES = 12


@dataclass(frozen=True)
class ResumePlan:
    """Where to continue: the first job index to send, and a completing line for a cut one."""

    start_index: int
    fixup: str | None
    done_through: int

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


def plan_resume(
    job: Sequence[JobLine],
    *,
    start_pos: Mapping[str, float],
    board_line: int,
    board_pos: Mapping[str, float],
    tolerance: float = 2e-3,
    fixup_rate: float = 1000.0,
    min_move_s: float = 0.005,
) -> ResumePlan:
    """Where a stopped job continues, from what the board reports.

    Parameters
    ----------
    job : the numbered job.
    start_pos : the board position when the job started (journal), axis -> value.
    board_line : ``sr.line`` now (0 = nothing of the job executed: the job's
        start marker ``N0``).
    board_pos : ``posx``... now, axis -> value.
    tolerance : position agreement meaning "the line completed" (units of the axis).
    fixup_rate : feed (units/min) for completing a cut rapid (G0) move.
    min_move_s : a completing move is slowed so it lasts at least this long
        (TinyG rejects moves under 2.5 ms).

    Raises
    ------
    DeviceError
        ``board_line`` is not a line of this job, or the position disagrees
        with the job there (an axis the line does not move is off, or the
        relative feed is outside the line's move): something ran that was not
        the job, and continuing would make a wrong part.
    """
    if board_line == 0:
        off = [
            a for a in AXES if abs(float(board_pos.get(a, 0.0)) - start_pos.get(a, 0.0)) > tolerance
        ]
        if off:
            raise DeviceError(
                f"the board has run none of the job but has moved ({', '.join(off)}) since it "
                "started: check the part and start again"
            )
        return ResumePlan(0, None, -1)
    index = {j.number: j.index for j in job}
    if board_line not in index:
        raise DeviceError(
            f"the board reports line N{board_line}, which is not in this job; "
            "it was reset or ran another job: re-zero the machine and start again"
        )
    k = index[board_line]
    planned = track_positions([j.block for j in job], start_pos)
    end = planned[k]
    rest = {a: end[a] - float(board_pos.get(a, 0.0)) for a in AXES}
    if all(abs(v) <= tolerance for v in rest.values()):
        return ResumePlan(k + 1, None, k)
    line = job[k]
    relative_modes = [
        b.block.distance_mode for b in job[: k + 1] if b.block.distance_mode is not None
    ]
    relative = bool(relative_modes) and relative_modes[-1] == "relative"
    moved = [a for a in AXES if a in line.block.axes]
    still = [a for a in AXES if a not in moved and abs(rest[a]) > tolerance]
    if still or not moved:
        raise DeviceError(
            f"the board's position disagrees with the job at line N{line.number} "
            f"({', '.join(f'{a} off by {-rest[a]:+.3f}' for a in still or AXES if abs(rest[a]) > tolerance)}): "
            "a corrupted line may have run; check the part and start again"
        )
    if relative:
        before = planned[k - 1] if k > 0 else {a: float(start_pos.get(a, 0.0)) for a in AXES}
        for a in moved:
            span = end[a] - before[a]
            if rest[a] * span < -tolerance or abs(rest[a]) > abs(span) + tolerance:
                raise DeviceError(
                    f"the board's {a} position is outside line N{line.number}'s move: "
                    "a corrupted line may have run; check the part and start again"
                )
    distance = sum(rest[a] ** 2 for a in moved) ** 0.5
    rate = line.block.feed if line.block.motion == 1 and line.block.feed else fixup_rate
    rate = min(rate, max(distance, 1e-6) / min_move_s * 60.0)
    if relative:
        words = " ".join(f"{a.upper()}{rest[a]:.4f}" for a in moved)
        fix = f"N{line.number} G91 G1 {words} F{rate:.4g}"
    else:
        words = " ".join(f"{a.upper()}{end[a]:.4f}" for a in moved)
        fix = f"N{line.number} G90 G1 {words} F{rate:.4g}"
    return ResumePlan(k + 1, fix, k - 1)


@dataclass(frozen=True)
class ResumeEvidence:
    """What is known about where the machine stopped.

    lower : a job line number the machine had started (None: perhaps none).
    upper : the line the board reports now; nothing after it was parsed.
    held : the line a fresh feedhold report named (exact), or None.
    sources : words for messages (where each bound came from).
    """

    lower: int | None
    upper: int
    held: int | None = None
    sources: dict[str, str] = field(default_factory=dict)


def _remaining(
    plan: ResumePlan, planned: Sequence[Mapping[str, float]], pos: Mapping[str, float], tol: float
) -> list[tuple[float, ...]]:
    """The next planned positions the machine will visit after ``plan`` (repeats dropped)."""
    targets = ([planned[plan.start_index - 1]] if plan.fixup else []) + list(
        planned[plan.start_index : plan.start_index + 4 * _COMPARE_MOVES]
    )
    out: list[tuple[float, ...]] = []
    last = tuple(float(pos.get(a, 0.0)) for a in AXES)
    for t in targets:
        point = tuple(float(t[a]) for a in AXES)
        if max(abs(x - y) for x, y in zip(point, last, strict=True)) > tol:
            out.append(point)
            last = point
        if len(out) >= _COMPARE_MOVES:
            break
    return out


def _same(a: list[tuple[float, ...]], b: list[tuple[float, ...]], tol: float) -> bool:
    return len(a) == len(b) and all(
        max(abs(x - y) for x, y in zip(p, q, strict=True)) <= tol for p, q in zip(a, b, strict=True)
    )


def locate_resume(
    job: Sequence[JobLine],
    *,
    start_pos: Mapping[str, float],
    board_pos: Mapping[str, float],
    evidence: ResumeEvidence,
    from_line: int | None = None,
    tolerance: float = 2e-3,
) -> tuple[ResumePlan, int]:
    """The resume plan proven by ``evidence`` and the position; (plan, last line run).

    Raises
    ------
    DeviceError
        No line between the bounds fits the position (something ran that is not the
        job), or lines that fit leave different motions to do and the operator has not
        said which (``from_line``): the message names the lines and what to check.
    InputError
        ``from_line`` is not where the position allows the job to continue.
    """
    index = {j.number: j.index for j in job}
    if evidence.upper != 0 and evidence.upper not in index:
        raise DeviceError(
            f"the board reports line N{evidence.upper}, which is not in this job; "
            "it was reset or ran another job: re-zero the machine and start again"
        )
    hi = index.get(evidence.upper, -1)
    lo = index.get(evidence.lower, -1) if evidence.lower else -1
    if evidence.held is not None and (evidence.held in index or evidence.held == 0):
        # an exact report (a fresh feedhold report, or a board that ran out of lines by
        # itself): that line, and only it, was the last to run
        lo = hi = index.get(evidence.held, -1)
    lo = min(lo, hi)
    planned = track_positions([j.block for j in job], start_pos)
    fits: list[tuple[int, ResumePlan]] = []
    for k in range(lo, hi + 1):
        number = 0 if k < 0 else job[k].number
        try:
            fits.append(
                (
                    k,
                    plan_resume(
                        job,
                        start_pos=start_pos,
                        board_line=number,
                        board_pos=board_pos,
                        tolerance=tolerance,
                    ),
                )
            )
        except DeviceError:
            continue
    where = ", ".join(f"{a.upper()}{float(board_pos.get(a, 0.0)):.3f}" for a in AXES)
    span = f"N{job[lo].number}" if lo >= 0 else "the start"
    if not fits:
        raise DeviceError(
            f"the board's position ({where}) fits no line from {span} to N{evidence.upper} "
            "(the lines that may have run): something ran that is not the job; check the "
            "part and start again"
        )
    if from_line is not None:
        chosen = (
            [
                (k, p)
                for k, p in fits
                if job[p.start_index - (1 if p.fixup else 0)].number == from_line
            ]
            if fits
            else []
        )
        if not chosen:
            starts = sorted({_first_sent(job, p) for _, p in fits})
            raise InputError(
                "--from-line",
                f"N{from_line} is not where the job can continue from this position ({where}); "
                f"it can continue at {', '.join(f'N{n}' for n in starts)}",
            )
        k, plan = chosen[0]
        return plan, k
    groups: list[list[tuple[int, ResumePlan]]] = []
    for k, plan in fits:
        rest = _remaining(plan, planned, board_pos, tolerance)
        for group in groups:
            if _same(_remaining(group[0][1], planned, board_pos, tolerance), rest, tolerance):
                group.append((k, plan))
                break
        else:
            groups.append([(k, plan)])
    if len(groups) == 1:
        k, plan = groups[0][0]  # the earliest: a repeated modal line is harmless, a skipped one not
        return plan, k
    options = [_first_sent(job, g[0][1]) for g in groups]
    first, last = options[0], options[-1]
    raise DeviceError(
        f"cannot tell which lines ran: the machine is at {where}, which is where the job is "
        f"before N{first} and before N{last} (the board last reported N{evidence.upper}; "
        f"{evidence.sources.get('lower', 'no line was seen running before the stop')}); check "
        f"whether N{first} to N{last - 1} were made (look at the part), then resume with "
        f"--from-line N{first} if they were not or --from-line N{last} if they were"
    )


def _first_sent(job: Sequence[JobLine], plan: ResumePlan) -> int:
    """The number of the first line a plan sends (the completed line, or the next)."""
    if plan.fixup:
        return job[plan.start_index - 1].number
    return job[plan.start_index].number if plan.start_index < len(job) else job[-1].number + 1


def journal_evidence(
    journal: Path | None, sha: str, source: str, *, force: bool = False
) -> tuple[dict[str, float], dict[str, Any], int | None, str]:
    """(start position, last start/stop/resume record, lower bound, where it came from).

    The lower bound is the highest line the journal saw the machine run (progress
    records, the stop's running line, a fresh feedhold report).
    """
    if journal is None or not journal.is_file():
        raise InputError(journal or source, "no journal to resume from")
    records = read_jsonl(journal, skip_partial_last=True)
    starts = [r for r in records if r.get("event") == "start"]
    if not starts or starts[-1].get("sha256") != sha:
        raise InputError(journal, "the journal belongs to a different job")
    last = [r for r in records if r.get("event") in ("start", "stop", "resume")][-1]
    if last.get("event") == "stop" and last.get("corrupt_line_ran") and not force:
        raise DeviceError(
            f"{journal}: the job stopped after the corrupted line N{last.get('line_number')} "
            "had reached the machine; check the part, then resume with --force"
        )
    since = records[len(records) - 1 - records[::-1].index(starts[-1]) :]
    lower, how = None, "no line was seen running before the stop"
    # the number a corrupted block was read as names no line that ran there
    misread = last.get("misread_line") if last.get("event") == "stop" else None
    for r in since:
        for key in ("executed_line", "running_line"):
            value = r.get(key)
            if value == misread:
                continue
            if isinstance(value, int) and value > 0 and (lower is None or value > lower):
                lower, how = value, f"N{value} was seen running before the stop"
        if r.get("event") == "resume" and isinstance(r.get("resumed_line"), int):
            lower, how = r["resumed_line"], f"N{r['resumed_line']} was where the last resume began"
    return {a: float(v) for a, v in starts[-1].get("start_pos", {}).items()}, last, lower, how
