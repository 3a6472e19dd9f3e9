"""DXF designs read with ezdxf: the model space, scaled to mm by ``$INSUNITS``.

Coordinates are used as they are (the design frame: x right, y up). Arcs and bulges are
kept on their true circles; ellipses and splines are flattened within the tolerance.

ezdxf is imported only when a DXF file is read.
"""

from __future__ import annotations

import math
import os
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
from cvmeasure.geometry import wrap_deg

__all__ = ["read_dxf"]

# DXF $INSUNITS code -> millimetres per drawing unit (0 = unitless, read as mm).
_DXF_UNIT_MM = {
    0: 1.0,
    1: 25.4,
    2: 304.8,
    4: 1.0,
    5: 10.0,
    6: 1000.0,
    8: 25.4e-6,
    9: 25.4e-3,
    10: 914.4,
    13: 1e-3,
    14: 100.0,
}

_DXF_UNIT_NAME = {1: "in", 2: "ft", 4: "mm", 5: "cm", 6: "m", 8: "microinch", 9: "mil",
                  10: "yd", 13: "um", 14: "dm"}  # fmt: skip
_DXF_SUPPORTED = {"LINE", "LWPOLYLINE", "POLYLINE", "ARC", "CIRCLE", "ELLIPSE", "SPLINE"}
_DXF_KIND: dict[str, PathKind] = {
    "LINE": "line",
    "LWPOLYLINE": "polyline",
    "POLYLINE": "polyline",
    "ARC": "arc",
    "CIRCLE": "circle",
    "ELLIPSE": "ellipse",
    "SPLINE": "spline",
}


def read_dxf(
    path: str | os.PathLike[str],
    *,
    tolerance_mm: float = DEFAULT_TOLERANCE_MM,
    ignore_unknown: bool = False,
    units: str | None = None,
) -> Design:
    """Read the model space of a DXF drawing with ezdxf (scaled to mm by ``$INSUNITS``).

    A drawing without units (``$INSUNITS`` 0) is refused unless ``units`` says
    what they are (``"mm"``, ``"in"``, ...).
    """
    import ezdxf

    path = Path(path)
    try:
        doc = ezdxf.readfile(str(path))
    except (
        OSError,
        ezdxf.DXFError,
        ValueError,
        StopIteration,
        EOFError,
        KeyError,
        IndexError,
    ) as exc:
        # a truncated file makes ezdxf's reader run out of tags (StopIteration)
        raise InputError(path, f"unreadable DXF: {exc or type(exc).__name__}") from None
    code = int(doc.header.get("$INSUNITS", 0) or 0)
    if code not in _DXF_UNIT_MM:
        raise InputError(path, f"unsupported DXF drawing units ($INSUNITS = {code})")
    scale = _DXF_UNIT_MM[code]
    unit_text = f"{_DXF_UNIT_NAME.get(code, 'units')} ($INSUNITS {code})"
    if code == 0:
        if units is None:
            raise InputError(
                path,
                "no drawing units ($INSUNITS 0, unitless): set the drawing's units in the CAD "
                "program, or pass --units mm (or in, cm)",
            )
        scale, unit_text = UNIT_MM[units], f"{units} (given by --units; $INSUNITS 0)"
    paths: list[DesignPath] = []
    for entity in doc.modelspace():
        kind_name = entity.dxftype()
        name = f"DXF {kind_name} #{entity.dxf.handle}"
        if kind_name not in _DXF_SUPPORTED:
            if ignore_unknown:
                continue
            raise InputError(
                path, f"unsupported DXF entity {name}; use lines, polylines, arcs and circles"
            )
        kind = _DXF_KIND[kind_name]
        if kind_name == "ELLIPSE" and math.isclose(entity.dxf.ratio, 1.0, rel_tol=1e-9):
            kind = "circle" if _ellipse_full(entity) else "arc"
        try:
            pts, arcs, closed, flags = _dxf_geometry(entity, tolerance_mm / scale)
        except (TypeError, ValueError, ZeroDivisionError) as exc:
            raise InputError(path, f"cannot read DXF entity {name}: {exc}") from None
        pts, flags = dedupe_flagged(pts * scale, np.asarray(flags, dtype=bool))
        arcs = tuple(_scaled_arc(a, scale) for a in arcs)
        if closed and len(pts) > 1 and np.hypot(*(pts[0] - pts[-1])) < 1e-9:
            pts, flags = pts[:-1], flags[:-1]
        if len(pts) < 2:
            continue
        paths.append(DesignPath(pts, closed, kind, name, arcs, tuple(flags)))
    if not paths:
        raise InputError(path, "no drawable geometry in the DXF model space")
    return Design(str(path), tuple(paths), unit_text)


def _ellipse_full(entity: Any) -> bool:
    span = (entity.dxf.end_param - entity.dxf.start_param) % (2 * math.pi)
    return math.isclose(span, 0.0, abs_tol=1e-9) or math.isclose(span, 2 * math.pi, abs_tol=1e-9)


def _scaled_arc(arc: DesignArc, scale: float) -> DesignArc:
    c = arc.centre_mm
    return DesignArc(
        (c[0] * scale, c[1] * scale), arc.radius_mm * scale, arc.start_deg, arc.sweep_deg
    )


def _dxf_geometry(
    entity: Any, tolerance: float
) -> tuple[np.ndarray, tuple[DesignArc, ...], bool, list[bool]]:
    """Exact points (drawing units), circular arcs, closed flag and curve flags of an entity.

    Arcs and bulges are sampled on the true circle (ezdxf's path conversion
    would approximate them by Bézier curves); ellipses and splines are
    evaluated with ezdxf's construction tools.
    """
    kind = entity.dxftype()
    if kind == "LINE":
        s, e = entity.dxf.start, entity.dxf.end
        return np.array([[s.x, s.y], [e.x, e.y]], dtype=np.float64), (), False, [False]
    if kind in ("ARC", "CIRCLE"):
        (arc,) = _dxf_arcs(entity, 1.0) or (None,)
        if arc is None:
            raise ValueError("arc not in the xy plane")
        pts = arc.points_mm(tolerance_mm=tolerance)
        return pts, (arc,), kind == "CIRCLE", [True] * (len(pts) - 1)
    if kind == "LWPOLYLINE":
        xyb = np.array([(x, y, b) for x, y, b in entity.get_points("xyb")], dtype=np.float64)
        mirror = float(entity.dxf.extrusion.z) < 0
        return _bulge_polyline(xyb, bool(entity.closed), mirror, tolerance)
    if kind == "POLYLINE":
        if entity.is_3d_polyline or entity.is_poly_face_mesh or entity.is_polygon_mesh:
            raise ValueError("only 2D polylines are supported")
        xyb = np.array(
            [(v.dxf.location.x, v.dxf.location.y, v.dxf.bulge) for v in entity.vertices],
            dtype=np.float64,
        )
        mirror = float(entity.dxf.extrusion.z) < 0
        return _bulge_polyline(xyb, bool(entity.is_closed), mirror, tolerance)
    if kind == "ELLIPSE":
        ellipse = entity.construction_tool()
        start, span = ellipse.start_param, ellipse.param_span

        def on_ellipse(t: np.ndarray) -> np.ndarray:
            return np.array([(v.x, v.y) for v in ellipse.vertices(start + span * t)])

        full = _ellipse_full(entity)
        pts = flatten_curve(on_ellipse, tolerance, min_chords=8)
        return pts, (), full, [True] * (len(pts) - 1)
    if kind == "SPLINE":
        spline = entity.construction_tool()

        def on_spline(t: np.ndarray) -> np.ndarray:
            return np.array([(v.x, v.y) for v in spline.points(t * spline.max_t)])

        pts = flatten_curve(on_spline, tolerance, min_chords=8)
        return pts, (), bool(entity.closed), [True] * (len(pts) - 1)
    raise ValueError(f"unsupported entity {kind}")


def _bulge_polyline(
    xyb: np.ndarray, closed: bool, mirror: bool, tolerance: float
) -> tuple[np.ndarray, tuple[DesignArc, ...], bool, list[bool]]:
    """Vertices with DXF bulges (tan of a quarter of each arc's included angle) -> points, arcs."""
    if mirror:  # OCS with extrusion -z: x mirrored, arcs turn the other way
        xyb = xyb * np.array([-1.0, 1.0, -1.0])
    n = len(xyb)
    pts: list[np.ndarray] = [xyb[:1, :2]]
    arcs: list[DesignArc] = []
    flags: list[bool] = []
    last = n if closed else n - 1
    for i in range(last):
        p0, p1, bulge = xyb[i, :2], xyb[(i + 1) % n, :2], xyb[i, 2]
        chord = float(np.hypot(*(p1 - p0)))
        if abs(bulge) < 1e-12 or chord == 0.0:
            pts.append(p1[None])
            flags.append(False)
            continue
        theta = 4.0 * math.atan(bulge)  # signed included angle, CCW positive
        d = (p1 - p0) / chord
        left = np.array([-d[1], d[0]])
        centre = 0.5 * (p0 + p1) + left * (0.5 * chord / math.tan(0.5 * theta))
        radius = 0.5 * chord / abs(math.sin(0.5 * theta))
        start = math.degrees(math.atan2(p0[1] - centre[1], p0[0] - centre[0]))
        arc = DesignArc((float(centre[0]), float(centre[1])), radius, start, math.degrees(theta))
        arcs.append(arc)
        pts.append(arc.points_mm(tolerance_mm=tolerance)[1:])
        flags.extend([True] * len(pts[-1]))
    return np.vstack(pts), tuple(arcs), closed, flags


def _dxf_arcs(entity: Any, scale: float) -> tuple[DesignArc, ...]:
    """Circular arcs of an ARC/CIRCLE entity in the world frame (extrusion +z or -z)."""
    kind = entity.dxftype()
    if kind not in ("ARC", "CIRCLE"):
        return ()
    ez = float(entity.dxf.extrusion.z) if entity.dxf.hasattr("extrusion") else 1.0
    if abs(abs(ez) - 1.0) > 1e-9:
        return ()  # not in the xy plane; the flattened points still describe it
    c = entity.dxf.center
    centre = (float(c.x) * scale, float(c.y) * scale)
    r = float(entity.dxf.radius) * scale
    if kind == "CIRCLE":
        start, sweep = 0.0, 360.0
    else:
        start = float(entity.dxf.start_angle)
        sweep = (float(entity.dxf.end_angle) - start) % 360.0 or 360.0
    if ez < 0:  # OCS mirrored in x: angles run clockwise in the world frame
        centre = (-centre[0], centre[1])
        start, sweep = 180.0 - start, -sweep
    return (DesignArc(centre, r, float(wrap_deg(start)), sweep),)
