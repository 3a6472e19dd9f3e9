"""Self-contained HTML reports of results files (plots and overlay thumbnails embedded).

:func:`build_report` turns per-photo records into one HTML page with no
external resources; :mod:`cvmeasure.report.plots` draws the PNG plots (also
used by ``cvmeasure agreement --plot``); :mod:`cvmeasure.report.thumbnails`
draws what was measured on a small copy of each photo.
"""

from __future__ import annotations

from cvmeasure.report.html import build_report, data_uri
from cvmeasure.report.plots import bland_altman_png
from cvmeasure.report.thumbnails import find_photo, overlay_thumbnail

__all__ = ["build_report", "data_uri", "bland_altman_png", "find_photo", "overlay_thumbnail"]
