"""The diagnosis reads a session as it is measured: the pin from the origin marker, and
a wire whose strength differs by direction moving its loaded leg too."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import diagnose
from cvmeasure.driver.session import SessionConfig, nominal_pin_for_loaded_deg
from cvmeasure.sim import Effect, SimParams, simulate

NOISE_DEG = 0.05


def _session(effect: Effect, seed: int) -> TrialTable:
    """A standard session's commands bent on the simulation with ``effect``, every reading
    (loaded, released, pin on the loaded photo) with ``NOISE_DEG`` of noise."""
    plan = SessionConfig(mode="standard").plan()
    cmd = np.array([round(nominal_pin_for_loaded_deg(a, d), 3) for d, a in plan])
    res = simulate(cmd, SimParams(), [effect])
    rng = np.random.default_rng(seed)
    loaded, unloaded, pin = (
        x + rng.normal(0.0, NOISE_DEG, cmd.size)
        for x in (res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg)
    )
    return TrialTable.from_arrays(cmd, loaded, unloaded, measured_pin_deg=pin, source="sim")


@pytest.mark.parametrize("offset_mm", [0.35, -0.4])
def test_an_axis_offset_read_from_the_marker_is_named_with_its_size(offset_mm):
    result = diagnose(_session(Effect("axis_offset", offset_mm), 7), follow_up=False)
    assert result.cause.primary == "axis_offset"
    lo, hi = result.intervals["axis_offset_mm"]
    assert lo <= offset_mm <= hi  # the 95 % interval holds the truth
    assert abs(result.params["axis_offset_mm"] - offset_mm) < 0.1  # mm


def test_a_strength_by_direction_that_moves_the_loaded_leg_is_named_asymmetry():
    shape = (("loaded_deg", -1.0),)
    result = diagnose(_session(Effect("springback_asymmetry", 0.45, shape), 11), follow_up=False)
    assert result.causes == ("springback_asymmetry",)  # no offset to make up the leg
    lo, hi = result.intervals["asymmetry"]
    assert lo <= 0.45 <= hi
    misfit = result.to_dict()["lack_of_fit"]
    assert not (misfit and misfit["refused"])
