"""Shared fixtures of the diagnosis tests: a calibration session bent on the simulation."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import pytest

from cvmeasure.contracts import TrialTable
from cvmeasure.driver.session import SessionConfig, nominal_pin_for_loaded_deg
from cvmeasure.sim import Effect, SimParams, simulate


def _bent_session(
    effects: Sequence[Effect] = (),
    *,
    params: SimParams | None = None,
    noise_deg: float = 0.05,
    seed: int = 0,
) -> TrialTable:
    """A standard session's commands bent on the simulation (``params``, default the
    built-in machine) with ``effects``; the loaded, released and pin readings each with
    ``noise_deg`` of Gaussian noise drawn from ``seed`` in that order."""
    plan = SessionConfig(mode="standard").plan()
    cmd = np.array([round(nominal_pin_for_loaded_deg(a, d), 3) for d, a in plan])
    sim = simulate(cmd, params if params is not None else SimParams(), effects)
    rng = np.random.default_rng(seed)
    loaded, released, pin = (
        v + rng.normal(0.0, noise_deg, cmd.size)
        for v in (sim.loaded_bend_deg, sim.unloaded_bend_deg, sim.pin_angle_deg)
    )
    return TrialTable.from_arrays(cmd, loaded, released, measured_pin_deg=pin)


@pytest.fixture(scope="session")
def bent_session():
    """``bent_session(effects=(), params=, noise_deg=0.05, seed=0)``: a standard session
    bent on the simulation, as its trials table."""
    return _bent_session
