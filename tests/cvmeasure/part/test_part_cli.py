"""``cvmeasure part`` through cvmeasure.cli.main: real JPEG files, exit codes, outputs."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.camera_model import save_camera
from cvmeasure.cli import main
from cvmeasure.fileio import atomic_write_json

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("part_cli")
    photo = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(55.0, 150.0, 10),
        board=BOARD,
        sheet="dark",
        seed=4,
        scale=0.4,
    )
    jpg, truth = photo.save(folder / "part")
    camera = folder / "camera.json"
    save_camera(camera, photo.camera)
    board = atomic_write_json(folder / "board.json", BOARD.to_dict())
    design = folder / "design.svg"
    # the design: R55 arc over 150 deg, drawn as a path (x right, y down in SVG)
    a0, a1 = np.radians(15.0), np.radians(165.0)
    x0, y0 = 100 + 55 * np.cos(a0), 100 - 55 * np.sin(a0)
    x1, y1 = 100 + 55 * np.cos(a1), 100 - 55 * np.sin(a1)
    design.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" viewBox="0 0 200 200">'
        f'<path d="M {x0} {y0} A 55 55 0 0 0 {x1} {y1}"/></svg>',
        encoding="utf-8",
    )
    # the camera moved over the board: the part is out of view (no wire)
    away = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(55.0, 150.0, 10),
        board=BOARD,
        sheet="dark",
        seed=4,
        scale=0.4,
        pose=cvmeasure_datasets.Pose(distance_mm=600.0, offset_mm=(120.0, 100.0)),
    )
    no_wire = folder / "no_wire.png"
    cv2.imwrite(str(no_wire), away.bgr)
    # the photo with the board covered: no board
    no_board_img = photo.bgr.copy()
    no_board_img[:, : int(photo.bgr.shape[1] * 0.55)] = 90
    no_board = folder / "no_board.png"
    cv2.imwrite(str(no_board), no_board_img)
    return {
        "jpg": jpg,
        "truth": json.loads(truth.read_text()),
        "camera": camera,
        "board": board,
        "design": design,
        "no_wire": no_wire,
        "no_board": no_board,
        "folder": folder,
    }


def test_part_json_overlay_and_plot(files, capsys):
    out = files["folder"]
    code = main(
        [
            "part",
            str(files["jpg"]),
            "--board",
            str(files["board"]),
            "--camera",
            str(files["camera"]),
            "--divisions",
            "10",
            "--design",
            str(files["design"]),
            "--overlay",
            str(out / "overlay.png"),
            "--plot",
            str(out / "deviation.png"),
            "-o",
            str(out / "result.json"),
            "--json",
        ]
    )
    assert code == 0
    result = json.loads(capsys.readouterr().out)
    truth = files["truth"]
    assert result["radius_mm"] == pytest.approx(truth["radius_mm"], rel=0.004)
    assert result["arc_angle_deg"] == pytest.approx(150.0, abs=0.6)
    assert result["segment_bend_deg"] == pytest.approx(15.0, abs=0.06)
    assert len(result["vertex_bend_deg"]) == 9
    for key in ("chord_width_mm", "height_mm"):
        assert result[key] == pytest.approx(truth[key], abs=0.4)
    assert set(result["methods"]) == {"centreline_fit", "seed_ellipse", "seed_sagitta"}
    cmp = result["comparison"]
    assert cmp["deviation"]["rms_mm"] < 0.1
    assert cmp["bends"]["max_abs_error_deg"] < 0.25
    assert "seed_relative_error_pct" in cmp["bends"]
    assert json.loads((out / "result.json").read_text())["radius_mm"] == result["radius_mm"]
    overlay = cv2.imread(str(out / "overlay.png"))
    assert overlay.shape == cv2.imread(str(files["jpg"])).shape
    plot = cv2.imread(str(out / "deviation.png"))
    assert plot is not None and plot.shape[0] > 100


def test_part_table_output(files, capsys):
    code = main(
        [
            "part",
            str(files["jpg"]),
            "--board",
            str(files["board"]),
            "--camera",
            str(files["camera"]),
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "radius_mm" in text and "[seed_ellipse]" in text and "[seed_sagitta]" in text


def test_part_with_a_plane_json_needs_no_camera(files, capsys):
    """``part PHOTO --plane P`` reads the camera from the plane JSON (as ``measure`` does):
    the same radius as through the board to 1e-9, and within 0.4 % of the render's truth;
    ``--board`` without ``--camera`` is one line naming --board, exit 2."""
    plane = files["folder"] / "plane.json"
    board_cam = ["--board", str(files["board"]), "--camera", str(files["camera"])]
    assert main(["plane", str(files["jpg"]), *board_cam, "-o", str(plane)]) == 0
    capsys.readouterr()
    assert main(["part", str(files["jpg"]), *board_cam, "--json"]) == 0
    via_board = json.loads(capsys.readouterr().out)
    assert main(["part", str(files["jpg"]), "--plane", str(plane), "--json"]) == 0
    via_plane = json.loads(capsys.readouterr().out)
    assert via_plane["radius_mm"] == pytest.approx(via_board["radius_mm"], rel=1e-9)
    assert via_plane["radius_mm"] == pytest.approx(files["truth"]["radius_mm"], rel=0.004)
    assert main(["part", str(files["jpg"]), "--board", str(files["board"])]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--board" in err and "--camera" in err


@pytest.mark.parametrize(
    ("photo_key", "message"),
    [("no_wire", "no wire found"), ("no_board", "")],
)
def test_photo_without_wire_or_board_exits_2_naming_it(files, capsys, photo_key, message):
    photo = files[photo_key]
    code = main(
        ["part", str(photo), "--board", str(files["board"]), "--camera", str(files["camera"])]
    )
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and str(photo) in err and message in err


def test_bad_inputs_exit_2(files, capsys, tmp_path):
    base = ["--board", str(files["board"]), "--camera", str(files["camera"])]
    broken = tmp_path / "broken.dxf"
    broken.write_text("0\nSECTION\n", encoding="utf-8")
    from cvmeasure.kit import default_kit

    flat_kit = tmp_path / "flat_kit.json"  # a kit written before wire sizes existed
    kit = default_kit().to_dict()
    kit.pop("wire_diameter_mm")
    atomic_write_json(flat_kit, kit)
    cases = [
        ([str(files["jpg"]), *base, "--kit", str(flat_kit)], "flat_kit.json"),
        ([str(tmp_path / "missing.jpg"), *base], "missing.jpg"),
        ([str(files["jpg"]), *base, "--design", str(broken)], "broken.dxf"),
        ([str(files["jpg"]), *base, "--plot", str(tmp_path / "p.png")], "--plot"),
    ]
    for argv, named in cases:
        assert main(["part", *argv]) == 2
        err = capsys.readouterr().err
        assert named in err
    with pytest.raises(SystemExit) as info:  # refused by the parser
        main(["part", str(files["jpg"]), *base, "--divisions", "0"])
    assert info.value.code == 2 and "--divisions" in capsys.readouterr().err
    assert not (tmp_path / "p.png").exists()


def test_part_help(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["part", "--help"])
    assert exc.value.code == 0
    assert "--divisions" in capsys.readouterr().out


def test_downsample_option(files, capsys):
    """``--downsample 2`` measures on 2 x 2 blocks (recorded as such); a count other than a
    whole number from 1 is refused by the parser, exit 2 naming the option."""
    base = ["--board", str(files["board"]), "--camera", str(files["camera"])]
    assert main(["part", str(files["jpg"]), *base, "--downsample", "2", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["downsample"] == 2
    assert rec["radius_mm"] == pytest.approx(files["truth"]["radius_mm"], rel=0.01)
    # auto (the default) keeps a 6 px wire on the photo's own pixels
    assert main(["part", str(files["jpg"]), *base, "--downsample", "auto", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["downsample"] == 1
    for bad in ("0", "1.5", "many"):
        with pytest.raises(SystemExit) as info:
            main(["part", str(files["jpg"]), *base, "--downsample", bad])
        assert info.value.code == 2 and "--downsample" in capsys.readouterr().err
