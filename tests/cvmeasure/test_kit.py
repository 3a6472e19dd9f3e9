import itertools
import json
from dataclasses import replace

import colour
import numpy as np
import pytest

from cvmeasure.errors import InputError
from cvmeasure.kit import ROLES, HeightsPose, MarkerKit, default_kit, srgb8_to_lab_d65


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


def test_the_heights_pose_roundtrips_and_matches_only_its_own_plane():
    """The plane a kit's heights were measured through: read back the same, the same pose
    matched (to the JSON's digits), one measured again (0.01 mm, 1e-5 rad off) not; a kit
    without it (every kit before it) reads as before."""
    pose = HeightsPose((0.123456789012, -0.2, 3.1), (-70.123456789, 40.0, 556.5))
    kit = replace(default_kit(), heights_pose=pose)
    data = json.loads(json.dumps(kit.to_dict()))
    back = MarkerKit.from_dict(data)
    assert back == kit
    assert back.heights_pose.matches(np.array(pose.rvec), np.array(pose.tvec_mm))
    assert not back.heights_pose.matches(pose.rvec, np.add(pose.tvec_mm, [0.01, 0.0, 0.0]))
    assert not back.heights_pose.matches(np.add(pose.rvec, [0.0, 1e-5, 0.0]), pose.tvec_mm)
    assert kit.flat().heights_pose is None
    assert "heights_pose" not in default_kit().to_dict()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        ([1, 2, 3], "heights_pose must be an object with rvec and tvec_mm"),
        ({"rvec": [0, 0], "tvec_mm": [0, 0, 500]}, "heights_pose.rvec must be three finite"),
        ({"rvec": [0, 0, 0], "tvec_mm": [0, "x", 500]}, "heights_pose.tvec_mm must be three"),
    ],
)
def test_a_bad_heights_pose_is_named(value, message):
    data = default_kit().to_dict()
    data["heights_pose"] = value
    with pytest.raises(InputError, match=f"kit.json: {message}"):
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


def test_one_truth_sheet_kit_renderer_and_docs_agree(tmp_path, capsys):
    """The spec's kit rule: the printed sheet, the built-in kit, `render bender`'s default
    and the docs tell one story (markers on caps at the kit's heights; flat is an option)."""
    import re
    from pathlib import Path

    from cvmeasure.cli import main
    from cvmeasure_calib_targets.markers import write_kit_sheet

    kit = default_kit()
    assert kit.has_heights
    svg = write_kit_sheet(kit, tmp_path / "kit.svg").read_text()
    assert "glue each on its cap" in svg and "glue flat" not in svg
    for m in kit.markers:
        assert f"face {m.height_mm:g} mm above the plate" in svg
    flat_svg = write_kit_sheet(kit.flat(), tmp_path / "flat.svg").read_text()
    assert "glue flat on the top plate" in flat_svg and "above the plate" not in flat_svg
    args = ["render", "bender", "--pin-deg", "40", "--bend-deg", "30", "--scale", "0.1"]
    assert main([*args, "-o", str(tmp_path / "r")]) == 0
    truth = json.loads((tmp_path / "r" / "bender.truth.json").read_text())
    assert {r: truth["markers"][r]["height_mm"] for r in ROLES} == {
        r: kit.height_mm(r) for r in ROLES
    }
    assert main([*args, "--flat-kit", "-o", str(tmp_path / "f")]) == 0
    truth = json.loads((tmp_path / "f" / "bender.truth.json").read_text())
    assert all(truth["markers"][r]["height_mm"] == 0.0 for r in ROLES)
    assert "height_mm" not in json.dumps(truth["kit"])
    assert main(["targets", "markers", "--format", "json", "--flat-kit"]) == 0
    assert "height_mm" not in capsys.readouterr().out
    docs = (Path(__file__).resolve().parents[2] / "docs" / "conventions.md").read_text()
    said = re.search(r"The built-in kit `seed-5` gives[^.]*\(([^)]*)\)", docs).group(1)
    assert (
        " ".join(said.split())
        == "origin and axis caps 12 mm, pin cap 18 mm, wire clips 8.5 mm, wire axis 5 mm"
    )
    assert [kit.height_mm(r) for r in ROLES] == [12.0, 12.0, 18.0, 8.5, 8.5]
    assert kit.wire_axis_height_mm == 5.0
