import itertools

import colour
import numpy as np
import pytest

from cvmeasure.errors import InputError
from cvmeasure.kit import ROLES, MarkerKit, default_kit, srgb8_to_lab_d65


def test_spec_example_lab_value():
    # the spec's example: dark green srgb [0, 110, 70] -> lab_d65 [40.6, -37.5, 14.9]
    np.testing.assert_allclose(srgb8_to_lab_d65([0, 110, 70]), [40.6, -37.5, 14.9], atol=0.05)


def test_default_kit_roles_and_separation():
    kit = default_kit()
    assert [m.role for m in kit.markers] == list(ROLES)
    for a, b in itertools.combinations(kit.markers, 2):
        assert colour.delta_E(a.lab_d65, b.lab_d65, method="CIE 2000") > 20


def test_kit_json_roundtrip():
    kit = default_kit()
    assert MarkerKit.from_dict(kit.to_dict()) == kit


def test_wrong_kit_is_named():
    data = default_kit().to_dict()
    data["markers"] = data["markers"][:4]
    with pytest.raises(InputError, match="kit.json: a kit needs exactly one marker per role"):
        MarkerKit.from_dict(data, source="kit.json")


def test_default_kit_has_heights_and_wire_and_they_roundtrip_through_json():
    kit = default_kit()
    assert kit.has_heights
    # the printable kit: pin cap highest, wire clips lowest, all above the wire's axis
    assert kit.height_mm("pin") == 18.0
    assert kit.height_mm("wire_a") == kit.height_mm("wire_b") == 8.5
    assert kit.wire_diameter_mm == 3.0 and kit.wire_axis_height_mm == 5.0
    for m in kit.markers:
        assert m.height_mm > kit.wire_axis_height_mm
    data = kit.to_dict()
    assert data["wire_axis_height_mm"] == 5.0
    assert [m["height_mm"] for m in data["markers"]] == [12.0, 12.0, 18.0, 8.5, 8.5]
    assert MarkerKit.from_dict(data) == kit


def test_a_kit_without_heights_is_flat_and_says_so():
    data = default_kit().to_dict()
    for m in data["markers"]:
        del m["height_mm"]
    del data["wire_diameter_mm"], data["wire_axis_height_mm"]
    kit = MarkerKit.from_dict(data)
    assert not kit.has_heights
    assert kit.height_mm("pin") == 0.0
    assert kit.wire_axis_height_mm is None
    assert "height_mm" not in kit.to_dict()["markers"][0]


@pytest.mark.parametrize(
    ("where", "value", "message"),
    [
        ("marker", -1.0, "height_mm must be a finite length >= 0 mm"),
        ("marker", "tall", "height_mm must be a number of millimetres"),
        ("wire_diameter_mm", 0.0, "wire_diameter_mm must be a finite length"),
        ("wire_axis_height_mm", float("nan"), "wire_axis_height_mm must be a finite length"),
    ],
)
def test_bad_heights_are_named(where, value, message):
    data = default_kit().to_dict()
    if where == "marker":
        data["markers"][2]["height_mm"] = value
    else:
        data[where] = value
    with pytest.raises(InputError, match=f"kit.json: .*{message}"):
        MarkerKit.from_dict(data, source="kit.json")


def test_flat_kit_drops_the_heights_only():
    kit = default_kit()
    flat = kit.flat()
    assert kit.has_heights and not flat.has_heights
    assert flat.height_mm("pin") == 0.0 and flat.wire_axis_height_mm is None
    assert [m.srgb for m in flat.markers] == [m.srgb for m in kit.markers]
    assert flat.wire_diameter_mm == kit.wire_diameter_mm


def test_a_kit_with_some_heights_missing_is_refused_naming_them():
    data = default_kit().to_dict()
    del data["markers"][2]["height_mm"]  # the pin's
    with pytest.raises(InputError, match=r"kit.json: height_mm is given for .* but not for pin"):
        MarkerKit.from_dict(data, source="kit.json")
