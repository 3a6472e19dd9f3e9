"""The one error path: every bad input is one stderr line naming the file or option, exit 2.

Representative cases of the fuzz corpus (``benchmarks/fuzz_inputs.py`` runs all of
them): the exception mapping itself, an unwritable output, a damaged photo whose
decoder chatters on stderr, a batch photo that fails and is retried, ``-`` as
standard output, and the readers' refusals of damaged or wrong-kind files.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

from cvmeasure.cli import main
from cvmeasure.cli.errors import classify_exit
from cvmeasure.errors import InputError
from cvmeasure.fileio import read_csv_rows, read_json, read_jsonl, sniff_kind

EXE = str(Path(sys.executable).with_name("cvmeasure"))


def _args(**kw) -> argparse.Namespace:
    return argparse.Namespace(command="fit", **kw)


def test_os_errors_name_the_file_and_what_failed(tmp_path):
    args = _args(trials=tmp_path / "t.csv", out=tmp_path / "ro" / "cal.json")
    code, line = classify_exit(
        PermissionError(13, "Permission denied", str(tmp_path / "ro" / ".cal.json.x1y2.tmp")),
        args,
    )
    assert (
        code == 2
        and line == f"{tmp_path / 'ro'}: cannot write a file in this folder: Permission denied"
    )
    code, line = classify_exit(
        PermissionError(13, "Permission denied", str(tmp_path / "t.csv")), args
    )
    assert (code, line) == (2, f"{tmp_path / 't.csv'}: cannot read: Permission denied")
    code, line = classify_exit(
        PermissionError(13, "Permission denied", str(tmp_path / "ro" / "cal.json")), args
    )
    assert (code, line) == (2, f"{tmp_path / 'ro' / 'cal.json'}: cannot write: Permission denied")


def test_library_refusals_are_bad_input_and_the_rest_internal(tmp_path):
    args = _args(trials=tmp_path / "t.csv", out=tmp_path / "cal.json")
    code, line = classify_exit(ValueError("could not convert string to float: 'abc'"), args)
    assert code == 2 and line.startswith(str(tmp_path / "t.csv")) and "\n" not in line
    err = cv2.error(
        "OpenCV(5.0.0) x.cpp:1: error: (-209:Sizes of input arguments do not match) bad"
    )
    code, line = classify_exit(err, args)
    assert code == 2 and "OpenCV cannot process it (Sizes of input arguments" in line
    code, line = classify_exit(AttributeError("'X' object has no attribute 'y'"), args)
    assert code == 1 and line.startswith("internal error on ") and "CVMEASURE_DEBUG" in line
    assert classify_exit(KeyboardInterrupt(), args) == (130, "interrupted")
    assert classify_exit(SystemExit(2), args) == (None, None)


def _run(*argv: str, cwd: Path, **kw) -> subprocess.CompletedProcess:
    return subprocess.run([EXE, *argv], cwd=cwd, capture_output=True, text=True, timeout=120, **kw)


def test_a_damaged_photo_is_one_line_without_the_decoders_chatter(tmp_path):
    img = np.full((240, 320, 3), 128, np.uint8)
    ok, data = cv2.imencode(".jpg", img)
    bad = tmp_path / "cut.jpg"
    bad.write_bytes(data.tobytes()[: len(data) // 2])  # libjpeg warns "Premature end..."
    proc = _run("measure", str(bad), cwd=tmp_path)
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert proc.returncode == 2 and len(lines) == 1, proc.stderr
    assert str(bad) in lines[0] and "Traceback" not in proc.stderr


@pytest.mark.skipif(
    shutil.which("setpriv") is None or os.geteuid() != 0, reason="needs root + setpriv"
)
def test_a_read_only_output_folder_is_one_line(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,commanded_pin_deg\n1,10\n2,20\n")
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    proc = subprocess.run(
        [
            "setpriv",
            "--inh-caps=-all",
            "--bounding-set=-dac_override,-dac_read_search",
            "--",
            EXE,
            "simulate",
            str(plan),
            "-o",
            str(ro / "out.csv"),
        ],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.strip() == (
        f"cvmeasure simulate: {ro}: cannot write a file in this folder: Permission denied"
    )


def test_dash_is_standard_output(tmp_path):
    plan = tmp_path / "plan.csv"
    plan.write_text("trial,commanded_pin_deg\n1,10\n2,20\n")
    proc = _run("simulate", str(plan), "-o", "-", cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[0].startswith("trial,commanded_pin_deg,pin_deg")
    assert len(proc.stdout.splitlines()) == 3  # only the data: the summary went to stderr
    assert not (tmp_path / "-").exists()


def test_batch_retries_a_failed_photo_and_names_it(tmp_path, capsys):
    from tests.cvmeasure.test_batch import disc_photos

    folder = tmp_path / "p"
    disc_photos(folder, 3)
    good = (folder / "photo_001.jpg").read_bytes()
    (folder / "photo_001.jpg").write_bytes(good[:200])  # damaged
    out = tmp_path / "r.jsonl"
    argv = ["batch", str(folder), "--kind", "disc", "-o", str(out), "--workers", "1", "--quiet"]
    assert main(argv) == 2
    assert "photo_001.jpg" in capsys.readouterr().err
    assert main(argv) == 2  # retried, not "already done": still failing
    assert "photo_001.jpg" in capsys.readouterr().err
    (folder / "photo_001.jpg").write_bytes(good)  # fixed
    assert main(argv) == 0
    records = read_jsonl(out)
    assert sorted(Path(r["photo"]).name for r in records) == [f"photo_00{i}.jpg" for i in range(3)]
    assert all(r["ok"] for r in records)  # one record per photo: its latest


def test_readers_refuse_damaged_and_wrong_kind_files(tmp_path):
    nan = tmp_path / "cam.json"
    nan.write_text('{"rms_px": NaN}')
    with pytest.raises(InputError, match="NaN is not a number JSON allows"):
        read_json(nan)
    huge = tmp_path / "huge.json"
    huge.write_text('{"k1": 1e308}')
    with pytest.raises(InputError, match="out of any sensible range"):
        read_json(huge)
    dup = tmp_path / "dup.csv"
    dup.write_text("trial,angle,angle\n1,2,3\n")
    with pytest.raises(InputError, match="angle appear more than once"):
        read_csv_rows(dup)
    nul = tmp_path / "nul.csv"
    nul.write_bytes(b"trial,angle\n1,\x002\n")
    with pytest.raises(InputError, match="line 2: a NUL byte"):
        read_csv_rows(nul)
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"format": "x", "samples": [], "angles_deg": [1, 2]}, indent=2))
    assert sniff_kind(cal).startswith("a calibration JSON")
    with pytest.raises(InputError, match="is a calibration JSON .* not a JSON Lines file"):
        read_jsonl(cal)
    with pytest.raises(InputError, match="is a calibration JSON .* not a CSV table"):
        read_csv_rows(cal, required=["trial"])


def test_session_options_are_refused_before_anything_runs(tmp_path, capsys):
    out = str(tmp_path / "cal.json")
    for argv, words in (  # usage errors, as the options are parsed
        (["--simulate", "--angles", ""], "argument --angles"),
        (["--port", "/dev/ttyUSB0", "--camera", "ftp://nowhere"], "argument --camera: 'ftp://"),
    ):
        with pytest.raises(SystemExit) as info:
            main(["session", "-o", out, *argv])
        assert info.value.code == 2 and words in capsys.readouterr().err
    for argv, words in (
        (["--simulate", "--camera", "folder:///tmp"], "--camera: --simulate photographs"),
        (["--simulate", "--plane", str(tmp_path / "plane.json")], "--plane: a plane JSON needs"),
    ):
        assert main(["session", "-o", out, *argv]) == 2
        err = capsys.readouterr().err
        assert words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "cal_session").exists()  # nothing ran


def test_a_job_cut_short_is_refused(tmp_path, capsys):
    job = tmp_path / "job.gcode"
    job.write_text("N1 G21 G90\nN2 G91 G1 Y20 F3000\nN3 G90 G1 X4")  # no end, no line break
    assert main(["bend", str(job), "--port", "sim://", "--quiet"]) == 2
    err = capsys.readouterr().err
    assert str(job) in err and "looks cut short" in err


def test_fit_plots_a_calibration_whose_extreme_sample_is_outside_the_fitted_range(tmp_path):
    # repeated angles with measurement noise: the curve is fitted over per-angle means, so
    # the smallest single final angle lies below its domain; the plot must still be drawn
    plan = tmp_path / "plan.csv"
    angles = [40, 60, 80, 100, 120]
    rows = [(i + 1, s * a) for i, (a, s) in enumerate((a, s) for s in (1, -1) for a in angles * 3)]
    plan.write_text("trial,commanded_pin_deg\n" + "".join(f"{t},{c}\n" for t, c in rows))
    trials = tmp_path / "trials.csv"
    assert main(["simulate", str(plan), "-o", str(trials), "--noise-deg", "0.1"]) == 0
    out, png = tmp_path / "cal.json", tmp_path / "cal.png"
    assert main(["fit", str(trials), "-o", str(out), "--plot", str(png)]) == 0
    assert out.exists() and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_json_of_another_kind_is_named_by_its_kind(tmp_path):
    """The operator's likeliest slip between steps: the camera JSON given as the board,
    the calibration as the camera. The line says what the file is, not a key it lacks."""
    camera = tmp_path / "camera.json"
    camera.write_text(
        json.dumps(
            {
                "image_size": [320, 240],
                "camera_matrix": [[300, 0, 160], [0, 300, 120], [0, 0, 1]],
                "dist_coeffs": [],
            }
        )
    )
    cal = tmp_path / "cal.json"
    cal.write_text(json.dumps({"format": "diwire-material/1", "samples": {}, "angles_deg": [10]}))
    board = tmp_path / "board.json"
    board.write_text(
        json.dumps({"type": "charuco", "squares_x": 5, "squares_y": 4, "square_mm": 20.0,
                    "marker_mm": 15.0})
    )  # fmt: skip
    photo = tmp_path / "plate.jpg"
    cv2.imwrite(str(photo), np.full((240, 320, 3), 128, np.uint8))
    design = tmp_path / "d.svg"
    design.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="50mm" '
        'viewBox="0 0 100 50"><path d="M 10 40 L 50 40 L 90 10" fill="none"/></svg>'
    )
    cases = [
        (("plane", "plate.jpg", "--board", "camera.json", "--camera", "camera.json"),
         "camera.json: is a camera JSON (`cvmeasure calibrate`), not a board JSON"),
        (("plane", "plate.jpg", "--board", "board.json", "--camera", "cal.json"),
         "cal.json: is a calibration JSON (`cvmeasure fit` / `session`), not a camera JSON"),
        (("gcode", "d.svg", "--material", "camera.json", "-o", "job.gcode"),
         "camera.json: is a camera JSON (`cvmeasure calibrate`), not a calibration JSON"),
    ]  # fmt: skip
    for argv, line in cases:
        proc = _run(*argv, cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert proc.stderr.strip() == f"cvmeasure {argv[0]}: {line}"
    assert not (tmp_path / "job.gcode").exists()


def test_our_own_long_messages_are_printed_whole_and_foreign_ones_capped():
    """A stopped job's message ends with what to do: it must reach the operator whole."""
    from cvmeasure.errors import DeviceError

    args = argparse.Namespace()
    advice = "check the part (did it make what the job says?) before resuming with --force"
    stop = DeviceError("job stopped (desync) at line N1276 " + "x" * 300 + "; " + advice)
    code, line = classify_exit(stop, args)
    assert code == 1 and line.endswith(advice) and "\n" not in line
    code, line = classify_exit(InputError("job.nc", "y" * 400 + " end"), args)
    assert code == 2 and line.endswith(" end")
    code, line = classify_exit(ValueError("z" * 400), args)
    assert code == 2 and len(line) <= 240 and line.endswith("...")
