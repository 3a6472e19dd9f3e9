"""Designs read from SVG (written by hand) and DXF (written with ezdxf) files."""

from __future__ import annotations

import math

import ezdxf
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cvmeasure.design import (
    arc_points_mm,
    bend_angles_deg,
    chord_lengths_mm,
    divide_into_chords,
    load_design,
)
from cvmeasure.errors import InputError

ATOL_MM = 1e-6
ATOL_DEG = 1e-6


def _svg(tmp_path, body: str, name: str = "design.svg"):
    path = tmp_path / name
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="300mm" height="200mm" '
        f'viewBox="0 0 300 200">{body}</svg>',
        encoding="utf-8",
    )
    return path


def _distance_to_polyline_mm(points_mm, vertices_mm):
    a, b = vertices_mm[:-1], vertices_mm[1:]
    d = b - a
    rel = points_mm[:, None, :] - a[None]
    u = np.clip(np.sum(rel * d, axis=2) / np.sum(d * d, axis=1), 0.0, 1.0)
    foot = a[None] + u[..., None] * d[None]
    return np.min(np.hypot(*(points_mm[:, None, :] - foot).transpose(2, 0, 1)), axis=1)


def _radial_error_mm(points_mm, centre_mm, radius_mm) -> float:
    return float(np.max(np.abs(np.hypot(*(points_mm - centre_mm).T) - radius_mm)))


def test_svg_half_circle_path_reads_in_mm_with_y_up(tmp_path):
    # half circle R100 from (20, 150) over the top to (220, 150) (SVG y down)
    path = _svg(tmp_path, '<path id="half" d="M 20 150 A 100 100 0 0 1 220 150"/>')
    design = load_design(path)
    (p,) = design.paths
    assert p.kind == "path" and not p.closed and p.element == "<path id=half>"
    np.testing.assert_allclose(p.points_mm[0], [20.0, -150.0], atol=ATOL_MM)
    np.testing.assert_allclose(p.points_mm[-1], [220.0, -150.0], atol=ATOL_MM)
    assert _radial_error_mm(p.points_mm, [120.0, -150.0], 100.0) < 1e-6
    # the top of the arc is at SVG y = 50, i.e. y_mm = -50 (y up)
    assert p.points_mm[:, 1].max() == pytest.approx(-50.0, abs=1e-3)
    (arc,) = p.arcs
    assert arc.radius_mm == pytest.approx(100.0, abs=ATOL_MM)
    assert arc.centre_mm == pytest.approx((120.0, -150.0), abs=ATOL_MM)
    assert arc.start_deg == pytest.approx(180.0, abs=ATOL_DEG)
    # over the top from left to right is clockwise (a right turn): negative sweep
    assert arc.sweep_deg == pytest.approx(-180.0, abs=ATOL_DEG)
    # the flattened chords stay within the default tolerance of the arc
    mids = 0.5 * (p.points_mm[1:] + p.points_mm[:-1])
    assert 100.0 - np.hypot(*(mids - [120.0, -150.0]).T).min() <= 0.001 + 1e-9


def test_svg_chords_of_half_circle_bend_9_deg_each(tmp_path):
    path = _svg(tmp_path, '<path d="M 20 150 A 100 100 0 0 1 220 150"/>')
    verts = load_design(path).wire().chords(20)
    assert verts.shape == (21, 2)
    np.testing.assert_allclose(bend_angles_deg(verts), -9.0, atol=ATOL_DEG)
    expected_chord = 2 * 100.0 * math.sin(math.radians(4.5))
    np.testing.assert_allclose(chord_lengths_mm(verts), expected_chord, atol=ATOL_MM)


def test_svg_shapes_lines_polylines_circles_and_transforms(tmp_path):
    body = (
        '<g transform="translate(10,0)">'
        '<line id="l" x1="0" y1="10" x2="50" y2="10"/>'
        '<polyline id="pl" points="0,20 30,20 30,50"/>'
        '<circle id="c" cx="100" cy="100" r="25"/>'
        '<rect id="r" x="0" y="60" width="40" height="20"/>'
        "</g>"
    )
    design = load_design(_svg(tmp_path, body))
    by_id = {p.element: p for p in design.paths}
    line = by_id["<line id=l>"]
    assert line.kind == "line"
    np.testing.assert_allclose(line.points_mm, [[10, -10], [60, -10]], atol=ATOL_MM)
    poly = by_id["<polyline id=pl>"]
    np.testing.assert_allclose(poly.points_mm, [[10, -20], [40, -20], [40, -50]], atol=ATOL_MM)
    # a right turn in the drawing (y down in SVG) is a clockwise, negative bend
    np.testing.assert_allclose(bend_angles_deg(poly.points_mm), [-90.0], atol=ATOL_DEG)
    circle = by_id["<circle id=c>"]
    assert circle.kind == "circle" and circle.closed
    assert _radial_error_mm(circle.points_mm, [110.0, -100.0], 25.0) < 1e-6
    assert circle.length_mm == pytest.approx(2 * math.pi * 25.0, rel=1e-5)
    rect = by_id["<rect id=r>"]
    assert rect.closed and rect.length_mm == pytest.approx(120.0, abs=ATOL_MM)


def test_svg_cubic_bezier_is_flattened_within_tolerance(tmp_path):
    design = load_design(_svg(tmp_path, '<path d="M 0 100 C 50 0 100 200 150 100"/>'))
    (p,) = design.paths
    import svgelements as se

    exact = se.Path("M 0 100 C 50 0 100 200 150 100").npoint(np.linspace(0, 1, 2001))
    exact_mm = np.column_stack((exact[:, 0], -exact[:, 1]))
    # every exact curve point lies within the tolerance of the polyline
    assert _distance_to_polyline_mm(exact_mm, p.points_mm).max() < 0.001 + 1e-9


def test_svg_text_element_is_named_in_the_error(tmp_path):
    path = _svg(tmp_path, '<line x1="0" y1="0" x2="10" y2="0"/><text id="label">R100</text>')
    with pytest.raises(InputError) as err:
        load_design(path)
    assert str(path) in str(err.value) and "<text id=label>" in str(err.value)
    # ...and can be skipped on request
    assert len(load_design(path, ignore_unknown=True).paths) == 1


def test_corrupt_and_unknown_files_are_input_errors(tmp_path):
    bad_svg = tmp_path / "bad.svg"
    bad_svg.write_text("<svg><path d='M 0 0 L", encoding="utf-8")
    bad_dxf = tmp_path / "bad.dxf"
    bad_dxf.write_text("not a dxf\n", encoding="utf-8")
    cut_dxf = tmp_path / "cut.dxf"
    cut_dxf.write_text("0\nSECTION\n", encoding="utf-8")  # truncated after two tags
    other = tmp_path / "design.step"
    other.write_text("x", encoding="utf-8")
    for path in (bad_svg, bad_dxf, cut_dxf, other, tmp_path / "missing.svg"):
        with pytest.raises(InputError) as err:
            load_design(path)
        assert str(path) in str(err.value)


def _dxf(tmp_path, units: int = 4, name: str = "design.dxf"):
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = units
    return doc, doc.modelspace(), tmp_path / name


def test_dxf_line_arc_line_chain_joins_into_one_wire(tmp_path):
    doc, msp, path = _dxf(tmp_path)
    # a U: straight leg, 180-degree arc R50 (CCW from 270 to 90 deg), straight leg back
    msp.add_line((0, -50), (100, -50))
    msp.add_arc((100, 0), 50, 270, 90)
    msp.add_line((0, 50), (100, 50))  # drawn in the opposite direction on purpose
    doc.saveas(path)
    design = load_design(path)
    assert [p.kind for p in design.paths] == ["line", "arc", "line"]
    wire = design.wire()
    assert wire.kind == "path" and not wire.closed
    assert wire.length_mm == pytest.approx(200.0 + math.pi * 50.0, rel=2e-5)  # chords
    np.testing.assert_allclose(wire.points_mm[[0, -1]], [[0, -50], [0, 50]], atol=ATOL_MM)
    (arc,) = wire.arcs
    assert arc.sweep_deg == pytest.approx(180.0) and arc.radius_mm == pytest.approx(50.0)
    # total turning along the wire is +180 degrees (left turns)
    assert bend_angles_deg(wire.points_mm).sum() == pytest.approx(180.0, abs=1e-6)


def test_dxf_units_bulged_polyline_and_circle(tmp_path):
    doc, msp, path = _dxf(tmp_path, units=1)  # inches
    # bulge 1 = a half circle between (0,0) and (2,0): radius 1 inch
    msp.add_lwpolyline([(0, 0, 0, 0, 1), (2, 0)], format="xyseb")
    msp.add_circle((5, 5), 1.0)
    doc.saveas(path)
    poly, circle = load_design(path).paths
    assert poly.kind == "polyline" and not poly.closed
    assert _radial_error_mm(poly.points_mm, [25.4, 0.0], 25.4) < 1e-6
    np.testing.assert_allclose(poly.points_mm[[0, -1]], [[0, 0], [50.8, 0]], atol=ATOL_MM)
    assert circle.kind == "circle" and circle.closed
    assert circle.arcs[0].radius_mm == pytest.approx(25.4)
    assert circle.arcs[0].centre_mm == pytest.approx((127.0, 127.0))


def test_dxf_unsupported_entity_is_named(tmp_path):
    doc, msp, path = _dxf(tmp_path)
    msp.add_line((0, 0), (10, 0))
    text = msp.add_text("R100")
    doc.saveas(path)
    with pytest.raises(InputError) as err:
        load_design(path)
    assert f"DXF TEXT #{text.dxf.handle}" in str(err.value) and str(path) in str(err.value)


def test_separate_paths_are_not_one_wire(tmp_path):
    doc, msp, path = _dxf(tmp_path)
    msp.add_line((0, 0), (10, 0))
    msp.add_line((20, 0), (30, 0))
    doc.saveas(path)
    with pytest.raises(InputError, match="2 separate paths"):
        load_design(path).wire()


@pytest.mark.parametrize("divisions", [1, 6, 13, 20])
def test_divide_into_chords_on_a_dense_arc(divisions):
    dense = arc_points_mm((0.0, 0.0), 80.0, 200.0, -140.0, tolerance_mm=1e-5)
    verts = divide_into_chords(dense, divisions)
    exact = arc_points_mm((0.0, 0.0), 80.0, 200.0, -140.0, chords=divisions)
    np.testing.assert_allclose(verts, exact, atol=1e-4)
    assert np.ptp(chord_lengths_mm(verts)) < 1e-9


def test_divide_into_chords_on_an_s_curve_keeps_equal_chords():
    t = np.linspace(0, 2 * np.pi, 4001)
    curve = np.column_stack((t * 30.0, 10.0 * np.sin(t)))
    verts = divide_into_chords(curve, 13)
    assert verts.shape == (14, 2)
    np.testing.assert_allclose(verts[[0, -1]], curve[[0, -1]], atol=1e-12)
    assert np.ptp(chord_lengths_mm(verts)) < 1e-9
    bends = bend_angles_deg(verts)
    assert bends[0] < 0 < bends[-1]  # the S changes its bend sign


def test_dxf_ellipse_spline_and_old_style_polyline(tmp_path):
    doc, msp, path = _dxf(tmp_path)
    msp.add_ellipse((10, 20), major_axis=(30, 0, 0), ratio=0.5)
    msp.add_spline([(0, 0), (10, 10), (20, 0), (30, 5)])
    msp.add_polyline2d([(0, 0), (10, 0), (10, 10)])
    doc.saveas(path)
    ellipse, spline, poly = load_design(path).paths
    assert ellipse.kind == "ellipse" and ellipse.closed
    x, y = (ellipse.points_mm - [10.0, 20.0]).T
    np.testing.assert_allclose((x / 30.0) ** 2 + (y / 15.0) ** 2, 1.0, atol=1e-9)
    assert spline.kind == "spline" and not spline.closed
    np.testing.assert_allclose(spline.points_mm[[0, -1]], [[0, 0], [30, 5]], atol=1e-9)
    np.testing.assert_allclose(poly.points_mm, [[0, 0], [10, 0], [10, 10]], atol=1e-12)
    np.testing.assert_allclose(bend_angles_deg(poly.points_mm), [90.0], atol=ATOL_DEG)


# -- properties ---------------------------------------------------------------


@settings(max_examples=40, deadline=None)
@given(
    radius=st.floats(20.0, 200.0),
    start=st.floats(-180.0, 180.0),
    sweep=st.floats(-300.0, 300.0).filter(lambda s: abs(s) > 10.0),
    chords=st.integers(1, 30),
)
def test_arc_chords_turn_by_sweep_over_n(radius, start, sweep, chords):
    verts = arc_points_mm((1.0, -2.0), radius, start, sweep, chords=chords)
    np.testing.assert_allclose(bend_angles_deg(verts), sweep / chords, atol=1e-9)
    assert np.ptp(chord_lengths_mm(verts)) < 1e-9 * radius
    # reversing the travel reverses the order and the sign of the bends
    np.testing.assert_allclose(
        bend_angles_deg(verts[::-1]), -bend_angles_deg(verts)[::-1], atol=1e-9
    )


@settings(max_examples=25, deadline=None)
@given(
    amplitude=st.floats(0.0, 30.0),
    divisions=st.integers(2, 25),
)
def test_divide_into_chords_gives_equal_chords_on_the_curve(amplitude, divisions):
    x = np.linspace(0.0, 200.0, 2001)
    curve = np.column_stack((x, amplitude * np.sin(x / 40.0)))
    verts = divide_into_chords(curve, divisions)
    assert verts.shape == (divisions + 1, 2)
    lengths = chord_lengths_mm(verts)
    assert np.ptp(lengths) < 1e-6 * lengths.mean()
    # every vertex lies on the (densely sampled) curve
    on = np.interp(verts[:, 0], x, curve[:, 1])
    np.testing.assert_allclose(verts[:, 1], on, atol=2e-3)


@pytest.mark.parametrize("bad", ["nan", "inf", "1e300"])
def test_non_finite_or_absurd_coordinates_are_refused(tmp_path, bad):
    from cvmeasure.errors import InputError

    svg = tmp_path / "bad.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
        f'viewBox="0 0 100 100"><polyline points="0,0 50,0 {bad},30" fill="none"/></svg>'
    )
    with pytest.raises(InputError, match=r"bad\.svg: .*(not a finite number|beyond|unreadable)"):
        load_design(svg)


def test_a_noisy_curve_that_doubles_back_is_divided_into_all_its_chords():
    # a noisy centreline (0.5 mm jitter every 0.17 mm) doubles back on itself: the walk at
    # the bisection's last midpoint lost its last step (39 of 41 vertices), which made the
    # part's chord search raise IndexError on a grainy photo
    rng = np.random.default_rng(26)
    t = np.linspace(0.0, 1.0, 600)
    pts = np.column_stack((100.0 * t, np.zeros_like(t))) + rng.normal(0.0, 0.5, (600, 2))
    verts = divide_into_chords(pts, 40)
    assert verts.shape == (41, 2)
    np.testing.assert_allclose(verts[[0, -1]], pts[[0, -1]])
    chords = np.hypot(*np.diff(verts, axis=0).T)
    # all but the last chord equal (measured: the last 0.7 mm longer, of 2.5 mm)
    assert np.ptp(chords[:-1]) < 1e-6
    assert chords[-1] >= chords[0] - 1e-6
