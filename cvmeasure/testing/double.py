"""A TinyG-like bender on a real pseudo-terminal: the test and demo double.

:class:`FakeTinyG` runs in a thread on the master side of ``os.openpty()``;
the host opens the slave (``double.port``, e.g. ``/dev/pts/7``) with pyserial
like any serial port. It behaves as reference ``diwire-tinyg.md`` section 3.3
proposes:

* **interrupt layer**: a 254-byte receive ring; a byte arriving when it is
  full is *dropped* (and counted, so overflow bugs show); the realtime
  characters ``!`` (feedhold), ``~`` (cycle start), ``%`` (queue flush) and
  ctrl-x (reset) are trapped anywhere in the stream; XOFF is sent at 203
  buffered bytes, XON below 25; XON/XOFF from the host pause its own output.
* **line reader**: a line (CR or LF) is read only while at least 4 of the 32
  planner slots are free; JSON lines are commands, anything else G-code; every
  line gets one ``{"r":...,"f":[1,status,bytes]}`` once parsed and queued.
* **planner and executor**: G0/G1 moves on X (pin, deg), Y (feed, mm), Z (pin
  duck), A; G90/G91, G21, G28.3; moves take ``distance / rate`` seconds of
  machine time (G0 at the axis maximum rate), divided by ``speedup`` in wall
  time; moves under 2.5 ms are rejected (status 202); ``sr.line`` follows the
  ``N`` word of the executing block (a bare ``N`` block is a marker).
* **reports**: filtered status reports every ``si`` ms and on every state
  change, queue reports (``qv``), exception reports, ``rx`` after a flush.
* **faults** (:class:`Fault`): a dropped byte, a malformed reply, an alarm
  (limit switch, ``er`` 204 + stat 2), a stall (the board freezes), the port
  vanishing (the pty closes; the machine finishes its queue; :meth:`reconnect`
  plugs it back in on a new pty).
* **machine**: every executed pin stroke is run through the simulation
  (:func:`cvmeasure.sim.simulate`), so the pin angle, the feed, the bend at
  the die and the bent wire's shape are known (:meth:`FakeTinyG.machine_state`,
  :meth:`FakeTinyG.wire_shape_mm`).

Modules: :mod:`~cvmeasure.testing.double_records` (faults, bends, snapshots),
:mod:`~cvmeasure.testing.double_firmware` (line reader, commands, G-code, executor,
reports); this one holds the pty, the thread, the interrupt layer, the faults' firing,
the realtime characters and the machine's simulation.

Simplifications, stated: the RX "wire" has no baud-rate delay (bytes arrive as
fast as the host writes them); a feedhold stops instantly (no deceleration);
a reset keeps the positions.

:mod:`cvmeasure.sim` is imported only when the double bends with its physical model
(a tenth of a second of start-up that a protocol test does not need).
"""

from __future__ import annotations

import errno
import logging
import math
import os
import select
import threading
import time
import tty
from collections import deque
from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np

from cvmeasure.driver.protocol import (
    AXES,
    PLANNER_HEADROOM,
    PLANNER_SLOTS,
    RX_BUFFER_BYTES,
    XOFF,
    XOFF_HIGH_WATER,
    XON,
    XON_LOW_WATER,
    FooterStyle,
    MachineStat,
    format_queue_report,
    format_response,
    format_rx_report,
)
from cvmeasure.testing.double_firmware import FirmwareLayer
from cvmeasure.testing.double_records import (
    BANNER,
    DEFAULT_MAX_RATE,
    FAULT_KINDS,
    LINE_REPORTS,
    BendRecord,
    DoubleStats,
    Fault,
    FaultKind,
    LineReport,
    MachineState,
    PlannedMove,
)

__all__ = [
    "FaultKind",
    "FAULT_KINDS",
    "LINE_REPORTS",
    "LineReport",
    "Fault",
    "BendRecord",
    "MachineState",
    "FakeTinyG",
]

log = logging.getLogger(__name__)


class FakeTinyG(FirmwareLayer):
    """A TinyG v8-like bender on a pseudo-terminal, driving the simulation.

    Parameters
    ----------
    speedup : machine seconds per wall second (1 = real time).
    faults : faults to inject (each fires once).
    footer_style : ``"g2"`` ``[1,st,n]`` (Pensa's DIWire), ``"440"`` or ``"446"``.
    rx_buffer_bytes, planner_slots, planner_headroom : the firmware's sizes.
    sim_params, sim_effects : the machine and wire of :mod:`cvmeasure.sim`
        (defaults: the simulation's). Measurement-only effects (camera tilt)
        are ignored: the double bends wire, it does not photograph it.
    max_rate : axis -> maximum rate (units/min) for G0.
    line_report : what ``sr.line`` says after a queue flush: ``"executing"`` (the
        line that was running) or ``"parsed"`` (TinyG firmware: the last line it
        parsed, including the lines the flush dropped unexecuted).

    Examples
    --------
    >>> with FakeTinyG(speedup=100.0) as board:  # doctest: +SKIP
    ...     link = open_link(board.port)
    """

    def __init__(
        self,
        *,
        speedup: float = 1.0,
        faults: Sequence[Fault] = (),
        footer_style: FooterStyle = "g2",
        rx_buffer_bytes: int = RX_BUFFER_BYTES,
        planner_slots: int = PLANNER_SLOTS,
        planner_headroom: int = PLANNER_HEADROOM,
        sim_params: Any = None,
        sim_effects: Iterable[Any] = (),
        max_rate: dict[str, float] | None = None,
        line_report: LineReport = "executing",
    ) -> None:
        if not speedup > 0:
            raise ValueError("speedup must be positive")
        if line_report not in LINE_REPORTS:
            raise ValueError(f"line_report must be one of {', '.join(LINE_REPORTS)}")
        self.line_report: LineReport = line_report
        self.speedup = float(speedup)
        self.footer_style: FooterStyle = footer_style
        self.rx_size = int(rx_buffer_bytes)
        self.slots = int(planner_slots)
        self.headroom = int(planner_headroom)
        self.max_rate = dict(DEFAULT_MAX_RATE, **(max_rate or {}))
        self._faults = list(faults)
        self._sim_params = sim_params
        self._sim_effects = tuple(e for e in sim_effects if getattr(e, "name", "") != "camera_tilt")
        self._lock = threading.RLock()
        self._thread: threading.Thread | None = None
        self._running = False
        self._master: int | None = None
        self._slave_keep: int | None = None
        self.port = ""
        self.stats = DoubleStats()
        self._reset_board(keep_position=False)
        # the machine (physical; survives resets and reconnects)
        self._bends: list[BendRecord] = []
        self._feed_since_bend = 0.0
        self._holding: tuple[float, float, float, float] | None = (
            None  # pin, loaded, unloaded, head
        )
        self._bend_at_die = 0.0
        self._bend_line: int | None = None
        self._vanished = False

    # ------------------------------------------------------------------ lifecycle

    def start(self) -> FakeTinyG:
        """Open the pty and start the board thread; ``self.port`` is the slave path."""
        self._open_pty()
        self._running = True
        self._thread = threading.Thread(target=self._run, name="FakeTinyG", daemon=True)
        self._thread.start()
        return self

    def close(self) -> None:
        """Stop the thread and close the pty."""
        self._running = False
        if self._thread is not None:
            self._thread.join(timeout=5)
            self._thread = None
        self._close_pty()

    def __enter__(self) -> FakeTinyG:
        return self.start() if self._thread is None else self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def reconnect(self) -> str:
        """Plug the board back in after a ``vanish`` fault; return the new port."""
        with self._lock:
            self._close_pty()
            self._open_pty()
            self._vanished = False
            return self.port

    @property
    def vanished(self) -> bool:
        return self._vanished

    def _open_pty(self) -> None:
        master, slave = os.openpty()
        # Raw mode on the slave *before* the host opens it: a fresh pty echoes,
        # and the board's first status report would come back as input. (Never
        # touch the termios later: it is shared with the host, whose pyserial
        # sets its own flags, IXON included, when it opens the port.)
        tty.setraw(slave)
        os.set_blocking(master, False)
        self._master = master
        self._slave_keep = slave  # keeps the pty alive while the host reopens it
        self.port = os.ttyname(slave)

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave_keep):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = None
        self._slave_keep = None

    # ------------------------------------------------------------------ state

    def _reset_board(self, *, keep_position: bool) -> None:
        pos = getattr(self, "_pos", None) if keep_position else None
        self._pos: dict[str, float] = dict(pos) if pos else {a: 0.0 for a in AXES}
        self._model_pos = dict(self._pos)
        self._relative = False
        self._feed_rate: float | None = None
        self._motion = 0
        self._ring = bytearray()
        self._rx_line_count = 0  # lines (terminators) seen by the interrupt
        self._rx_byte_in_line = 0
        self._xoff = False
        self._tx = bytearray()
        self._tx_paused = False
        self._planner: deque[PlannedMove] = deque()
        self._stat = MachineStat.READY
        self._line = 0
        self._last_parsed_line: int | None = None
        self._hold_req = self._cycle_req = self._flush_req = self._reset_req = False
        self._flush_pending = False
        self._stall_until = 0.0
        self._pending_stall_line: tuple[bytes, int] | None = None
        self._settings: dict[str, Any] = {
            "ej": 1, "jv": 1, "js": 1, "ee": 0, "ec": 0, "ex": 1,
            "sv": 1, "si": 100, "qv": 0, "fv": 0.97, "fb": 440.21,
        }  # fmt: skip
        self._sr_last: dict[str, Any] = {}
        self._sr_due = 0.0
        self._qr_last = self.slots
        self._seq = 0

    def machine_state(self) -> MachineState:
        """A consistent snapshot of the machine (thread-safe)."""
        with self._lock:
            return MachineState(
                pin_deg=self._pos["x"],
                feed_mm=self._pos["y"],
                duck=self._pos["z"],
                stat=int(self._stat),
                line=self._line,
                bend_angle_deg=self._bend_at_die,
                holding=self._holding is not None,
                bends=tuple(self._bends),
                planner_depth=len(self._planner),
                rx_bytes=len(self._ring),
                head_deg=self._pos["x"] if self._holding is None else self._holding[3],
            )

    def wire_shape_mm(self) -> np.ndarray:
        """The bent wire as a polyline (N, 2), mm, in the order it was fed.

        The first fed point is at the origin, the first leg along +x; at each
        bend the polyline turns by minus the machine bend angle (the already
        fed leg rotates, so walking from the first fed point the turn is
        mirrored), with the *unloaded* (final) angle. The wire still in the
        feeder since the last bend is included as the last leg.
        """
        with self._lock:
            bends = list(self._bends)
            tail = self._feed_since_bend
        pts = [np.zeros(2)]
        heading = 0.0
        for b in bends:
            step = b.feed_before_mm * np.array([math.cos(heading), math.sin(heading)])
            pts.append(pts[-1] + step)
            heading -= math.radians(b.unloaded_bend_deg)
        pts.append(pts[-1] + tail * np.array([math.cos(heading), math.sin(heading)]))
        return np.asarray(pts)

    def executed_lines(self) -> tuple[list[int | None], list[int | None]]:
        """(line numbers of completed blocks, of blocks cut short by a flush/alarm)."""
        with self._lock:
            return list(self.stats.completed), list(self.stats.partial)

    def executed_moves(self) -> list[tuple[int | None, dict[str, float], dict[str, float]]]:
        """Every block that moved, in order: (its N word, start, end), axis units.

        The end is where the block stopped (a block cut short by a flush or an alarm
        ends on its path). A block whose N word arrived corrupted carries the label
        the firmware read; its start and end say which motion actually ran.
        """
        with self._lock:
            return [(n, dict(a), dict(b)) for n, a, b in self.stats.moves]

    # ------------------------------------------------------------------ thread

    def _run(self) -> None:
        last = time.monotonic()
        while self._running:
            now = time.monotonic()
            with self._lock:
                stalled = now < self._stall_until
                if not stalled:
                    if self._pending_stall_line is not None:
                        raw, nbytes = self._pending_stall_line
                        self._pending_stall_line = None
                        self._process_line(raw, nbytes, now)
                    self._service_realtime(now)
                    self._advance((now - last) * self.speedup, now)
                    self._read_lines(now)
                    self._reports(now)
                last = now
                self._flush_tx()
                fd = self._master
            if fd is None:
                time.sleep(0.005)
                continue
            busy = bool(self._planner) and not stalled
            timeout = 0.001 if busy else 0.01
            try:
                readable, _, _ = select.select([fd], [fd] if self._tx else [], [], timeout)
            except (OSError, ValueError):
                time.sleep(0.005)
                continue
            if not readable:
                continue
            try:
                data = os.read(fd, 256)
            except BlockingIOError:
                continue
            except OSError as exc:
                if exc.errno == errno.EIO:  # no slave open: host away
                    time.sleep(0.005)
                    continue
                raise
            with self._lock:
                for byte in data:
                    self._isr(byte)

    # ------------------------------------------------------------------ interrupt layer

    def _isr(self, byte: int) -> None:
        byte &= 0x7F
        if byte in (XON, XOFF):
            self._tx_paused = byte == XOFF
            return
        if byte == 0x21:
            self._hold_req = True
            return
        if byte == 0x7E:
            self._cycle_req = True
            return
        if byte == 0x25:
            self._flush_req = True
            return
        if byte == 0x18:
            self._reset_req = True
            return
        fault = self._fault("drop_byte", self._rx_line_count + 1, consume=False)
        if fault is not None:
            terminator = byte in (0x0A, 0x0D)
            index = self._rx_byte_in_line
            if index == fault.byte_index or terminator:
                self._consume(fault)
                self._rx_byte_in_line = 0 if terminator else index + 1
                if terminator:
                    self._rx_line_count += 1
                return
        if len(self._ring) >= self.rx_size:
            self.stats.rx_dropped_bytes += 1
        else:
            self._ring.append(byte)
            self.stats.rx_peak_bytes = max(self.stats.rx_peak_bytes, len(self._ring))
        if byte in (0x0A, 0x0D):
            self._rx_line_count += 1
            self._rx_byte_in_line = 0
        else:
            self._rx_byte_in_line += 1
        if (
            self._settings["ex"] == 1
            and not self._xoff
            and len(self._ring) >= min(XOFF_HIGH_WATER, self.rx_size - 1)
        ):
            self._xoff = True
            self.stats.xoff_sent += 1
            self._write_now(bytes([XOFF]))

    def _check_xon(self) -> None:
        if self._xoff and len(self._ring) < XON_LOW_WATER:
            self._xoff = False
            self.stats.xon_sent += 1
            self._write_now(bytes([XON]))

    def _write_now(self, data: bytes) -> None:
        if self._master is None:
            return
        try:
            os.write(self._master, data)
        except OSError:
            pass

    def _send(self, data: bytes) -> None:
        self._tx += data

    def _flush_tx(self) -> None:
        if not self._tx or self._tx_paused or self._master is None:
            return
        try:
            n = os.write(self._master, bytes(self._tx))
        except BlockingIOError:
            return
        except OSError:
            self._tx.clear()
            return
        del self._tx[:n]

    # ------------------------------------------------------------------ faults

    def _fault(self, kind: str, line: int, *, consume: bool = True) -> Fault | None:
        for f in self._faults:
            if f.kind == kind and f.at_line == line:
                if consume:
                    self._consume(f)
                return f
        return None

    def _consume(self, fault: Fault) -> None:
        self._faults.remove(fault)
        self.stats.faults_fired.append(f"{fault.kind}@{fault.at_line}")
        log.debug("fault %s at line %d", fault.kind, fault.at_line)

    def _vanish(self) -> None:
        self._flush_tx_blocking()
        self._vanished = True
        self._close_pty()

    def _flush_tx_blocking(self) -> None:
        deadline = time.monotonic() + 0.5
        while self._tx and self._master is not None and time.monotonic() < deadline:
            self._flush_tx()

    # ------------------------------------------------------------------ realtime

    def _service_realtime(self, now: float) -> None:
        if self._reset_req:
            self._reset_req = False
            self._drop_planner()
            self._reset_board(keep_position=True)
            self._send(format_response({**BANNER, "msg": "SYSTEM READY"}, 0, 0, style="g2"))
            return
        if self._hold_req:
            self._hold_req = False
            if self._stat == MachineStat.RUN:
                self._set_stat(MachineStat.HOLD, now)
        if self._cycle_req:
            self._cycle_req = False
            if self._stat == MachineStat.HOLD and not self._flush_req and not self._flush_pending:
                self._set_stat(MachineStat.RUN if self._planner else MachineStat.STOP, now)
        if self._flush_req:
            self._flush_req = False
            self._flush_pending = True
        if self._flush_pending and self._stat != MachineStat.RUN:
            self._flush_pending = False
            self._queue_flush(now)

    def _queue_flush(self, now: float) -> None:
        if self.line_report == "parsed" and self._last_parsed_line is not None:
            self._line = self._last_parsed_line  # the firmware's gm.linenum: last parsed
        self._ring.clear()
        self._rx_byte_in_line = 0
        self._drop_planner()
        self._check_xon()
        if self._stat != MachineStat.ALARM:
            self._set_stat(MachineStat.STOP, now)
        if self._settings["qv"]:
            self._send(format_queue_report(self.slots))
            self._qr_last = self.slots
        self._send(format_rx_report(self.rx_size))

    def _drop_planner(self) -> None:
        if self._planner:
            head = self._planner[0]
            if head.start is not None:
                self.stats.partial.append(head.line_number)
                self.stats.moves.append((head.line_number, dict(head.start), dict(self._pos)))
                self._machine_move_done(head, complete=False)
        self._planner.clear()
        self._model_pos = dict(self._pos)

    # ------------------------------------------------------------------ machine (simulation)

    def _simulate(self, pin_deg: float) -> tuple[float, float, float]:
        """Loaded and unloaded bend and the head's real rotation (deg) for the command X."""
        from cvmeasure.sim import simulate

        res = simulate(
            [pin_deg], self._sim_params, self._sim_effects, bend_index=[len(self._bends)]
        )
        return float(res.loaded_bend_deg[0]), float(res.unloaded_bend_deg[0]), float(res.pin_deg[0])

    def _machine_move_start(self, move: PlannedMove) -> None:
        if move.start is not None and move.target["y"] != move.start["y"]:
            self._release()
            self._bend_at_die = 0.0

    def _machine_move_done(self, move: PlannedMove, *, complete: bool) -> None:
        start = move.start or self._pos
        dy = self._pos["y"] - start["y"]
        if dy:
            self._feed_since_bend += dy
        if self._pos["x"] == start["x"] or self._pos["z"] > 90.0 or start["z"] > 90.0:
            return
        pin = self._pos["x"]
        held = self._holding
        toward_home = start["x"] * pin >= 0.0 and abs(pin) < abs(start["x"])
        if toward_home and held is None:
            # a retreating pin presses nothing: a return to home cut by two stops
            # (its fix-up ending off home) is not a new bend
            return
        loaded, unloaded, head = self._simulate(pin)
        if loaded != 0.0 and (held is None or abs(loaded) > abs(held[1]) + 1e-9):
            if held is not None and math.copysign(1, loaded) != math.copysign(1, held[1]):
                self._release()
            self._holding = (pin, loaded, unloaded, head)
            self._bend_at_die = loaded
            self._bend_line = move.line_number
        elif held is not None and abs(loaded) < abs(held[1]) - 1e-9:
            self._release()

    def _release(self) -> None:
        if self._holding is None:
            return
        pin, loaded, unloaded, _ = self._holding
        self._bends.append(
            BendRecord(self._bend_line, self._feed_since_bend, pin, loaded, unloaded)
        )
        self._feed_since_bend = 0.0
        self._bend_at_die = unloaded
        self._holding = None
