"""Self-contained HTML reports of results files (plots and overlay thumbnails embedded).

:func:`build_report` turns per-photo records into one HTML page with no
external resources; :mod:`cvmeasure.report.plots` draws the PNG plots (also
used by ``cvmeasure agreement --plot``); :mod:`cvmeasure.report.thumbnails`
draws what was measured on a small copy of each photo.

The names load on first use (PEP 562, ``docs/design/imports.md``): the commands that
only print a warning summary (:mod:`cvmeasure.report.console`) must not pay for the
report's part tracking, OpenCV and SciPy.
"""

from __future__ import annotations

from cvmeasure._lazy import lazy_names

#: Each public name and the module that defines it.
_NAMES = {
    "build_report": "cvmeasure.report.html",
    "data_uri": "cvmeasure.report.html",
    "bland_altman_png": "cvmeasure.report.plots",
    "find_photo": "cvmeasure.report.thumbnails",
    "overlay_thumbnail": "cvmeasure.report.thumbnails",
}

__all__ = ["build_report", "data_uri", "bland_altman_png", "find_photo", "overlay_thumbnail"]


__getattr__, __dir__ = lazy_names(__name__, globals(), _NAMES)
