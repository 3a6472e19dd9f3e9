"""A catalogue name is tested against the library's terms on the data's noise.

A once-per-revolution runout of the head (the pin's orbit off the head's axis) looks like
a scale over the angles a session bends: the data decide between them only when the
difference of their fits is beyond the noise; otherwise a tie is reported with the
bends that separate them. Sessions from :mod:`cvmeasure.sim` (the tests' own seeds).
"""

from __future__ import annotations

import numpy as np

from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import Cause, diagnose
from cvmeasure.driver.session import SessionConfig, nominal_pin_for_loaded_deg
from cvmeasure.sim import Effect, SimParams, simulate

NOISE_DEG = 0.03
#: The runout's phase (rad): over 15-120 deg of head rotation it then rises like a scale.
PHASE = 1.8


def _bend(
    cmd: np.ndarray, rng: np.random.Generator, runout_deg: float, effects: tuple[Effect, ...]
) -> list[np.ndarray]:
    """Loaded, released and pin angles (deg, noisy) of ``cmd`` bent on the simulation; the
    head turns by the command plus a once-per-revolution runout of ``runout_deg``, zero at
    home (where the head is referenced)."""
    turn = np.radians(np.abs(cmd))
    head = cmd + np.sign(cmd) * runout_deg * (np.sin(turn - PHASE) + np.sin(PHASE))
    res = simulate(head, SimParams(), effects)
    return [
        c + rng.normal(0.0, NOISE_DEG, cmd.size)
        for c in (res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg)
    ]


def _session(
    seed: int, runout_deg: float = 0.0, effects: tuple[Effect, ...] = (), more: tuple = ()
) -> TrialTable:
    """A standard session (then the bends ``more``) as the table records them."""
    rng = np.random.default_rng(seed)
    plan = SessionConfig(mode="standard").plan()
    cmd = np.array([round(nominal_pin_for_loaded_deg(a, d), 3) for d, a in plan] + list(more))
    loaded, released, pin = _bend(cmd, rng, runout_deg, effects)
    return TrialTable.from_arrays(cmd, loaded, released, measured_pin_deg=pin, source="sim")


def test_a_head_runout_is_not_given_a_catalogue_name_alone():
    result = diagnose(_session(3701, runout_deg=0.6))
    named_alone = result.cause.named and not any(Cause.parse(t) is None for t in result.tie)
    assert not named_alone, (result.cause, result.tie)
    if result.cause.named:  # tied with the runout: the follow-up plans against the term
        assert "gear_runout_360" in result.tie
        assert result.follow_up is not None
        assert "gear_runout_360" in result.follow_up.rivals
        assert result.follow_up.expected_separation_se > 1.0
        # its bends, run on the same machine after the session's, give no catalogue name
        # alone either (the head's runout is none)
        again = diagnose(
            _session(3701, runout_deg=0.6, more=result.follow_up.commanded_pin_deg),
            follow_up=False,
        )
        alone = again.cause.named and not any(Cause.parse(t) is None for t in again.tie)
        assert not alone, (again.cause, again.tie)


def test_a_scale_beyond_the_noise_is_named_alone():
    result = diagnose(_session(3702, effects=(Effect("scale", 0.03),)), follow_up=False)
    assert result.cause == Cause.of(["scale"])
    assert "gear_runout_360" not in result.tie
    lo, hi = result.intervals["scale"]
    assert lo <= 0.03 <= hi
