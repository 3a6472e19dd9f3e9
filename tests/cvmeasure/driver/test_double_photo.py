"""The simulated camera draws the pin where the double's head really is."""

from __future__ import annotations

import pytest

from cvmeasure.driver.session import (
    SessionConfig,
    nominal_pin_for_loaded_deg,
    session_gcode,
)
from cvmeasure.sim import SimParams, parse_effect, simulate
from cvmeasure.testing.bender import simulated_bender
from cvmeasure_datasets.simcapture import double_photo_state


@pytest.mark.parametrize("effect", ["backlash=0.5", "offset=0.8"])
@pytest.mark.parametrize("direction", ["ccw", "cw"])
def test_photo_pin_follows_command_effects(effect, direction):
    # a command effect moves the head off the controller's X: the photo's pin must show
    # it (it was drawn at X, so the pin contradicted the bend and no cause fitted both)
    effects = (parse_effect(effect),)
    config = SessionConfig()
    pin = round(nominal_pin_for_loaded_deg(45.0, direction), 3)
    truth = simulate([pin], SimParams(), effects)
    nominal = simulate([pin])
    bender = simulated_bender(effects=effects, speedup=500.0)
    try:
        bender.run(session_gcode("setup", config))
        bender.run(session_gcode("feed", config) + session_gcode("bend", config, pin_deg=pin))
        state = bender.double.machine_state()
        assert state.pin_deg == pytest.approx(pin, abs=1e-9)  # the controller's X
        assert state.head_deg == pytest.approx(truth.pin_deg[0], abs=1e-9)
        loaded = double_photo_state(bender.double)
        assert loaded.pin_angle_deg == pytest.approx(truth.pin_angle_deg[0], abs=1e-9)
        # the effect moved the pin by more than a photo's noise (~0.01 deg)
        assert abs(loaded.pin_angle_deg - nominal.pin_angle_deg[0]) > 0.4
        bender.run(session_gcode("release", config))
        assert bender.double.machine_state().head_deg == pytest.approx(0.0, abs=1e-9)
    finally:
        bender.close()
