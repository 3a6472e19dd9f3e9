"""The typed cause of a diagnosis: its label as the JSON writes it, read back."""

from __future__ import annotations

import pytest

from cvmeasure.diagnose import Cause, CauseKind


@pytest.mark.parametrize(
    "label", ["none", "unexplained", "backlash", "axis_offset + compliance", "scale + offset"]
)
def test_label_round_trips(label):
    cause = Cause.from_label(label)
    assert cause.label == label
    assert Cause.from_label(cause.label) == cause


def test_a_pair_is_equal_in_either_order_and_keeps_its_own_order():
    ab, ba = Cause.of(("backlash", "offset")), Cause.from_label("offset + backlash")
    assert ab == ba and hash(ab) == hash(ba) and len({ab, ba}) == 1
    assert ab.label == "backlash + offset" and ba.label == "offset + backlash"
    assert ab.primary == "backlash" and ba.primary == "offset"  # the JSON's `cause`
    assert "offset" in ab and "drift" not in ab
    assert ab != Cause.of(("backlash",)) and ab != Cause.of(("backlash", "drift"))


def test_the_states_without_a_name():
    assert Cause.of(()) == Cause.none() and Cause.none().kind is CauseKind.NONE
    assert Cause.none() != Cause.unexplained()
    assert not Cause.none().named and not Cause.unexplained().named
    assert Cause.none().effects == Cause.unexplained().effects == ()
    assert Cause.unexplained().primary == "unexplained"


@pytest.mark.parametrize("label", ["warm_up_45", "backlash + warm_up_45", "backlash + backlash"])
def test_names_outside_the_catalogue_are_refused(label):
    with pytest.raises(ValueError):
        Cause.from_label(label)
    assert Cause.parse(label) is None
    assert Cause.parse("drift") == Cause.of(("drift",))


def test_comparing_with_text_is_an_error_not_a_silent_false():
    with pytest.raises(TypeError):
        _ = Cause.none() == "none"
