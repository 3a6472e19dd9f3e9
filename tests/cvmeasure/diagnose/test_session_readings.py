"""The diagnosis reads a session as it is measured: the pin from the origin marker, and
a wire whose strength differs by direction moving its loaded leg too."""

from __future__ import annotations

import pytest

from cvmeasure.diagnose import diagnose
from cvmeasure.sim import Effect

NOISE_DEG = 0.05


@pytest.mark.parametrize("offset_mm", [0.35, -0.4])
def test_an_axis_offset_read_from_the_marker_is_named_with_its_size(bent_session, offset_mm):
    result = diagnose(
        bent_session((Effect("axis_offset", offset_mm),), noise_deg=NOISE_DEG, seed=7),
        follow_up=False,
    )
    assert result.cause.primary == "axis_offset"
    lo, hi = result.intervals["axis_offset_mm"]
    assert lo <= offset_mm <= hi  # the 95 % interval holds the truth
    assert abs(result.params["axis_offset_mm"] - offset_mm) < 0.1  # mm


def test_a_strength_by_direction_that_moves_the_loaded_leg_is_named_asymmetry(bent_session):
    shape = (("loaded_deg", -1.0),)
    result = diagnose(
        bent_session((Effect("springback_asymmetry", 0.45, shape),), noise_deg=NOISE_DEG, seed=11),
        follow_up=False,
    )
    assert result.causes == ("springback_asymmetry",)  # no offset to make up the leg
    lo, hi = result.intervals["asymmetry"]
    assert lo <= 0.45 <= hi
    misfit = result.to_dict()["lack_of_fit"]
    assert not (misfit and misfit["refused"])
