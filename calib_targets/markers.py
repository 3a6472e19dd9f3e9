"""The printable marker-kit sheet at exact scale (PDF, SVG, PNG).

One A4 page: for each role, ``copies`` discs of the kit's colour on their
white rings (a thin grey cut line at the ring's outer edge), labelled with the
role, colour name, sRGB, a naive CMYK breakdown for the print shop, the
sizes and, for a kit with heights, the height of each disc's face above the top
plate (the spec: markers stand on caps at those heights; a kit without heights
is flat stickers, and its sheet says so); the kit JSON; and a 100 mm
print-check ruler. Print at 100 % ("actual
size") and check the ruler.

The kit's colours are moderate-chroma sRGB values chosen to print on ordinary
CMYK printers (the seed paper designed its markers in CMYK for the same
reason); after printing, ``cvmeasure markers learn`` measures what actually
came out, under D65-balanced light, and writes a kit JSON with those colours.

Frames: the page in mm, origin top-left, y down.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from cvmeasure.kit import MarkerKit
from cvmeasure_calib_targets.sheet import SheetFormat, figure_bytes, sheet_format

__all__ = [
    "SheetFormat",
    "KIT_PAGE_MM",
    "naive_cmyk",
    "kit_sheet_positions_mm",
    "render_kit_sheet",
    "write_kit_sheet",
]


#: A4 portrait, mm.
KIT_PAGE_MM = (210.0, 297.0)
_MARGIN_MM = 15.0
_ROW_MM = 38.0
_INCH_MM = 25.4
_RULER_MM = 100.0
_CUT_GREY = "#b0b0b0"


def naive_cmyk(srgb8: tuple[int, int, int]) -> tuple[float, float, float, float]:
    """Naive (profile-free) CMYK percentages of an 8-bit sRGB colour: a starting point for a print shop."""
    rgb = np.asarray(srgb8, dtype=np.float64) / 255.0
    k = 1.0 - float(rgb.max())
    if k >= 1.0:
        return (0.0, 0.0, 0.0, 100.0)
    c, m, y = ((1.0 - rgb - k) / (1.0 - k)).tolist()
    return (round(100 * c, 1), round(100 * m, 1), round(100 * y, 1), round(100 * k, 1))


def kit_sheet_positions_mm(kit: MarkerKit, copies: int = 3) -> list[tuple[str, float, float]]:
    """Centres (role, x_mm, y_mm) of every printed marker on the page."""
    if not 1 <= copies <= 5:
        raise ValueError(f"copies must be 1..5, got {copies}")
    out = []
    for i, marker in enumerate(kit.markers):
        y = _MARGIN_MM + 18.0 + i * _ROW_MM
        pitch = max(m.ring_mm for m in kit.markers) + 6.0
        for j in range(copies):
            out.append((marker.role, _MARGIN_MM + marker.ring_mm / 2 + 2.0 + j * pitch, y))
    return out


def _mounting(kit: MarkerKit) -> str:
    """How to mount the cut markers: at the kit's heights, or flat (a kit without heights)."""
    if kit.has_heights:
        return (
            "\nglue each on its cap: its face stands at the height printed beside it above "
            "the top plate\n(measure yours: cvmeasure markers heights); for flat stickers print "
            "the flat kit instead (targets markers --flat-kit)"
        )
    return "\nglue flat on the top plate, all markers in one plane (a flat kit: no heights)"


def render_kit_sheet(
    kit: MarkerKit, fmt: SheetFormat, *, dpi: float = 300.0, copies: int = 3
) -> bytes:
    """The printable kit sheet as bytes (matplotlib; the figure is the page, so 1 mm is 1 mm)."""
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure
    from matplotlib.patches import Circle

    if max(m.ring_mm for m in kit.markers) > _ROW_MM - 8.0:
        raise ValueError(f"rings larger than {_ROW_MM - 8.0:g} mm do not fit the sheet")
    pw, ph = KIT_PAGE_MM
    if fmt == "png":  # whole pixels, so nothing is cropped or shifted
        pw = np.ceil(pw * dpi / _INCH_MM - 1e-9) * _INCH_MM / dpi
        ph = np.ceil(ph * dpi / _INCH_MM - 1e-9) * _INCH_MM / dpi
    fig = Figure(figsize=(pw / _INCH_MM, ph / _INCH_MM))
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0))
    ax.set_xlim(0.0, pw)
    ax.set_ylim(ph, 0.0)
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.text(
        _MARGIN_MM,
        _MARGIN_MM,
        f"cvmeasure marker kit '{kit.name}' -- cut along the grey circles; " + _mounting(kit),
        fontsize=7,
        va="top",
    )
    by_role = {m.role: m for m in kit.markers}
    positions = kit_sheet_positions_mm(kit, copies)
    for role, x, y in positions:
        m = by_role[role]
        ax.add_patch(
            Circle((x, y), m.ring_mm / 2, facecolor="white", edgecolor=_CUT_GREY, linewidth=0.3)
        )
        r, g, b = (v / 255.0 for v in m.srgb)
        ax.add_patch(Circle((x, y), m.diameter_mm / 2, facecolor=(r, g, b), edgecolor="none"))
    for m in kit.markers:
        _, x_last, y = [p for p in positions if p[0] == m.role][-1]
        c, mg, ye, k = naive_cmyk(m.srgb)
        ax.text(
            x_last + m.ring_mm / 2 + 6.0,
            y,
            f"{m.role} -- {m.name}\n"
            f"sRGB {list(m.srgb)}, CIELAB D65 {[round(float(v), 1) for v in m.lab_d65]}\n"
            f"naive CMYK {c:g}/{mg:g}/{ye:g}/{k:g} %\n"
            f"disc {m.diameter_mm:g} mm on a {m.ring_mm:g} mm white ring"
            + (f", face {m.height_mm:g} mm above the plate" if m.height_mm is not None else ""),
            fontsize=6.5,
            va="center",
        )
    rx, ry = _MARGIN_MM, _MARGIN_MM + 18.0 + len(kit.markers) * _ROW_MM + 4.0
    ax.plot([rx, rx + _RULER_MM], [ry, ry], color="black", linewidth=0.6)
    for mm in range(int(_RULER_MM) + 1):
        tick = 4.0 if mm % 10 == 0 else (2.5 if mm % 5 == 0 else 1.5)
        ax.plot([rx + mm, rx + mm], [ry, ry - tick], color="black", linewidth=0.3)
        if mm % 10 == 0:
            ax.text(rx + mm, ry - 4.8, str(mm), fontsize=5, ha="center", va="bottom")
    ax.text(
        rx + _RULER_MM + 3.0,
        ry,
        "mm  print at 100 % (actual size);\nthis ruler must measure 100 mm",
        fontsize=5.5,
        va="center",
    )
    text = json.dumps(kit.to_dict(), separators=(",", ":"))
    lines = [text[i : i + 150] for i in range(0, len(text), 150)]
    ax.text(
        rx, ry + 6.0, "kit JSON:\n" + "\n".join(lines), fontsize=4.5, va="top", family="monospace"
    )
    return figure_bytes(fig, fmt, dpi=dpi)


def write_kit_sheet(
    kit: MarkerKit,
    path: str | os.PathLike[str],
    fmt: SheetFormat | None = None,
    *,
    dpi: float = 300.0,
    copies: int = 3,
) -> Path:
    """Write the kit sheet atomically; the format comes from ``fmt`` or the file suffix."""
    from cvmeasure.fileio import atomic_write_bytes

    path = Path(path)
    f = sheet_format(path, fmt)
    return atomic_write_bytes(path, render_kit_sheet(kit, f, dpi=dpi, copies=copies))
