"""The wire's resolution check: rendered part photos at low and normal resolution."""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.camera_model import save_camera
from cvmeasure.cli import main
from cvmeasure.errors import InputError
from cvmeasure.fileio import atomic_write_json
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import PartOptions
from cvmeasure.part.resolution import (
    MIN_PX_PER_RADIUS,
    WARN_PX_PER_RADIUS,
    coarse_line_hint,
    resolution_warning,
    wire_resolution,
)
from cvmeasure.warning import StageWarning, has_code

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
CODE = "part_low_resolution"


@functools.cache
def _photo(sheet: str, scale: float):
    """R60 120 deg in 10 chords of 2 mm wire from 900 mm (0.129 mm/px at scale 1)."""
    return cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(60.0, 120.0, 10), board=BOARD, sheet=sheet, seed=1,
        scale=scale,
    )  # fmt: skip


def _bend_errors(photo, m) -> np.ndarray:
    """Measured - true vertex bends (deg); the truth's direction of travel is arbitrary."""
    true = np.asarray(photo.truth["segment_bend_deg"], dtype=float)
    e1, e2 = m.vertex_bend_deg - true, m.vertex_bend_deg + true[::-1]
    return e1 if np.max(np.abs(e1)) <= np.max(np.abs(e2)) else e2


def _measure(photo):
    return measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=10))


def test_thresholds():
    # a stated diameter over the plane's scale; else the measured half-width read as a radius
    stated = wire_resolution(1.0, 0.43, 2.0, "dark")
    assert stated.stated and stated.px_per_radius == pytest.approx(1.0 / 0.43)
    assert wire_resolution(2.4, 0.3, None, "dark").px_per_radius == pytest.approx(3.0)
    assert wire_resolution(2.4, 0.3, None, "light").px_per_radius == pytest.approx(2.4)
    low = resolution_warning(stated, "p.jpg")
    assert low is not None and low.code == CODE and low.subject == "p.jpg"
    assert "2.33 px per wire radius" in low.message and "stated diameter" in low.message
    assert resolution_warning(wire_resolution(3.0, 0.3, None, "light"), "p.jpg") is None
    with pytest.raises(InputError, match="p.jpg: .*move the camera closer"):
        resolution_warning(wire_resolution(0.9 * MIN_PX_PER_RADIUS, 0.5, None, "light"), "p.jpg")
    with pytest.raises(InputError):
        resolution_warning(wire_resolution(float("nan"), 0.5, None, "dark"), "p.jpg")
    assert WARN_PX_PER_RADIUS > MIN_PX_PER_RADIUS


def test_low_resolution_light_sheet_is_warned():
    # 0.64 mm/px: about 1.6 px per wire radius; the centreline follows the shadow along a
    # stretch and vertex bends are off by degrees, beyond their sigmas
    photo = _photo("light", 0.2)
    m = _measure(photo)
    assert has_code(m.warnings, CODE)
    err = _bend_errors(photo, m)
    assert np.max(np.abs(err) / m.vertex_bend_sigma_deg) > 3.0  # what the warning is for


def test_low_resolution_dark_sheet_is_warned():
    m = _measure(_photo("dark", 0.3))  # about 1.9 px per (apparent) wire radius
    assert has_code(m.warnings, CODE)


@pytest.mark.parametrize("sheet", ["dark", "light"])
def test_normal_resolution_not_warned_and_sigma_covers(sheet):
    photo = _photo(sheet, 0.5)  # 0.26 mm/px: 3-4 px per apparent wire radius
    m = _measure(photo)
    assert not has_code(m.warnings, CODE)
    err = _bend_errors(photo, m)
    assert np.all(np.abs(err) <= 3.0 * m.vertex_bend_sigma_deg), (err, m.vertex_bend_sigma_deg)


@pytest.fixture(scope="module")
def low_files(tmp_path_factory):
    """Files of the warned photo (dark sheet, 0.43 mm/px) and a refused one (light, same)."""
    folder = tmp_path_factory.mktemp("low_resolution")
    warned, _ = _photo("dark", 0.3).save(folder / "warned")
    refused, _ = _photo("light", 0.3).save(folder / "refused")
    save_camera(folder / "camera.json", _photo("dark", 0.3).camera)
    atomic_write_json(folder / "board.json", BOARD.to_dict())
    return folder, warned, refused


def _part_args(folder, photo) -> list[str]:
    return [
        "part", str(photo), "--board", str(folder / "board.json"),
        "--camera", str(folder / "camera.json"), "--divisions", "10",
    ]  # fmt: skip


def test_warning_reaches_console_json_and_report(low_files, capsys):
    folder, warned, _ = low_files
    assert main(_part_args(folder, warned)) == 0
    assert "warning: part_low_resolution:" in capsys.readouterr().out
    assert main([*_part_args(folder, warned), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert CODE in [w["code"] for w in result["warnings"]]
    records = folder / "results.jsonl"
    args = ["batch", str(warned), "--kind", "part", "--board", str(folder / "board.json")]
    args += ["--camera", str(folder / "camera.json"), "--divisions", "10", "--workers", "1"]
    assert main([*args, "-o", str(records), "--quiet"]) == 0
    (record,) = [json.loads(line) for line in records.read_text().splitlines()]
    assert CODE in [StageWarning.from_json(w).code for w in record["warnings"]]
    assert main(["report", str(records), "-o", str(folder / "r.html"), "--quiet"]) == 0
    assert CODE in (folder / "r.html").read_text(encoding="utf-8")


def test_wire_too_fine_is_refused(low_files, capsys):
    # light sheet at 0.43 mm/px: the centreline's half-width collapses to under a pixel
    # (its bends were 1.3 deg off at 5 sigma): refused, exit 2, one line naming the photo
    folder, _, refused = low_files
    assert main(_part_args(folder, refused)) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert str(refused) in err and "px per wire radius" in err and "closer" in err


def test_coarse_photo_that_loses_the_wire_says_so():
    # light sheet at 0.51 mm/px: the wire and its shadow are one asymmetric line, refused as
    # no wire; the refusal says the photo is too coarse and what to do
    assert coarse_line_hint(WARN_PX_PER_RADIUS, 0.3, "light") == ""
    assert "too coarse" in coarse_line_hint(1.5, 0.5, "light")
    photo = _photo("light", 0.25)
    with pytest.raises(InputError, match="no wire found.*too coarse.*move the camera closer"):
        _measure(photo)
