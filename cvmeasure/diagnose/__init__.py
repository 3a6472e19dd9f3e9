"""Diagnosis of the simulation against measured trials (issue 6).

:func:`diagnose` fits the nuisance parameter, tries every named effect of
:mod:`cvmeasure.sim.effects`, selects by grouped cross-validated error with a
penalty, and reports the cause, its 95 % interval, the held-out gain and an
identifiability check. :mod:`cvmeasure_datasets.trials` hides effects in
simulated trials for tests and benchmarks. Trials are
:class:`cvmeasure.contracts.TrialTable`.
"""

from cvmeasure.diagnose.core import CandidateResult, Diagnosis, diagnose
from cvmeasure.diagnose.result import Cause, CauseKind

__all__ = [
    "CandidateResult",
    "Cause",
    "CauseKind",
    "Diagnosis",
    "diagnose",
]
