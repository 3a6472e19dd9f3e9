"""The app's one-sentence diagnosis (``adapter.diagnose_session``) reads the typed cause.

Truth: a backlash of typical size hidden in simulated trials (``hidden_case``, fixed seed).
"""

from __future__ import annotations

from cvmeasure.app.adapter import diagnose_session
from cvmeasure_datasets.trials import hidden_case


def test_the_sentence_names_the_hidden_cause():
    case = hidden_case(11, effect="backlash")
    result = diagnose_session(case.trials)
    assert result.sentence.startswith("most likely backlash: it cuts"), result.sentence
