"""The public API: ``import cvmeasure`` gives one verb per job, documented, loaded lazily."""

from __future__ import annotations

import json
import pydoc
import subprocess
import sys

import numpy as np
import pytest

import cvmeasure
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.errors import InputError


def test_import_is_light():
    """The CLI imports the package for --help: that must not load OpenCV or the stages."""
    code = "import sys, cvmeasure; print('cv2' in sys.modules, 'cvmeasure.api' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]


def test_help_shows_every_verb_and_an_example():
    text = pydoc.render_doc(cvmeasure, renderer=pydoc.plaintext)
    for name in cvmeasure.__all__:
        assert name in text, name
    assert "measure_part(" in text and "cvmeasure.save(" in text
    assert set(dir(cvmeasure)) >= set(cvmeasure.__all__)
    with pytest.raises(AttributeError):
        cvmeasure.not_a_verb  # noqa: B018


def test_the_lazy_names_are_the_api_modules_names():
    """``cvmeasure`` lists the API's names without importing it (start-up time): the two
    lists must stay the same."""
    import cvmeasure.api

    assert [n for n in cvmeasure.__all__ if n != "__version__"] == cvmeasure.api.__all__


def test_save_and_load_round_trip(tmp_path):
    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    assert cvmeasure.load_board(cvmeasure.save(tmp_path / "b.json", board)) == board
    kit = cvmeasure.load_kit()
    assert cvmeasure.load_kit(cvmeasure.save(tmp_path / "k.json", kit)) == kit
    with pytest.raises(TypeError, match="no file format"):
        cvmeasure.save(tmp_path / "x.json", object())


def test_trials_to_material_to_gcode(tmp_path):
    """fit_material takes the trials CSV a session writes; gcode_for uses its compensation."""
    rows = ["trial,commanded_pin_deg,loaded_bend_deg,unloaded_bend_deg"]
    for i, a in enumerate((10, 20, 30, 45, 60, 90, 110), start=1):
        for s in (1, -1):
            loaded = s * a
            rows.append(f"{i}{'ab'[s < 0]},{s * (a + 5)},{loaded},{loaded - s * 0.08 * a}")
    csv = tmp_path / "trials.csv"
    csv.write_text("\n".join(rows) + "\n", encoding="utf-8")
    material = cvmeasure.fit_material(csv)
    path = cvmeasure.save(tmp_path / "material.json", material)
    assert json.loads(path.read_text())["name"] == "trials"
    svg = tmp_path / "v.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
        'viewBox="0 0 100 100"><polyline points="0,0 50,0 50,50" fill="none" '
        'stroke="black"/></svg>',
        encoding="utf-8",
    )
    job = cvmeasure.gcode_for(svg, path)
    assert len(job.pin_deg) == 1
    # a 90 deg bend with 8 % springback: the pin goes past 90 deg by about the springback
    assert 90.0 < abs(job.pin_deg[0]) < 120.0
    assert cvmeasure.save(tmp_path / "j.gcode", job).read_text() == job.text()


def test_bad_input_names_the_problem(tmp_path):
    with pytest.raises(InputError, match="board and camera, or a plane"):
        cvmeasure.measure_part(np.zeros((10, 10, 3), np.uint8))
    with pytest.raises(InputError, match="camera"):
        cvmeasure.measure_part(
            np.zeros((10, 10, 3), np.uint8), board=CharucoBoardSpec(5, 4, 20.0, 15.0)
        )
    with pytest.raises(InputError, match="missing.jpg"):
        cvmeasure.measure_bender_photo(tmp_path / "missing.jpg")


def test_measure_part_takes_its_options_and_reads_the_old_keywords(monkeypatch):
    """The option keywords of earlier versions set the same PartOptions, with a warning."""
    import cvmeasure.api as api
    from cvmeasure.camera_model import CameraModel

    seen: list = []
    monkeypatch.setattr(api, "_measure_part", lambda *a, **k: seen.append(k["options"]))
    cam = CameraModel((10, 10), np.eye(3), np.zeros(5))
    args = (np.zeros((10, 10, 3), np.uint8),)
    kw = {"board": CharucoBoardSpec(5, 4, 20.0, 15.0), "camera": cam}
    opts = cvmeasure.PartOptions(
        divisions=8, method="seed_sagitta", allow_mirror=False,
        wire=cvmeasure.WireOptions(diameter_mm=2.0), lift=cvmeasure.LiftOptions(shadow=False),
    )  # fmt: skip
    cvmeasure.measure_part(*args, **kw, options=opts)
    cvmeasure.measure_part(*args, **kw)
    assert seen == [opts, cvmeasure.PartOptions()]
    old = {"divisions": 8, "method": "sagitta", "allow_mirror": False}
    with pytest.warns(DeprecationWarning, match=r"wire=WireOptions\(diameter_mm=\.\.\.\)"):
        cvmeasure.measure_part(*args, **kw, **old, wire_diameter_mm=2.0, shadow_lift=False)
    assert seen[-1] == opts  # the older method name read as the current one
    with pytest.raises(TypeError, match="max_lift"):
        cvmeasure.measure_part(*args, **kw, max_lift=2.0)
