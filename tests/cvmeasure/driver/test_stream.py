"""Streaming jobs to the double over a real pty: windows, faults, safe stops, resume."""

from __future__ import annotations

import re
import threading
import time

import numpy as np
import pytest

from cvmeasure.design import arc_points_mm, bend_angles_deg
from cvmeasure.driver.protocol import QueueReport
from cvmeasure.driver.stream import (
    JobStopped,
    StreamConfig,
    StreamControl,
    plan_resume,
    prepare_job,
    stream_job,
)
from cvmeasure.driver.transport import open_link
from cvmeasure.errors import DeviceError, InputError
from cvmeasure.fileio import read_jsonl
from cvmeasure.gcode import design_job
from cvmeasure.testing.double import FakeTinyG, Fault

# a stall needs a full second of silence, so a loaded CI machine does not fake one
FAST = StreamConfig(stall_timeout_s=1.0, flush_timeout_s=5.0)
HALF = arc_points_mm((0.0, 0.0), 100.0, 90.0, 180.0, chords=20)


@pytest.fixture(scope="module")
def job():
    return design_job(HALF, source="half.svg")


def run_clean(job, speedup=300.0):
    with FakeTinyG(speedup=speedup) as board:
        link = open_link(board.port)
        result = stream_job(link, job.lines, config=FAST)
        link.close()
        return result, board.wire_shape_mm(), board.executed_lines(), board.stats


def test_clean_job_bends_the_design(job, tmp_path):
    result, shape, (completed, partial), stats = run_clean(job)
    n = len(job.lines)
    assert result.lines_sent == n and result.executed_line == n
    assert completed == list(range(0, n + 1)) and partial == []  # N0 marker, then every line once
    np.testing.assert_allclose(bend_angles_deg(shape), bend_angles_deg(HALF), atol=1e-3)
    assert stats.rx_dropped_bytes == 0 and stats.rx_peak_bytes <= 200


def test_byte_window_bounds_what_is_buffered(job):
    cfg = StreamConfig(window_lines=50, window_bytes=90)
    with FakeTinyG(speedup=300.0) as board:
        link = open_link(board.port)
        stream_job(link, job.lines, config=cfg)
        link.close()
        assert board.stats.rx_peak_bytes <= 90 and board.stats.rx_dropped_bytes == 0


def test_sim_url_and_progress(job, tmp_path):
    seen = []
    with open_link("sim://?speedup=300") as link:
        result = stream_job(
            link, job.lines, journal=tmp_path / "j.jsonl", progress=lambda *a: seen.append(a)
        )
        assert link.double is not None and len(link.double.machine_state().bends) == 19
    assert seen[-1][:2] == (len(job.lines), len(job.lines))
    records = read_jsonl(tmp_path / "j.jsonl")
    events = [r["event"] for r in records]
    assert events[0] == "start" and events[-1] == "done"
    assert records[0]["firmware"] == {"fv": 0.97, "fb": 440.21}
    assert result.executed_line == len(job.lines)


FAULTS = [
    (Fault("drop_byte", 30, byte_index=5), "desync"),
    # the line terminator itself: with one line in flight the board waits for the rest of
    # the line and never acks it (nothing follows that it could run merged with)
    (Fault("drop_byte", 31, byte_index=99), "stall"),
    (Fault("malformed_reply", 30), "malformed"),
    (Fault("alarm", 30), "alarm"),
    (Fault("stall", 30, duration_s=1.6), "stall"),
    (Fault("vanish", 30), "port_gone"),
]


@pytest.mark.parametrize(
    ("fault", "reason"), FAULTS, ids=[f[0].kind + str(f[0].byte_index) for f in FAULTS]
)
@pytest.mark.parametrize("line_report", ["executing", "parsed"])
def test_fault_stops_safely_and_the_job_resumes(job, tmp_path, fault, reason, line_report):
    # "parsed": sr.line after the stop's queue flush names the last line the firmware
    # parsed (flushed, never run), as TinyG does; resuming after it would lose lines
    _, clean_shape, _, _ = run_clean(job)
    journal = tmp_path / "job.journal.jsonl"
    board = FakeTinyG(speedup=50.0, faults=[fault], line_report=line_report).start()
    try:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=journal, config=FAST)
        link.close()
        stop = info.value.stop
        assert stop.reason == reason
        assert stop.line_number is not None and f"N{stop.line_number}" in str(info.value)
        last = read_jsonl(journal)[-1]
        assert last["event"] == "stop" and last["line_number"] == stop.line_number
        if reason != "port_gone":
            assert stop.board is not None and stop.board["stat"] in (2, 3)
        if board.vanished:
            board.reconnect()
        link = open_link(board.port)
        if stop.corrupt_line_ran:
            # a host slow to see the desync (a loaded machine) lets the board run the
            # corrupted line (TinyG has no input checksum): the board must truly have
            # reached it, and the resume must refuse without --force
            completed, partial = board.executed_lines()
            assert max(completed + partial) >= stop.line_number
            with pytest.raises(DeviceError, match=rf"corrupted line N{stop.line_number}\b"):
                stream_job(link, job.lines, journal=journal, resume=True, config=FAST)
            link.close()
            return
        result = stream_job(link, job.lines, journal=journal, resume=True, config=FAST)
        link.close()
        assert result.executed_line == len(job.lines)
        completed, partial = board.executed_lines()
        # every line completed exactly once; a line cut by the stop is completed by the fix-up
        assert completed == list(range(0, len(job.lines) + 1))
        assert len(partial) <= 1
        assert board.stats.rx_dropped_bytes == 0
        np.testing.assert_allclose(board.wire_shape_mm(), clean_shape, atol=2e-3)
        assert read_jsonl(journal)[-1]["event"] == "done"
    finally:
        board.close()


def test_a_rejected_line_is_never_skipped_silently(job, tmp_path):
    """A line answered with an error status did not run; the lines after it may have.

    Either nothing after it ran (resume re-sends it and the part comes out right) or
    something did (the part is wrong: the stop says so and resume refuses to go on).
    """
    _, clean_shape, _, _ = run_clean(job)
    outcomes = {}

    # (a) a slow machine: the lines after the rejected one wait in the planner, the stop
    # flushes them; (b) a fast one that was reading slowly: with the default single line
    # in flight nothing follows the rejected line, (c) with four in flight the host had
    # sent the next lines, which run at once after it (deterministic: the stall holds them)
    def fast():
        return [Fault("stall", 40, duration_s=0.3), Fault("error_status", 40)]

    four = StreamConfig(window_lines=4, stall_timeout_s=1.0, flush_timeout_s=5.0)
    for label, speedup, faults, config in (
        ("slow", 50.0, [Fault("error_status", 22)], FAST),
        ("fast", 20000.0, fast(), FAST),
        ("fast, 4 in flight", 20000.0, fast(), four),
    ):
        journal = tmp_path / f"{label}.journal.jsonl"
        board = FakeTinyG(speedup=speedup, faults=faults, line_report="parsed").start()
        try:
            link = open_link(board.port)
            with pytest.raises(JobStopped) as info:
                stream_job(link, job.lines, journal=journal, config=config)
            link.close()
            stop = info.value.stop
            assert stop.reason == "error" and "status 130" in stop.detail
            link = open_link(board.port)
            try:
                stream_job(link, job.lines, journal=journal, resume=True, config=FAST)
            except DeviceError as exc:
                assert stop.ran_past_rejected_line
                assert f"N{stop.line_number} was rejected" in str(exc) and "--force" in str(exc)
                outcomes[label] = "refused"
            else:
                assert not stop.ran_past_rejected_line
                completed, _ = board.executed_lines()
                assert completed == list(range(0, len(job.lines) + 1))
                np.testing.assert_allclose(board.wire_shape_mm(), clean_shape, atol=2e-3)
                outcomes[label] = "completed"
            finally:
                link.close()
        finally:
            board.close()
    assert outcomes == {"slow": "completed", "fast": "completed", "fast, 4 in flight": "refused"}


def test_resume_needs_the_journal_of_this_job(job, tmp_path):
    with open_link("sim://?speedup=300") as link:
        with pytest.raises(InputError, match="no journal"):
            stream_job(link, job.lines, journal=tmp_path / "none.jsonl", resume=True)
        stream_job(link, job.lines[:5] + job.lines[-1:], journal=tmp_path / "other.jsonl")
        with pytest.raises(InputError, match="different job"):
            stream_job(link, job.lines, journal=tmp_path / "other.jsonl", resume=True)


def test_alarmed_board_refuses_a_new_job(job):
    with FakeTinyG(speedup=300.0, faults=[Fault("alarm", 14)]) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped):
            stream_job(link, job.lines, config=FAST)
        with pytest.raises(DeviceError, match="alarmed"):
            stream_job(link, job.lines, config=FAST)
        link.close()


def test_prepare_job_numbers_and_checks(tmp_path):
    job = prepare_job(["G21 G90", "", "(comment)", "G91 G1 Y5 F100"])
    assert [j.text for j in job] == ["N1 G21 G90", "N2 G91 G1 Y5 F100"]
    assert [j.nbytes for j in job] == [11, 18]
    with pytest.raises(InputError, match=r"job.gcode: line 2: .*forbidden"):
        prepare_job(["G21", "G1 X5 ! F1"], source="job.gcode")
    with pytest.raises(InputError, match="some lines have N numbers"):
        prepare_job(["N1 G21", "G90"])
    with pytest.raises(InputError, match="does not increase"):
        prepare_job(["N2 G21", "N2 G90"])
    with pytest.raises(InputError, match="line 1: .*unsupported"):
        prepare_job(["G2 X1"])


def test_plan_resume_from_board_reports():
    job = prepare_job(
        ["G21 G90", "G91 G1 Y10 F600", "G90 G1 X30 F6000", "G0 X0", "G91 G1 Y10 F600"]
    )
    start = {"x": 0.0, "y": 100.0, "z": 0.0}
    assert plan_resume(job, start_pos=start, board_line=0, board_pos=start).start_index == 0
    # line 2 done (y = 110): continue with line 3
    p = plan_resume(job, start_pos=start, board_line=2, board_pos={"y": 110.0})
    assert (p.start_index, p.fixup) == (2, None)
    # line 2 cut at y = 104: feed the remaining 6 mm, then line 3
    p = plan_resume(job, start_pos=start, board_line=2, board_pos={"y": 104.0})
    assert (p.start_index, p.fixup) == (2, "N2 G91 G1 Y6.0000 F600")
    # line 3 (absolute pin) cut at x = 29.9999: tiny remainder slowed above 2.5 ms
    p = plan_resume(job, start_pos=start, board_line=3, board_pos={"x": 29.99, "y": 110.0})
    assert p.start_index == 3 and p.fixup is not None and p.fixup.startswith("N3 G90 G1 X30.0000 F")
    rate = float(p.fixup.rsplit("F", 1)[1])
    assert 0.01 / rate * 60 >= 0.005 - 1e-9
    with pytest.raises(DeviceError, match="N99, which is not in this job"):
        plan_resume(job, start_pos=start, board_line=99, board_pos=start)
    # positions that no line of the job explains are refused, never papered over
    with pytest.raises(DeviceError, match=r"disagrees with the job at line N3 \(y off by -3.000\)"):
        plan_resume(job, start_pos=start, board_line=3, board_pos={"x": 30.0, "y": 107.0})
    with pytest.raises(DeviceError, match="outside line N2's move"):
        plan_resume(job, start_pos=start, board_line=2, board_pos={"y": 111.0})
    with pytest.raises(DeviceError, match="has run none of the job but has moved"):
        plan_resume(job, start_pos=start, board_line=0, board_pos={"y": 104.0})


def test_feedhold_and_cycle_start_from_another_thread(job, tmp_path):
    control = StreamControl()
    states = []

    def progress(sent, total, executed):
        if sent == 30:
            control.hold()

    with FakeTinyG(speedup=20.0) as board:
        link = open_link(board.port)
        watcher = threading.Thread(target=_watch_hold, args=(board, control, states))
        watcher.start()
        result = stream_job(
            link,
            job.lines,
            journal=tmp_path / "j.jsonl",
            config=FAST,
            control=control,
            progress=progress,
        )
        watcher.join()
        link.close()
        completed, partial = board.executed_lines()
    assert result.executed_line == len(job.lines)
    assert states and states[0][0] == 6  # the board held ...
    assert states[0][1] == states[1][1]  # ... and did not move while held
    assert completed == list(range(0, len(job.lines) + 1)) and partial == []
    events = [r["event"] for r in read_jsonl(tmp_path / "j.jsonl")]
    assert "hold" in events and "cycle_start" in events


def _watch_hold(board, control, states):
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and not control.held:
        time.sleep(0.005)
    time.sleep(0.15)
    for _ in range(2):
        s = board.machine_state()
        states.append((s.stat, s.feed_mm, s.pin_deg))
        time.sleep(0.1)
    control.resume()


def test_abort_stops_safely_and_resumes(job, tmp_path):
    control = StreamControl()
    journal = tmp_path / "j.jsonl"

    def progress(sent, total, executed):
        if sent == 40:
            control.abort()

    with FakeTinyG(speedup=50.0) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(
                link, job.lines, journal=journal, config=FAST, control=control, progress=progress
            )
        assert info.value.stop.reason == "aborted"
        state = board.machine_state()
        assert state.stat == 3 and state.planner_depth == 0 and state.rx_bytes == 0
        stream_job(link, job.lines, journal=journal, config=FAST, resume=True)
        link.close()
        completed, _ = board.executed_lines()
    assert completed == list(range(0, len(job.lines) + 1))


def test_ctrl_c_is_journalled_then_reraised(job, tmp_path):
    journal = tmp_path / "j.jsonl"

    def progress(sent, total, executed):
        if sent == 25:
            raise KeyboardInterrupt

    with FakeTinyG(speedup=50.0) as board:
        link = open_link(board.port)
        with pytest.raises(KeyboardInterrupt):
            stream_job(link, job.lines, journal=journal, config=FAST, progress=progress)
        assert read_jsonl(journal)[-1]["reason"] == "interrupted"
        stream_job(link, job.lines, journal=journal, config=FAST, resume=True)
        link.close()
        completed, _ = board.executed_lines()
    assert completed == list(range(0, len(job.lines) + 1))


def test_xoff_in_the_data_pauses_the_sender():
    """Without tty flow control (socket://, --no-xonxoff) XON/XOFF arrive as data."""
    from cvmeasure.driver.stream import BoardConnection

    with open_link("loop://", xonxoff=False) as link:
        board = BoardConnection(link)
        try:
            link.write(b"\x13")
            deadline = time.monotonic() + 2
            while not board.paused and time.monotonic() < deadline:
                time.sleep(0.01)
            assert board.paused
            link.write(b'{"qr":3}\x11\n')
            msg = board.next_message(2.0)
            assert not board.paused and msg == QueueReport(3)
        finally:
            board.close()


def test_a_board_frozen_past_the_flush_timeout_is_reported_unresponsive(job, tmp_path):
    journal = tmp_path / "j.jsonl"
    cfg = StreamConfig(stall_timeout_s=0.5, flush_timeout_s=0.5)
    with FakeTinyG(speedup=50.0, faults=[Fault("stall", 30, duration_s=2.0)]) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=journal, config=cfg)
        stop = info.value.stop
        assert stop.reason == "stall" and stop.board is None
        assert "did not confirm the flush (unresponsive)" in stop.detail
        time.sleep(1.2)  # the board wakes up, and acts on the ! and % it was sent
        try:
            stream_job(link, job.lines, journal=journal, config=FAST, resume=True)
        except DeviceError as exc:
            # where the pin stands before two lines alike the resume cannot tell which ran:
            # it refuses naming both; the operator looks at the part (here: the board's log)
            choices = [int(n) for n in re.findall(r"--from-line N(\d+)", str(exc))]
            assert len(choices) == 2 and "cannot tell which lines ran" in str(exc)
            ran, _ = board.executed_lines()
            first_unrun = min(set(range(1, len(job.lines) + 1)) - set(ran))
            assert first_unrun in choices
            stream_job(
                link, job.lines, journal=journal, config=FAST, resume=True, from_line=first_unrun
            )
        link.close()
        completed, _ = board.executed_lines()
    assert completed == list(range(0, len(job.lines) + 1))


def test_a_corrupted_line_that_ran_needs_force_to_resume(job, tmp_path):
    """TinyG 440 has no input checksum: with an idle planner a corrupted line runs at once."""
    from cvmeasure.driver.stream import FIRMWARE_QUERIES, SETUP_COMMANDS

    target = job.lines[4]
    assert target.startswith("N5 G90 G1 X-")
    # lines the board reads: settings, identification, {"ex"}, {"sr":null}, the N0 marker, N1..N5
    at_line = len(SETUP_COMMANDS) + len(FIRMWARE_QUERIES) + 2 + 1 + 5
    fault = Fault("drop_byte", at_line, byte_index=target.index("-"))
    journal = tmp_path / "j.jsonl"
    # one line in flight: N5 arrives after N4's ack, when the (1e6 x fast) N4 is done
    one = StreamConfig(window_lines=1, stall_timeout_s=1.0, flush_timeout_s=5.0)
    with FakeTinyG(speedup=1e6, faults=[fault]) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=journal, config=one)
        stop = info.value.stop
        assert stop.reason == "desync" and stop.line_number == 5 and stop.corrupt_line_ran
        assert "check the part" in str(info.value)
        with pytest.raises(DeviceError, match="resume with --force"):
            stream_job(link, job.lines, journal=journal, config=FAST, resume=True)
        stream_job(link, job.lines, journal=journal, config=FAST, resume=True, force=True)
        link.close()


def test_an_alarm_that_tripped_while_the_host_was_away_is_said_at_resume(job, tmp_path):
    journal = tmp_path / "job.journal.jsonl"
    # the port goes at line 30; the board runs on through what it holds and trips at 28..29
    board = FakeTinyG(speedup=5.0, faults=[Fault("vanish", 30), Fault("alarm", 29)]).start()
    try:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=journal, config=FAST)
        link.close()
        assert info.value.stop.reason == "port_gone"
        deadline = time.monotonic() + 10
        while "alarm@29" not in board.stats.faults_fired and time.monotonic() < deadline:
            time.sleep(0.05)
        assert "alarm@29" in board.stats.faults_fired  # tripped with no host connected
        board.reconnect()
        link = open_link(board.port)
        result = stream_job(link, job.lines, journal=journal, resume=True, config=FAST)
        link.close()
        assert any("in alarm" in n and "check the machine" in n for n in result.notes)
        assert any(r["event"] == "alarm_cleared" for r in read_jsonl(journal))
    finally:
        board.close()


def test_from_line_without_resume_is_refused_before_anything_is_sent(job):
    """``from_line`` continues a stopped job; without ``resume`` the job would start again
    from its first line (every bend made twice), so it is refused and the board gets nothing."""
    with FakeTinyG(speedup=300.0) as board:
        link = open_link(board.port)
        try:
            with pytest.raises(InputError, match="only applies with resume"):
                stream_job(link, job.lines, config=FAST, from_line=9)
        finally:
            link.close()
        completed, _ = board.executed_lines()
    assert completed == []
