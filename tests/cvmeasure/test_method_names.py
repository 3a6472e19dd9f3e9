"""Method names: the older names read from scripts and result files map to the current ones."""

from cvmeasure.contracts import MachinePhotoResult
from cvmeasure.method_names import (
    MARKER_METHODS,
    PART_METHODS,
    marker_method,
    part_method,
)


def test_older_names_map_to_the_current_ones():
    assert [part_method(n) for n in ("ours", "ellipse", "sagitta")] == list(PART_METHODS)
    assert [marker_method(n) for n in ("ours", "seed")] == list(MARKER_METHODS)
    # current names pass unchanged
    assert [part_method(n) for n in PART_METHODS] == list(PART_METHODS)
    assert [marker_method(n) for n in MARKER_METHODS] == list(MARKER_METHODS)


def _record(method: str | None) -> dict:
    d = {
        "pin_angle_deg": 10.0,
        "bend_angle_deg": 5.0,
        "markers": {},
        "uncertainty_deg": {"pin_angle_deg": 0.1, "bend_angle_deg": 0.1},
    }
    if method is not None:
        d["method"] = method
    return d


def test_a_machine_photo_record_with_an_older_method_name_reads_back_with_the_current_one():
    seed = MachinePhotoResult.from_dict(_record("seed"))
    assert seed.method == "seed_hough"
    assert seed.to_dict()["method"] == "seed_hough"
    # the default method is left out of the record and read back as the default
    default = MachinePhotoResult.from_dict(_record("ours"))
    assert default.method == "edge_fit" and "method" not in default.to_dict()
    assert MachinePhotoResult.from_dict(_record(None)).method == "edge_fit"
