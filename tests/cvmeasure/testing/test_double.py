"""The TinyG double on a real pseudo-terminal: buffers, footers, realtime, timing, faults."""

from __future__ import annotations

import threading
import time

import pytest
import serial

from cvmeasure.driver.protocol import (
    LineSplitter,
    Response,
    RxReport,
    StatusReport,
    parse_message,
)
from cvmeasure.sim import pin_command_for_angle
from cvmeasure.testing.double import FakeTinyG, Fault


class Host:
    """A bare pyserial host on the double's pty (no streamer: raw bytes)."""

    def __init__(self, port: str, *, xonxoff: bool = True, write_timeout: float | None = 2.0):
        self.ser = serial.Serial(
            port, 115200, xonxoff=xonxoff, timeout=0.01, write_timeout=write_timeout
        )
        self.split = LineSplitter()
        self.messages: list = []

    def send(self, data: bytes) -> None:
        self.ser.write(data)

    def collect(self, seconds: float, until=None) -> list:
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            for raw in self.split.feed(self.ser.read(4096)):
                self.messages.append(parse_message(raw))
                if until is not None and until(self.messages[-1]):
                    return self.messages
        return self.messages

    def responses(self) -> list[Response]:
        return [m for m in self.messages if isinstance(m, Response)]

    def close(self) -> None:
        self.ser.close()


@pytest.fixture
def board():
    b = FakeTinyG(speedup=20.0).start()
    yield b
    b.close()


def stat_is(value):
    return lambda m: isinstance(m, StatusReport) and m.stat == value


def test_every_line_gets_one_response_with_its_byte_count(board):
    host = Host(board.port)
    lines = [
        b'{"qr":null}\n',
        b"N1 G21 G90\n",
        b"N2 G91 G1 Y5 F3000\n",
        b'{"nope":1}\n',
        b"N3 G2 X1\n",
        b"\n",
    ]
    for line in lines:
        host.send(line)
    host.collect(0.5, until=lambda m: len(host.responses()) == 5)
    rs = host.responses()
    assert [r.nbytes for r in rs] == [len(x) for x in lines[:5]]
    assert [r.status for r in rs] == [0, 0, 0, 100, 131]
    assert rs[0].body == {"qr": 32}
    host.close()


def test_minimum_time_move_is_rejected(board):
    host = Host(board.port)
    host.send(b"G1 X0.01 F6000\n")  # 0.1 ms of motion: under TinyG's 2.5 ms
    host.collect(0.5, until=lambda m: isinstance(m, Response))
    assert host.responses()[0].status == 202
    host.close()


def test_timed_moves_follow_the_speedup():
    with FakeTinyG(speedup=10.0) as b:
        host = Host(b.port)
        t0 = time.monotonic()
        host.send(b"N7 G91 G1 Y10 F600\n")  # 1 s of machine time -> 0.1 s wall
        host.collect(2.0, until=stat_is(3))
        elapsed = time.monotonic() - t0
        assert 0.09 <= elapsed <= 1.0
        state = b.machine_state()
        assert state.feed_mm == pytest.approx(10.0) and state.line == 7
        host.close()


def test_feedhold_resume_and_flush(board):
    host = Host(board.port)
    host.send(b"N1 G91 G1 Y100 F600\nN2 G1 Y100\nN3 G1 Y100\n")  # 10 s each -> 0.5 s wall
    host.collect(1.0, until=stat_is(5))
    host.send(b"!")
    host.collect(1.0, until=stat_is(6))
    held = board.machine_state().feed_mm
    time.sleep(0.1)
    assert board.machine_state().feed_mm == held and 0 < held < 100
    host.send(b"~")
    host.collect(1.0, until=stat_is(5))
    deadline = time.monotonic() + 2.0
    while board.machine_state().feed_mm == held and time.monotonic() < deadline:
        time.sleep(0.01)
    assert board.machine_state().feed_mm > held
    host.send(b"!%")
    host.collect(1.0, until=lambda m: isinstance(m, RxReport))
    state = board.machine_state()
    assert state.planner_depth == 0 and state.stat == 3 and state.rx_bytes == 0
    completed, partial = board.executed_lines()
    assert completed == [] and partial == [1]
    host.close()


def test_reset_sends_the_banner(board):
    host = Host(board.port)
    host.send(b"\x18")
    host.collect(0.5, until=lambda m: isinstance(m, Response))
    assert host.responses()[0].is_banner
    host.close()


def _fill(host: Host, n: int, errors: list) -> None:
    try:
        for i in range(n):
            host.send(b"N%d G1 X%d F60\n" % (i + 1, i + 1))  # 1 s per move at speedup 1
            time.sleep(0.002)  # about the time 15 bytes take at 115200 baud
    except serial.SerialTimeoutException as exc:
        errors.append(exc)


def test_xoff_stops_the_host_before_the_buffer_overflows():
    with FakeTinyG(speedup=1.0) as b:
        host = Host(b.port, xonxoff=True, write_timeout=0.5)
        errors: list = []
        t = threading.Thread(target=_fill, args=(host, 80, errors))
        t.start()
        t.join(timeout=30)  # the writer ends when a write blocks 0.5 s (slower on a loaded host)
        assert b.stats.xoff_sent >= 1
        assert errors, "the host's write should block on XOFF"
        assert b.stats.rx_dropped_bytes == 0
        # 32 slots, reads stop below 4 free: 29, or 28 for the instant between a move
        # finishing (one a second) and the next line read into its slot
        assert b.machine_state().planner_depth in (28, 29)
        host.close()


def test_without_flow_control_overflow_bytes_are_dropped():
    with FakeTinyG(speedup=1.0) as b:
        host = Host(b.port, xonxoff=False)
        _fill(host, 80, [])
        time.sleep(0.2)
        assert b.stats.rx_dropped_bytes > 0
        assert b.stats.rx_peak_bytes == 254
        host.close()


def test_executed_bends_drive_the_simulation(board):
    host = Host(board.port)
    pin = float(pin_command_for_angle(30.0))
    host.send(b"N1 G91 G1 Y20 F3000\nN2 G90 G1 X%.4f F6000\n" % pin)
    host.collect(1.0, until=stat_is(3))
    held = board.machine_state()
    assert held.holding and held.bend_angle_deg > 30.0  # loaded: before springback
    host.send(b"N3 G0 X0\nN4 G91 G1 Y15 F3000\n")
    time.sleep(0.05)
    host.collect(1.0, until=stat_is(3))
    state = board.machine_state()
    assert not state.holding and len(state.bends) == 1
    bend = state.bends[0]
    assert bend.unloaded_bend_deg == pytest.approx(30.0, abs=1e-4)
    assert bend.feed_before_mm == 20.0 and bend.line_number == 2
    shape = board.wire_shape_mm()
    assert shape[1].tolist() == pytest.approx([20.0, 0.0])
    assert shape[2].tolist() == pytest.approx([20 + 15 * 0.8660254, -15 * 0.5], abs=1e-4)
    host.close()


@pytest.mark.parametrize("kind", ["malformed_reply", "drop_byte"])
def test_reply_and_byte_faults(kind):
    b = FakeTinyG(speedup=20.0, faults=[Fault(kind, 2, byte_index=3)]).start()
    host = Host(b.port)
    host.send(b"N1 G21\nN2 G91 G1 Y5 F3000\nN3 G90\n")
    host.collect(
        0.5, until=lambda m: isinstance(m, Response) and m.nbytes == 7 and len(host.messages) > 2
    )
    deadline = time.monotonic() + 2.0
    while b.machine_state().planner_depth and time.monotonic() < deadline:
        time.sleep(0.01)
    replies = [m for m in host.messages if not isinstance(m, StatusReport)]
    if kind == "malformed_reply":
        assert [type(m).__name__ for m in replies] == ["Response", "Unparsed", "Response"]
        assert replies[1].text == '{"r":{},"f"'
        assert b.machine_state().feed_mm == pytest.approx(5.0)  # the line itself was fine
    else:
        # the 'G' of 'G91' never arrived: 18 of 19 bytes, and '91' alone is no G-code
        assert [(r.nbytes, r.status) for r in replies] == [(7, 0), (18, 130), (7, 0)]
        assert b.machine_state().feed_mm == 0.0
    assert b.stats.faults_fired == [f"{kind}@2"]
    host.close()
    b.close()


def test_alarm_stall_and_vanish():
    b = FakeTinyG(
        speedup=50.0,
        faults=[Fault("alarm", 2), Fault("stall", 3, duration_s=0.3), Fault("vanish", 5)],
    )
    b.start()
    host = Host(b.port)
    host.send(b"N1 G91 G1 Y5 F3000\nN2 G1 Y5\n")
    host.collect(1.0, until=stat_is(2))
    assert any(getattr(m, "status", None) == 204 for m in host.messages)
    assert b.machine_state().line == 2 and b.machine_state().feed_mm == pytest.approx(5.0)
    host.send(b"N3 G1 Y5\n")  # line 3 stalls the board
    t0 = time.monotonic()
    host.collect(1.0, until=lambda m: isinstance(m, Response))
    assert time.monotonic() - t0 >= 0.25
    assert host.responses()[-1].status == 203  # still alarmed
    host.send(b'{"clear":null}\nN5 G1 Y5\n')  # the port vanishes after line 5
    with pytest.raises(serial.SerialException):
        host.collect(1.0)
    assert b.vanished
    host.close()
    port = b.reconnect()
    host = Host(port)
    host.send(b'{"sr":null}\n')
    host.collect(0.5, until=lambda m: isinstance(m, Response))
    assert host.responses()[0].body["sr"]["posy"] == pytest.approx(10.0)
    host.close()
    b.close()


def test_silent_mode_answers_nothing(board):
    host = Host(board.port)
    host.send(b'{"jv":0}\nN1 G21\n')
    host.collect(0.4)
    assert host.responses() == []  # jv=0 silences even the reply to itself
    host.close()


def test_queue_and_filtered_status_reports():
    from cvmeasure.driver.protocol import QueueReport

    with FakeTinyG(speedup=5.0) as b:
        host = Host(b.port)
        host.send(b'{"qv":1}\n{"si":100}\n')
        host.send(b"N1 G91 G1 Y5 F600\nN2 G1 Y5\nN3 G1 Y5\n")  # 0.5 s each -> 0.1 s wall
        host.collect(2.0, until=stat_is(3))
        qr = [m.free_slots for m in host.messages if isinstance(m, QueueReport)]
        assert min(qr) == 29 and qr[-1] == 32  # three queued, then drained one by one
        assert qr == sorted(qr[: qr.index(29) + 1], reverse=True) + qr[qr.index(29) + 1 :]
        sr = [m.fields for m in host.messages if isinstance(m, StatusReport)]
        ys = [f["posy"] for f in sr if "posy" in f]
        assert ys == sorted(ys) and ys[-1] == 15.0 and len(ys) >= 3  # reported while moving
        assert all(len(f) < 7 for f in sr[1:])  # filtered: only what changed
        host.close()


def _hold_when(board: FakeTinyG, host: Host, below_deg: float) -> float:
    """Feedhold + flush once the retreating pin is under ``below_deg``; the pin where it stopped."""
    deadline = time.monotonic() + 5.0
    while board.machine_state().pin_deg >= below_deg and time.monotonic() < deadline:
        time.sleep(0.002)
    host.send(b"!%")
    host.messages.clear()
    host.collect(2.0, until=lambda m: isinstance(m, RxReport))
    return board.machine_state().pin_deg


def test_a_retreat_cut_twice_is_one_bend():
    # the pin's return to home cut by two stops (each resumed by a fix-up to X0):
    # a retreating pin presses nothing, so the part has one bend, not two
    with FakeTinyG(speedup=4.0) as b:
        host = Host(b.port)
        pin = float(pin_command_for_angle(60.0))
        host.send(b"N1 G91 G1 Y20 F3000\nN2 G90 G1 X%.4f F6000\n" % pin)
        host.collect(2.0, until=stat_is(3))
        assert b.machine_state().holding
        host.send(b"N3 G90 G1 X0 F1000\n")  # 67 deg/s wall
        first = _hold_when(b, host, 0.75 * pin)
        assert 0.55 * pin < first < 0.75 * pin  # cut midway: the wire was let go
        assert len(b.machine_state().bends) == 1 and not b.machine_state().holding
        host.send(b"N3 G90 G1 X0 F1000\n")
        second = _hold_when(b, host, 0.45 * pin)
        assert 0.3 * pin < second < 0.45 * pin  # cut again, the pin still off home
        assert not b.machine_state().holding
        host.send(b"N3 G90 G1 X0 F1000\nN4 G91 G1 Y15 F3000\n")
        host.messages.clear()
        host.collect(3.0, until=lambda m: isinstance(m, StatusReport) and m.line == 4)
        host.collect(3.0, until=stat_is(3))
        state = b.machine_state()
        assert state.pin_deg == 0.0 and state.feed_mm == pytest.approx(35.0)
        assert len(state.bends) == 1
        bend = state.bends[0]
        assert bend.pin_deg == pytest.approx(pin) and bend.feed_before_mm == 20.0
        assert bend.unloaded_bend_deg == pytest.approx(60.0, abs=1e-4)
        host.close()
