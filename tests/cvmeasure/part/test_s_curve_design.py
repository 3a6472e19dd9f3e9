"""An S-shaped design, whose best-fitting circle is a line: compared, never a crash.

A polyline S symmetric about its middle (bends +45, -45) has no circle through its
vertices (Taubin's algebraic fit degenerates to a line). ``part --design`` must still
compare the part vertex for vertex, reporting the design's radius as unbounded.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.camera_model import save_camera
from cvmeasure.cli import main
from cvmeasure.design import DesignPath, load_design
from cvmeasure.fileio import atomic_write_json
from cvmeasure.part.arc import polygon_arc
from cvmeasure.part.measure import compare_with_design
from cvmeasure.part.result import ArcResult

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
_C, _S = math.cos(math.radians(45.0)), math.sin(math.radians(45.0))
#: the S drawn (design frame, y up): 30 mm chords, bends +45 then -45 deg
S_MM = np.array([(0.0, 0.0), (30.0, 0.0), (30 + 30 * _C, 30 * _S), (60 + 30 * _C, 30 * _S)])
#: a rendered part's vertex bends against the truth (deg); the fit's scatter is ~0.02
BEND_TOL_DEG = 0.1


def test_polygon_arc_of_a_symmetric_s_and_a_straight_wire_is_a_line():
    geo, circle = polygon_arc(S_MM)
    assert math.isinf(geo.radius_mm) and geo.arc_angle_deg == 0.0
    assert geo.chord_width_mm == pytest.approx(float(np.hypot(*(S_MM[-1] - S_MM[0]))), rel=1e-12)
    assert math.isinf(circle.radius)
    geo, _ = polygon_arc(np.array([(0.0, 0.0), (50.0, 0.0)]))
    assert math.isinf(geo.radius_mm) and geo.chord_width_mm == pytest.approx(50.0)
    # an arc is still the circle through its vertices
    t = np.radians(np.linspace(0.0, 90.0, 4))
    geo, _ = polygon_arc(np.column_stack((40 * np.cos(t), 40 * np.sin(t))))
    assert geo.radius_mm == pytest.approx(40.0, rel=1e-9)
    assert geo.arc_angle_deg == pytest.approx(90.0, rel=1e-9)


def test_compare_with_an_s_design_matches_its_bends():
    design = DesignPath(S_MM, False, "polyline", "<polyline id=s>")
    seen_board = S_MM * np.array([1.0, -1.0])  # board frame (y down as the camera sees it)
    measured = ArcResult("centreline_fit", math.inf, 84.0, 7.6, 0.0, 3)
    cmp = compare_with_design(seen_board, np.array([-45.0, 45.0]), measured, design)
    assert cmp.bends is not None
    np.testing.assert_allclose(cmp.bends.design_bend_deg, [45.0, -45.0], atol=1e-9)
    assert cmp.bends.max_abs_error_deg < 1e-9
    assert math.isinf(cmp.design_arc.radius_mm)
    assert cmp.deviation.max_mm < 1e-9


def test_part_cli_on_a_rendered_s_part(tmp_path, capsys):
    photo = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.polyline_part(S_MM), board=BOARD, sheet="dark", seed=4, scale=0.4
    )
    jpg, _ = photo.save(tmp_path / "part")
    save_camera(tmp_path / "camera.json", photo.camera)
    atomic_write_json(tmp_path / "board.json", BOARD.to_dict())
    svg = tmp_path / "s.svg"
    pts = " ".join(f"{x + 20:.6f},{60 - y:.6f}" for x, y in S_MM)  # SVG: y down
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="100mm" '
        f'viewBox="0 0 200 100"><polyline id="s" points="{pts}" fill="none"/></svg>',
        encoding="utf-8",
    )
    assert len(load_design(svg).wire().points_mm) == 4
    out = tmp_path / "part.json"
    code = main(
        ["part", str(jpg), "--board", str(tmp_path / "board.json"),
         "--camera", str(tmp_path / "camera.json"), "--design", str(svg),
         "--divisions", "3", "-o", str(out)]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    cmp = json.loads(out.read_text())["comparison"]
    assert cmp["design_arc"]["radius_mm"] is None  # unbounded: no circle describes an S
    np.testing.assert_allclose(cmp["bends"]["design_bend_deg"], [45.0, -45.0], atol=1e-6)
    assert cmp["bends"]["max_abs_error_deg"] < BEND_TOL_DEG
    assert cmp["deviation"]["max_mm"] < 0.1
