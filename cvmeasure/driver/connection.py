"""The host side of the serial link: a reader thread, commands, feedhold, flush, status."""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections.abc import Mapping
from typing import Any

from cvmeasure.driver.protocol import (
    FEEDHOLD,
    QUEUE_FLUSH,
    XOFF,
    XON,
    LineSplitter,
    MachineStat,
    Message,
    Response,
    RxReport,
    StatusReport,
    Unparsed,
    encode_json,
    parse_message,
)
from cvmeasure.driver.transport import Link
from cvmeasure.errors import DeviceError, DeviceTimeoutError

__all__ = ["BoardConnection", "BoardStuckError", "IDLE", "MOVING"]

log = logging.getLogger("cvmeasure.driver.stream")

#: Machine states with nothing running, and those in motion.
IDLE = (MachineStat.READY, MachineStat.STOP, MachineStat.END)
MOVING = (MachineStat.RUN, MachineStat.CYCLE, MachineStat.JOG, MachineStat.HOMING)
_MOVING = MOVING
#: States in which ``sr.line`` is the runtime's line (the block being run or held).
_IN_CYCLE = (*MOVING, MachineStat.HOLD)


class BoardStuckError(DeviceTimeoutError):
    """A board that is not idle neither moves nor answers: its motion is frozen.

    ``line`` is the last ``sr.line`` it reported (None when it said nothing).
    """

    def __init__(self, line: int | None, stuck_s: float, url: str) -> None:
        self.line = line
        where = f"line N{line}" if line is not None else "its line"
        super().__init__(
            f"{url}: the board is not idle but has neither moved nor answered for "
            f"{stuck_s:g} s at {where} (its motion is frozen)"
        )


class BoardConnection:
    """Reads the board in a thread; one consumer takes messages in arrival order.

    Parameters
    ----------
    link : an open :class:`~cvmeasure.driver.transport.Link`.
    """

    def __init__(self, link: Link) -> None:
        self.link = link
        self.state: dict[str, Any] = {}
        self.last_rx = time.monotonic()
        self.error: DeviceError | None = None
        self.unparsed: list[Unparsed] = []
        #: XOFF seen in the data (a link without tty flow control, e.g. socket://)
        self.paused = False
        #: firmware version and build (``fv``, ``fb``) as the board reported them
        self.firmware: dict[str, Any] = {}
        #: the last ``sr.line`` the board reported while the machine was in a cycle
        #: (running or held): a line the machine had certainly started
        self.running_line: int | None = None
        self._queue: queue.Queue[Message | None] = queue.Queue()
        self._stop = threading.Event()
        self._splitter = LineSplitter()
        self._thread = threading.Thread(target=self._reader, name="board-reader", daemon=True)
        self._thread.start()

    def _reader(self) -> None:
        while not self._stop.is_set():
            try:
                data = self.link.read_available()
            except DeviceError as exc:
                self.error = exc
                self._queue.put(None)
                return
            if not data:
                continue
            self.last_rx = time.monotonic()
            for byte in data:
                if byte in (XON, XOFF):
                    self.paused = byte == XOFF
            for raw in self._splitter.feed(data):
                msg = parse_message(raw)
                log.debug("board -> %r", raw)
                self._queue.put(msg)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=2)

    def write(self, data: bytes) -> None:
        if self.error is not None:
            raise self.error
        log.debug("host -> %r", data)
        self.link.write(data)

    def next_message(self, timeout_s: float) -> Message | None:
        """The next message (status reports merged into :attr:`state`), or None."""
        try:
            msg = self._queue.get(timeout=max(timeout_s, 0.0))
        except queue.Empty:
            return None
        if msg is None:
            self._queue.put(None)  # keep reporting the error
            return None
        if isinstance(msg, StatusReport):
            self._merge(msg.fields)
        elif isinstance(msg, Response) and isinstance(msg.body.get("sr"), dict):
            self._merge(msg.body["sr"])
        elif isinstance(msg, Unparsed):
            self.unparsed.append(msg)
        return msg

    def _merge(self, fields: Mapping[str, Any]) -> None:
        self.state.update(fields)
        line = self.state.get("line")
        if self.state.get("stat") in _IN_CYCLE and isinstance(line, int) and line > 0:
            self.running_line = line

    def command(self, obj: Mapping[str, Any], *, timeout_s: float = 2.0) -> Response:
        """Send one JSON command and wait for its response (nothing else in flight)."""
        data = encode_json(obj)
        self.write(data)
        deadline = time.monotonic() + timeout_s
        while True:
            if self.error is not None:
                raise self.error
            msg = self.next_message(deadline - time.monotonic())
            if isinstance(msg, Response) and not msg.is_banner:
                if msg.nbytes != len(data):
                    raise DeviceError(
                        f"{self.link.url}: reply to {data!r} counts {msg.nbytes} bytes, "
                        f"sent {len(data)}"
                    )
                return msg
            if time.monotonic() >= deadline:
                raise DeviceTimeoutError(
                    f"{self.link.url}: no reply to {data.decode().strip()} in {timeout_s:g} s"
                )

    def hold(self, *, timeout_s: float) -> dict[str, Any] | None:
        """Feedhold; the status the board reports *after* it, once nothing runs; or None.

        Read before any queue flush, ``line`` is then exact: the runtime's line while
        held (stat 6), or, idle, the last line parsed with nothing left to run. Only a
        report that arrives after the ``!`` counts: the last state seen before it may
        be old (a board whose reports stalled while its machine ran on). A machine
        that was idle is asked (``{"sr":null}``), and the answer comes after the lines
        still in flight were parsed: if they started it, it is held again.
        """
        deadline = time.monotonic() + timeout_s
        self.write(FEEDHOLD)
        if self.state.get("stat") in _MOVING:
            state = self._await_stop(deadline)
            if state is None or state.get("stat") == MachineStat.HOLD:
                return state
        for _ in range(2):
            state = self._ask_status(deadline)
            if state is None or state.get("stat") not in _MOVING:
                return state
            self.write(FEEDHOLD)  # lines in flight started it after the first hold
            state = self._await_stop(deadline)
            if state is None or state.get("stat") == MachineStat.HOLD:
                return state
        return None

    def _ask_status(self, deadline: float) -> dict[str, Any] | None:
        """Send ``{"sr":null}``; the full status once its answer arrives (None: no answer)."""
        self.write(encode_json({"sr": None}))
        while time.monotonic() < deadline:
            if self.error is not None:
                raise self.error
            msg = self.next_message(deadline - time.monotonic())
            if isinstance(msg, Response) and isinstance(msg.body.get("sr"), dict):
                return dict(self.state)
        return None

    def _await_stop(self, deadline: float) -> dict[str, Any] | None:
        """The status once a report received from now on says the machine is not moving."""
        while time.monotonic() < deadline:
            if self.error is not None:
                raise self.error
            msg = self.next_message(deadline - time.monotonic())
            if isinstance(msg, StatusReport) and self.state.get("stat") not in _MOVING:
                return dict(self.state)
        return None

    def wait_idle(
        self, *, timeout_s: float, query_timeout_s: float, stuck_s: float | None = None
    ) -> dict[str, Any]:
        """Let a running machine finish what it holds; its full status once idle.

        A board whose planner is full reads no command until a slot frees, so each
        status query may wait for the machine. DeviceTimeoutError after ``timeout_s``;
        :class:`BoardStuckError` as soon as a machine that is not idle has neither
        moved, changed line nor answered for ``stuck_s`` (a frozen runtime never
        finishes: waiting would hang).
        """
        deadline = time.monotonic() + timeout_s
        seen: tuple[Any, ...] | None = None
        seen_t = time.monotonic()
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise DeviceTimeoutError(
                    f"{self.link.url}: the board was still running after {timeout_s:g} s"
                )
            if self.error is not None:
                raise self.error
            try:
                state = self.query_status(timeout_s=min(max(query_timeout_s, 0.1), remaining))
            except DeviceError:
                # its planner is full (the query is read when a slot frees), or a reply
                # to a line of the dead connection arrived first: ask again
                self.drain(0.05)
                state = None
            if state is not None and state.get("stat") not in _MOVING:
                return state
            now_seen = tuple(self.state.get(k) for k in ("line", "posx", "posy", "posz", "posa"))
            if now_seen != seen:
                seen, seen_t = now_seen, time.monotonic()
            elif stuck_s is not None and time.monotonic() - seen_t > stuck_s:
                raise BoardStuckError(self.state.get("line"), stuck_s, self.link.url)
            if state is not None:
                self.next_message(min(0.1, remaining))

    def flush_board(self, *, timeout_s: float) -> bool:
        """Feedhold + queue flush; wait for the flush's rx report. True when it came."""
        self.write(FEEDHOLD)
        self.write(QUEUE_FLUSH)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self.error is not None:
                raise self.error
            msg = self.next_message(deadline - time.monotonic())
            if isinstance(msg, RxReport):
                self.drain(0.02)
                return True
        return False

    def drain(self, quiet_s: float) -> None:
        """Consume messages until none arrives for ``quiet_s``."""
        while self.next_message(quiet_s) is not None:
            pass

    def query_status(self, *, timeout_s: float = 2.0) -> dict[str, Any]:
        """All status fields (``{"sr":null}``), merged into :attr:`state`."""
        self.command({"sr": None}, timeout_s=timeout_s)
        return dict(self.state)
