"""A command's start-up: its libraries imported without the cyclic collector's passes.

Importing numpy, SciPy and OpenCV creates ~10^5 long-lived objects and almost no
garbage; the cyclic collector's passes while they load (~130 of them) and every later
full pass over them (one during the work, one at exit) cost a short command 0.05-0.1 s of
CPU. A command imports its libraries inside :func:`libraries_loading`, which pauses the
collector and then freezes what was imported (``gc.freeze``: never collected, never
walked again); objects made afterwards are collected as usual.
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

__all__ = ["libraries_loading"]


@contextlib.contextmanager
def libraries_loading() -> Iterator[None]:
    """Run the ``with`` block's imports with the collector paused; freeze their objects."""
    collecting = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        gc.freeze()  # the modules' objects live until exit
        if collecting:
            gc.enable()
