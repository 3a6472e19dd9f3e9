"""A command's start-up: what its path imports, the packages' late names, the collector.

Which modules load late and why: ``docs/design/imports.md``.
"""

from __future__ import annotations

import gc
import importlib
import subprocess
import sys

import pytest

from cvmeasure.cli.startup import libraries_loading


def _loaded(imports: str, names: tuple[str, ...]) -> list[str]:
    """Of ``names``, the modules loaded in a fresh interpreter after ``imports``."""
    code = f"import sys; {imports}; print(sorted(m for m in {names!r} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return eval(out.stdout)  # noqa: S307 - our own child's printed list


def test_a_bender_photo_path_loads_no_scipy_and_no_part_stages():
    imports = (
        "import cvmeasure.cli.measure, cvmeasure.markers.measure, cvmeasure.report.console, "
        "cvmeasure.kit, cvmeasure.camera_model, cvmeasure.board, cvmeasure.imageio"
    )
    heavy = (
        "scipy",
        "skimage",
        "matplotlib",
        "cvmeasure.api",
        "cvmeasure.part",
        "cvmeasure.diagnose",
    )
    assert _loaded(imports, heavy) == []


def test_a_trials_path_loads_no_opencv():
    imports = "import cvmeasure.contracts, cvmeasure.diagnose, cvmeasure.provenance, cvmeasure.sim"
    assert _loaded(imports, ("cv2", "cvmeasure.plane_model", "scipy.stats")) == []


def test_a_part_path_loads_no_scipy_stats():
    assert _loaded("import cvmeasure.part.measure", ("scipy.stats", "scipy.signal")) == []


@pytest.mark.parametrize("package", ["cvmeasure.lens", "cvmeasure.report", "cvmeasure.contracts"])
def test_every_late_name_resolves_and_is_listed(package):
    module = importlib.import_module(package)
    assert set(module.__all__) <= set(dir(module))
    for name in module.__all__:
        value = getattr(module, name)
        if callable(value):  # a function or class: the module it was loaded from
            assert value.__module__.startswith("cvmeasure."), name
    with pytest.raises(AttributeError):
        module.not_a_name  # noqa: B018


def test_libraries_loading_freezes_the_imports_and_restores_the_collector():
    was = gc.isenabled()
    gc.enable()
    before = gc.get_freeze_count()
    try:
        with libraries_loading():
            assert not gc.isenabled()
            kept = [[i] for i in range(1000)]  # objects made while loading
        assert gc.isenabled()
        assert gc.get_freeze_count() >= before + len(kept)
        gc.disable()
        with libraries_loading():
            pass
        assert not gc.isenabled()  # a paused collector stays paused
    finally:
        gc.unfreeze()
        if was:
            gc.enable()
        else:
            gc.disable()
