"""Stamps for every output: which command, which version, when, on what."""

from __future__ import annotations

import datetime as _dt
import platform
import sys
from typing import Any

import numpy as np

from cvmeasure import __version__

__all__ = ["provenance"]


def provenance(argv: list[str] | None = None) -> dict[str, Any]:
    """A small dict recording how an output was made (command line, versions, time)."""
    import cv2  # here, not at the top: trials-only commands need no OpenCV (docs/design/imports.md)

    return {
        "generated_by": f"cvmeasure {__version__}",
        "command": " ".join(argv if argv is not None else sys.argv),
        "time_utc": _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        "python": platform.python_version(),
        "opencv": cv2.__version__,
        "numpy": np.__version__,
    }
