"""Wire designs from SVG and DXF drawings, as polylines in millimetres.

A design is what a part was bent from: one or more paths (lines, polylines,
arcs, circles, ellipses, splines, SVG paths with Bézier curves). Every path is
flattened into a polyline whose chords stay within ``tolerance_mm`` of the true
curve; straight pieces keep exactly their end points, and circular arcs are
also kept as :class:`DesignArc` records so that a caller (G-code generation)
can divide them into equal chords itself (:func:`arc_points_mm`,
:func:`divide_into_chords`).

Design frame: x right, y **up**, millimetres, as a CAD viewer shows the
drawing. DXF coordinates are used as they are (scaled by ``$INSUNITS``); SVG's
y-down user space (96 px per inch, as CSS and svgelements define it) is mirrored
to y up, so counter-clockwise as seen in the drawing is positive in both.
Signed bend angles (:func:`bend_angles_deg`) are turning angles at the
vertices, counter-clockwise positive, wrapped to (-180, 180].

Readers raise :class:`~cvmeasure.errors.InputError` naming the file and, for
an unsupported element (SVG ``<text>``, DXF ``TEXT``, ``INSERT``, ...), the
element.

The paths and their geometry are in :mod:`cvmeasure.design_path`, the readers in
:mod:`cvmeasure.design_svg` and :mod:`cvmeasure.design_dxf`; this module chooses the
reader and checks what it read.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cvmeasure.design_dxf import read_dxf
from cvmeasure.design_path import (
    DEFAULT_TOLERANCE_MM,
    UNIT_MM,
    Design,
    DesignArc,
    DesignPath,
    PathKind,
    arc_points_mm,
    bend_angles_deg,
    chord_lengths_mm,
    divide_into_chords,
    join_paths,
    polyline_length_mm,
)
from cvmeasure.design_svg import read_svg
from cvmeasure.errors import InputError

__all__ = [
    "DesignArc",
    "DesignPath",
    "Design",
    "PathKind",
    "load_design",
    "check_design_coordinates",
    "read_svg",
    "read_dxf",
    "arc_points_mm",
    "divide_into_chords",
    "bend_angles_deg",
    "chord_lengths_mm",
    "polyline_length_mm",
    "join_paths",
    "DEFAULT_TOLERANCE_MM",
    "UNIT_MM",
    "MAX_DESIGN_COORDINATE_MM",
]


def load_design(
    path: str | os.PathLike[str],
    *,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    ignore_unknown: bool = False,
    units: str | None = None,
) -> Design:
    """Read an SVG or DXF design (chosen by the file suffix).

    Parameters
    ----------
    path : the ``.svg`` or ``.dxf`` file.
    tolerance_mm : largest chord-to-curve distance when curves are flattened, mm.
    ignore_unknown : skip unsupported elements (text, images, blocks) instead of failing.
    units : the unit of a drawing that declares none (a key of :data:`UNIT_MM`); such a
        drawing is refused without it.

    Raises
    ------
    InputError
        The file is missing or unreadable, has an unsupported element (named),
        or holds no geometry.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if not path.is_file():
        raise InputError(path, "design file not found")
    if units is not None and units not in UNIT_MM:
        raise InputError("--units", f"unknown unit {units!r}; valid: {', '.join(UNIT_MM)}")
    if suffix == ".svg":
        design = read_svg(
            path, tolerance_mm=tolerance_mm, ignore_unknown=ignore_unknown, units=units
        )
    elif suffix == ".dxf":
        design = read_dxf(
            path, tolerance_mm=tolerance_mm, ignore_unknown=ignore_unknown, units=units
        )
    else:
        raise InputError(path, f"unknown design format {suffix or '(no suffix)'}; use .svg or .dxf")
    check_design_coordinates(design)
    return design


#: Largest coordinate a design may have, mm (a 100 m drawing is a unit error, not a part).
MAX_DESIGN_COORDINATE_MM = 100_000.0


def check_design_coordinates(design: Design) -> None:
    """InputError naming the file and element when a coordinate is NaN, infinite or beyond
    :data:`MAX_DESIGN_COORDINATE_MM` (a NaN once went on to write a job of 0-degree bends)."""
    for p in design.paths:
        pts = np.asarray(p.points_mm, dtype=np.float64)
        if not np.all(np.isfinite(pts)):
            raise InputError(design.source, f"{p.element}: a coordinate is not a finite number")
        if pts.size and np.max(np.abs(pts)) > MAX_DESIGN_COORDINATE_MM:
            raise InputError(
                design.source,
                f"{p.element}: a coordinate of {np.max(np.abs(pts)):.3g} mm is beyond "
                f"{MAX_DESIGN_COORDINATE_MM:g} mm (wrong units?)",
            )
