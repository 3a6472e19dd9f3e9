"""SVG designs read with svgelements: units, viewBox and transforms applied, y mirrored up.

SVG's y-down user space (96 px per inch, as CSS and svgelements define it) is mirrored to
the design frame's y up (:mod:`cvmeasure.design`). A document without physical units is
read only where the program that wrote it declares its px, or the operator says.

svgelements and the XML parser are imported only when an SVG file is read.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.design_path import (
    DEFAULT_TOLERANCE_MM,
    UNIT_MM,
    Design,
    DesignArc,
    DesignPath,
    PathKind,
    dedupe_flagged,
    flatten_curve,
)
from cvmeasure.errors import InputError

__all__ = ["read_svg"]

# svgelements' own px-per-mm at 96 ppi (3.7795296, not 96 / 25.4), so that a
# drawing made in mm reads back in exact mm.
_SVG_PX_PER_MM: float | None = None


#: SVG attributes that hold coordinates (svgelements drops a token it cannot read, such
#: as ``nan``, silently: a polyline then loses a point and a bend).
_SVG_GEOMETRY_ATTRIBUTES = (
    "points",
    "d",
    "x",
    "y",
    "x1",
    "y1",
    "x2",
    "y2",
    "cx",
    "cy",
    "r",
    "rx",
    "ry",
    "width",
    "height",
    "transform",
    "viewBox",
)
_NON_NUMBER = re.compile(r"(?<![a-z])(nan|inf|infinity)(?![a-z])", re.IGNORECASE)


def _refuse_non_numbers(path: Path) -> dict[str, str] | None:
    """InputError naming the element when a geometry attribute holds nan or inf.

    Returns the root element's attributes (None when the XML does not parse).
    """
    import xml.etree.ElementTree as ET

    try:
        root = ET.parse(path).getroot()
    except (ET.ParseError, OSError, ValueError):
        return None  # the SVG parser says what is wrong
    for element in root.iter():
        for name in _SVG_GEOMETRY_ATTRIBUTES:
            value = element.attrib.get(name)
            if value and _NON_NUMBER.search(value):
                tag = element.tag.rsplit("}", 1)[-1]
                raise InputError(path, f"<{tag}> {name}={value[:60]!r}: not a finite number")
    return dict(root.attrib)


_SVG_LENGTH = re.compile(r"^\s*([-+0-9.eE]+)\s*([a-zA-Z%]*)\s*$")


def _svg_units(path: Path, root_attrib: Mapping[str, str], units: str | None) -> tuple[float, str]:
    """Scale onto svgelements' 96-per-inch reading, and where the units came from.

    A document whose ``width`` carries a physical unit (mm, cm, in, pt, pc) is read in
    it (viewBox applied). One in px, or unitless, has a physical size only when the
    program that wrote it declares it: Adobe Illustrator's px are points (72 per inch),
    Inkscape's are CSS px (96 per inch). Otherwise ``units`` (the operator's word) or
    an InputError: no design is read at a guessed scale.
    """
    width = root_attrib.get("width", "")
    match = _SVG_LENGTH.match(width)
    unit = match.group(2).lower() if match else ""
    if unit in ("mm", "cm", "in", "pt", "pc", "q"):
        return 1.0, f"{unit} (width={width.strip()})"
    try:
        head = path.read_text(encoding="utf-8", errors="replace")[:6000]
    except OSError:
        head = ""
    described = f"width={width.strip()}" if width else "no width"
    if "Adobe Illustrator" in head:
        return 96.0 / 72.0, f"pt: px at 72 per inch (Adobe Illustrator, {described})"
    if "inkscape.org/namespaces/inkscape" in head or "sodipodi" in head:
        return 1.0, f"px at 96 per inch (Inkscape, {described})"
    if units is not None:
        return UNIT_MM[units] / UNIT_MM[
            "px"
        ], f"{units} (given by --units; the file has {described})"
    raise InputError(
        path,
        f"no physical units (size {width.strip() or 'not given'}, no program declaring its "
        "px): re-export in mm, or pass --units px (96/in, Inkscape) or --units pt (72/in, "
        "Illustrator)",
    )


def read_svg(
    path: str | os.PathLike[str],
    *,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    ignore_unknown: bool = False,
    units: str | None = None,
) -> Design:
    """Read an SVG drawing with svgelements (units, viewBox and transforms applied).

    ``units``: the unit of a drawing that declares no physical size (see
    :func:`_svg_units`); refused without it.
    """
    import svgelements as se

    path = Path(path)
    root = _refuse_non_numbers(path)
    try:
        svg = se.SVG.parse(str(path), reify=True)
    except Exception as exc:  # svgelements raises assorted parser errors
        raise InputError(path, f"unreadable SVG: {exc}") from None
    if root is None:
        raise InputError(path, "unreadable SVG: not well-formed XML")
    scale, unit_text = _svg_units(path, root, units)

    structural = (
        (se.SVG, se.Group, se.Desc, se.Title)
        if hasattr(se, "Title")
        else (se.SVG, se.Group, se.Desc)
    )
    paths: list[DesignPath] = []
    for element in svg.elements():
        if isinstance(element, structural):
            continue
        name = _svg_name(element)
        if not isinstance(element, se.Shape) and _svg_not_drawn(element):
            continue  # an editor's metadata (Inkscape's sodipodi:namedview), styles, defs
        if not isinstance(element, se.Shape):
            if ignore_unknown:
                continue
            raise InputError(path, f"unsupported SVG element {name}; use lines, paths and shapes")
        if element.values.get("visibility") == "hidden" or element.values.get("display") == "none":
            continue
        kind = _svg_kind(element)
        paths.extend(_svg_shape_paths(se.Path(element), kind, name, tolerance_mm, scale))
    if not paths:
        raise InputError(path, "no drawable geometry in the SVG")
    return Design(str(path), tuple(paths), unit_text)


#: SVG elements that draw nothing themselves.
_SVG_NOT_DRAWN = {
    "metadata", "style", "defs", "title", "desc", "symbol", "marker", "clippath", "mask",
    "pattern", "lineargradient", "radialgradient", "stop", "filter", "script", "namedview",
}  # fmt: skip


def _svg_not_drawn(element: Any) -> bool:
    """Metadata, styles and definitions, or an element of another program's namespace."""
    tag = str(element.values.get("tag", "")) if hasattr(element, "values") else ""
    if tag.startswith("{") and not tag.startswith("{http://www.w3.org/2000/svg}"):
        return True
    return tag.rsplit("}", 1)[-1].lower() in _SVG_NOT_DRAWN


def _svg_name(element: Any) -> str:
    tag = element.values.get("tag") if hasattr(element, "values") else None
    tag = tag or type(element).__name__.lower()
    ident = getattr(element, "id", None)
    return f"<{tag} id={ident}>" if ident else f"<{tag}>"


def _svg_kind(element: Any) -> PathKind:
    import svgelements as se

    if isinstance(element, se.SimpleLine):
        return "line"
    if isinstance(element, se.Polygon):
        return "polygon"
    if isinstance(element, se.Polyline):
        return "polyline"
    if isinstance(element, se.Rect):
        return "rect"
    if isinstance(element, se.Circle):
        return "circle"
    if isinstance(element, se.Ellipse):
        rx, ry = float(element.rx), float(element.ry)
        return "circle" if math.isclose(rx, ry, rel_tol=1e-9) else "ellipse"
    return "path"


def _svg_px_per_mm() -> float:
    global _SVG_PX_PER_MM
    if _SVG_PX_PER_MM is None:
        import svgelements as se

        _SVG_PX_PER_MM = float(se.Length("1mm").value(ppi=96.0))
    return _SVG_PX_PER_MM


def _svg_xy(points_px: np.ndarray) -> np.ndarray:
    """SVG user units (px, y down) -> design frame (mm, y up)."""
    pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2) / _svg_px_per_mm()
    pts[:, 1] *= -1.0
    return pts


def _svg_shape_paths(
    svg_path: Any, kind: PathKind, name: str, tolerance_mm: float, scale: float = 1.0
) -> list[DesignPath]:
    import svgelements as se

    out: list[DesignPath] = []
    pts: list[np.ndarray] = []
    flags: list[bool] = []  # per point after the first: is the segment ending there a curve
    arcs: list[DesignArc] = []
    closed = False

    def xy(points_px: Any) -> np.ndarray:
        return _svg_xy(points_px) * scale

    def flush() -> None:
        nonlocal pts, arcs, closed, flags
        if pts:
            joined, curve = dedupe_flagged(np.vstack(pts), np.array(flags, dtype=bool))
            if closed and len(joined) > 1 and np.hypot(*(joined[0] - joined[-1])) < 1e-9:
                joined, curve = joined[:-1], curve[:-1]
            if len(joined) >= 2:
                out.append(DesignPath(joined, closed, kind, name, tuple(arcs), tuple(curve)))
        pts, arcs, closed, flags = [], [], False, []

    for seg in svg_path:
        if isinstance(seg, se.Move):
            flush()
            pts = [xy([seg.end.x, seg.end.y])]
            continue
        if isinstance(seg, se.Close):
            if seg.start is not None and seg.end is not None:
                pts.append(xy([seg.end.x, seg.end.y]))
                flags.append(False)
            closed = True
            continue
        if isinstance(seg, se.Line):
            pts.append(xy([seg.end.x, seg.end.y]))
            flags.append(False)
            continue
        curve = flatten_curve(lambda t, s=seg: xy(s.npoint(t)), tolerance_mm)
        pts.append(curve[1:])
        flags.extend([True] * (len(curve) - 1))
        if isinstance(seg, se.Arc) and math.isclose(float(seg.rx), float(seg.ry), rel_tol=1e-9):
            centre = xy([seg.center.x, seg.center.y])[0]
            start = curve[0] - centre
            arcs.append(
                DesignArc(
                    (float(centre[0]), float(centre[1])),
                    float(seg.rx) / _svg_px_per_mm() * scale,
                    float(np.degrees(np.arctan2(start[1], start[0]))),
                    -float(np.degrees(seg.sweep)),
                )
            )
    flush()
    if kind == "circle" and len(out) == 1 and out[0].arcs:
        a0 = out[0].arcs[0]
        sweep = math.copysign(360.0, sum(a.sweep_deg for a in out[0].arcs))
        out[0] = DesignPath(
            out[0].points_mm,
            True,
            "circle",
            name,
            (DesignArc(a0.centre_mm, a0.radius_mm, a0.start_deg, sweep),),
            out[0].curve,
        )
    return out
