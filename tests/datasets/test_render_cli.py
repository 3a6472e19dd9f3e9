"""``cvmeasure render`` through the CLI entry point."""

from __future__ import annotations

import json

import cv2
import pytest

from cvmeasure.cli import main


def test_render_bender_writes_photo_and_truth(tmp_path, capsys):
    code = main(
        ["render", "bender", "--pin-deg", "-40", "--bend-deg", "30", "--scale", "0.1",
         "--occlude", "wire_b=0.3", "--tilt-deg", "10", "--bayer", "--lateral-ca", "5e-4", "-o", str(tmp_path), "--json"]
    )  # fmt: skip
    assert code == 0
    out = json.loads(capsys.readouterr().out)
    assert out[0]["bend_angle_deg"] == pytest.approx(30.0) and out[0][
        "pin_angle_deg"
    ] == pytest.approx(-40.0)
    truth = json.loads((tmp_path / "bender.truth.json").read_text())
    assert truth["markers"]["wire_b"]["occluded_fraction"] == 0.3
    assert truth["pose"]["tilt_deg"] == 10.0 and truth["lighting"]["bayer"] is True
    assert truth["lighting"]["lateral_ca"] == 5e-4
    assert cv2.imread(str(tmp_path / "bender.jpg")).shape == (307, 461, 3)


def test_render_board_views_and_part(tmp_path, capsys):
    assert (
        main(["render", "board", "--count", "2", "--scale", "0.1", "--clean", "-o", str(tmp_path)])
        == 0
    )
    assert (tmp_path / "board_000.png").exists() and (tmp_path / "board_001.truth.json").exists()
    code = main(
        ["render", "part", "--arc", "60", "90", "6", "--sheet", "light", "--scale", "0.1",
         "--linear", "--name", "arc", "-o", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    truth = json.loads((tmp_path / "arc.truth.json").read_text())
    assert truth["radius_mm"] == 60.0 and truth["divisions"] == 6
    assert (
        cv2.imread(str(tmp_path / "arc.linear.tiff"), cv2.IMREAD_UNCHANGED).dtype.name == "uint16"
    )
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["bender", "--pin-deg", "0", "--bend-deg", "0", "--occlude", "foo=2"], "--occlude"),
        (["bender", "--pin-deg", "0", "--bend-deg", "0", "--tilt-deg", "95"], "tilt_deg"),
        (["bender", "--pin-deg", "0", "--bend-deg", "0", "--cct-k", "100"], "cct_k"),
        (["part", "--arc", "-5", "90", "4"], "bad part"),
    ],
)
def test_bad_arguments_exit_2(tmp_path, capsys, argv, message):
    assert main(["render", *argv, "--scale", "0.05", "-o", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1
    assert not list(tmp_path.iterdir())


def test_bad_board_and_kit_files_exit_2(tmp_path, capsys):
    board = tmp_path / "board.json"
    board.write_text('{"type": "charuco"}')
    assert main(["render", "board", "--board", str(board), "-o", str(tmp_path / "o")]) == 2
    assert "board.json" in capsys.readouterr().err
    kit = tmp_path / "kit.json"
    kit.write_text("{not json")
    argv = ["render", "bender", "--pin-deg", "0", "--bend-deg", "0", "--kit", str(kit)]
    assert main([*argv, "-o", str(tmp_path / "o")]) == 2
    assert "kit.json" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_render_with_effects(tmp_path, capsys):
    code = main(
        ["render", "bender", "--pin-deg", "20", "--bend-deg", "15", "--scale", "0.1",
         "--effects", "marker_heights,wire_3d,clutter=3,wire_across=wire_b", "-o", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    truth = json.loads((tmp_path / "bender.truth.json").read_text())
    assert truth["effects"]["marker_heights"] and truth["effects"]["clutter"] == 3
    assert truth["markers"]["pin"]["height_mm"] == 18.0
    assert truth["markers"]["wire_b"]["wire_across"] is True
    code = main(
        ["render", "part", "--arc", "60", "90", "6", "--scale", "0.1", "--effects",
         "wire_3d,part_lift_mm=2.5", "-o", str(tmp_path)]
    )  # fmt: skip
    assert code == 0
    truth = json.loads((tmp_path / "part.truth.json").read_text())
    assert truth["lift_mm"] == 2.5 and len(truth["part"]["centreline_3d_mm"]) == 7
    capsys.readouterr()
    assert main(["render", "bender", "--pin-deg", "0", "--bend-deg", "0", "--effects", "fog",
                 "-o", str(tmp_path)]) == 2  # fmt: skip
    assert "--effects" in capsys.readouterr().err
