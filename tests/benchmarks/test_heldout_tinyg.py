"""The held-out TinyG controller on a real pty, driven by plain pyserial.

Each test checks the model against TinyG's documented behaviour (responses and footers,
flow control, feedhold/flush/reset sequencing, the truth log) or one injected fault.
"""

from __future__ import annotations

import json
import os
import time

import pytest
import serial

from benchmarks.heldout.tinyg_controller import TinyGController
from benchmarks.heldout.tinyg_faults import Fault, parse_fault
from benchmarks.heldout.tinyg_machine import MachineConfig

FAST = MachineConfig(speedup=200.0, boot_s=0.02)


class Host:
    """A minimal host: writes lines, reads JSON replies (XON/XOFF bytes kept aside)."""

    def __init__(self, port: str, xonxoff: bool = True) -> None:
        self.ser = serial.Serial(port, 115200, timeout=0.01, xonxoff=xonxoff)
        self.flow: list[int] = []
        self.msgs: list[dict] = []
        self.text: list[str] = []
        self._buf = b""

    def send(self, *lines: str) -> None:
        for line in lines:
            self.ser.write(line.encode() + b"\n")

    def pump(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self._read_some()

    def _read_some(self) -> None:
        data = self.ser.read(4096)
        for b in data:
            if b in (0x11, 0x13):
                self.flow.append(b)
            else:
                self._buf += bytes([b])
        while b"\n" in self._buf:
            line, self._buf = self._buf.split(b"\n", 1)
            try:
                self.msgs.append(json.loads(line))
            except json.JSONDecodeError:
                self.text.append(line.decode())

    def until(self, pred, timeout_s: float = 3.0) -> dict:
        """Read until a message satisfies ``pred``; return it."""
        end = time.monotonic() + timeout_s
        seen = 0
        while time.monotonic() < end:
            for msg in self.msgs[seen:]:
                if pred(msg):
                    return msg
            seen = len(self.msgs)
            self._read_some()
        raise AssertionError(f"no such message in {self.msgs[-5:]}")

    def acks(self) -> list[dict]:
        return [m for m in self.msgs if "r" in m and "msg" not in m.get("r", {})]

    def stat(self, value: int, timeout_s: float = 3.0) -> dict:
        return self.until(lambda m: m.get("sr", {}).get("stat") == value, timeout_s)

    def state(self) -> dict:
        """The board's state as the filtered status reports tell it so far."""
        merged: dict = {}
        for m in self.msgs:
            merged.update(m.get("sr", {}))
        return merged

    def wait_state(self, timeout_s: float = 5.0, **want: object) -> dict:
        end = time.monotonic() + timeout_s
        while time.monotonic() < end:
            self._read_some()
            state = self.state()
            if all(state.get(k) == v for k, v in want.items()):
                return state
        raise AssertionError(f"state {self.state()} never reached {want}")

    def close(self) -> None:
        self.ser.close()


@pytest.fixture
def board_factory():
    boards: list[TinyGController] = []
    hosts: list[Host] = []

    def make(faults=(), config=FAST, link=None, xonxoff=True):
        board = TinyGController([parse_fault(f) for f in faults], config, link=link).start()
        boards.append(board)
        host = Host(board.port, xonxoff)
        hosts.append(host)
        host.until(lambda m: m.get("r", {}).get("msg") == "SYSTEM READY")
        return board, host

    yield make
    for h in hosts:
        h.close()
    for b in boards:
        b.stop()


def job(n_moves: int, feed_mm: float = 10.0) -> list[str]:
    """Relative feeds and absolute bends, numbered from N1, ending in an N marker."""
    lines = ["N1 G21 G90"]
    for i in range(n_moves):
        n = len(lines) + 1
        if i % 2 == 0:
            lines.append(f"N{n} G91 G1 Y{feed_mm:.1f} F3000")
        else:
            lines.append(f"N{n} G90 G1 X{30 + i % 7} F6000")
    lines.append(f"N{len(lines) + 1} (end)")
    return lines


def test_every_line_gets_one_response_with_its_byte_count(board_factory):
    _, host = board_factory()
    lines = ['{"jv":4}', '{"qr":null}', '{"rx":"n"}', "{sr:n}", "N7 G21 G90", '{"zz":1}', "{x"]
    host.send(*lines)
    # every line's response (after the banner), however slowly a loaded machine reads them
    host.until(lambda _m: sum("r" in m for m in host.msgs) > len(lines), timeout_s=10.0)
    host.pump(0.1)  # nothing more may follow
    acks = [m for m in host.msgs if "r" in m][1:]  # after the banner
    assert [a["f"][2] for a in acks] == [len(s) + 1 for s in lines]
    assert [a["f"][1] for a in acks] == [0, 0, 0, 0, 0, 100, 111]
    assert acks[1]["r"]["qr"] == 32 and 253 - 40 <= acks[2]["r"]["rx"] <= 253
    assert acks[3]["r"]["sr"]["stat"] == 1 and acks[4]["r"] == {"n": 7}


def test_dollar_switches_to_text_mode_and_brace_back(board_factory):
    _, host = board_factory()
    host.send("$ex", "G21")
    deadline = time.monotonic() + 10.0  # both answers, however loaded the machine
    while host.text.count("tinyg [mm] ok> ") < 2 and time.monotonic() < deadline:
        host.pump(0.05)
    assert host.text[:2] == ["[ex] 1", "tinyg [mm] ok> "] and host.text[-1] == "tinyg [mm] ok> "
    host.send('{"ex":null}')
    assert host.until(lambda m: "r" in m and "ex" in m["r"])["f"] == [1, 0, 12]


def test_truth_log_runs_every_line_once_in_order(board_factory):
    board, host = board_factory()
    lines = job(40)
    for line in lines:  # send-response
        n = len(host.acks())
        host.send(line)
        host.until(lambda m, n=n: len(host.acks()) > n)
    host.wait_state(line=42, stat=3)
    truth = board.truth()
    assert truth.executed_lines() == list(range(2, 42))
    assert all(e.fraction == 1.0 and e.how == "done" for e in truth.executed)
    assert truth.position["y"] == pytest.approx(20 * 10.0, abs=1e-9)
    assert host.msgs[-1]["sr"]["line"] == 42  # the end marker, once stopped


def test_planner_holds_28_moves_and_reading_waits_for_headroom(board_factory):
    board, host = board_factory(faults=["stall@3"])
    host.send(*job(40)[:36])
    deadline = time.monotonic() + 10.0  # the acks, however loaded the machine
    while len(host.acks()) < 31 and time.monotonic() < deadline:
        host.pump(0.05)
    host.pump(0.2)  # and nothing beyond them
    s = board.status()
    # a line is read while >= 4 of the 32 buffers are free: 29 moves, the rest wait in RX
    assert s["stalled"] and s["planner_moves"] == 29
    assert len(host.acks()) == 1 + 1 + 29  # N1 (no move), N2 (ran), 29 moves


def test_xoff_at_high_water_and_no_byte_lost_with_xonxoff(board_factory):
    board, host = board_factory(faults=["stall@3:1.0"])
    lines = job(80)
    host.send(*lines)  # ~1.6 kB at once: only flow control keeps the 254-byte ring intact
    deadline = time.monotonic() + 0.9
    while not board.status()["xoff"] and time.monotonic() < deadline:
        host.pump(0.02)
    host.pump(0.05)
    s = board.status()
    assert s["stalled"] and s["xoff"] and 203 < s["rx_bytes"] <= 203 + 3 + 1
    host.wait_state(line=82, stat=3)
    truth = board.truth()
    assert not [e for e in truth.events if e["kind"] == "rx_overflow_drop"]
    assert [r.text for r in truth.received] == lines
    assert truth.executed_lines() == list(range(2, 82))


def test_without_flow_control_overflow_is_dropped_silently(board_factory):
    board, host = board_factory(faults=["stall@3"], xonxoff=False)
    host.send(*job(80))  # ~1.6 kB while the planner is stuck full
    deadline = time.monotonic() + 3.0
    while board.status()["rx_bytes"] < 253 and time.monotonic() < deadline:
        host.pump(0.05)
    host.pump(0.2)
    assert 0x13 in host.flow  # XOFF arrives as a data byte the host ignored
    drops = [e for e in board.truth().events if e["kind"] == "rx_overflow_drop"]
    assert len(drops) > 100 and board.status()["rx_bytes"] == 253


def test_feedhold_resume_then_hold_and_flush(board_factory):
    board, host = board_factory(config=MachineConfig(speedup=20.0, boot_s=0.02))
    host.send(*job(10, feed_mm=100.0))  # each feed 2 s of machine time = 0.1 s here
    host.pump(0.15)
    host.ser.write(b"!")
    held = host.wait_state(stat=6)  # stat 6 from the request on, while it decelerates
    host.pump(0.05)
    frozen = board.status()["position"]
    host.pump(0.2)
    assert board.status()["position"] == frozen
    host.ser.write(b"~")
    host.stat(5)
    host.pump(0.1)
    host.ser.write(b"!%")
    host.stat(3)
    truth = board.truth()
    flushed = [e for e in truth.executed if e.how == "flushed"]
    assert len(flushed) == 1 and 0.0 < flushed[0].fraction < 1.0
    flush = next(e for e in truth.events if e["kind"] == "flush")
    assert flush["unexecuted_lines"] and held["line"] >= 2
    # the flush resynced the model to where the runtime stopped, and sr.line is the model's
    assert board.status()["line"] == 12 and board.status()["planner_moves"] == 0
    assert truth.position["y"] == pytest.approx(flushed[0].end["y"])


def test_feedhold_deceleration_runs_into_the_next_moves(board_factory):
    slow_stop = MachineConfig(speedup=20.0, boot_s=0.02, hold_decel_s=2.0)  # 1 s at speed
    board, host = board_factory(config=slow_stop)
    host.send(*job(30))  # moves of 0.2 s (feeds) and under 0.1 s (bends) machine time
    host.pump(0.1)
    host.ser.write(b"!")
    host.pump(0.3)
    events = board.truth().events
    held = next(e for e in events if e["kind"] == "feedhold")
    reached = next(e for e in events if e["kind"] == "hold_reached")
    assert reached["line"] >= held["line"] + 4
    assert board.status()["stat"] == 6 and board.status()["planner_moves"] > 0


def test_reset_reboots_with_banner_and_zero_position(board_factory):
    board, host = board_factory()
    host.send(*job(4))
    host.wait_state(line=6, stat=3)
    assert board.truth().position["y"] > 0
    host.ser.write(b"\x18")
    host.until(lambda m: m.get("r", {}).get("msg") == "SYSTEM READY" and m is not host.msgs[0])
    assert board.truth().position == {"x": 0.0, "y": 0.0, "z": 0.0, "a": 0.0}


def test_stall_until_reset_freezes_motion(board_factory):
    board, host = board_factory(faults=["stall@5"])
    host.send(*job(8))
    host.pump(0.4)
    assert board.truth().executed_lines() == [2, 3, 4]
    assert board.status()["stalled"] and board.status()["stat"] == 5
    host.ser.write(b"!%")  # the hold cannot finish while the runtime is frozen
    host.pump(0.2)
    assert board.status()["planner_moves"] == 5  # N5 running, N6-N9 queued
    host.ser.write(b"\x18")
    host.pump(0.2)
    assert board.truth().executed[-1].how == "reset" and not board.status()["stalled"]


def test_timed_stall_then_pending_hold_and_flush_take_effect(board_factory):
    board, host = board_factory(faults=["stall@5:0.3"])
    host.send(*job(20))
    host.pump(0.1)
    host.ser.write(b"!%")
    host.stat(3, timeout_s=2.0)
    ran = board.truth().executed_lines()
    assert ran[:3] == [2, 3, 4] and ran[3] == 5 and len(ran) < 19
    assert board.status()["line"] == 22  # the model's last parsed line, never run


def test_noack_swallows_only_that_response(board_factory):
    board, host = board_factory(faults=["noack@3"])
    lines = job(4)
    host.send(*lines)
    host.wait_state(line=6, stat=3)
    sizes = [len(s) + 1 for s in lines]
    assert [a["f"][2] for a in host.acks()] == sizes[:2] + sizes[3:]  # N3's missing
    assert board.truth().executed_lines() == [2, 3, 4, 5]


def test_stuck_xoff_blocks_the_host_then_releases(board_factory):
    board, host = board_factory(faults=["xoff@3:0.5"], xonxoff=False)
    host.send(*job(4))
    host.pump(0.2)
    assert host.flow == [0x13]
    host.pump(0.5)
    assert host.flow == [0x13, 0x11]
    assert board.truth().executed_lines() == [2, 3, 4, 5]


def test_error_status_line_is_not_run(board_factory):
    board, host = board_factory(faults=["error@4:202"])
    host.send(*job(4))
    host.wait_state(line=6, stat=3)
    assert [a["f"][1] for a in host.msgs if "f" in a][1:] == [0, 0, 0, 202, 0, 0]
    assert board.truth().executed_lines() == [2, 3, 5]


def test_dropped_lf_merges_two_lines(board_factory):
    board, host = board_factory(faults=["drop@3"])
    lines = job(4)
    host.send(*lines)
    host.wait_state(line=6, stat=3)
    acks = [a for a in host.msgs if "f" in a][1:]
    sizes = [len(s) + 1 for s in lines]
    assert [a["f"][2] for a in acks] == [
        sizes[0],
        sizes[1],
        sizes[2] - 1 + sizes[3],
        sizes[4],
        sizes[5],
    ]
    merged = board.truth().received[2]
    assert merged.text == lines[2] + lines[3] and merged.line == 4  # the last N wins
    assert board.truth().executed_lines() == [2, 4, 5]


def test_dropped_and_garbled_digits_run_silently_wrong(board_factory):
    board, host = board_factory(faults=["drop@2:12", "garble@3:12"])
    host.send("N1 G21 G90", "N2 G91 G1 Y12.5 F3000", "N3 G90 G1 X31 F6000")
    host.wait_state(line=3, stat=3)
    acks = [a["f"] for a in host.msgs if "f" in a][1:]
    assert acks == [[1, 0, 11], [1, 0, 21], [1, 0, 20]]  # N2 one byte short
    ex = board.truth().executed
    assert ex[0].text == "N2 G91 G1 Y1.5 F3000" and ex[1].text == "N3 G90 G1 X30 F6000"
    assert board.truth().position["y"] == pytest.approx(1.5)


def test_garbled_letter_gives_an_error(board_factory):
    board, host = board_factory(faults=["garble@2:0"])  # 'N' ^ 1 = 'O'
    host.send("N1 G21 G90", "N2 G91 G1 Y12.5 F3000")
    host.pump(0.3)
    assert [a["f"][1] for a in host.msgs if "f" in a][1:] == [0, 130]
    assert board.truth().executed == []


def test_port_gone_board_runs_on_and_port_returns(board_factory, tmp_path):
    link = tmp_path / "tinyg0"
    slow = MachineConfig(speedup=20.0, boot_s=0.02)
    board, host = board_factory(faults=["gone@4:0.4"], link=link, config=slow)
    host.send(*job(6, feed_mm=50.0))  # all 6 moves are queued before N4 starts
    with pytest.raises(serial.SerialException):
        host.pump(1.0)
    assert not link.exists()
    assert board.wait_idle(timeout_s=3.0)
    time.sleep(0.4)
    assert link.is_symlink() and os.path.exists(os.readlink(link))
    assert board.truth().executed_lines() == [2, 3, 4, 5, 6, 7]
    again = Host(str(link))
    again.send('{"sr":null}')
    assert again.until(lambda m: "r" in m)["r"]["sr"]["line"] == 8
    again.close()


def test_fault_spec_round_trip_and_refusal():
    assert parse_fault("stall@1836:2").spec == "stall@1836:2"
    assert parse_fault("xoff@t1.5").at_s == 1.5
    with pytest.raises(ValueError, match="bad fault 'melt@3'"):
        parse_fault("melt@3")
    with pytest.raises(ValueError):
        Fault("stall")
