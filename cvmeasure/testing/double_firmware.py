"""The TinyG double's firmware layer: line reader, JSON and G-code, executor, reports.

A mixin of :class:`cvmeasure.testing.double.FakeTinyG`, which owns the state it reads
(planner, settings, positions) and the pty; split out so each module keeps one job.
"""

from __future__ import annotations

import json
import math
from typing import Any

from cvmeasure.driver.protocol import (
    AXES,
    INPUT_LINE_MAX,
    GcodeError,
    MachineStat,
    Status,
    format_exception,
    format_queue_report,
    format_response,
    format_status_report,
    parse_block,
)
from cvmeasure.testing.double_records import (
    MIN_MOVE_S,
    PlannedMove,
)

__all__ = ["FirmwareLayer"]


class FirmwareLayer:
    """Reads lines from the RX ring, runs JSON commands and G-code, executes, reports."""

    # ------------------------------------------------------------------ line reader

    def _free_slots(self) -> int:
        return self.slots - len(self._planner)

    def _read_lines(self, now: float) -> None:
        while self._stall_until <= now and self._pending_stall_line is None:
            if self._free_slots() < self.headroom:
                return
            cut = -1
            for i, b in enumerate(self._ring):
                if b in (0x0A, 0x0D):
                    cut = i
                    break
            if cut < 0:
                if len(self._ring) >= self.rx_size:  # a line longer than the buffer
                    self._ring.clear()
                    self._send(format_response({}, Status.INPUT_TOO_LONG, self.rx_size))
                return
            raw = bytes(self._ring[:cut])
            del self._ring[: cut + 1]
            self._check_xon()
            if not raw:
                continue  # an empty line: no response in JSON mode
            self.stats.lines_received += 1
            count = self.stats.lines_received
            stall = self._fault("stall", count)
            if stall is not None and raw.lstrip().startswith(b"{"):
                self.stats.faults_fired[-1] += " (on a JSON command)"
            if stall is not None:
                self._stall_until = now + stall.duration_s
                self._pending_stall_line = (raw, len(raw) + 1)
                return
            self._process_line(raw, len(raw) + 1, now)
            if self._master is None:
                return

    def _process_line(self, raw: bytes, nbytes: int, now: float) -> None:
        count = self.stats.lines_received
        text = raw.decode("ascii", errors="replace").strip()
        if len(raw) + 1 > INPUT_LINE_MAX:
            body, status = {}, int(Status.INPUT_TOO_LONG)
        elif text.startswith("{"):
            body, status = self._json_command(text, now)
        elif text[:1] in ("$", "?"):
            body, status = {}, int(Status.UNRECOGNIZED_NAME)
        else:
            body, status = self._gcode(text, count, now)
        if self._settings["jv"] == 0:
            return  # silent: no response at all (why hosts must never set it)
        reply = format_response(body, status, nbytes, style=self.footer_style)
        if self._fault("malformed_reply", count) is not None:
            reply = reply[: max(3, len(reply) // 2)] + b"\n"
        self._send(reply)
        if self._fault("vanish", count) is not None:
            self._vanish()

    def _json_command(self, text: str, now: float) -> tuple[dict[str, Any], int]:
        try:
            obj = json.loads(text)
        except json.JSONDecodeError:
            return {}, int(Status.JSON_SYNTAX)
        if not isinstance(obj, dict):
            return {}, int(Status.MALFORMED_COMMAND)
        out: dict[str, Any] = {}
        for key, value in obj.items():
            if key == "sr":
                if isinstance(value, dict):
                    out["sr"] = value
                else:
                    out["sr"] = self._sr_values()
            elif key == "qr":
                out["qr"] = self._free_slots()
            elif key == "rx":
                out["rx"] = self.rx_size - len(self._ring)
            elif key == "clear":
                if self._stat == MachineStat.ALARM:
                    self._set_stat(MachineStat.STOP, now)
                out["clear"] = 1
            elif key == "qf":
                self._flush_req = True
                out["qf"] = 1
            elif key in self._settings:
                if value is not None and key not in ("fv", "fb"):
                    if not isinstance(value, (int, float)) or isinstance(value, bool):
                        return {}, int(Status.BAD_NUMBER)
                    self._settings[key] = value
                out[key] = self._settings[key]
            else:
                return {}, int(Status.UNRECOGNIZED_NAME)
        return out, 0

    def _gcode(self, text: str, seq: int, now: float) -> tuple[dict[str, Any], int]:
        try:
            block = parse_block(text)
        except GcodeError as exc:
            return {}, exc.status
        if self._stat in (MachineStat.ALARM, MachineStat.SHUTDOWN):
            return {}, int(Status.MACHINE_ALARMED)
        if self._fault("error_status", seq) is not None:
            return {}, int(Status.GCODE_GENERIC)
        if block.line_number is not None:
            self._last_parsed_line = block.line_number
        relative = self._relative
        mode = block.distance_mode
        if mode is not None:
            relative = mode == "relative"
        motion = block.motion if block.motion is not None else self._motion
        feed = block.feed if block.feed is not None else self._feed_rate
        moved = {k: v for k, v in block.axes.items() if k in AXES}
        if 28.3 in block.g_codes:
            self._relative, self._feed_rate = relative, feed
            self._model_pos.update(moved)
            self._pos.update(moved)
            return {}, 0
        target = dict(self._model_pos)
        for axis, value in moved.items():
            target[axis] = target[axis] + value if relative else value
        deltas = {a: target[a] - self._model_pos[a] for a in AXES}
        distance = math.sqrt(sum(d * d for d in deltas.values()))
        duration, rate = 0.0, 0.0
        if distance > 0:
            if motion == 1:
                if not feed or feed <= 0:
                    return {}, int(Status.FEEDRATE_MISSING)
                duration, rate = distance / feed * 60.0, feed
            else:
                duration = max(abs(d) / self.max_rate[a] * 60.0 for a, d in deltas.items() if d)
                rate = distance / duration * 60.0
            if duration < MIN_MOVE_S:
                return {}, int(Status.MINIMUM_TIME_MOVE)
        self._relative, self._motion, self._feed_rate = relative, motion, feed
        if distance == 0 and block.line_number is None:
            return {}, 0  # modal-only block: nothing to execute
        self._model_pos = target
        self._planner.append(PlannedMove(seq, block.line_number, text, target, duration, rate))
        if self._stat not in (MachineStat.HOLD,):
            self._set_stat(MachineStat.RUN, now)
            self._advance(0.0, now)  # an idle machine starts the move at once
        return {}, 0

    # ------------------------------------------------------------------ executor

    def _advance(self, dt: float, now: float) -> None:
        while self._planner and self._stat == MachineStat.RUN:
            head = self._planner[0]
            if head.start is None:
                head.start = dict(self._pos)
                if head.line_number is not None:
                    self._line = head.line_number
                if self._fault("alarm", head.seq) is not None:
                    self._alarm(now)
                    return
                self._machine_move_start(head)
            remaining = head.duration_s - head.elapsed_s
            step = min(dt, remaining)
            head.elapsed_s += step
            dt -= step
            frac = 1.0 if head.duration_s <= 0 else min(1.0, head.elapsed_s / head.duration_s)
            for a in AXES:
                self._pos[a] = head.start[a] + (head.target[a] - head.start[a]) * frac
            if head.elapsed_s >= head.duration_s:
                self._pos = dict(head.target)
                self._planner.popleft()
                self.stats.completed.append(head.line_number)
                self.stats.moves.append((head.line_number, dict(head.start), dict(head.target)))
                self._machine_move_done(head, complete=True)
                continue
            return
        if not self._planner and self._stat == MachineStat.RUN:
            self._set_stat(MachineStat.STOP, now)

    def _alarm(self, now: float) -> None:
        self._send(format_exception(Status.LIMIT_SWITCH_HIT, "limit switch hit"))
        self._drop_planner()
        self._set_stat(MachineStat.ALARM, now)

    def _set_stat(self, stat: MachineStat, now: float) -> None:
        if stat != self._stat:
            self._stat = stat
            self._sr_due = 0.0  # report a state change at once

    # ------------------------------------------------------------------ reports

    def _sr_values(self) -> dict[str, Any]:
        head = self._planner[0] if self._planner else None
        moving = self._stat == MachineStat.RUN and head is not None and head.start is not None
        return {
            "line": self._line,
            "posx": self._pos["x"],
            "posy": self._pos["y"],
            "posz": self._pos["z"],
            "posa": self._pos["a"],
            "vel": head.rate if moving and head is not None else 0.0,
            "stat": int(self._stat),
        }

    def _reports(self, now: float) -> None:
        if self._settings["qv"]:
            free = self._free_slots()
            if free != self._qr_last:
                self._qr_last = free
                self._send(format_queue_report(free))
        if not self._settings["sv"] or now < self._sr_due:
            return
        values = {
            k: round(v, 3) if isinstance(v, float) else v for k, v in self._sr_values().items()
        }
        changed = {k: v for k, v in values.items() if self._sr_last.get(k) != v}
        if self._settings["sv"] == 2:
            changed = values
        if changed:
            self._sr_last.update(changed)
            self._send(format_status_report(changed))
        self._sr_due = now + max(float(self._settings["si"]), 1.0) / 1000.0
