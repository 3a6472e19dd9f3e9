"""The TinyG double behind the session's streamer (``cvmeasure session --simulate``)."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

from cvmeasure.driver.session import StreamedBender
from cvmeasure.driver.transport import open_link
from cvmeasure.testing.double import FakeTinyG

__all__ = ["simulated_bender"]


def simulated_bender(
    *,
    params: Any = None,
    effects: Sequence[Any] = (),
    speedup: float = 200.0,
    faults: Sequence[Any] = (),
) -> StreamedBender:
    """The TinyG double on a fresh pseudo-terminal, behind the streamer.

    The double simulates the machine with :mod:`cvmeasure.sim` (``params``,
    ``effects``); moves run ``speedup`` times faster than the real machine;
    ``faults`` (:class:`~cvmeasure.testing.double.Fault`) are injected.
    ``bender.double`` is the :class:`~cvmeasure.testing.double.FakeTinyG`;
    ``bender.close()`` stops it.
    """
    double = FakeTinyG(
        speedup=speedup, sim_params=params, sim_effects=effects, faults=faults
    ).start()
    try:
        link = open_link("sim://", double=double)
    except BaseException:
        double.close()
        raise
    return StreamedBender(link, double=double)
