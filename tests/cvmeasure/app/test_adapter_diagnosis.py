"""The app's one-sentence diagnosis (``adapter.diagnose_session``) reads the typed cause.

Truth: a backlash or a scale of typical size hidden in simulated trials (``hidden_case``, fixed
seed).
"""

from __future__ import annotations

from cvmeasure.app.adapter import diagnose_session
from cvmeasure_datasets.trials import hidden_case


def test_the_sentence_names_the_hidden_cause():
    case = hidden_case(11, effect="backlash")
    result = diagnose_session(case.trials)
    assert result.sentence.startswith("most likely backlash: it cuts"), result.sentence


def test_a_follow_up_plan_reaches_the_page_as_numbered_bends():
    """A tie's follow-up plan (the head's runout ties a scale on this plan) becomes
    (trial, commanded pin angle) rows the page can list; trials continue the session's."""
    case = hidden_case(11, effect="scale")
    result = diagnose_session(case.trials)
    assert "a follow-up plan separates" in result.sentence
    trials = [int(t) for t, _ in result.follow_up_rows]
    assert trials == list(range(trials[0], trials[0] + len(trials)))
    assert trials[0] > len(case.trials)
    assert all(0.0 < abs(c) <= 180.0 for _, c in result.follow_up_rows)
