"""Streaming a G-code job to the bender without losing or repeating a line.

The host algorithm of reference ``diwire-tinyg.md`` section 2.10:

* JSON mode; the session settings are sent one at a time (send-response);
* at most ``window_lines`` lines **and** ``window_bytes`` bytes in flight
  (default 1 and 200 of the board's 254-byte receive buffer), so the buffer
  cannot overflow; XON/XOFF stays on as the safety net (the tty honours it).
  One line at a time by default: TinyG acks a line once it is parsed and queued,
  so the planner stays full all the same, and no later line is already in the
  board when a line is rejected (the board would skip it and run the next ones),
  loses its LF (it would run merged with the next) or its ack is uncertain;
* each ``{"r":...}`` acks the head of the in-flight FIFO and its footer's byte
  count must equal that line's length: a mismatch (a dropped or garbled byte),
  a non-zero status, a reply that cannot be parsed, a reset banner, an alarm
  (``er`` >= 200 or stat 2), silence while work is pending (a stall) or the
  port vanishing stop the job *safely*: feedhold ``!`` then queue flush ``%``
  (the board defers the flush until the hold has stopped the motion), wait for
  the flush's ``{"rx":n}``, read the board's line and position, write them to
  the journal, and raise :class:`JobStopped` naming the line;
* status, queue, exception and rx reports are never taken for acks;
* the job's lines carry ``N`` numbers; ``sr.line`` says which one the machine
  is executing, so the journal knows what the board has *done* (acked lines
  still in the planner are not done: a flush discards them).

The journal is JSON Lines, append-only (``start``, ``progress``, ``stop``,
``resume``, ``done``). :func:`stream_job` with ``resume=True`` re-reads it,
flushes whatever the board still holds, asks the board for its line and
position, and continues from there (:func:`plan_resume`): a line that was cut
short is completed (absolute axes: the line again; the relative feed: the
remaining millimetres), nothing done is sent twice.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from cvmeasure.driver.connection import IDLE as _IDLE
from cvmeasure.driver.connection import BoardConnection, BoardStuckError
from cvmeasure.driver.job import JobLine, job_sha256, prepare_job
from cvmeasure.driver.protocol import (
    AXES,
    CYCLE_START,
    FEEDHOLD,
    STATUS_TEXT,
    ExceptionReport,
    MachineStat,
    Message,
    QueueReport,
    Response,
    RxReport,
    StatusReport,
    Unparsed,
    encode_json,
    encode_line,
    parse_block,
)
from cvmeasure.driver.resume import (
    ResumeEvidence,
    ResumePlan,
    journal_evidence,
    locate_resume,
    plan_resume,
)
from cvmeasure.driver.stream_types import (
    FIRMWARE_QUERIES,
    SETUP_COMMANDS,
    JobStopped,
    StopInfo,
    StreamConfig,
    StreamControl,
    StreamResult,
)
from cvmeasure.driver.transport import Link
from cvmeasure.errors import DeviceError, DeviceTimeoutError, InputError
from cvmeasure.fileio import append_jsonl

__all__ = [
    "StreamConfig",
    "JobLine",
    "StopInfo",
    "StreamResult",
    "ResumePlan",
    "JobStopped",
    "BoardConnection",
    "StreamControl",
    "prepare_job",
    "job_sha256",
    "plan_resume",
    "locate_resume",
    "stream_job",
    "SETUP_COMMANDS",
    "FIRMWARE_QUERIES",
]

log = logging.getLogger(__name__)


def _position(state: Mapping[str, Any]) -> dict[str, float]:
    return {a: float(state.get(f"pos{a}", 0.0) or 0.0) for a in AXES}


def _now_utc() -> str:
    return datetime.now(UTC).isoformat(timespec="seconds")


# ---------------------------------------------------------------------------
# Streaming


@dataclass
class _Run:
    job: list[JobLine]
    board: BoardConnection
    config: StreamConfig
    journal: Path | None
    progress: Callable[[int, int, int | None], None] | None
    control: StreamControl | None = None
    inflight: deque[JobLine] = field(default_factory=deque)
    sent: int = 0
    last_progress_t: float = 0.0
    last_progress_line: int | None = None
    #: the last job line written to the board (acked or in flight)
    last_sent: JobLine | None = None
    #: index of the highest job line the board has reported running, in cycle (lines
    #: run in order: a report below it, or past the last line sent, is a line the board
    #: was never sent there, a corrupted block's N word)
    ran_index: int = -1

    def misread(self, number: Any) -> bool:
        """True when ``number`` cannot be the line the board runs now (see ``ran_index``)."""
        if not isinstance(number, int) or number == 0:
            return False
        index = _index_of(self.job, number)
        top = self.last_sent.index if self.last_sent is not None else -1
        return index < 0 or index < self.ran_index or index > top

    def log(self, record: dict[str, Any]) -> None:
        if self.journal is not None:
            append_jsonl(self.journal, {"time_utc": _now_utc(), **record})

    def note_progress(self, force: bool = False) -> None:
        line = self.board.state.get("line")
        now = time.monotonic()
        # only a report in cycle names the line running; out of cycle TinyG reports the
        # last line parsed, which can be ahead of lines still waiting to run
        running = self.board.running_line
        if running is not None and not self.misread(running):
            self.ran_index = max(self.ran_index, _index_of(self.job, running))
        if line is None or line == self.last_progress_line:
            return
        if force or now - self.last_progress_t >= self.config.progress_interval_s:
            self.last_progress_t = now
            self.last_progress_line = int(line)
            self.log({"event": "progress", "executed_line": int(line)})


def _stop(run: _Run, reason: str, line: JobLine | None, detail: str, *, number: int | None = None):
    """Stop the board safely, journal where and why, raise JobStopped."""
    board = run.board
    state: dict[str, Any] | None = None
    held: dict[str, Any] | None = None
    flush_sent = False
    if board.error is None and reason != "port_gone":
        held, state, flush_sent, problem = _halt(run, reason)
        detail += problem
    running = held if held is not None else state
    if line is None and number is None and running is not None:
        # an alarm names the line the machine was executing when it tripped
        number = running.get("line")
        line = _line_by_number(run.job, number)
    corrupt_ran = False
    misread = None
    if reason == "desync" and line is not None and running is not None:
        # TinyG 440 has no input checksum: a corrupted line runs like any other
        corrupt_ran = _index_of(run.job, running.get("line")) >= line.index
        if run.misread(running.get("line")):
            # the board runs a line it was never sent there: the corrupted block, its
            # N word read wrong (a lost or garbled digit). It reached the machine.
            misread = int(running["line"])
            corrupt_ran = True
            detail += (
                f"; the board reports running N{misread}, a line it was not sent there: "
                f"it read N{line.number}'s corrupted number as N{misread} and ran that "
                "block: check the part (did it make what the job says?) before resuming "
                "with --force"
            )
        elif corrupt_ran:
            detail += (
                f"; the machine had reached it (sr.line N{running.get('line')}): "
                "check the part before resuming with --force"
            )
    ran_past = False
    if reason == "error" and line is not None and running is not None:
        # the board skips a line it rejects and runs the ones after it
        ran_to = _index_of(run.job, running.get("line"))
        ran_past = ran_to > line.index
        if ran_past:
            detail += (
                f"; the board went on to run up to N{running.get('line')} without it: "
                "the part is wrong; check it (resume needs --force)"
            )
    run.inflight.clear()
    stop = StopInfo(
        reason=reason,
        line_number=line.number if line is not None else number,
        line=line.text if line is not None else "",
        detail=detail,
        board=state,
        corrupt_line_ran=corrupt_ran,
        held=held,
        ran_past_rejected_line=ran_past,
        flush_sent=flush_sent,
        misread_line=misread,
    )
    run.log({"event": "stop", **stop.to_dict(), "running_line": board.running_line})
    raise JobStopped(stop)


def _halt(run: _Run, reason: str) -> tuple[dict[str, Any] | None, dict[str, Any] | None, bool, str]:
    """Feedhold and flush: (held report, status after the flush, flush sent, problem).

    A stall with the machine idle had nothing queued (it ran all it parsed): the line
    in flight may wait in the board's input without its end (a lost LF), and a status
    query sent now would merge with it, so the flush (which clears the input) comes
    first and the status after it is exact, as a held report is.
    """
    board, config = run.board, run.config
    idle = reason == "stall" and board.state.get("stat") in _IDLE
    held = state = None
    flush_sent = False
    try:
        if not idle:
            held = board.hold(timeout_s=config.flush_timeout_s)
        flush_sent = True
        if not board.flush_board(timeout_s=config.flush_timeout_s):
            return held, None, True, "; the board did not confirm the flush (unresponsive)"
        state = board.query_status(timeout_s=config.command_timeout_s)
    except DeviceError as exc:
        return held, state, flush_sent, f"; stopping failed: {exc}"
    if idle and state.get("stat") in _IDLE:
        held = state
    return held, state, True, ""


def _handle(run: _Run, msg: Message) -> None:
    """Act on one message while streaming (acks, alarms, garbage)."""
    if isinstance(msg, Response):
        if msg.is_banner:
            head = run.inflight[0] if run.inflight else None
            _stop(run, "reset", head, "the board reset itself (start-up banner)")
        if not run.inflight:
            _stop(run, "desync", None, f"a reply arrived with no line in flight: {msg}")
        head = run.inflight.popleft()
        if msg.nbytes != head.nbytes:
            _stop(
                run,
                "desync",
                head,
                f"the board consumed {msg.nbytes} bytes for a {head.nbytes}-byte line "
                "(a byte was lost or garbled on the way)",
            )
        echo = msg.body.get("gc")
        if isinstance(echo, str) and _squeeze(echo) != _squeeze(head.text):
            _stop(
                run,
                "desync",
                head,
                f"the board read {echo.strip()!r} for {head.text!r} (a byte garbled on the way)",
            )
        if msg.status != 0:
            text = STATUS_TEXT.get(msg.status, "")
            _stop(
                run,
                "error",
                head,
                f"the board rejected the line with status {msg.status}"
                + (f" ({text})" if text else ""),
            )
    elif isinstance(msg, ExceptionReport):
        if msg.status >= 200:
            _stop(run, "alarm", None, f"alarm {msg.status} ({msg.message})")
    elif isinstance(msg, StatusReport):
        if msg.stat in (MachineStat.ALARM, MachineStat.SHUTDOWN):
            _stop(run, "alarm", None, f"machine state {msg.stat} (alarm)")
        run.note_progress()
    elif isinstance(msg, Unparsed):
        head = run.inflight[0] if run.inflight else None
        _stop(run, "malformed", head, f"unreadable reply {msg.text!r} ({msg.reason})")
    elif isinstance(msg, (QueueReport, RxReport)):
        pass


def _squeeze(text: str) -> str:
    """A G-code block as the board may echo it: upper case, no spaces."""
    return "".join(text.split()).upper()


def _index_of(job: Sequence[JobLine], number: Any) -> int:
    """Index of the job line numbered ``number``; -1 for N0 or anything else."""
    line = _line_by_number(job, number)
    return line.index if line is not None else -1


def _line_by_number(job: Sequence[JobLine], number: Any) -> JobLine | None:
    for j in job:
        if j.number == number:
            return j
    return None


def _setup(board: BoardConnection, config: StreamConfig, xonxoff: bool) -> dict[str, Any]:
    for cmd in SETUP_COMMANDS:
        board.command(cmd, timeout_s=config.command_timeout_s)
    for query in FIRMWARE_QUERIES:
        reply = board.command(query, timeout_s=config.command_timeout_s)
        board.firmware.update(reply.body)
    board.command({"ex": 1 if xonxoff else 0}, timeout_s=config.command_timeout_s)
    return board.query_status(timeout_s=config.command_timeout_s)


def stream_job(
    link: Link,
    lines: Sequence[str] | Sequence[JobLine],
    *,
    journal: str | Path | None = None,
    resume: bool = False,
    config: StreamConfig | None = None,
    progress: Callable[[int, int, int | None], None] | None = None,
    source: str = "job",
    control: StreamControl | None = None,
    force: bool = False,
    from_line: int | None = None,
) -> StreamResult:
    """Stream a job to the board and wait until it has executed.

    Parameters
    ----------
    link : the open link.
    lines : G-code lines (numbered by :func:`prepare_job` when they are not
        :class:`JobLine` already).
    journal : the JSON Lines journal (needed for ``resume``).
    resume : continue a stopped job from its journal and the board's state.
    config : windows and timeouts.
    progress : called as ``progress(lines_sent, lines_total, executed_line)``.
    source : the job's name in messages.
    control : feedhold / cycle start / abort requests from another thread.
    force : resume even after a stop whose corrupted line had reached the machine.
    from_line : with ``resume``, the line to continue at, on the operator's word, when
        the board's report and position leave it uncertain whether lines ran.

    Raises
    ------
    JobStopped
        A fault stopped the job (after a safe stop; the journal has the line).
    InputError
        ``resume`` without a journal for this job, or ``from_line`` without ``resume``.
    DeviceError
        The board is alarmed before a new job, or does not answer.
    """
    if from_line is not None and not resume:
        # without resume the job would start again from its first line: bends made twice
        raise InputError("from_line", "only applies with resume")
    config = config or StreamConfig()
    job = (
        list(lines)
        if lines and isinstance(lines[0], JobLine)
        else prepare_job(lines, source=source)  # type: ignore[arg-type]
    )
    sha = job_sha256(job)
    journal_path = Path(journal) if journal is not None else None
    t0 = time.perf_counter()
    board = BoardConnection(link)
    run = _Run(job, board, config, journal_path, progress, control)
    try:
        return _stream(run, sha, resume, source, link.xonxoff, t0, force, from_line)
    except KeyboardInterrupt:
        head = run.inflight[0] if run.inflight else None
        try:
            _stop(run, "interrupted", head, "interrupted by the user")
        except JobStopped:
            pass
        raise
    finally:
        board.close()


def _stream(
    run: _Run,
    sha: str,
    resume: bool,
    source: str,
    xonxoff: bool,
    t0: float,
    force: bool,
    from_line: int | None = None,
) -> StreamResult:
    board, config, job = run.board, run.config, run.job
    start_index, fixup, resumed_from = 0, None, None
    notes: list[str] = []
    if resume:
        plan = _resume_plan(run, sha, source, xonxoff, force, from_line, notes)
        start_index, fixup, resumed_from = plan.start_index, plan.fixup, plan.start_index
        run.ran_index = plan.done_through
    else:
        if not board.flush_board(timeout_s=config.flush_timeout_s):
            raise DeviceTimeoutError(f"{board.link.url}: the board did not answer a queue flush")
        state = _setup(board, config, xonxoff)
        if state.get("stat") in (MachineStat.ALARM, MachineStat.SHUTDOWN):
            raise DeviceError(f"{board.link.url}: the board is alarmed; clear it before a job")
        marker = JobLine(-1, 0, "N0", parse_block("N0"))
        board.write(encode_line(marker.text))
        run.inflight.append(marker)
        _wait_acks(run)
        run.log(
            {
                "event": "start",
                "source": source,
                "sha256": sha,
                "lines": len(job),
                "start_pos": _position(state),
                "firmware": board.firmware,
            }
        )
    queue_lines: list[JobLine] = []
    if fixup is not None:
        k = start_index - 1
        queue_lines.append(JobLine(k, job[k].number, fixup, parse_block(fixup)))
    queue_lines.extend(job[start_index:])
    _send_all(run, queue_lines)
    executed = _wait_done(run, job[-1].number)
    run.log({"event": "done", "executed_line": executed})
    return StreamResult(
        lines_total=len(job),
        lines_sent=run.sent,
        resumed_from=resumed_from,
        executed_line=executed,
        seconds=time.perf_counter() - t0,
        fixup=fixup,
        notes=tuple(notes),
    )


def _resume_plan(
    run: _Run,
    sha: str,
    source: str,
    xonxoff: bool,
    force: bool,
    from_line: int | None,
    notes: list[str],
) -> ResumePlan:
    """Settle, flush and set up the board; where the stopped job continues (journalled)."""
    board, config, job = run.board, run.config, run.job
    start_pos, last, lower, lower_how = journal_evidence(run.journal, sha, source, force=force)
    # a board still running (the host died mid-job) finishes the lines it holds:
    # flushing them would make TinyG report the last line it *parsed*, not run
    try:
        settled = board.wait_idle(
            timeout_s=config.settle_timeout_s,
            query_timeout_s=config.command_timeout_s,
            stuck_s=config.stall_timeout_s,
        )
    except BoardStuckError as exc:
        line = exc.line if exc.line is not None else last.get("line_number")
        raise DeviceError(
            f"cannot resume at line N{line}: {exc}; check the machine, reset the board "
            "(power it off and on), then resume"
        ) from None
    if not board.flush_board(timeout_s=config.flush_timeout_s):
        raise DeviceTimeoutError(f"{board.link.url}: the board did not answer a queue flush")
    state = _setup(board, config, xonxoff)
    state = _clear_alarm(run, state, last, notes)
    held = last.get("held") if last.get("event") == "stop" else None
    if settled.get("stat") == MachineStat.HOLD or not (
        last.get("event") == "stop" and last.get("flush_sent", True)
    ):
        # held (its line is the runtime's), or it ran out of lines by itself with no
        # flush sent since: it ran every line it parsed, and its line is exact
        held = settled
    misread = last.get("misread_line") if last.get("event") == "stop" else None
    if isinstance(held, dict) and misread is not None and held.get("line") == misread:
        # the held report named the corrupted block by the number the board read for
        # it: the line running at the hold was the corrupted one (its position decides)
        held = {**held, "line": last.get("line_number")}
    reported = [
        int(x)
        for x in (settled.get("line"), state.get("line"))
        if isinstance(x, int) and x != misread
    ]
    upper = max(reported, key=lambda n: _index_of(job, n), default=0)
    if last.get("event") == "stop" and last.get("reason") == "desync":
        # a block that reached the board corrupted may carry a wrong N: the bound is every
        # line the board may have received (the window after the corrupted one)
        bad = _index_of(job, last.get("line_number"))
        window = job[min(len(job) - 1, max(bad, 0) + config.window_lines)].number
        upper = max(
            [n for n in reported if n in {j.number for j in job}] + [window],
            key=lambda n: _index_of(job, n),
        )
    evidence = ResumeEvidence(
        lower=lower,
        upper=upper,
        held=int(held["line"]) if isinstance(held, dict) and "line" in held else None,
        sources={"lower": lower_how},
    )
    plan, k = _locate(run, last, start_pos, _position(state), evidence, from_line, force)
    board_line = 0 if k < 0 else job[k].number
    _check_rejected(run, last, board_line, force)
    run.log(
        {
            "event": "resume",
            "sha256": sha,
            "board": state,
            "settled": settled,
            "evidence": {
                "lower": evidence.lower,
                "upper": evidence.upper,
                "held": evidence.held,
            },
            "executed_line": board_line,
            "from_line": from_line,
            "firmware": board.firmware,
            **plan.to_dict(),
        }
    )
    return plan


def _locate(
    run: _Run,
    last: Mapping[str, Any],
    start_pos: Mapping[str, float],
    board_pos: Mapping[str, float],
    evidence: ResumeEvidence,
    from_line: int | None,
    force: bool,
) -> tuple[ResumePlan, int]:
    """:func:`locate_resume`; after a desync, also the corrupted line as the held one.

    A corrupted N word can read as a line the board was sent shortly before (N45 as
    N44): the held report then names a line the position does not fit. When the
    position fits the corrupted line instead, that line ran under the wrong number:
    a check of the part (``force``) is needed before it goes on from there.
    """
    try:
        return locate_resume(
            run.job,
            start_pos=start_pos,
            board_pos=board_pos,
            evidence=evidence,
            from_line=from_line,
        )
    except DeviceError as exc:
        error = exc
        bad = last.get("line_number")
        if not (
            last.get("event") == "stop"
            and last.get("reason") == "desync"
            and evidence.held is not None
            and evidence.held != bad
            and _line_by_number(run.job, bad) is not None
        ):
            raise
    as_bad = replace(evidence, held=bad)
    try:
        found = locate_resume(
            run.job, start_pos=start_pos, board_pos=board_pos, evidence=as_bad, from_line=from_line
        )
    except (DeviceError, InputError):
        raise error from None
    if not (force or last.get("corrupt_line_ran")):
        raise DeviceError(
            f"the board named N{evidence.held} as running when it stopped, but its position "
            f"is on the corrupted line N{bad}'s move: N{bad} ran with its number read as "
            f"N{evidence.held}; check the part (did it make what the job says?), then "
            "resume with --force"
        )
    return found


def _clear_alarm(
    run: _Run, state: dict[str, Any], last: Mapping[str, Any], notes: list[str]
) -> dict[str, Any]:
    """Clear an alarm that tripped while no host was there to see it, and say so."""
    board, config = run.board, run.config
    if state.get("stat") != MachineStat.ALARM:
        return state
    alarmed = dict(state)
    board.command({"clear": None}, timeout_s=config.command_timeout_s)
    state = board.query_status(timeout_s=config.command_timeout_s)
    if not (last.get("event") == "stop" and last.get("reason") == "alarm"):
        notes.append(
            f"the board was in alarm at line N{alarmed.get('line')} when resumed (it "
            "tripped while the host was away: check the machine and the part); cleared"
        )
        run.log({"event": "alarm_cleared", "board": alarmed})
    return state


def _check_rejected(run: _Run, last: Mapping[str, Any], board_line: int, force: bool) -> None:
    """Refuse to go on past a line the board rejected and then ran beyond (unless forced)."""
    if (
        last.get("event") == "stop"
        and last.get("reason") == "error"
        and last.get("line_number") is not None
        and not force
        and _index_of(run.job, board_line) > _index_of(run.job, last["line_number"])
    ):
        raise DeviceError(
            f"{run.journal}: line N{last['line_number']} was rejected by the board "
            f"({last.get('detail', 'an error status')}) but the board went on to run up "
            f"to N{board_line} without it: the part is wrong; check it, then start again "
            "(or resume with --force to finish it as it is)"
        )


def _check_board(run: _Run) -> None:
    board = run.board
    if board.error is not None:
        # a board cut off runs on through all it parsed: it ends at the line in
        # flight, or at the last one sent (the board's last report is older)
        head = run.inflight[0] if run.inflight else None
        _stop(
            run,
            "port_gone",
            head or run.last_sent or _line_by_number(run.job, board.state.get("line")),
            str(board.error),
        )


def _watchdog(run: _Run, waiting_for: str) -> None:
    silence = time.monotonic() - run.board.last_rx
    if silence > run.config.stall_timeout_s:
        head = run.inflight[0] if run.inflight else None
        line = run.board.state.get("line")
        # the machine is where the board last said it was: the line in flight may wait
        # behind a full planner, so the board's line is the one the stop names
        _stop(
            run,
            "stall",
            _line_by_number(run.job, line) or head,
            f"no word from the board for {silence:.1f} s while waiting for {waiting_for}",
            number=line,
        )


def _wait_acks(run: _Run) -> None:
    run.board.last_rx = time.monotonic()
    while run.inflight:
        _check_board(run)
        msg = run.board.next_message(0.05)
        if msg is not None:
            _handle(run, msg)
        else:
            _watchdog(run, "an ack")


def _service_control(run: _Run) -> bool:
    """Act on hold/resume/abort requests; True while the job is held."""
    control = run.control
    if control is None:
        return False
    hold, resume, abort = control.take()
    head = run.inflight[0] if run.inflight else None
    if abort:
        _stop(run, "aborted", head, "aborted by the user")
    if hold and not control.held:
        run.board.write(FEEDHOLD)
        control.held = True
        run.log({"event": "hold", "executing_line": run.board.state.get("line")})
    if resume and control.held:
        run.board.write(CYCLE_START)
        control.held = False
        run.log({"event": "cycle_start", "executing_line": run.board.state.get("line")})
    if control.held:
        run.board.last_rx = time.monotonic()  # a held board is quiet, not stalled
    return control.held


def _send_all(run: _Run, lines: Sequence[JobLine]) -> None:
    board, config = run.board, run.config
    board.last_rx = time.monotonic()
    i = 0
    n_total = len(run.job)
    while i < len(lines) or run.inflight:
        _check_board(run)
        # take everything that has arrived, in order
        while True:
            msg = board.next_message(0.0)
            if msg is None:
                break
            _handle(run, msg)
        held = _service_control(run)
        if i < len(lines) and not held and not board.paused:
            line = lines[i]
            in_flight_bytes = sum(j.nbytes for j in run.inflight)
            if (
                len(run.inflight) < config.window_lines
                and in_flight_bytes + line.nbytes <= config.window_bytes
            ):
                if not run.inflight:
                    board.last_rx = time.monotonic()  # the watchdog counts from here
                try:
                    board.write(encode_line(line.text))
                except DeviceError as exc:
                    board.error = board.error or exc
                # counted as sent even when the write raised: the bytes can be out and
                # parsed before the drain fails (a port gone mid-line), so the board may
                # end at this line
                run.inflight.append(line)
                run.sent += 1
                run.last_sent = line
                _check_board(run)
                i += 1
                if run.progress:
                    run.progress(line.index + 1, n_total, board.state.get("line"))
                continue
        msg = board.next_message(0.05)
        if msg is not None:
            _handle(run, msg)
        elif run.inflight:
            _watchdog(run, f"the ack of N{run.inflight[0].number}")


def _wait_done(run: _Run, last_number: int) -> int | None:
    board = run.board
    board.last_rx = time.monotonic()
    deadline_query = time.monotonic() + 1.0
    while True:
        _check_board(run)
        state = board.state
        if state.get("line") == last_number and state.get("stat") in _IDLE:
            run.note_progress(force=True)
            return int(last_number)
        held = _service_control(run)
        msg = board.next_message(0.05)
        if msg is not None:
            _handle(run, msg)
            continue
        if held:
            continue
        if time.monotonic() > deadline_query:
            # filtered reports may have nothing new to say: ask (nothing is in flight)
            deadline_query = time.monotonic() + 1.0
            _query_status(run)
            continue
        _watchdog(run, f"the end of N{last_number}")


def _query_status(run: _Run) -> None:
    """Ask for a full status report while no job line is in flight."""
    board = run.board
    try:
        board.write(encode_json({"sr": None}))
    except DeviceError:
        _check_board(run)
    deadline = time.monotonic() + run.config.stall_timeout_s
    while time.monotonic() < deadline:
        _check_board(run)
        msg = board.next_message(0.05)
        if msg is None:
            continue
        if isinstance(msg, Response) and not msg.is_banner and not run.inflight:
            if msg.status != 0:
                _stop(run, "error", None, f"status query answered {msg.status}")
            return
        _handle(run, msg)
    _watchdog(run, "a status reply")
