"""A corrupted N word: the board runs a line under a number it was never sent there.

TinyG has no input checksum, so a byte lost on the wire can make ``N112 G0 X0`` read
``N12 G0 X0``: the machine runs line 112's motion and reports it as N12, a line it
finished long before. The stop must say the corrupted line ran and what to check; a
forced resume must continue from the machine's position (line 112's end), not from
the number the board gave it.
"""

from __future__ import annotations

import json
from types import SimpleNamespace

import pytest

from cvmeasure.driver.job import prepare_job
from cvmeasure.driver.stream import (
    FIRMWARE_QUERIES,
    SETUP_COMMANDS,
    JobStopped,
    StreamConfig,
    _Run,
    stream_job,
)
from cvmeasure.driver.transport import open_link
from cvmeasure.errors import DeviceError
from cvmeasure.testing.double import FakeTinyG, Fault

FAST = StreamConfig(stall_timeout_s=1.0, flush_timeout_s=5.0)
#: lines the double reads before N1: settings, identification, {"ex"}, {"sr":null}, N0
BEFORE_N1 = len(SETUP_COMMANDS) + len(FIRMWARE_QUERIES) + 2 + 1
BAD = 112  # its N word loses byte 2 ("1"): N112 reads N12


def _job(bad_move: str) -> list:
    """Feeds and bends, fast; line BAD a slow move so it is running when the stop comes."""
    text = ["G21 G90", "G0 Z0", "G0 X0"]
    while len(text) < BAD - 1:
        text += ["G91 G1 Y2 F30000", "G90", "G0 X20", "G0 X0"]
    text = text[: BAD - 1] + [bad_move, "G91 G1 Y2 F30000", "G90", "G0 X-20", "G0 X0", "M2"]
    return prepare_job([f"N{i} {t}" for i, t in enumerate(text, start=1)], source="t.nc")


def _planned_x(job, number: int) -> float:
    """X at the end of line ``number`` (the job's absolute X words)."""
    x = 0.0
    for line in job[:number]:
        for word in line.text.split()[1:]:
            if word.startswith("X"):
                x = float(word[1:])
    return x


@pytest.mark.parametrize("line_report", ["executing", "parsed"])
def test_a_misread_line_number_stops_asking_for_a_check_and_resumes_by_position(
    tmp_path, line_report
):
    job = _job("G1 X40 F2")
    journal = tmp_path / "j.jsonl"
    fault = Fault("drop_byte", BEFORE_N1 + BAD, byte_index=2)
    with FakeTinyG(speedup=1e4, faults=[fault], line_report=line_report) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped) as info:
            stream_job(link, job, journal=journal, config=FAST)
        stop = info.value.stop
        message = str(info.value)
        assert stop.reason == "desync" and stop.line_number == BAD
        # the board ran line 112's block as N12: said, and the part must be checked
        assert stop.misread_line == 12 and stop.corrupt_line_ran
        assert "N12, a line it was not sent there" in message and "--force" in message
        # its last words, what to do, agree with the advice before them
        assert message.endswith("resume with --resume --force once the part is checked")
        with pytest.raises(DeviceError, match="check the part, then resume with --force"):
            stream_job(link, job, journal=journal, config=FAST, resume=True)
        result = stream_job(link, job, journal=journal, config=FAST, resume=True, force=True)
        link.close()
        moves = board.executed_moves()
    # the resume goes on after N112, completing its move first if the hold cut it
    assert result.resumed_from == BAD  # the index of N113
    assert result.fixup is None or result.fixup.startswith(f"N{BAD} ")
    records = [json.loads(r) for r in journal.read_text().splitlines()]
    assert [r for r in records if r["event"] == "resume"][-1]["evidence"]["held"] == BAD
    # what the machine did after N111 at line 112's feed position: its X move 0 -> 40
    # once in all (the misread block and the fix-up add up to it), no more
    after = moves[max(i for i, m in enumerate(moves) if m[0] == BAD - 1) + 1 :]
    y_bad = stop.held["posy"]
    out = sum(b["x"] - a["x"] for _, a, b in after if a["y"] == b["y"] == y_bad and b["x"] > a["x"])
    assert out == pytest.approx(40.0, abs=1e-3)
    assert board.machine_state().pin_deg == pytest.approx(_planned_x(job, len(job)), abs=1e-3)


def test_a_held_line_the_position_does_not_fit_is_the_corrupted_line_if_it_fits(tmp_path):
    """A corrupted N word can read as a line sent shortly before (no way to tell it by
    its number): here the stop's journal says the board held at N107 (a return, a feed
    before N112), whose move the machine's position (on N112's) does not fit. The resume finds the
    position on the corrupted N112's move: it ran, so a check and --force come first."""
    job = _job("G1 X40 F2")
    journal = tmp_path / "j.jsonl"
    fault = Fault("drop_byte", BEFORE_N1 + BAD, byte_index=2)
    with FakeTinyG(speedup=1e4, faults=[fault]) as board:
        link = open_link(board.port)
        with pytest.raises(JobStopped):
            stream_job(link, job, journal=journal, config=FAST)
        records = [json.loads(r) for r in journal.read_text().splitlines()]
        stop = records[-1]
        assert stop["event"] == "stop" and stop["misread_line"] == 12
        stop.update(misread_line=None, corrupt_line_ran=False, running_line=107)
        stop["held"]["line"] = 107
        journal.write_text("".join(json.dumps(r) + "\n" for r in records))
        with pytest.raises(DeviceError, match=r"N112 ran with its number read as N107") as info:
            stream_job(link, job, journal=journal, config=FAST, resume=True)
        assert "--force" in str(info.value) and "check the part" in str(info.value)
        result = stream_job(link, job, journal=journal, config=FAST, resume=True, force=True)
        link.close()
    assert result.resumed_from == BAD
    assert result.fixup is None or result.fixup.startswith(f"N{BAD} ")
    assert board.machine_state().pin_deg == pytest.approx(_planned_x(job, len(job)), abs=1e-3)


def test_a_parsed_line_reported_out_of_cycle_does_not_make_the_running_one_misread():
    """Out of cycle TinyG reports the last line parsed, ahead of lines still waiting to
    run: only the in-cycle (runtime) reports bound the line the machine can be on."""
    job = _job("G1 X40 F2")
    board = SimpleNamespace(state={}, running_line=None)
    run = _Run(job, board, FAST, None, None)
    run.last_sent = job[99]
    board.state, board.running_line = {"stat": 5, "line": 80}, 80  # running N80
    run.note_progress()
    board.state = {"stat": 3, "line": 95}  # starved: stopped, N81..N95 parsed, not run
    run.note_progress()
    assert not run.misread(85)  # the machine then runs N85: a line it was sent
    assert run.misread(12) and run.misread(150) and run.misread(9999)
