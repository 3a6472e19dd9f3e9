"""Where a stopped job continues: decided from the board's report and position after the stop.

The job feeds, bends and returns the pin, so the pin is home both before a bend and
after its return: a position alone cannot say whether the bend was made.
"""

from __future__ import annotations

import pytest

from cvmeasure.driver.job import prepare_job
from cvmeasure.driver.resume import ResumeEvidence, locate_resume
from cvmeasure.errors import DeviceError, InputError

JOB = prepare_job(
    [
        "G21 G90",
        "G91 G1 Y20 F3000",  # N2 feed
        "G90",  # N3
        "G1 X40 F6000",  # N4 bend
        "G0 X0",  # N5 return
        "G91 G1 Y15 F3000",  # N6 feed
        "G90",  # N7
        "G1 X-30 F6000",  # N8 bend
        "G0 X0",  # N9 return
        "M2",
    ]
)
START = {"x": 0.0, "y": 0.0, "z": 0.0, "a": 0.0}


def _at(x: float, y: float) -> dict[str, float]:
    return {"x": x, "y": y, "z": 0.0, "a": 0.0}


def test_the_stall_case_refuses_instead_of_bending_again():
    # the run: N3 last seen running, the board later reports N5 (what it parsed),
    # the pin is home at Y20: after N3 (bend not made) or after N5 (bend and return made)
    with pytest.raises(DeviceError) as info:
        locate_resume(JOB, start_pos=START, board_pos=_at(0.0, 20.0), evidence=ResumeEvidence(3, 5))
    message = str(info.value)
    assert "cannot tell which lines ran" in message
    assert "--from-line N4" in message and "--from-line N6" in message


def test_the_operators_word_decides_and_is_checked():
    evidence = ResumeEvidence(3, 5)
    plan, last = locate_resume(
        JOB, start_pos=START, board_pos=_at(0.0, 20.0), evidence=evidence, from_line=6
    )
    assert plan.start_index == 5 and plan.fixup is None and JOB[last].number == 5
    plan, _ = locate_resume(
        JOB, start_pos=START, board_pos=_at(0.0, 20.0), evidence=evidence, from_line=4
    )
    assert JOB[plan.start_index].number == 4 and plan.fixup is None
    with pytest.raises(InputError, match="--from-line"):
        locate_resume(
            JOB, start_pos=START, board_pos=_at(0.0, 20.0), evidence=evidence, from_line=8
        )


def test_an_exact_report_decides_alone():
    # a fresh feedhold report named N5: the return was running, the bend made
    plan, last = locate_resume(
        JOB,
        start_pos=START,
        board_pos=_at(0.0, 20.0),
        evidence=ResumeEvidence(3, 9, held=5),
    )
    assert JOB[last].number == 5 and JOB[plan.start_index].number == 6


def test_a_cut_move_is_completed_once():
    # held in the bend N4 at X25 (of 40): completed to X40, then N5 onwards
    plan, last = locate_resume(
        JOB, start_pos=START, board_pos=_at(25.0, 20.0), evidence=ResumeEvidence(4, 9, held=4)
    )
    assert JOB[last].number == 4 and plan.fixup is not None and "X40.0000" in plan.fixup
    assert JOB[plan.start_index].number == 5


def test_one_line_between_the_bounds_fits_without_a_held_report():
    # mid-feed of N6 (Y27 of 20..35): only N6 fits, whatever the board parsed since
    plan, last = locate_resume(
        JOB, start_pos=START, board_pos=_at(0.0, 27.0), evidence=ResumeEvidence(5, 9)
    )
    assert JOB[last].number == 6 and "Y8.0000" in plan.fixup


def test_a_position_no_line_fits_refuses():
    with pytest.raises(DeviceError, match="fits no line from N5 to N9"):
        locate_resume(
            JOB, start_pos=START, board_pos=_at(12.0, 99.0), evidence=ResumeEvidence(5, 9)
        )
