"""Packaging: the distribution owns only ``cvmeasure*`` names and lists every package.

The folders ``datasets/`` (the photo lab) and ``calib_targets/`` install as
``cvmeasure_datasets`` and ``cvmeasure_calib_targets``: installing cvmeasure must
never shadow another distribution's top-level package (Hugging Face's
``datasets`` is widely installed) nor be shadowed by it.
"""

from __future__ import annotations

import os
import site
import subprocess
import sys
import tomllib
import venv
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
FOLDERS = {
    "cvmeasure": "cvmeasure",
    "cvmeasure_datasets": "datasets",
    "cvmeasure_calib_targets": "calib_targets",
}


def _pyproject() -> dict:
    return tomllib.loads((REPO / "pyproject.toml").read_text())


def test_every_package_folder_is_listed_and_every_name_is_ours():
    setup = _pyproject()["tool"]["setuptools"]
    listed = set(setup["packages"])
    assert setup["package-dir"] == {
        name: folder for name, folder in FOLDERS.items() if name != folder
    }
    on_disk = set()
    for name, folder in FOLDERS.items():
        for d, dirs, files in os.walk(REPO / folder):
            dirs[:] = [x for x in dirs if x != "__pycache__"]
            if "__init__.py" in files:
                rel = Path(d).relative_to(REPO / folder)
                on_disk.add(".".join((name, *rel.parts)))
    assert listed == on_disk
    assert all(name.split(".")[0].startswith("cvmeasure") for name in listed)


def test_no_stage_imports_the_lab_and_the_lab_is_installed_under_our_name():
    """Import arrows run downward: only the CLI (above the stages) reaches the lab."""
    offenders = []
    for path in (REPO / "cvmeasure").rglob("*.py"):
        rel = path.relative_to(REPO)
        if rel.parts[1] == "cli":
            continue
        text = path.read_text()
        for needle in (
            "import cvmeasure_datasets",
            "from cvmeasure_datasets",
            "import datasets",
            "from datasets",
        ):
            if needle in text:
                offenders.append(f"{rel}: {needle}")
    assert offenders == []


@pytest.mark.slow
def test_installed_beside_hugging_face_datasets(tmp_path):
    """A venv with Hugging Face ``datasets`` and a built (non-editable) cvmeasure: both import,
    each is its own, from any working folder."""
    env_dir = tmp_path / "venv"
    venv.EnvBuilder(system_site_packages=True, with_pip=True).create(env_dir)
    py = env_dir / "bin" / "python"
    _see_this_venvs_packages(py)
    pip = [str(py), "-m", "pip", "install", "-q", "--disable-pip-version-check"]
    hf = subprocess.run([*pip, "datasets"], capture_output=True, text=True, timeout=900)
    if hf.returncode != 0:
        pytest.skip(f"cannot install Hugging Face datasets from the registry: {hf.stderr[-300:]}")
    ours = subprocess.run(
        [*pip, "--no-deps", "--no-build-isolation", str(REPO)]
        if _has_build_backend(py)
        else [*pip, "--no-deps", str(REPO)],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert ours.returncode == 0, ours.stderr[-2000:]
    probe = (
        "import datasets, cvmeasure, cvmeasure_datasets, cvmeasure_calib_targets\n"
        "from cvmeasure_datasets import render_bender_photo\n"
        "assert hasattr(datasets, 'load_dataset'), datasets.__file__\n"
        "assert 'site-packages' in cvmeasure_datasets.__file__, cvmeasure_datasets.__file__\n"
        "assert 'site-packages' in datasets.__file__, datasets.__file__\n"
        "p = render_bender_photo(pin_angle_deg=-40.0, bend_angle_deg=30.0, scale=0.1)\n"
        "print(datasets.__file__, cvmeasure_datasets.__file__, p.bgr.shape)\n"
    )
    run = subprocess.run(
        [str(py), "-c", probe],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
        env={**os.environ, "PYTHONPATH": ""},
    )
    assert run.returncode == 0, run.stderr[-2000:]
    hf_file, lab_file, _ = run.stdout.split(" ", 2)
    assert "cvmeasure_datasets" in lab_file and "/datasets/" in hf_file
    assert str(REPO) not in lab_file  # the built copy, not this checkout


def _see_this_venvs_packages(py: Path) -> None:
    """Let the venv at ``py`` import the packages of the environment running the tests.

    ``system_site_packages`` reaches the base interpreter's packages only; run from a
    virtual environment (as the README sets up) the dependencies live in it. A ``.pth``
    line adds its site-packages after the new venv's own; the ``.pth`` files in them are
    not run, so the checkout's editable cvmeasure stays out of sight.
    """
    if sys.prefix == sys.base_prefix:
        return
    ask = "import sysconfig; print(sysconfig.get_paths()['purelib'])"
    own = subprocess.run([str(py), "-c", ask], capture_output=True, text=True, check=True)
    lines = "\n".join(site.getsitepackages()) + "\n"
    (Path(own.stdout.strip()) / "outer_environment.pth").write_text(lines)


def _has_build_backend(py: Path) -> bool:
    check = subprocess.run(
        [
            str(py),
            "-c",
            "import setuptools, sys; sys.exit(int(setuptools.__version__.split('.')[0]) < 68)",
        ],
        capture_output=True,
    )
    return check.returncode == 0
