import json

import numpy as np
import pytest

from cvmeasure.errors import InputError
from cvmeasure.fileio import (
    append_jsonl,
    atomic_write_json,
    read_csv_rows,
    read_json,
    read_jsonl,
    write_csv_rows,
)


def test_atomic_json_roundtrip_with_numpy(tmp_path):
    path = atomic_write_json(tmp_path / "a" / "x.json", {"k": np.arange(3), "f": np.float32(1.5)})
    assert read_json(path) == {"k": [0, 1, 2], "f": 1.5}
    assert [p.name for p in path.parent.iterdir()] == ["x.json"]  # no temp file left


def test_atomic_write_gives_the_umask_mode_not_a_private_file(tmp_path):
    import os

    old = os.umask(0o022)
    try:
        path = atomic_write_json(tmp_path / "r.json", {"a": 1})
    finally:
        os.umask(old)
    assert path.stat().st_mode & 0o777 == 0o644


def test_corrupt_json_names_file(tmp_path):
    p = tmp_path / "cam.json"
    p.write_text("{not json")
    with pytest.raises(InputError, match="cam.json: corrupt"):
        read_json(p)
    with pytest.raises(InputError, match="not found"):
        read_json(tmp_path / "missing.json")


def test_jsonl_append_and_partial_last_line(tmp_path):
    p = tmp_path / "log.jsonl"
    append_jsonl(p, {"a": 1})
    append_jsonl(p, {"a": 2})
    with open(p, "a") as fh:
        fh.write('{"a": 3')  # a write cut by a crash
    assert read_jsonl(p, skip_partial_last=True) == [{"a": 1}, {"a": 2}]
    with pytest.raises(InputError, match="line 3"):
        read_jsonl(p)
    assert json.loads(p.read_text().splitlines()[0]) == {"a": 1}
    # the next append cuts the torn line first: the log stays readable after resumes
    append_jsonl(p, {"a": 4})
    append_jsonl(p, {"a": 5})
    assert read_jsonl(p) == [{"a": 1}, {"a": 2}, {"a": 4}, {"a": 5}]


def test_csv_roundtrip_and_missing_column(tmp_path):
    p = write_csv_rows(tmp_path / "t.csv", [{"trial": 1, "x": 0.5}], ["trial", "x"])
    assert read_csv_rows(p, required=["trial"]) == [{"trial": "1", "x": "0.500000"}]
    with pytest.raises(InputError, match="missing column"):
        read_csv_rows(p, required=["commanded_pin_deg"])
