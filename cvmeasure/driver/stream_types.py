"""The streamer's settings, its stop and result records, and the operator's controls.

Types shared by :mod:`cvmeasure.driver.stream` (which re-exports them) and the modules that
drive it (the CLI's ``bend``, the session, the app).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

from cvmeasure.errors import DeviceError

__all__ = [
    "FIRMWARE_QUERIES",
    "JobStopped",
    "SETUP_COMMANDS",
    "StopInfo",
    "StreamConfig",
    "StreamControl",
    "StreamResult",
]


#: Session settings, sent one at a time before a job (reference section 2.4).
SETUP_COMMANDS: tuple[dict[str, Any], ...] = (
    {"ej": 1},
    {"js": 1},
    {"jv": 5},  # verbose: each G-code ack echoes the block, so a garbled byte shows
    {"ee": 0},
    {"ec": 0},
    {"sv": 1},
    {"si": 100},
    {"qv": 0},
    {"sr": {"line": True, "posx": True, "posy": True, "posz": True, "vel": True, "stat": True}},
)
#: Identification asked for before every job and recorded in the journal.
FIRMWARE_QUERIES: tuple[dict[str, Any], ...] = ({"fv": None}, {"fb": None})


@dataclass(frozen=True)
class StreamConfig:
    """Tunables of the streamer (times in wall seconds).

    window_lines, window_bytes : lines and bytes allowed in flight (one line: a
        rejected, merged or unacknowledged line is never overtaken by a later one).
    stall_timeout_s : silence from the board, while it owes an ack or is
        running, after which the job is stopped as stalled.
    flush_timeout_s : how long a safe stop waits for the board's flush report.
    command_timeout_s : how long a setup command waits for its reply.
    progress_interval_s : how often executed-line progress is journalled.
    settle_timeout_s : how long a resume lets a board that is still running finish
        the lines it already holds (its ``sr.line`` is then exact).
    """

    window_lines: int = 1
    window_bytes: int = 200
    stall_timeout_s: float = 5.0
    flush_timeout_s: float = 5.0
    command_timeout_s: float = 2.0
    progress_interval_s: float = 0.5
    settle_timeout_s: float = 120.0

    def __post_init__(self) -> None:
        if self.window_lines < 1 or self.window_bytes < 2:
            raise ValueError("window_lines must be >= 1 and window_bytes >= 2")


@dataclass(frozen=True)
class StopInfo:
    """Why and where a job stopped.

    ``reason`` is one of ``desync``, ``error``, ``malformed``, ``alarm``,
    ``stall``, ``port_gone``, ``reset``, ``interrupted``, ``aborted``; ``line_number`` is
    the ``N`` of the line that caused it (None when unknown); ``board`` is the
    board's last known ``sr`` fields after the stop (None when unreachable);
    ``held`` the fields when the feedhold had stopped the machine, before the queue
    flush (its ``line`` is the line that was running: TinyG's ``sr.line`` after a
    flush names the last line *parsed*, flushed ones included); ``corrupt_line_ran``
    says that a line the board received corrupted (a ``desync``) had reached the
    machine before the feedhold, and ``ran_past_rejected_line`` that the board ran
    lines after the one it rejected (an ``error``): the part may be wrong, and a
    resume needs ``force``; ``flush_sent`` that a queue flush was sent (confirmed or
    not): the board's line after it is then the last line *parsed*, not run;
    ``misread_line`` the number the board reported for the corrupted line when it
    read that line's N word wrong (a line it was never sent there), else None.
    """

    reason: str
    line_number: int | None
    line: str
    detail: str
    board: dict[str, Any] | None = None
    corrupt_line_ran: bool = False
    held: dict[str, Any] | None = None
    ran_past_rejected_line: bool = False
    flush_sent: bool = False
    misread_line: int | None = None

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class StreamResult:
    """A finished job: lines sent and acked, the last executed ``N``, timings."""

    lines_total: int
    lines_sent: int
    resumed_from: int | None
    executed_line: int | None
    seconds: float
    fixup: str | None = None
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


class JobStopped(DeviceError):
    """The job stopped safely on a fault; ``stop`` says where and why."""

    def __init__(self, stop: StopInfo) -> None:
        self.stop = stop
        where = f"line N{stop.line_number}" if stop.line_number is not None else "unknown line"
        # a part the stop may have spoiled needs a look before the job goes on
        check = stop.corrupt_line_ran or stop.ran_past_rejected_line
        then = "resume with --resume" + (" --force once the part is checked" if check else "")
        super().__init__(
            f"job stopped ({stop.reason}) at {where} {stop.line!r}: {stop.detail}; {then}"
        )


# ---------------------------------------------------------------------------
# Jobs


class StreamControl:
    """Requests to a running job from another thread: feedhold, cycle start, abort.

    ``hold()`` sends ``!`` (the board decelerates and holds, stat 6) and stops
    sending lines; ``resume()`` sends ``~``; ``abort()`` stops the job safely
    (feedhold, flush, journal) and :func:`stream_job` raises :class:`JobStopped`
    with reason ``aborted``, resumable like any other stop.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._hold = self._resume = self._abort = False
        self.held = False

    def hold(self) -> None:
        with self._lock:
            self._hold, self._resume = True, False

    def resume(self) -> None:
        with self._lock:
            self._resume, self._hold = True, False

    def abort(self) -> None:
        with self._lock:
            self._abort = True

    def take(self) -> tuple[bool, bool, bool]:
        """(hold, resume, abort) requested since the last call."""
        with self._lock:
            out = (self._hold, self._resume, self._abort)
            self._hold = self._resume = self._abort = False
            return out


# ---------------------------------------------------------------------------
# The host side of the link
