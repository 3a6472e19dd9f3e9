"""Fault causes found in the serial fault runs, each on a real pty against the double.

Each test is one cause of a lost, doubled or wrongly named line: a line that loses its LF
while the machine is idle, a stall whose stop named the line in flight instead of the
machine's, and a resume that waited forever on a frozen board.
"""

from __future__ import annotations

import re
import time

import pytest

from cvmeasure.design import arc_points_mm
from cvmeasure.driver.stream import (
    FIRMWARE_QUERIES,
    SETUP_COMMANDS,
    JobStopped,
    StreamConfig,
    stream_job,
)
from cvmeasure.driver.transport import open_link
from cvmeasure.errors import DeviceError
from cvmeasure.gcode import design_job
from cvmeasure.testing.double import FakeTinyG, Fault

FAST = StreamConfig(stall_timeout_s=1.0, flush_timeout_s=5.0)
#: lines the double reads before N1: settings, identification, {"ex"}, {"sr":null}, N0
BEFORE_N1 = len(SETUP_COMMANDS) + len(FIRMWARE_QUERIES) + 2 + 1


@pytest.fixture(scope="module")
def job():
    return design_job(arc_points_mm((0.0, 0.0), 100.0, 90.0, 180.0, chords=20), source="half.svg")


def test_a_line_that_loses_its_lf_on_an_idle_machine_resumes_exactly(job, tmp_path):
    """The board waits for the rest of the line; a status query sent then would merge
    with it. The stop flushes first, so the board's line after it is exact."""
    n = 12
    fault = Fault("drop_byte", BEFORE_N1 + n, byte_index=999)  # the terminator
    journal = tmp_path / "j.jsonl"
    with FakeTinyG(speedup=1e6, faults=[fault]) as board:  # every line done at once: idle
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=journal, config=FAST)
        stop = info.value.stop
        assert stop.reason == "stall" and stop.line_number == n - 1
        assert stop.held is not None and stop.held["line"] == n - 1  # exact: nothing queued
        result = stream_job(link, job.lines, journal=journal, config=FAST, resume=True)
        link.close()
        assert result.resumed_from == n - 1  # index of N12: it is sent again, once
        completed, partial = board.executed_lines()
        assert completed == list(range(0, len(job.lines) + 1)) and partial == []


def test_a_stall_names_the_line_the_machine_is_on(job, tmp_path):
    """With the planner full the line awaiting its ack is far ahead of the machine."""
    fault = Fault("stall", BEFORE_N1 + 40, duration_s=2.5)
    with FakeTinyG(speedup=20.0, faults=[fault]) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=tmp_path / "j.jsonl", config=FAST)
        link.close()
        stop = info.value.stop
        completed, partial = board.executed_lines()
    running = partial[-1] if partial else completed[-1]
    # the board's line, not the one in flight (N40, 28 lines ahead): at most the line the
    # machine is on, which the stop reads from the board's last status report (on a loaded
    # machine that report can be a few lines old; the resume asks the board again)
    assert stop.reason == "stall" and stop.line_number <= running
    # not the line in flight (a word match: the ack of N4 is not the ack of N40)
    assert not re.search(rf"the ack of N{stop.line_number}\b", str(info.value))
    assert "N40" in str(info.value)  # the line in flight is still said


def test_a_resume_on_a_frozen_board_refuses_naming_the_line(job, tmp_path):
    """A board that neither moves nor answers never finishes: the resume must not wait."""
    journal = tmp_path / "j.jsonl"
    quick = StreamConfig(stall_timeout_s=1.0, flush_timeout_s=0.5, command_timeout_s=0.5)
    with FakeTinyG(speedup=20.0, faults=[Fault("stall", BEFORE_N1 + 40, duration_s=60)]) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=journal, config=quick)
        line = info.value.stop.line_number
        t0 = time.monotonic()
        with pytest.raises(DeviceError, match=rf"N{line}\b.*frozen") as refused:
            stream_job(link, job.lines, journal=journal, config=quick, resume=True)
        assert time.monotonic() - t0 < 15.0
        assert "reset the board" in str(refused.value)
        link.close()


def test_a_port_gone_names_the_line_the_board_ends_at(job, tmp_path):
    """Cut off, the board runs on through all it parsed: the stop names where it ends."""
    fault = Fault("vanish", BEFORE_N1 + 30)
    with FakeTinyG(speedup=20.0, faults=[fault]) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job.lines, journal=tmp_path / "j.jsonl", config=FAST)
        link.close()
        deadline = time.monotonic() + 20.0
        while board.machine_state().planner_depth and time.monotonic() < deadline:
            time.sleep(0.05)
        completed, partial = board.executed_lines()
    stop = info.value.stop
    assert stop.reason == "port_gone" and partial == []
    # the last line sent, where the board ends (with 4 lines in flight it named N33); the
    # byte stream may be cut inside N31, which the board then never runs
    assert completed[-1] == 30 and stop.line_number in (30, 31)
