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
