"""Part measurement end to end on rendered photos with exact truth (reduced size)."""

from __future__ import annotations

import functools

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.design import arc_points_mm, load_design
from cvmeasure.part.compare import point_to_polyline
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import PartOptions
from cvmeasure.warning import codes, has_code

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
SCALE = 0.45  # 2074 x 1382 px, 0.29 mm/px: the 2 mm wire is 7 px wide

# tolerances at this size (the benchmark holds the full-size targets)
RADIUS_REL = 0.003
VERTEX_BEND_DEG = 0.15
SEGMENT_BEND_DEG = 0.05


@functools.cache
def _photo(kind: str, sheet: str):
    parts = {
        "half": cvmeasure_datasets.arc_part(60.0, 180.0, 10),
        "short": cvmeasure_datasets.arc_part(80.0, 70.0, 6),
        "saddle": cvmeasure_datasets.saddle_part(200.0, 20.0, 13),
    }
    pose = cvmeasure_datasets.Pose(
        tilt_deg=2.5, tilt_direction_deg=40.0, distance_mm=900.0, offset_mm=(280.0, 100.0)
    )
    return cvmeasure_datasets.render_part_photo(
        part=parts[kind], board=BOARD, sheet=sheet, pose=pose, seed=3, scale=SCALE
    )


def _aligned_bend_error(measured: np.ndarray, true: np.ndarray) -> float:
    """Worst vertex-bend error; the truth's direction of travel is arbitrary."""
    return min(float(np.max(np.abs(measured - true))), float(np.max(np.abs(measured + true[::-1]))))


@pytest.mark.parametrize(
    ("kind", "sheet"), [("half", "dark"), ("half", "light"), ("short", "light"), ("short", "dark")]
)
def test_arcs_on_both_sheets(kind, sheet):
    photo = _photo(kind, sheet)
    truth = photo.truth
    n = truth["divisions"]
    m = measure_part(
        photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=n), source=f"{kind}-{sheet}"
    )
    assert m.result.method == "centreline_fit"
    assert m.result.radius_mm == pytest.approx(truth["radius_mm"], rel=RADIUS_REL)
    assert m.result.segment_bend_deg == pytest.approx(
        truth["arc_angle_deg"] / n, abs=SEGMENT_BEND_DEG
    )
    assert m.result.chord_width_mm == pytest.approx(truth["chord_width_mm"], abs=0.3)
    assert m.result.height_mm == pytest.approx(truth["height_mm"], abs=0.3)
    true_bends = np.asarray(truth["segment_bend_deg"])
    assert _aligned_bend_error(m.vertex_bend_deg, true_bends) < VERTEX_BEND_DEG
    # an arc is ordered to turn counter-clockwise in the board frame
    assert np.all(m.vertex_bend_deg > 0)
    assert not has_code(m.warnings, "part_cut_off")
    # the centreline lies on the true wire axis
    _, dist, _ = point_to_polyline(m.centreline_mm, np.asarray(truth["part"]["centreline_mm"]))
    assert np.sqrt(np.mean(dist**2)) < 0.05
    # the seed's methods ran on the same photo, and were worse on the radius
    assert set(m.methods) == {"centreline_fit", "seed_ellipse", "seed_sagitta"}
    for name in ("seed_ellipse", "seed_sagitta"):
        err = abs(m.methods[name].radius_mm / truth["radius_mm"] - 1)
        assert err > abs(m.result.radius_mm / truth["radius_mm"] - 1)


def test_headline_method_can_be_the_seeds():
    photo = _photo("half", "dark")
    m = measure_part(
        photo.bgr,
        BOARD,
        photo.camera,
        options=PartOptions(divisions=10, method="sagitta"),
    )  # the older name is read
    assert m.result.method == "seed_sagitta"
    assert m.result.radius_mm == m.methods["seed_sagitta"].radius_mm
    with pytest.raises(ValueError, match="method must be one of"):
        PartOptions(method="hough")  # type: ignore[arg-type]


@pytest.mark.parametrize("sheet", ["dark", "light"])
def test_saddle_bends_change_sign(sheet):
    photo = _photo("saddle", sheet)
    truth = photo.truth
    m = measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=13))
    true_bends = np.asarray(truth["segment_bend_deg"])
    assert np.sign(true_bends).min() < 0 < np.sign(true_bends).max()
    assert _aligned_bend_error(m.vertex_bend_deg, true_bends) < VERTEX_BEND_DEG
    assert m.result.chord_width_mm == pytest.approx(truth["chord_width_mm"], abs=0.3)
    assert m.result.height_mm == pytest.approx(truth["height_mm"], abs=0.2)
    # a saddle says what its numbers are: no arc, bends of both signs
    assert m.shape == "s-curve" and has_code(m.warnings, "part_s_curve")
    assert measure_part(photo.bgr, BOARD, photo.camera).result.divisions == 13  # found


def test_without_divisions_the_vertices_are_found_in_the_photo():
    photo = _photo("short", "dark")
    m = measure_part(photo.bgr, BOARD, photo.camera)
    assert m.divisions_from == "photo" and m.result.divisions == 6  # 5 vertices found
    given = measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=6))
    assert m.result.radius_mm == pytest.approx(given.result.radius_mm, abs=1e-9)
    assert m.result.radius_mm == pytest.approx(80.0, rel=3e-3)  # the vertices' circle
    assert len(m.chords_found.vertex_arclength_mm) == 5
    assert not codes(m.warnings) & {"divisions_mismatch", "divisions_not_found"}
    # a wrong --divisions is used as given, and said
    wrong = measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=5))
    assert any(
        w.code == "divisions_mismatch"
        and "--divisions 5, but the photo shows 6 chords" in w.message
        for w in wrong.warnings
    )


@pytest.mark.parametrize("kind", ["half", "short"])
def test_a_seed_method_far_from_the_centreline_is_warned_about(kind):
    photo = _photo(kind, "light")
    m = measure_part(photo.bgr, BOARD, photo.camera, options=PartOptions(method="seed_ellipse"))
    ours = m.methods["centreline_fit"].arc_angle_deg
    for name in ("seed_ellipse", "seed_sagitta"):
        if name not in m.methods:
            continue
        far = abs(m.methods[name].arc_angle_deg - ours) > 10.0
        said = any(
            w.code == "seed_method_disagrees" and f"the {name} method" in w.message
            for w in m.warnings
        )
        assert far == said, (name, m.methods[name].arc_angle_deg, ours)


def test_a_smooth_arc_has_no_vertices_and_is_fitted_as_a_circle():
    part = cvmeasure_datasets.arc_part(80.0, 120.0, 400)  # chords of 0.4 mm: a smooth arc
    pose = cvmeasure_datasets.Pose(distance_mm=900.0, offset_mm=(280.0, 100.0))
    photo = cvmeasure_datasets.render_part_photo(
        part=part, board=BOARD, sheet="dark", pose=pose, seed=4, scale=SCALE
    )
    m = measure_part(photo.bgr, BOARD, photo.camera)
    assert m.divisions_from is None and m.result.divisions is None
    assert m.vertex_bend_deg is None and m.shape == "arc"
    assert m.result.radius_mm == pytest.approx(80.0, rel=3e-3)
    assert m.result.arc_angle_deg == pytest.approx(120.0, abs=0.5)


def test_comparison_with_the_design_from_svg_and_dxf(tmp_path):
    import ezdxf

    photo = _photo("half", "light")
    svg = tmp_path / "half.svg"
    svg.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="100mm" '
        'viewBox="0 0 200 100"><path d="M 20 80 A 60 60 0 0 1 140 80"/></svg>',
        encoding="utf-8",
    )
    doc = ezdxf.new()
    doc.header["$INSUNITS"] = 4
    doc.modelspace().add_arc((0, 0), 60.0, 0.0, 180.0)
    dxf = tmp_path / "half.dxf"
    doc.saveas(dxf)
    for path in (svg, dxf):
        design = load_design(path).wire()
        m = measure_part(
            photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=10), design=design
        )
        cmp = m.comparison
        assert cmp is not None and cmp.bends is not None
        assert cmp.design_arc.radius_mm == pytest.approx(60.0, abs=1e-6)
        assert cmp.design_arc.segment_bend_deg == pytest.approx(18.0, abs=1e-6)
        assert cmp.deviation.rms_mm < 0.05 and cmp.deviation.max_mm < 0.3
        assert cmp.bends.max_abs_error_deg < VERTEX_BEND_DEG
        assert abs(cmp.bends.seed_absolute_error_deg) < SEGMENT_BEND_DEG
        assert cmp.bends.seed_relative_error_pct == pytest.approx(
            100 * cmp.bends.seed_absolute_error_deg / 18.0
        )
    # a design of another radius shows up in the deviation and the seed errors
    other = tmp_path / "r70.dxf"
    doc2 = ezdxf.new()
    doc2.modelspace().add_lwpolyline(arc_points_mm((0, 0), 70.0, 0.0, 180.0, chords=10))
    doc2.saveas(other)
    m = measure_part(
        photo.bgr,
        BOARD,
        photo.camera,
        options=PartOptions(divisions=10),
        design=load_design(other).wire(),
    )
    assert m.comparison.deviation.max_mm > 3.0
    # the 70 mm polyline's chords turn by 18 deg as well: only the size differs
    assert abs(m.comparison.bends.seed_absolute_error_deg) < SEGMENT_BEND_DEG


def test_raised_plane_mapping_inverts_the_projection():
    import cv2

    from cvmeasure.lens.plane import estimate_plane

    photo = _photo("short", "dark")
    plane = estimate_plane(photo.bgr, BOARD, photo.camera)
    board_xy = np.array([[350.0, 60.0], [420.0, 150.0], [300.0, 100.0]])
    height = 1.59  # a 1/8 inch wire's axis above the board
    obj = np.column_stack((board_xy, np.full(3, -height)))  # board z points away from the camera
    px, _ = cv2.projectPoints(
        obj, plane.rvec, plane.tvec_mm, photo.camera.camera_matrix, photo.camera.dist_coeffs
    )
    px = px.reshape(-1, 2)
    np.testing.assert_allclose(plane.image_to_plane_mm(px, height_mm=height), board_xy, atol=1e-6)
    # read in the board's plane instead, the raised points spread out from the
    # camera's foot point by about height / distance (0.18 % at 0.9 m)
    flat = plane.image_to_plane_mm(px, height_mm=0.0)
    spread = np.hypot(*np.diff(flat, axis=0).T) / np.hypot(*np.diff(board_xy, axis=0).T)
    np.testing.assert_allclose(spread, 1 + height / 900.0, rtol=3e-4)


def test_real_board_photos_without_a_wire_are_refused(shared_real):
    """Real photos of a ChArUco board on a cluttered desk: thin lines, but no wire."""
    from cvmeasure.camera_model import CameraModel
    from cvmeasure.errors import InputError
    from cvmeasure.imageio import read_photo

    folder = shared_real / "opencv-contrib-aruco-charuco-5x7"
    # OpenCV's reference calibration of these photos (tutorial_camera_charuco.yml)
    camera = CameraModel(
        (640, 480),
        np.array([[452.5107, 0, 317.7030], [0, 456.7671, 277.7516], [0, 0, 1]]),
        np.array([0.121369, -1.085466, 0.000117868, -0.000462407, 2.954259]),
    )
    board = CharucoBoardSpec(5, 7, 40.0, 20.0, "DICT_6X6_250")
    for k in range(4):
        path = folder / f"img_0{k}.jpg"
        with pytest.raises(InputError, match="no wire found") as err:
            measure_part(read_photo(path).bgr, board, camera, source=str(path))
        assert str(path) in str(err.value)


def test_a_wire_cut_by_the_photos_edge_is_flagged():
    photo = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(60.0, 180.0, 10),
        board=BOARD,
        sheet="dark",
        seed=3,
        scale=SCALE,
        placement_deg=90.0,
        pose=cvmeasure_datasets.Pose(distance_mm=900.0, offset_mm=(160.0, 100.0)),
    )
    m = measure_part(photo.bgr, BOARD, photo.camera)
    assert any(
        w.code == "part_cut_off" and "next to the photo's edge" in w.message for w in m.warnings
    )
