"""``cvmeasure calibrate`` and ``cvmeasure plane`` through cvmeasure.cli.main, exit-2 paths included."""

from __future__ import annotations

import json
import re

import cv2
import numpy as np
import pytest
from _calib_synth import look_at_pose, render_view

from cvmeasure.camera_model import load_camera, save_camera
from cvmeasure.cli import main


@pytest.fixture(scope="module")
def photo_dir(tmp_path_factory, rendered_views, charuco_board):
    d = tmp_path_factory.mktemp("photos")
    for i, (img, _, _) in enumerate(rendered_views[:10]):
        if i == 0:  # one 16-bit TIFF among the JPEGs and PNGs
            cv2.imwrite(str(d / f"view{i:02d}.tiff"), img.astype(np.uint16) * 257)
        elif i % 2:
            cv2.imwrite(str(d / f"view{i:02d}.jpg"), img, [cv2.IMWRITE_JPEG_QUALITY, 95])
        else:
            cv2.imwrite(str(d / f"view{i:02d}.png"), img)
    cv2.imwrite(str(d / "blank.png"), np.full((640, 960), 200, np.uint8))
    (d / "board.json").write_text(json.dumps(charuco_board.to_dict()))
    return d


def _photos(d):
    return sorted(str(p) for p in d.iterdir() if p.suffix in (".png", ".jpg", ".tiff"))


def test_calibrate_writes_the_camera_json(photo_dir, tmp_path, true_camera, capsys, shared_real):
    out = tmp_path / "camera.json"
    raw = str(shared_real / "raw" / "Nikon_uncompressed.nef")  # a RAW file without a board
    argv = [
        "calibrate",
        *_photos(photo_dir),
        raw,
        "--board",
        str(photo_dir / "board.json"),
        "-o",
        str(out),
        "--json",
    ]
    assert main(argv) == 0
    summary = json.loads(capsys.readouterr().out)
    cam = load_camera(out)
    assert cam.fx == pytest.approx(true_camera.fx, rel=4e-3)
    data = json.loads(out.read_text())
    for key in (
        "rms_px",
        "std_devs",
        "per_view_errors_px",
        "views_used",
        "views_rejected",
        "coverage",
        "projection_uncertainty",
        "cross_validation",
        "warnings",
        "board",
        "provenance",
        "observations",
    ):
        assert key in data, key
    rejected = {r["source"].rsplit("/", 1)[-1]: r["reason"] for r in data["views_rejected"]}
    assert "no ChArUco board found" in rejected["blank.png"]
    assert "Nikon_uncompressed.nef" in rejected
    assert len(data["views_used"]) == 10 and len(data["per_view_errors_px"]) == 10
    assert data["board"] == json.loads((photo_dir / "board.json").read_text())
    assert summary["views_used"] == 10 and summary["cross_validation_central_rms_px"] < 0.5
    assert data["cross_validation"]["views"] == [5, 5]
    # --model auto (the default) says which model, why, and what the next best would change
    # at the image corners; the board warp says what the lens model's extension saw
    choice = data["model_choice"]
    assert choice["chosen"] == data["model"] and choice["why"]
    assert choice["next_best"]["model"] != data["model"]
    assert choice["next_best"]["image_corner_change_px"] >= 0.0
    for cand in choice["candidates"]:
        assert cand["held_out_centre_rms_px"] > 0 and cand["held_out_edge_rms_px"] > 0
    warp = data["board_warp"]
    assert warp["used"] is False and warp["reason"]
    assert warp["extension_model"] in ("2", "5", "rational", "thin-prism")


def test_calibrate_human_output_and_models(photo_dir, tmp_path, capsys):
    base = ["calibrate", *_photos(photo_dir), "--board", str(photo_dir / "board.json")]
    out = tmp_path / "cam5.json"
    assert main([*base, "-o", str(out), "--model", "5"]) == 0
    text = capsys.readouterr().out
    assert "cross-validation" in text and "skipped" in text and "blank.png" in text
    # the summary says what was dropped
    assert re.search(r"dropped \d+ outlier corners and 1 photos", text), text
    assert len(load_camera(out).dist_coeffs) == 5
    # model 8 on these few views: written only when it is a lens every reader accepts;
    # a fit that folds the image is refused with the reason, nothing written
    out = tmp_path / "cam8.json"
    code = main([*base, "-o", str(out), "--model", "8"])
    captured = capsys.readouterr()
    if code == 0:
        cam = load_camera(out)
        assert len(cam.dist_coeffs) == 8
        unc_max = cam.lens_record.get("projection_uncertainty", {}).get("max_px", 0.0)
        ill = bool(np.any(np.abs(cam.dist_coeffs) > 10.0)) or unc_max > 10 * max(cam.image_size_px)
        assert ("ill-conditioned" in captured.out) == ill
    else:
        assert code == 2 and not out.exists()
        err = captured.err.strip().splitlines()
        assert len(err) == 1 and "cam8.json" in err[0] and "not written" in err[0], err


def test_calibrate_board_warp_flag(photo_dir, tmp_path, capsys):
    """--board-warp: the renders' board is flat; auto says so (warp in mm with its sigma)
    and keeps the flat solve, off prints no warp line, on keeps it in the camera JSON."""
    base = ["calibrate", *_photos(photo_dir), "--board", str(photo_dir / "board.json")]
    cams = {}
    for mode in ("auto", "off", "on"):
        out = tmp_path / f"cam_{mode}.json"
        assert main([*base, "-o", str(out), "--model", "5", "--board-warp", mode]) == 0
        text = capsys.readouterr().out
        line = [t for t in text.splitlines() if t.startswith("board warp")]
        cams[mode] = load_camera(out)
        warp = cams[mode].lens_record["board_warp"]
        if mode == "off":
            assert not line and warp is None
            continue
        side = r"\d\.\d{4} \+- \d\.\d{4} mm (towards the camera|away from it) along the \d+ mm side"
        assert re.match(
            rf"board warp \(the middle out of the plane of the edges\): {side}, {side}", line[0]
        )
        assert warp["used"] == (mode == "on")
        assert "flat within noise" in line[0], line  # the renderer's board is flat
        assert abs(warp["warp_mm"][0]) <= 3 * warp["sigma_mm"][0]
    assert cams["auto"].fx == cams["off"].fx
    assert "--board-warp on" in cams["on"].lens_record["provenance"]["command"]


def test_calibrate_bad_inputs_exit_2(photo_dir, tmp_path, capsys):
    out = tmp_path / "never.json"
    board = str(photo_dir / "board.json")
    cases = []
    bad_board = tmp_path / "bad.json"
    bad_board.write_text('{"type": "charuco", "squares_x": 5}')
    cases.append(
        (["calibrate", *_photos(photo_dir), "--board", str(bad_board), "-o", str(out)], "bad.json")
    )
    broken = tmp_path / "broken.jpg"
    broken.write_bytes(b"\xff\xd8\xff\xe0 not really a jpeg")
    cases.append(
        (
            ["calibrate", str(broken), *_photos(photo_dir), "--board", board, "-o", str(out)],
            "broken.jpg",
        )
    )
    cases.append(
        (
            ["calibrate", *_photos(photo_dir)[:2], "--board", board, "-o", str(out)],
            "need at least 3",
        )
    )
    cases.append(
        (["calibrate", str(photo_dir / "blank.png"), "--board", board, "-o", str(out)], "blank.png")
    )
    wrong = tmp_path / "wrong.json"
    wrong.write_text(
        json.dumps({"type": "chessboard", "inner_x": 8, "inner_y": 5, "square_mm": 25.0})
    )
    cases.append(
        (
            ["calibrate", *_photos(photo_dir)[:2], "--board", str(wrong), "-o", str(out)],
            "no usable board",
        )
    )
    for argv, needle in cases:
        capsys.readouterr()
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert needle in err and err.count("\n") == 1, err
    assert not out.exists()


def test_plane_cli(charuco_board, true_camera, tmp_path, capsys):
    cam_path = save_camera(tmp_path / "camera.json", true_camera)
    (tmp_path / "board.json").write_text(json.dumps(charuco_board.to_dict()))
    rvec, tvec = look_at_pose(charuco_board, 400.0, 0.0, 8.0)
    photo = tmp_path / "plane.png"
    cv2.imwrite(str(photo), render_view(charuco_board, true_camera, rvec, tvec))
    rect = tmp_path / "rect.png"
    argv = [
        "plane",
        str(photo),
        "--board",
        str(tmp_path / "board.json"),
        "--camera",
        str(cam_path),
        "--json",
        "--rectified",
        str(rect),
        "--px-per-mm",
        "2",
        "-o",
        str(tmp_path / "plane.json"),
    ]
    assert main(argv) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["tilt_deg"] == pytest.approx(8.0, abs=0.15)
    assert result["tilt_direction_deg"] == pytest.approx(180.0, abs=2.0)
    assert result["affine_ok"] is False and result["tolerance_deg"] == 0.05
    assert np.asarray(result["H_board_image"]).shape == (3, 3)
    assert json.loads((tmp_path / "plane.json").read_text())["tilt_deg"] == result["tilt_deg"]
    assert cv2.imread(str(rect)) is not None
    loose = [
        "plane",
        str(photo),
        "--board",
        str(tmp_path / "board.json"),
        "--camera",
        str(cam_path),
    ]
    assert main([*loose, "--tolerance-deg", "2.0"]) == 0
    assert "affine model OK" in capsys.readouterr().out
    # Bad inputs: missing camera, corrupt camera, no board, bad tolerance.
    bad = tmp_path / "corrupt.json"
    bad.write_text("{")
    blank = tmp_path / "blank.png"
    cv2.imwrite(str(blank), np.full((640, 960), 255, np.uint8))
    base = ["--board", str(tmp_path / "board.json")]
    for argv2, needle in [
        (["plane", str(photo), *base, "--camera", str(tmp_path / "nope.json")], "nope.json"),
        (["plane", str(photo), *base, "--camera", str(bad)], "corrupt.json"),
        (["plane", str(blank), *base, "--camera", str(cam_path)], "blank.png: no ChArUco board"),
        (
            ["plane", str(photo), *base, "--camera", str(cam_path), "--tolerance-deg", "0"],
            "--tolerance-deg",
        ),
    ]:
        capsys.readouterr()
        try:
            code = main(argv2)
        except SystemExit as exc:  # an option value refused by the parser
            code = exc.code
        assert code == 2
        err = capsys.readouterr().err
        assert needle in err and err.count("\n") == 1, err


def test_help_lists_the_commands(capsys):
    for cmd in (["calibrate", "--help"], ["plane", "--help"], ["targets", "charuco", "--help"]):
        with pytest.raises(SystemExit) as exc:
            main(cmd)
        assert exc.value.code == 0
    assert "--tolerance-deg" in capsys.readouterr().out
