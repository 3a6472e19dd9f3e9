"""Scoring a job against the held-out controller's truth log: each verdict on a made-up log."""

from __future__ import annotations

from benchmarks.heldout.score import expected_job, score_job
from benchmarks.heldout.tinyg_truth import Executed, TruthLog

JOB = "\n".join([
    "N1 G21 G90",
    "N2 G0 Z0",  # no motion from the power-up position
    "N3 G91 G1 Y10 F3000",
    "N4 G90 G1 X40 F6000",
    "N5 G0 X0",
    "N6 G91 G1 Y5 F3000",
    "N7 (end)",
])  # fmt: skip


def rec(line, y0, y1, x0, x1, fraction=1.0, how="done", text=""):
    start = {"x": x0, "y": y0, "z": 0.0, "a": 0.0}
    end = {"x": x1, "y": y1, "z": 0.0, "a": 0.0}
    return Executed(line, text, fraction, start, end, 0.0, 0.0, how)


CLEAN = [rec(3, 0, 10, 0, 0), rec(4, 10, 10, 0, 40), rec(5, 10, 10, 40, 0), rec(6, 10, 15, 0, 0)]


def test_expected_job_names_the_moving_lines_and_the_feed():
    job = expected_job(JOB)
    assert job.moving_lines == [3, 4, 5, 6] and job.total_feed_mm == 15.0
    assert job.moves[3].relative and job.moves[4].named == {"x": 40.0}


def test_a_clean_run_scores_clean():
    s = score_job(expected_job(JOB), TruthLog(executed=list(CLEAN)), finished=True)
    assert (s.ran_twice, s.lost, s.out_of_order, s.corrupted) == ([], [], [], [])
    assert s.feed_error_mm == 0.0


def test_a_bend_rerun_after_later_lines_is_twice_and_out_of_order():
    log = CLEAN[:3] + [rec(4, 10, 10, 0, 40), rec(5, 10, 10, 40, 0), CLEAN[3]]
    s = score_job(expected_job(JOB), TruthLog(executed=log), finished=True)
    assert s.ran_twice == [4, 5] and s.out_of_order == [4] and s.lost == []  # as issue 43


def test_partial_absolute_move_finished_by_another_line_text_is_fine():
    log = [CLEAN[0], rec(4, 10, 10, 0, 12, 0.3, "flushed"), rec(4, 10, 10, 12, 40, text="fix")]
    s = score_job(expected_job(JOB), TruthLog(executed=log + CLEAN[2:]), finished=True)
    assert (s.ran_twice, s.lost, s.corrupted) == ([], [], [])


def test_partial_feed_then_full_feed_overfeeds():
    log = [rec(3, 0, 4, 0, 0, 0.4, "flushed"), rec(3, 4, 14, 0, 0)] + CLEAN[1:]
    s = score_job(expected_job(JOB), TruthLog(executed=log), finished=True)
    assert s.ran_twice == [3] and abs(s.feed_error_mm - 4.0) < 1e-9


def test_skipped_line_is_lost_and_a_wrong_target_corrupted():
    log = [CLEAN[0], rec(4, 10, 10, 0, 41), CLEAN[3]]  # N5 never ran; N4 went to X41
    s = score_job(expected_job(JOB), TruthLog(executed=log), finished=False)
    assert s.lost == [5] and s.corrupted == [4]


def test_stopped_job_does_not_count_the_unrun_tail_as_lost():
    s = score_job(expected_job(JOB), TruthLog(executed=CLEAN[:2]), finished=False)
    assert s.lost == [] and s.feed_error_mm is None
    s = score_job(expected_job(JOB), TruthLog(executed=CLEAN[:2]), finished=True)
    assert s.lost == [5, 6]


def test_one_feed_of_the_wrong_length_is_corrupted_not_twice():
    log = [rec(3, 0, 10.01, 0, 0)] + CLEAN[1:]  # a garbled digit: Y10.01 instead of Y10
    s = score_job(expected_job(JOB), TruthLog(executed=log), finished=True)
    assert s.corrupted == [3] and s.ran_twice == [] and abs(s.feed_error_mm - 0.01) < 1e-9


def test_a_line_skipped_before_a_partly_run_later_line_is_lost():
    log = [CLEAN[0], rec(5, 10, 10, 0, -12, 0.3, "flushed")]  # N4 rejected, N5 began
    s = score_job(expected_job(JOB), TruthLog(executed=log), finished=False)
    assert s.lost == [4]
