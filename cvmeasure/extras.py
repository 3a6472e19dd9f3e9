"""Optional extras: the core install measures photos; hardware and scale are extras.

``cvmeasure[camera]`` (python-gphoto2: a DSLR on USB), ``cvmeasure[raw]`` (rawpy: camera
RAW files), ``cvmeasure[cluster]`` (dask.distributed: ``batch --scheduler``),
``cvmeasure[all]``. Code that needs one imports it through :func:`require`, so a missing
extra is one line naming what to install (an :class:`~cvmeasure.errors.InputError`: the
CLI exits 2) instead of a traceback.
"""

from __future__ import annotations

import importlib
from types import ModuleType

from cvmeasure.errors import InputError

__all__ = ["EXTRAS", "MissingExtraError", "require"]

#: Each extra and the modules it provides.
EXTRAS: dict[str, tuple[str, ...]] = {
    "camera": ("gphoto2",),
    "raw": ("rawpy",),
    "cluster": ("distributed", "dask"),
}


class MissingExtraError(InputError):
    """An optional extra is not installed; the message names it and how to install it."""

    def __init__(self, source: str, extra: str, module: str) -> None:
        self.extra = extra
        self.module = module
        super().__init__(
            source,
            f"needs the optional extra '{extra}' ({module} is not installed): "
            f"pip install 'cvmeasure[{extra}]'",
        )


def require(module: str, extra: str, source: str) -> ModuleType:
    """Import ``module`` of the optional ``extra``; ``source`` names what needed it.

    >>> require("json", "raw", "x.dng").__name__
    'json'
    """
    try:
        return importlib.import_module(module)
    except ImportError:
        raise MissingExtraError(source, extra, module) from None
