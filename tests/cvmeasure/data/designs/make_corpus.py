"""Write the design corpus: files as operators' programs export them, with expected outcomes.

Run from the repository root: ``python tests/cvmeasure/data/designs/make_corpus.py``. Each
file is built from its construction (chords and turns, arcs, units); ``expected.json``
states the outcome from that construction alone (no cvmeasure code is used here):

* ``"ok"``: the polygon bent, as ``chords_mm`` and ``turns_deg`` (design frame, counter-
  clockwise positive as seen in the drawing; the machine bends are minus the turns),
  or for a curve the chord count and the equal chord length, and ``changes``: what
  ``cvmeasure gcode`` must print (the curves it divides);
* ``"refused"``: exit 2 and words the message must contain (the element and the number).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import ezdxf
import numpy as np

HERE = Path(__file__).resolve().parent
PX_PER_MM = 96.0 / 25.4
PT_PER_MM = 72.0 / 25.4
MIN_MM = 12.0

INKSCAPE_HEAD = (
    '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n'
    "<!-- Created with Inkscape (http://www.inkscape.org/) -->\n"
    '<svg width="{w}" height="{h}" viewBox="0 0 {vw} {vh}" version="1.1" id="svg1" '
    'inkscape:version="1.3.2 (091e20e, 2023-11-25)" sodipodi:docname="{name}" '
    'xmlns:inkscape="http://www.inkscape.org/namespaces/inkscape" '
    'xmlns:sodipodi="http://sodipodi.sourceforge.net/DTD/sodipodi-0.dtd" '
    'xmlns="http://www.w3.org/2000/svg" xmlns:svg="http://www.w3.org/2000/svg">\n'
    '  <sodipodi:namedview id="namedview1" pagecolor="#ffffff" bordercolor="#000000" '
    'inkscape:document-units="{units}" />\n'
    '  <defs id="defs1" />\n'
    '  <g inkscape:label="Layer 1" inkscape:groupmode="layer" id="layer1"{transform}>\n'
    "{body}"
    "  </g>\n</svg>\n"
)
ILLUSTRATOR_HEAD = (
    '<?xml version="1.0" encoding="utf-8"?>\n'
    "<!-- Generator: Adobe Illustrator 27.5.0, SVG Export Plug-In . SVG Version: 6.00 Build 0)"
    "  -->\n"
    '<svg version="1.1" id="Layer_1" xmlns="http://www.w3.org/2000/svg" '
    'xmlns:xlink="http://www.w3.org/1999/xlink" x="0px" y="0px"\n\t viewBox="0 0 {vw} {vh}" '
    'style="enable-background:new 0 0 {vw} {vh};" xml:space="preserve">\n'
    '<style type="text/css">\n\t.st0{{fill:none;stroke:#000000;stroke-miterlimit:10;}}\n'
    "</style>\n{body}</svg>\n"
)
PLAIN_HEAD = '<svg xmlns="http://www.w3.org/2000/svg"{size}>\n{body}</svg>\n'


def polygon(chords, turns, start=(0.0, 0.0), heading_deg=0.0) -> np.ndarray:
    """Vertices (y up, mm) of chords and turns (CCW positive)."""
    heading = np.radians(heading_deg + np.concatenate(([0.0], np.cumsum(turns))))
    steps = np.asarray(chords, float)[:, None] * np.column_stack((np.cos(heading), np.sin(heading)))
    return np.vstack((start, np.asarray(start) + np.cumsum(steps, axis=0)))


def to_svg(pts_mm: np.ndarray, unit_per_mm: float, height_units: float) -> np.ndarray:
    """y-up mm -> SVG user units (y down)."""
    p = np.asarray(pts_mm, float) * unit_per_mm
    return np.column_stack((p[:, 0], height_units - p[:, 1]))


def pts_attr(p: np.ndarray) -> str:
    return " ".join(f"{x:.4f},{y:.4f}" for x, y in p)


def ok_poly(chords, turns, **extra) -> dict:
    return {"outcome": "ok", "chords_mm": list(map(float, chords)),
            "turns_deg": list(map(float, turns)), "changes": [], **extra}  # fmt: skip


def ok_arc(radius, sweep_deg, *, lines=(), divisions=None, **extra) -> dict:
    """An arc divided into the most chords >= 12 mm (or ``divisions``): count, chord, turn."""
    length = radius * math.radians(abs(sweep_deg))
    n = divisions or max(1, int(length // MIN_MM))
    chord = 2 * radius * math.sin(math.radians(abs(sweep_deg)) / (2 * n))
    return {"outcome": "ok", "arc_chords": n, "arc_chord_mm": chord,
            "arc_turn_deg": sweep_deg / n, "straight_mm": list(map(float, lines)),
            "changes": ["curve divided"], **extra}  # fmt: skip


def refused(*words: str) -> dict:
    return {"outcome": "refused", "message": list(words)}


def inkscape(name: str, body: str, *, mm: bool, transform: str = "") -> None:
    if mm:
        size = dict(w="210mm", h="297mm", vw=210, vh=297, units="mm")
    else:
        size = dict(w="793.70081", h="1122.5197", vw="793.70081", vh="1122.5197", units="px")
    t = f' transform="{transform}"' if transform else ""
    text = INKSCAPE_HEAD.format(name=name, body=body, transform=t, **size)
    (HERE / name).write_text(text, encoding="utf-8")


def illustrator(name: str, body: str) -> None:
    text = ILLUSTRATOR_HEAD.format(vw="595.3", vh="841.9", body=body)
    (HERE / name).write_text(text, encoding="utf-8")


def plain(name: str, body: str, size: str) -> None:
    (HERE / name).write_text(PLAIN_HEAD.format(size=size, body=body), encoding="utf-8")


def dxf(name: str, units: int, draw) -> None:
    doc = ezdxf.new("R2010", units=units)
    draw(doc.modelspace())
    doc.saveas(HERE / name)


def svg_corpus(expected: dict) -> None:
    zig_c, zig_t = [40, 42, 40, 42], [45, -45, 45]
    p = to_svg(polygon(zig_c, zig_t, (20, 150)), PX_PER_MM, 1122.5197)
    d = (
        "m "
        + f"{p[0, 0]:.4f},{p[0, 1]:.4f} "
        + " ".join(f"{dx:.4f},{dy:.4f}" for dx, dy in np.diff(p, axis=0))
    )  # Inkscape writes relative moves
    body = f'    <path style="fill:none;stroke:#000000;stroke-width:0.26" d="{d}" id="path1" />\n'
    inkscape("inkscape_px_zigzag.svg", body, mm=False)
    expected["inkscape_px_zigzag.svg"] = ok_poly(zig_c, zig_t)

    # Inkscape mm document, a layer moved by a transform: an L bracket 60 + 45 mm
    p = to_svg(polygon([60, 45], [90], (30, 200)), 1.0, 297)
    body = f'    <polyline points="{pts_attr(p)}" style="fill:none;stroke:#000" id="bracket" />\n'
    inkscape("inkscape_mm_bracket.svg", body, mm=True, transform="translate(12.5,-7.25)")
    expected["inkscape_mm_bracket.svg"] = ok_poly([60, 45], [90])

    # hook: line 60 mm, quarter arc R 40 (left turn), line 50 mm (Inkscape mm, absolute path)
    body = '    <path d="M 20,150 H 80 A 40,40 0 0 0 120,110 V 60" style="fill:none" id="hook" />\n'
    inkscape("inkscape_mm_hook.svg", body, mm=True)
    expected["inkscape_mm_hook.svg"] = ok_arc(40, 90, lines=[60, 50])

    # a 120 deg arc of R 80 drawn in px (Inkscape, 96 px per inch)
    r = 80 * PX_PER_MM
    x0, y0 = 400.0, 600.0
    a = math.radians(120)
    x1, y1 = x0 + r - r * math.cos(a), y0 - r * math.sin(a)
    body = f'    <path d="M {x0 - 0:.4f},{y0:.4f} A {r:.4f},{r:.4f} 0 0 0 {x1:.4f},{y1:.4f}" id="arc1" />\n'
    inkscape("inkscape_px_arc.svg", body, mm=False)
    # sweep-flag 0: counter-clockwise as seen, a left turn
    expected["inkscape_px_arc.svg"] = ok_arc(80, 120)

    # S-jog of 8 mm segments (bends -45, +45, +45, -45): too short for the bender
    p = to_svg(polygon([8] * 5, [-45, 45, 45, -45], (30, 150)), 1.0, 297)
    body = f'    <polyline points="{pts_attr(p)}" id="sjog" />\n'
    inkscape("inkscape_mm_sjog_short.svg", body, mm=True)
    expected["inkscape_mm_sjog_short.svg"] = refused("<polyline id=sjog>", "8.00 mm long", "12 mm")

    body = '    <rect x="20" y="20" width="60" height="40" id="frame" style="fill:none" />\n'
    inkscape("inkscape_mm_closed_rect.svg", body, mm=True)
    expected["inkscape_mm_closed_rect.svg"] = refused("closed shape", "<rect id=frame>")

    body = '    <path d="M 20,20 L 80,20 L 80,70 Z" id="tri" style="fill:none" />\n'
    inkscape("inkscape_mm_closed_path.svg", body, mm=True)
    expected["inkscape_mm_closed_path.svg"] = refused("closed shape", "<path id=tri>")

    body = '    <path d="M 20,100 H 70" id="a" />\n    <path d="M 70.2,100 L 100,70" id="b" />\n'
    inkscape("inkscape_mm_gap.svg", body, mm=True)
    expected["inkscape_mm_gap.svg"] = refused("gap of 0.200 mm", "<path id=a>", "<path id=b>")

    # lines drawn out of order and direction: a 3-segment hook 50/30/40 with turns +90, +60
    q = polygon([50, 30, 40], [90, 60], (20, 100))
    s = to_svg(q, 1.0, 297)
    body = (
        f'    <line x1="{s[3, 0]:.4f}" y1="{s[3, 1]:.4f}" x2="{s[2, 0]:.4f}" y2="{s[2, 1]:.4f}" id="l3" />\n'
        f'    <line x1="{s[0, 0]:.4f}" y1="{s[0, 1]:.4f}" x2="{s[1, 0]:.4f}" y2="{s[1, 1]:.4f}" id="l1" />\n'
        f'    <line x1="{s[2, 0]:.4f}" y1="{s[2, 1]:.4f}" x2="{s[1, 0]:.4f}" y2="{s[1, 1]:.4f}" id="l2" />\n'
    )
    inkscape("inkscape_mm_out_of_order.svg", body, mm=True)
    expected["inkscape_mm_out_of_order.svg"] = ok_poly([50, 30, 40], [90, 60], either_end=True)

    p = to_svg(polygon([60, 30, 30, 40], [120, 120, 60], (60, 150)), 1.0, 297)
    inkscape(
        "inkscape_mm_self_contact.svg",
        f'    <polyline points="{pts_attr(p)}" id="loop" />\n',
        mm=True,
    )
    expected["inkscape_mm_self_contact.svg"] = refused("self-contact", "<polyline id=loop>")

    p = to_svg(polygon([50, 50], [150], (60, 150)), 1.0, 297)
    inkscape("inkscape_mm_sharp.svg", f'    <polyline points="{pts_attr(p)}" id="v" />\n', mm=True)
    expected["inkscape_mm_sharp.svg"] = refused("150.0 deg", "at most 135 deg")

    # a Bezier S-curve: divided into equal chords (count from its length)
    body = '    <path d="M 20,150 C 60,100 100,200 140,150" id="bez" style="fill:none" />\n'
    inkscape("inkscape_mm_bezier.svg", body, mm=True)
    t = np.linspace(0, 1, 200001)[:, None]
    b = ((1 - t) ** 3 * [20, 150] + 3 * (1 - t) ** 2 * t * [60, 100]
         + 3 * (1 - t) * t**2 * [100, 200] + t**3 * [140, 150])  # fmt: skip
    length = float(np.sum(np.hypot(*np.diff(b, axis=0).T)))
    expected["inkscape_mm_bezier.svg"] = {
        "outcome": "ok", "arc_chords": int(length // MIN_MM), "equal_chords": True,
        "end_to_end_mm": 120.0, "changes": ["curve divided"],
    }  # fmt: skip

    # Illustrator: px are points (72 per inch)
    c, t_ = [30, 45, 25], [-30, 50]
    p = to_svg(polygon(c, t_, (40, 300)), PT_PER_MM, 841.9)
    illustrator("illustrator_pt_polyline.svg", f'<polyline class="st0" points="{pts_attr(p)}"/>\n')
    expected["illustrator_pt_polyline.svg"] = ok_poly(c, t_)

    # a half circle of radius 170 pt (59.97 mm), as Illustrator writes it (a null curve first)
    body = '<path class="st0" d="M100,400c0,0,0,0,0,0 A170,170 0 0 1 440,400"/>\n'
    illustrator("illustrator_pt_half_circle.svg", body)
    expected["illustrator_pt_half_circle.svg"] = ok_arc(170 / PT_PER_MM, -180)

    p = to_svg(polygon([10, 30, 10], [40, -40], (40, 300)), PT_PER_MM, 841.9)
    illustrator("illustrator_pt_short.svg", f'<polyline class="st0" points="{pts_attr(p)}"/>\n')
    expected["illustrator_pt_short.svg"] = refused("10.00 mm long", "12 mm")

    # no physical units and no program declaring them: refused
    p = to_svg(polygon([40, 40], [30], (20, 100)), 1.0, 300)
    plain("plain_unitless.svg", f'<polyline points="{pts_attr(p)}"/>\n', ' viewBox="0 0 300 300"')
    expected["plain_unitless.svg"] = refused("no physical units", "--units")
    plain("plain_px.svg", f'<polyline points="{pts_attr(p)}"/>\n', ' width="300px" height="300px"')
    expected["plain_px.svg"] = refused("no physical units")
    # physical units: inches, centimetres, points as the document's width
    p = to_svg(polygon([40, 40], [30], (20, 100)), 1 / 25.4, 10)
    plain(
        "plain_in.svg",
        f'<polyline points="{pts_attr(p)}"/>\n',
        ' width="10in" height="10in" viewBox="0 0 10 10"',
    )
    expected["plain_in.svg"] = ok_poly([40, 40], [30])
    p = to_svg(polygon([35, 50], [-25], (20, 100)), 0.1, 30)
    plain(
        "plain_cm.svg",
        f'<polyline points="{pts_attr(p)}"/>\n',
        ' width="30cm" height="30cm" viewBox="0 0 30 30"',
    )
    expected["plain_cm.svg"] = ok_poly([35, 50], [-25])
    p = to_svg(polygon([35, 50], [-25], (20, 100)), PT_PER_MM, 600)
    plain(
        "plain_pt.svg",
        f'<polyline points="{pts_attr(p)}"/>\n',
        ' width="600pt" height="600pt" viewBox="0 0 600 600"',
    )
    expected["plain_pt.svg"] = ok_poly([35, 50], [-25])


def dxf_corpus(expected: dict) -> None:
    zig_c, zig_t = [40, 42, 40, 42], [45, -45, 45]
    v = polygon(zig_c, zig_t, (10, 10))
    order = [2, 0, 3, 1]  # LibreCAD saves lines in the order drawn, not along the wire

    def lines(msp):
        for i in order:
            a, b = (v[i], v[i + 1]) if i % 2 else (v[i + 1], v[i])
            msp.add_line(tuple(a), tuple(b))

    dxf("librecad_mm_lines.dxf", 4, lines)
    expected["librecad_mm_lines.dxf"] = ok_poly(zig_c, zig_t, either_end=True)

    # LWPOLYLINE with a bulge: line 50, 90 deg arc of R 30 (bulge tan(90/4)), line 40
    def bulged(msp):
        b = math.tan(math.radians(90) / 4)
        msp.add_lwpolyline([(0, 0, 0), (50, 0, b), (80, 30, 0), (80, 70, 0)], format="xyb")

    dxf("qcad_mm_bulge.dxf", 4, bulged)
    expected["qcad_mm_bulge.dxf"] = ok_arc(30, 90, lines=[50, 40])

    c, t_ = [30, 45, 25], [-30, 50]
    v_in = polygon(c, t_) / 25.4

    def inches(msp):
        msp.add_lwpolyline([tuple(p) for p in v_in])

    dxf("ezdxf_in_polyline.dxf", 1, inches)
    expected["ezdxf_in_polyline.dxf"] = ok_poly(c, t_)

    def small(msp):
        msp.add_lwpolyline([tuple(p) for p in polygon([40, 40], [30])])

    dxf("ezdxf_unitless.dxf", 0, small)
    expected["ezdxf_unitless.dxf"] = refused("$INSUNITS 0", "--units")
    dxf("ezdxf_default_metres.dxf", 6, small)  # ezdxf.new()'s default units are metres
    expected["ezdxf_default_metres.dxf"] = refused("wrong units")

    def arc(msp):
        msp.add_arc((0, 0), 100, 10, 100)

    dxf("dxf_arc_entity.dxf", 4, arc)
    expected["dxf_arc_entity.dxf"] = ok_arc(100, 90)

    def spline(msp):
        msp.add_spline_control_frame([(0, 0), (40, 30), (90, -10), (120, 25)])

    dxf("dxf_spline.dxf", 4, spline)
    expected["dxf_spline.dxf"] = {"outcome": "ok", "equal_chords": True, "end_to_end_mm": float(np.hypot(120, 25)), "changes": ["curve divided"]}  # fmt: skip

    def closed(msp):
        msp.add_lwpolyline([(0, 0), (60, 0), (60, 40), (0, 40)], close=True)

    dxf("dxf_closed_polyline.dxf", 4, closed)
    expected["dxf_closed_polyline.dxf"] = refused("closed shape", "LWPOLYLINE")

    def tiny_gap(msp):
        msp.add_line((0, 0), (50, 0))
        msp.add_line((50.004, 0.003), (80, 30))

    dxf("dxf_tiny_gap.dxf", 4, tiny_gap)
    # within the default 0.01 mm (an export's rounding): closed, and said so
    expected["dxf_tiny_gap.dxf"] = {"outcome": "ok", "bends": 1, "changes": ["gap bridged"]}

    def gap(msp):
        msp.add_line((0, 0), (50, 0))
        msp.add_line((50.5, 0), (80, 30))

    dxf("dxf_gap.dxf", 4, gap)
    expected["dxf_gap.dxf"] = refused("gap of 0.500 mm", "LINE")

    def short(msp):
        msp.add_lwpolyline([(0, 0), (30, 0), (30, 8), (60, 8)])

    dxf("dxf_short_segment.dxf", 4, short)
    expected["dxf_short_segment.dxf"] = refused("segment 2", "8.00 mm long")

    def ellipse(msp):
        msp.add_ellipse((0, 0), major_axis=(50, 0), ratio=0.5)

    dxf("dxf_ellipse_full.dxf", 4, ellipse)
    expected["dxf_ellipse_full.dxf"] = refused("closed shape", "ELLIPSE")

    def circle(msp):
        msp.add_circle((0, 0), 40)

    dxf("dxf_circle.dxf", 4, circle)
    expected["dxf_circle.dxf"] = refused("closed shape", "CIRCLE")

    def fillet(msp):
        # line 60 mm, tangent arc of R 30 over 60 deg (left), line 40 mm: three entities
        msp.add_line((0, 0), (60, 0))
        msp.add_arc((60, 30), 30, -90, -30)
        end = np.array(
            [60 + 30 * math.cos(math.radians(-30)), 30 + 30 * math.sin(math.radians(-30))]
        )
        direction = np.array([math.cos(math.radians(60)), math.sin(math.radians(60))])
        msp.add_line(tuple(end), tuple(end + 40 * direction))

    dxf("dxf_fillet_entities.dxf", 4, fillet)
    expected["dxf_fillet_entities.dxf"] = ok_arc(30, 60, lines=[60, 40])

    def crossing(msp):
        msp.add_lwpolyline([tuple(p) for p in polygon([60, 30, 30, 40], [120, 120, 60])])

    dxf("dxf_self_contact.dxf", 4, crossing)
    expected["dxf_self_contact.dxf"] = refused("self-contact")

    def mm_zig(msp):
        msp.add_lwpolyline([tuple(p) for p in polygon([25, 35, 25], [-50, 50])])

    dxf(
        "dxf_cm_units.dxf",
        5,
        lambda msp: msp.add_lwpolyline([tuple(p / 10) for p in polygon([25, 35, 25], [-50, 50])]),
    )
    expected["dxf_cm_units.dxf"] = ok_poly([25, 35, 25], [-50, 50])
    dxf("dxf_mm_zigzag.dxf", 4, mm_zig)
    expected["dxf_mm_zigzag.dxf"] = ok_poly([25, 35, 25], [-50, 50])


def main() -> None:
    for old in HERE.glob("*.svg"):
        old.unlink()
    for old in HERE.glob("*.dxf"):
        old.unlink()
    expected: dict = {}
    svg_corpus(expected)
    dxf_corpus(expected)
    (HERE / "expected.json").write_text(json.dumps(expected, indent=1, sort_keys=True) + "\n")
    print(f"{len(expected)} designs")


if __name__ == "__main__":
    main()
