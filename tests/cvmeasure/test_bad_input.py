"""Bad input, fuzzed: every file-reading command answers one line naming the file, exit 2.

The readers (:mod:`cvmeasure.fileio`) get arbitrary bytes from hypothesis and must
either parse them or raise :class:`InputError`; every CLI command that reads a file
gets a corpus of bad files (binary, a folder, JSON nested 100k deep, a CSV row with
more cells than its header, a cell over the csv field limit, JSON Lines of the wrong
type, an empty file) and must exit 2 with one line on stderr naming that file.
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cvmeasure.cli import main
from cvmeasure.errors import InputError
from cvmeasure.fileio import read_csv_rows, read_json, read_jsonl


def _corpus(folder: Path) -> dict[str, Path]:
    folder.mkdir(parents=True, exist_ok=True)
    files = {
        "binary": b"\x89PNG\r\n\x1a\n\xff\xfe\x00\x01" * 64,
        "deep_json": b"[" * 100_000 + b"]" * 100_000,
        "extra_cells": b"trial,commanded_pin_deg,loaded_bend_deg,unloaded_bend_deg\n1,20,21,19,7,8\n",
        "huge_cell": b"trial,commanded_pin_deg\n1," + b"9" * 200_000 + b"\n",
        "jsonl_wrong_type": b'[1, 2]\n"text"\n',
        "empty": b"",
        "not_utf8": "trial,commanded_pin_deg\n1,20\xb0\n".encode("latin-1"),
    }
    out = {}
    for name, data in files.items():
        path = folder / f"{name}.dat"
        path.write_bytes(data)
        out[name] = path
    (folder / "a_folder.csv").mkdir(exist_ok=True)
    out["folder"] = folder / "a_folder.csv"
    return out


@settings(
    max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(data=st.binary(max_size=2048))
def test_readers_parse_or_raise_input_error(tmp_path, data):
    path = tmp_path / "fuzz.dat"
    path.write_bytes(data)
    for reader in (read_json, read_jsonl, read_csv_rows):
        try:
            reader(path)
        except InputError as exc:
            assert str(path) in str(exc)


@pytest.mark.parametrize(
    "name",
    ["binary", "deep_json", "extra_cells", "huge_cell", "jsonl_wrong_type", "folder", "not_utf8"],
)
def test_readers_name_the_file_and_the_problem(tmp_path, name):
    path = _corpus(tmp_path)[name]
    for reader in (read_json, read_jsonl, read_csv_rows):
        try:
            reader(path)
        except InputError as exc:
            assert str(path) in str(exc) and "\n" not in str(exc)


def test_csv_problems_say_which_line(tmp_path):
    c = _corpus(tmp_path)
    with pytest.raises(InputError, match=r"line 2: more cells than the header's 4"):
        read_csv_rows(c["extra_cells"])
    with pytest.raises(InputError, match=r"line 2: not a valid CSV row"):
        read_csv_rows(c["huge_cell"])
    with pytest.raises(InputError, match=r"nested too deeply"):
        read_json(c["deep_json"])
    with pytest.raises(InputError, match=r"line 1 is a JSON list, not an object"):
        read_jsonl(c["jsonl_wrong_type"])
    with pytest.raises(InputError, match=r"is a folder"):
        read_csv_rows(c["folder"])
    with pytest.raises(InputError, match=r"not a CSV file: byte \d+ is not utf-8-sig text"):
        read_csv_rows(c["not_utf8"])


def _commands(bad: Path, good: dict[str, Path]) -> list[list[str]]:
    o = str(good["out"])
    return [
        ["fit", str(bad), "-o", o],
        ["diagnose", str(bad), "--json"],
        ["simulate", str(bad), "-o", o],
        ["agreement", str(bad), str(good["jsonl"])],
        ["agreement", str(good["manual"]), str(bad)],
        ["report", str(bad), "-o", o + ".html"],
        ["gcode", str(bad), "-o", o],
        ["gcode", str(good["svg"]), "--material", str(bad), "-o", o],
        ["measure", str(good["photo"]), "--kit", str(bad), "--json"],
        ["measure", str(bad), "--json", "--kit", str(good["kit"])],
        ["calibrate", str(good["photo"]), "--board", str(bad), "-o", o],
        ["plane", str(good["photo"]), "--board", str(good["board"]), "--camera", str(bad)],
        ["bend", str(bad), "--port", "sim://"],
        ["targets", "charuco", "--board", str(bad), "-o", o + ".svg"],
    ]


@pytest.mark.slow
def test_every_reading_command_answers_bad_input_with_one_line(tmp_path, capsys):
    corpus = _corpus(tmp_path / "bad")
    good = {
        "out": tmp_path / "out.dat",
        "jsonl": tmp_path / "v.jsonl",
        "manual": tmp_path / "m.csv",
        "svg": tmp_path / "d.svg",
        "photo": tmp_path / "p.png",
        "kit": tmp_path / "kit.json",
        "board": tmp_path / "board.json",
    }
    good["jsonl"].write_text(json.dumps({"photo": "a.jpg", "bend_angle_deg": 1.0}) + "\n")
    good["manual"].write_text("photo,bend_angle_deg\na.jpg,1\n")
    good["svg"].write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="100mm" height="100mm" '
        'viewBox="0 0 100 100"><polyline points="0,0 50,0 80,30" fill="none"/></svg>'
    )
    import cv2
    import numpy as np

    cv2.imwrite(str(good["photo"]), np.full((60, 90, 3), 200, np.uint8))
    assert main(["targets", "markers", "--format", "json", "-o", str(good["kit"])]) == 0
    good["board"].write_text(
        '{"type": "chessboard", "inner_x": 9, "inner_y": 6, "square_mm": 25.0}'
    )
    capsys.readouterr()
    failures = []
    for name, bad in corpus.items():
        for argv in _commands(bad, good):
            code = main(argv)
            err = capsys.readouterr().err
            lines = err.strip().splitlines()
            if code != 2 or len(lines) != 1 or str(bad) not in lines[0]:
                failures.append(f"{name}: {' '.join(argv[:1])} -> exit {code}: {err[-300:]!r}")
    assert failures == []
