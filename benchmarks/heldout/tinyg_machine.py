"""The firmware side of the held-out TinyG controller: bytes in, bytes out, a clock.

Modelled on TinyG v8 (0.97, build 440) as its wiki and sources document it:

* RX ISR: a 254-byte ring; ``!`` feedhold, ``~`` cycle start, ``%`` queue flush, ^X reset
  and (with ``$ex=1``) XON/XOFF are trapped anywhere in the stream and never buffered; a
  byte arriving at a full ring is dropped silently; XOFF above 80 % (203 bytes), XON below
  10 % (25).
* Main loop: a line (ended by CR or LF) is read only while at least 4 of the 32 planner
  buffers are free; ``{`` starts a JSON command, ``$``/``?`` a text-mode command, anything
  else is G-code. Every line gets one response ``{"r":{...},"f":[1,status,bytes]}`` once
  parsed and queued (``bytes`` counts the terminator); an empty line gets none in JSON mode.
* Feedhold/flush/cycle-start sequencing as ``cm_feedhold_sequencing_callback``: a flush
  waits for the hold to finish decelerating; the flush clears the RX ring and the planner,
  resyncs the model position to the runtime position and ends in program stop (stat 3).
* ``sr.line`` is the runtime's line while a cycle runs or holds, and the G-code model's
  line (the last line parsed) once the machine has stopped, which is how an end marker
  ``N<last>`` shows up with stat 3.
* ^X reboots: everything is cleared, positions are zero, a banner follows.

Moves run in machine time = real time x ``speedup``.
"""

from __future__ import annotations

import json
import math
import re
from collections import deque
from dataclasses import dataclass, field

from benchmarks.heldout.tinyg_commands import (
    json_command,
    queue_report,
    status_report,
    text_command,
)
from benchmarks.heldout.tinyg_faults import Fault
from benchmarks.heldout.tinyg_gcode import (
    AXES,
    STAT_INPUT_TOO_LONG,
    STAT_OK,
    ModelState,
    Move,
    parse_block,
    plan_move,
)
from benchmarks.heldout.tinyg_truth import Executed, Received, TruthLog

__all__ = ["MachineConfig", "TinyGMachine"]

XON, XOFF, RESET = 0x11, 0x13, 0x18
_N_AT_START = re.compile(rb"^\s*[Nn](\d+)")
_MESSAGES = {
    0: "OK",
    100: "Unrecognized command or config name",
    102: "Bad number format",
    107: "Input exceeds max length",
    111: "JSON syntax error",
    130: "Generic Gcode input error",
    131: "Gcode command unsupported",
    132: "M code unsupported",
    142: "Move has no feedrate",
    202: "Move less than minimum time",
}
_DEFAULT_SETTINGS: dict[str, float | int | str] = {  # TinyG 440 defaults
    "ej": 1, "jv": 2, "js": 1, "tv": 1, "qv": 0, "sv": 1, "si": 500, "ex": 1, "ec": 0,
    "ee": 0, "baud": 5, "fv": 0.97, "fb": 440.21, "hv": 8, "hp": 1, "id": "heldout-tinyg",
}  # fmt: skip
_SR_DEFAULT = ("line", "posx", "posy", "posz", "posa", "feed", "vel", "unit", "coor", "dist",
               "frmo", "momo", "stat")  # fmt: skip


@dataclass
class MachineConfig:
    """Sizes, speeds and timing of the model (TinyG 440 values by default)."""

    rx_buffer_bytes: int = 254
    xoff_high_bytes: int = 203
    xon_low_bytes: int = 25
    planner_buffers: int = 32
    planner_headroom: int = 4
    input_line_max: int = 255
    speedup: float = 100.0
    footer: str = "pensa"  # "pensa" = [1,status,bytes]; "440" = [1,status,bytes,checksum]
    boot_s: float = 0.05
    hold_decel_s: float = 0.2  # machine seconds from full feed to rest
    min_move_s: float = 0.0025
    min_report_s: float = 0.01  # floor of the status-report interval in real seconds
    vmax_mm_min: dict[str, float] = field(
        default_factory=lambda: {"x": 7500.0, "y": 10000.0, "z": 30000.0, "a": 7500.0}
    )
    tx_backlog_max: int = 2048  # bytes of unsent output that stop command processing


class TinyGMachine:
    """TinyG's firmware behaviour, driven by :meth:`receive` and :meth:`step`.

    Parameters
    ----------
    config
        Sizes and speeds.
    faults
        Faults to inject (each fires once).
    now
        The real time (s, any monotonic origin) the machine powers up at.
    """

    def __init__(self, config: MachineConfig, faults: list[Fault], now: float) -> None:
        self.cfg = config
        self.faults = faults
        self.t0 = now
        self.truth = TruthLog()
        self.settings = dict(_DEFAULT_SETTINGS)
        self.sr_fields = list(_SR_DEFAULT)
        self.out = bytearray()  # ordinary output, in order
        self.flow_out = bytearray()  # XON/XOFF, sent ahead of ordinary output
        self.port_gone_s: float | None = None  # set when a 'gone' fault fires; the IO layer acts
        self.host_xoff = False
        self._power_up(now)

    # ------------------------------------------------------------------ state
    def _power_up(self, now: float) -> None:
        self.ring = bytearray()
        self.merge_prefix = b""
        self.text_mode = False
        self.model = ModelState()
        self.runtime_pos = dict.fromkeys(AXES, 0.0)
        self.planner: deque[Move] = deque()
        self.current: Move | None = None
        self.elapsed_s = 0.0
        self.current_t0 = 0.0
        self.runtime_line = 0
        self.machine = "ready"  # ready | cycle | stop | end | alarm
        self.motion = "stop"  # stop | run | hold
        self.hold = "off"  # off | sync | hold
        self.decel_left_s = 0.0
        self.req_hold = self.req_flush = self.req_start = self.req_reset = False
        self.stall_until: float | None = None
        self.xoff_sent = False
        self.xoff_stuck_until: float | None = None
        self.booting_until = now + self.cfg.boot_s
        self.last_step = now
        self.last_sr: dict[str, object] = {}
        self.last_sr_t = now
        self.sr_now = False
        self.last_qr: int | None = None
        self.qi = self.qo = 0
        self.swallow_next = False
        self.booted = False

    def t(self, now: float) -> float:
        """Seconds since power-up."""
        return round(now - self.t0, 6)

    def event(self, now: float, kind: str, **detail: object) -> None:
        self.truth.events.append({"t_s": self.t(now), "kind": kind, **detail})

    @property
    def planner_free(self) -> int:
        return self.cfg.planner_buffers - len(self.planner) - (self.current is not None)

    @property
    def rx_free(self) -> int:
        return self.cfg.rx_buffer_bytes - 1 - len(self.ring)

    def stat(self) -> int:
        if self.machine == "alarm":
            return 2
        if self.machine == "cycle":
            return 6 if self.motion == "hold" else 5
        return {"ready": 1, "stop": 3, "end": 4}[self.machine]

    def position(self) -> dict[str, float]:
        """The runtime (machine) position, mm."""
        if self.current is None or self.current.duration_s <= 0.0:
            return dict(self.runtime_pos)
        f = min(1.0, self.elapsed_s / self.current.duration_s)
        s, g = self.current.start, self.current.target
        return {a: s[a] + (g[a] - s[a]) * f for a in AXES}

    def reported_line(self) -> int:
        return self.runtime_line if self.machine == "cycle" else self.model.line

    def input_gated(self) -> bool:
        """True while this side has asked the host to stop sending (XOFF out)."""
        return self.xoff_sent

    # ------------------------------------------------------------------ RX ISR
    def receive(self, data: bytes, now: float) -> None:
        """Bytes arriving on RX, one at a time through the ISR."""
        for b in data:
            self._isr(b & 0x7F, now)

    def _isr(self, c: int, now: float) -> None:
        if now < self.booting_until:
            return  # the board is rebooting: the byte is lost
        if c == RESET:
            self.req_reset = True
        elif c in (XON, XOFF) and self.settings["ex"] == 1:
            self.host_xoff = c == XOFF
        elif c == ord("!"):
            self.req_hold = True
        elif c == ord("~"):
            self.req_start = True
        elif c == ord("%"):
            self.req_flush = True
        elif len(self.ring) >= self.cfg.rx_buffer_bytes - 1:
            self.event(now, "rx_overflow_drop", byte=c)
        else:
            self.ring.append(c)
            if (
                self.settings["ex"] == 1
                and not self.xoff_sent
                and len(self.ring) > self.cfg.xoff_high_bytes
            ):
                self._send_flow(XOFF)

    def _send_flow(self, c: int) -> None:
        self.flow_out.append(c)
        self.xoff_sent = c == XOFF

    # ------------------------------------------------------------------ output
    def emit(self, obj: dict) -> None:
        if self.swallow_next and "r" in obj:
            self.swallow_next = False
            return
        self.out += json.dumps(obj, separators=(",", ":")).encode() + b"\n"

    def respond(self, body: dict, status: int, nbytes: int) -> None:
        if self.settings["jv"] == 0:
            return
        if status and self.settings["jv"] >= 2:
            body = {**body, "msg": _MESSAGES.get(status, "Error")}
        footer = [1, status, nbytes]
        if self.cfg.footer == "440":
            footer.append(sum(json.dumps(body).encode()) % 10000)
        self.emit({"r": body, "f": footer})

    def text_out(self, text: str) -> None:
        self.out += text.encode()

    # ------------------------------------------------------------------ main loop
    def step(self, now: float) -> None:
        """One pass of the main loop: resets, faults, sequencing, motion, input, reports."""
        if self.req_reset:
            self._reset(now)
        if now < self.booting_until:
            self.last_step = now
            return
        if not self.booted:
            self.booted = True
            self.boot_banner(now)
        self._time_faults(now)
        self._sequence(now)
        dt = max(0.0, now - self.last_step) * self.cfg.speedup
        self.last_step = now
        if self.stall_until is not None and now >= self.stall_until:
            self.stall_until = None
            self.event(now, "stall_end")
        if self.stall_until is None:
            self._advance(dt, now)
            self._sequence(now)
        self._read_lines(now)
        self._flow_control(now)
        self._reports(now)

    def boot_banner(self, now: float) -> None:
        """The startup banner (after power-up and after ^X)."""
        body = {k: self.settings[k] for k in ("fv", "fb", "hp", "hv", "id")}
        self.emit({"r": {**body, "msg": "SYSTEM READY"}, "f": [1, 0, 0]})
        self.event(now, "boot")

    def _flow_control(self, now: float) -> None:
        if self.xoff_stuck_until is not None:
            if now < self.xoff_stuck_until:
                return
            self.xoff_stuck_until = None
            self.event(now, "xoff_released")
            self._send_flow(XON)
            return
        if self.xoff_sent and len(self.ring) < self.cfg.xon_low_bytes:
            self._send_flow(XON)

    def _sequence(self, now: float) -> None:
        """Feedhold, queue flush and cycle start, in TinyG's order of precedence."""
        if self.req_hold:
            if self.motion == "run" and self.hold == "off":
                self.motion, self.hold = "hold", "sync"
                self.decel_left_s = self.cfg.hold_decel_s / 2.0
                self.event(now, "feedhold", line=self.runtime_line)
            self.req_hold = False
        if self.req_flush and (
            self.motion == "stop" or (self.motion == "hold" and self.hold == "hold")
        ):
            self.req_flush = False
            self._flush(now)
        if self.req_start and not self.req_flush and self.hold != "sync":
            self.req_start = False
            if self.hold == "hold":
                self.hold = "off"
                self.motion = "run"
                self.sr_now = True
                self.event(now, "cycle_start")
            elif self.machine in ("stop", "end", "ready") and (self.planner or self.current):
                self._cycle_start()

    def _cycle_start(self) -> None:
        if self.machine != "cycle":
            self.sr_now = True
        self.machine = "cycle"
        if self.hold == "off":
            self.motion = "run"

    def _flush(self, now: float) -> None:
        """``%``: clear the RX ring and the planner, resync the model to the runtime."""
        self.ring.clear()
        self.merge_prefix = b""
        dropped = [m.line for m in self.planner if m.kind == "move"]
        self._end_current(now, "flushed")
        self.planner.clear()
        self.model.position = dict(self.runtime_pos)
        self.machine, self.motion, self.hold = "stop", "stop", "off"
        self.req_start = False
        self.sr_now = True
        self.event(now, "flush", unexecuted_lines=dropped, position=dict(self.runtime_pos))
        queue_report(self, force=True)
        self.emit({"rx": self.rx_free})

    def _reset(self, now: float) -> None:
        """^X: reboot. Moves in progress stop where they are; the position reads zero after."""
        self._end_current(now, "reset")
        self.event(now, "reset", unexecuted_lines=[m.line for m in self.planner])
        if self.xoff_sent or self.xoff_stuck_until is not None:
            self.flow_out.append(XON)
        self._power_up(now)

    def _end_current(self, now: float, how: str) -> None:
        if self.current is None:
            return
        pos = self.position()
        self._log_move(self.current, pos, now, how)
        self.runtime_pos = pos
        self.current = None

    def _log_move(self, move: Move, end: dict[str, float], now: float, how: str) -> None:
        if move.kind != "move":
            return
        span = math.dist([move.start[a] for a in AXES], [move.target[a] for a in AXES])
        done = math.dist([move.start[a] for a in AXES], [end[a] for a in AXES])
        frac = 1.0 if how == "done" else (done / span if span > 0 else 0.0)
        self.truth.executed.append(
            Executed(
                move.line, move.text, round(frac, 6), dict(move.start),
                {a: round(v, 6) for a, v in end.items()}, self.current_t0, self.t(now), how,
            )
        )  # fmt: skip

    # ------------------------------------------------------------------ motion
    def _advance(self, dt: float, now: float) -> None:
        """Run the runtime for ``dt`` machine seconds.

        A feedhold decelerates over ``hold_decel_s``, i.e. the machine still travels for
        half that time at speed, into the next queued moves when the current one ends
        first (TinyG plans the deceleration over the queue, not within one block).
        """
        while self.hold != "hold":
            if self.current is None:
                if self.hold == "sync" and (self.decel_left_s <= 1e-12 or not self.planner):
                    self._hold_reached(now)
                    return
                if self.motion == "stop" or not self._start_next(now):
                    return
                if self.stall_until is not None:
                    return
                continue
            move = self.current
            step = min(dt, move.duration_s - self.elapsed_s)
            if self.hold == "sync":
                step = min(step, self.decel_left_s)
                self.decel_left_s -= step
            self.elapsed_s += step
            dt -= step
            if self.elapsed_s >= move.duration_s - 1e-12:
                self.elapsed_s = move.duration_s
                self.runtime_pos = dict(move.target)
                self._log_move(move, move.target, now, "done")
                self.current = None
            if self.hold == "sync" and self.decel_left_s <= 1e-12:
                self._hold_reached(now)
                return
            if dt <= 1e-12:
                return

    def _hold_reached(self, now: float) -> None:
        if self.current is not None:
            self.runtime_pos = self.position()
        self.hold = "hold"
        self.sr_now = True
        self.event(now, "hold_reached", line=self.runtime_line, position=self.position())

    def _start_next(self, now: float) -> bool:
        """Take the next planner buffer; False when the queue ran dry (cycle end)."""
        if not self.planner:
            if self.machine == "cycle":
                self.machine, self.motion = "stop", "stop"
                self.sr_now = True
            return False
        move = self.planner.popleft()
        self.qo += 1
        if move.kind in ("stop", "end"):
            self.machine = "stop" if move.kind == "stop" else "end"
            self.motion = "stop"
            self.sr_now = True
            return False
        self.current, self.elapsed_s, self.current_t0 = move, 0.0, self.t(now)
        self.runtime_line = move.line
        for fault in self._due(move.line, ("stall", "gone")):
            if fault.kind == "stall":
                self._fire_stall(fault, now)
            else:
                self._fire_gone(fault, now)
        return True

    def _fire_stall(self, fault: Fault, now: float) -> None:
        self.stall_until = math.inf if fault.arg is None else now + fault.arg
        self.event(now, "stall", fault=fault.spec, line=self.runtime_line)

    def _fire_gone(self, fault: Fault, now: float) -> None:
        self.port_gone_s = 1.0 if fault.arg is None else fault.arg
        self.event(now, "port_gone", fault=fault.spec, line=self.runtime_line)

    # ------------------------------------------------------------------ faults
    def _due(self, line: int | None, kinds: tuple[str, ...]) -> list[Fault]:
        """Unfired faults of these kinds set for this line (or armed by time); marks them fired."""
        due = []
        for f in self.faults:
            if f.fired or f.kind not in kinds:
                continue
            if (line is not None and f.line == line) or (f.at_s is not None and f.line == -1):
                f.fired = True
                self.truth.faults.append({"spec": f.spec, "line": line})
                due.append(f)
        return due

    def _time_faults(self, now: float) -> None:
        for f in self.faults:
            if f.fired or f.at_s is None or f.line == -1 or now - self.t0 < f.at_s:
                continue
            if f.kind == "stall":
                f.fired = True
                self.truth.faults.append({"spec": f.spec, "line": self.runtime_line})
                self._fire_stall(f, now)
            elif f.kind == "gone":
                f.fired = True
                self.truth.faults.append({"spec": f.spec, "line": self.runtime_line})
                self._fire_gone(f, now)
            elif f.kind == "xoff":
                f.fired = True
                self.truth.faults.append({"spec": f.spec, "line": self.model.line})
                self._fire_xoff(f, now)
            else:
                f.line = -1  # armed: fires on the next line read

    def _fire_xoff(self, fault: Fault, now: float) -> None:
        self.xoff_stuck_until = now + (3.0 if fault.arg is None else fault.arg)
        self._send_flow(XOFF)
        self.event(now, "xoff_stuck", fault=fault.spec)

    def _rx_fault(self, raw: bytes, now: float) -> bytes | None:
        """Apply a drop/garble fault to a line taken from the ring; None = merged into the next."""
        m = _N_AT_START.match(raw)
        line = int(m.group(1)) if m else None
        for f in self._due(line, ("drop", "garble")):
            k = int(f.arg) if f.arg is not None else (-1 if f.kind == "drop" else 1)
            if k < 0:
                k += len(raw) + 1  # -1 = the terminator
            self.event(now, f.kind, fault=f.spec, line=line, index=k)
            if f.kind == "drop":
                if k >= len(raw):
                    self.merge_prefix = raw  # the LF is lost: this line runs into the next
                    return None
                raw = raw[:k] + raw[k + 1 :]
            elif k < len(raw):
                c = raw[k] ^ 0x01
                raw = raw[:k] + raw[k + 1 :]
                if c in (RESET, XON, XOFF) or chr(c) in "!~%":
                    self._isr(c, now)  # the flipped byte is a realtime character
                else:
                    raw = raw[:k] + bytes([c]) + raw[k:]
        return raw

    # ------------------------------------------------------------------ input
    def _read_lines(self, now: float) -> None:
        while (
            self.planner_free >= self.cfg.planner_headroom
            and len(self.out) < self.cfg.tx_backlog_max
            and self.machine != "alarm"
        ):
            ends = [i for i in (self.ring.find(b"\n"), self.ring.find(b"\r")) if i >= 0]
            if not ends:
                return
            i = min(ends)
            raw = bytes(self.ring[:i])
            del self.ring[: i + 1]
            nbytes = i + 1
            if self.merge_prefix:
                raw, nbytes = self.merge_prefix + raw, nbytes + len(self.merge_prefix)
                self.merge_prefix = b""
            else:
                corrupted = self._rx_fault(raw, now)
                if corrupted is None:
                    continue
                nbytes -= len(raw) - len(corrupted)
                raw = corrupted
            self._process_line(raw.decode("ascii", "replace"), nbytes, now)

    def _process_line(self, text: str, nbytes: int, now: float) -> None:
        stripped = text.strip()
        if not stripped:
            if self.text_mode:
                self.text_out("tinyg [mm] ok> \n")
            return
        if len(text) > self.cfg.input_line_max:
            self._record(None, text, nbytes, STAT_INPUT_TOO_LONG, now, False)
            self.respond({}, STAT_INPUT_TOO_LONG, nbytes)
            return
        if stripped[0] == "{":
            self.text_mode = False
            json_command(self, stripped, nbytes, now)
        elif stripped[0] in "$?" or stripped.lower() in ("h", "help"):
            self.text_mode = True
            text_command(self, stripped)
        else:
            status, body = self._gcode(text, nbytes, now)
            if self.text_mode:
                self.text_out("tinyg [mm] ok> \n" if status == 0 else f"error: {status}\n")
            else:
                self.respond(body, status, nbytes)

    def _record(self, line, text, nbytes, status, now, queued) -> None:
        self.truth.received.append(Received(line, text, nbytes, status, self.t(now), queued))

    def _gcode(self, text: str, nbytes: int, now: float) -> tuple[int, dict]:
        """Parse, check and queue one G-code block; its status and response body."""
        block = parse_block(text)
        line = block.line_number
        for f in self._due(line, ("noack", "xoff", "error")):
            if f.kind == "noack":
                self.swallow_next = True
                self.event(now, "noack", fault=f.spec, line=line)
            elif f.kind == "xoff":
                self._fire_xoff(f, now)
            else:
                status = 130 if f.arg is None else int(f.arg)
                self.event(now, "error_status", fault=f.spec, line=line, status=status)
                self._record(line, text, nbytes, status, now, False)
                return status, {}
        status, move = (block.status, None)
        if status == STAT_OK:
            status, move = plan_move(
                block, self.model, text.strip(), self.cfg.vmax_mm_min, self.cfg.min_move_s
            )
        self._record(line, text, nbytes, status, now, move is not None)
        if move is not None:
            self.planner.append(move)
            self.qi += 1
            if self.hold == "off" and move.kind != "stop":
                self._cycle_start()
        body: dict = {}
        jv = self.settings["jv"]
        if jv >= 4 and line is not None:
            body["n"] = line
        if jv >= 5:
            body["gc"] = text.strip()
        return status, body

    # ------------------------------------------------------------------ reports
    def _reports(self, now: float) -> None:
        """Status reports on a change of state at once, else every ``$si`` (scaled)."""
        if self.settings["sv"] != 0:
            interval = max(float(self.settings["si"]) / 1000.0 / self.cfg.speedup,
                           self.cfg.min_report_s)  # fmt: skip
            if self.sr_now or now - self.last_sr_t >= interval:
                self.sr_now = False
                sr = status_report(self, now)
                if sr:
                    self.emit({"sr": sr})
        queue_report(self)
