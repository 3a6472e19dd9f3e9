"""Optional extras: the core measures photos without them; a missing one is one line, exit 2."""

from __future__ import annotations

import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from cvmeasure.batch import _dask_client
from cvmeasure.cli import main
from cvmeasure.driver.capture import GPhoto2Capture
from cvmeasure.extras import EXTRAS, MissingExtraError

ROOT = Path(__file__).resolve().parents[2]


def _without(monkeypatch, *modules: str) -> None:
    for name in modules:
        monkeypatch.setitem(sys.modules, name, None)  # import raises ImportError


def test_core_install_has_no_extra():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    core = " ".join(project["dependencies"])
    for modules in EXTRAS.values():
        for module in modules:
            assert module not in core
    extras = project["optional-dependencies"]
    assert {"camera", "raw", "cluster", "all"} <= set(extras)
    (everything,) = extras["all"]
    assert {"camera", "raw", "cluster"} <= set(everything.split("[")[1].rstrip("]").split(","))


def test_measuring_imports_no_extra():
    code = (
        "import sys, cvmeasure.api, cvmeasure.cli.measure, cvmeasure.cli.part; "
        "print(sorted(m for m in ('rawpy', 'gphoto2', 'distributed', 'dask') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_raw_photo_without_the_raw_extra(tmp_path, monkeypatch, capsys):
    _without(monkeypatch, "rawpy")
    photo = tmp_path / "bend.dng"
    photo.write_bytes(b"II*\x00" + bytes(64))
    assert main(["measure", str(photo), "--json"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert str(photo) in err[0] and "pip install 'cvmeasure[raw]'" in err[0]


def test_camera_without_the_camera_extra(tmp_path, monkeypatch):
    _without(monkeypatch, "gphoto2")
    with pytest.raises(MissingExtraError, match=r"cvmeasure\[camera\]") as info:
        GPhoto2Capture(tmp_path)
    assert info.value.extra == "camera"


def test_scheduler_without_the_cluster_extra(monkeypatch):
    _without(monkeypatch, "distributed")
    with pytest.raises(MissingExtraError, match=r"--scheduler: .*cvmeasure\[cluster\]"):
        _dask_client("tcp://127.0.0.1:8786")
