"""The serial-faults scorer counts what the machine did, not the labels moves carried."""

from __future__ import annotations

from benchmarks.serial_faults import RunResult, attribute_moves, score

JOB = [
    "N1 G21 G90",
    "N2 G91 G1 Y10 F3000",
    "N3 G90",
    "N4 G1 X30 F6000",
    "N5 G0 X0",
    "N6 G91 G1 Y10 F3000",
    "N7 G90",
    "N8 G1 X-20 F6000",
    "N9 G0 X0",
    "N10 M2",
]


def _at(x: float, y: float) -> dict[str, float]:
    return {"x": x, "y": y, "z": 0.0, "a": 0.0}


def _clean() -> list[tuple[int, dict, dict]]:
    return [
        (2, _at(0, 0), _at(0, 10)),
        (4, _at(0, 10), _at(30, 10)),
        (5, _at(30, 10), _at(0, 10)),
        (6, _at(0, 10), _at(0, 20)),
        (8, _at(0, 20), _at(-20, 20)),
        (9, _at(-20, 20), _at(0, 20)),
    ]


def test_a_misread_label_on_the_right_motion_is_that_line_once_in_order():
    moves = _clean()
    moves[5] = (0, moves[5][1], moves[5][2])  # N9 read as N0 (its '9' lost)
    moves[2] = (2, moves[2][1], moves[2][2])  # N5 read as N2 (garbled): line 2 is a Y feed
    executed, foreign = attribute_moves(JOB, moves)
    assert [n for n, _ in executed] == [2, 4, 5, 6, 8, 9] and foreign == []
    assert score(JOB, executed) == ([], [], [])


def test_a_cut_move_and_its_fixup_add_up_to_one_run():
    moves = _clean()
    moves[1:2] = [(4, _at(0, 10), _at(12, 10)), (4, _at(12, 10), _at(30, 10))]
    executed, foreign = attribute_moves(JOB, moves)
    assert score(JOB, executed) == ([], [], []) and foreign == []


def test_a_corrupted_line_that_ran_another_motion_leaves_its_lines_short():
    moves = _clean()
    moves[1] = (4, _at(0, 10), _at(3, 10))  # "X30" read "X3": a smaller bend
    moves[2] = (5, _at(3, 10), _at(0, 10))
    executed, foreign = attribute_moves(JOB, moves)
    twice, lost, order = score(JOB, executed)
    # 0 -> 3 lies on line 4's path (0 -> 30) and 3 -> 0 on line 5's: both short of
    # their length, so both are lines the part lacks (lost), not lines made
    assert foreign == [] and lost == [4, 5] and twice == [] and order == []


def test_a_move_on_no_line_s_path_is_foreign_and_a_finished_run_with_it_is_wrong():
    moves = _clean()
    moves[1] = (4, _at(0, 10), _at(3, 13))  # "X30" garbled "X3 Y3": a move the job lacks
    moves[2] = (5, _at(3, 13), _at(0, 13))
    executed, foreign = attribute_moves(JOB, moves)
    assert foreign == [4, 5]
    run = RunResult("m", "f", finished=True, foreign=foreign)
    assert run.silent_wrong and run.foreign_unchecked
    checked = RunResult("m", "f", finished=True, forced=True, foreign=foreign)
    assert not checked.silent_wrong and not checked.foreign_unchecked
