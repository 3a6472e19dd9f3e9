"""Bad input over every file-reading command: exit 2, one stderr line naming the file (issue 43).

A corpus of bad inputs is generated from valid ones (made by the CLI itself: the
demo's files, a board, a kit, rendered board views): every file argument of every
command gets the generic mutations (missing, a folder, empty, random bytes, NUL
bytes, cut in half, not UTF-8, unreadable, a valid file of another kind), the
JSON ones (invalid, an array, NaN, strings for numbers, huge numbers, a key
dropped), the CSV ones (header only, duplicated header, a word in a number
column, NaN, a missing column), the image ones (cut JPEG/PNG/TIFF, 1x1 pixel, text
named .jpg, a PNG header declaring 100,000 x 100,000 px); every output gets a
read-only folder, a folder whose parent is a file, and an existing folder; and
options get values out of range or of the wrong kind. Each case runs as a process
(``cvmeasure ...``; the permission cases as an unprivileged user, since root reads
everything) and passes when it exits 2 with exactly one stderr line naming the bad
file or option and no traceback. Valid-but-unusual inputs (CRLF and BOM CSVs,
names with spaces and accents, an upper-case suffix) must still exit 0.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import zlib
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from benchmarks import Metric, Table, finish

SECTION = "Bad input: the fuzz corpus over every file-reading command"

EXE = str(Path(sys.executable).with_name("cvmeasure"))


@dataclass
class Case:
    """One run: the command line, the names the stderr line must contain (any one)."""

    name: str
    argv: list[str]
    names: tuple[str, ...]
    expect_ok: bool = False
    unprivileged: bool = False
    setup: Callable[[], None] | None = field(default=None, repr=False)


@dataclass
class Outcome:
    case: Case
    code: int
    stderr: str
    seconds: float

    @property
    def lines(self) -> list[str]:
        return [ln for ln in self.stderr.splitlines() if ln.strip()]

    @property
    def traceback(self) -> bool:
        return "Traceback (most recent call last)" in self.stderr

    @property
    def named(self) -> bool:
        return any(n in self.stderr for n in self.case.names)

    @property
    def passed(self) -> bool:
        if self.case.expect_ok:
            return self.code == 0 and not self.traceback
        return self.code == 2 and len(self.lines) == 1 and self.named and not self.traceback


# ----------------------------------------------------------------------------- valid inputs


def _run(argv: list[str], cwd: Path) -> None:
    subprocess.run([EXE, *argv], cwd=cwd, check=True, capture_output=True, timeout=300)


def make_base(root: Path) -> dict[str, Path]:
    """Valid inputs of every kind, made by the CLI itself."""
    _run(["demo", "-o", "demo"], root)
    _run(["targets", "charuco", "-o", "board.png"], root)
    _run(["targets", "markers", "--format", "json", "-o", "kit.json"], root)
    _run(["render", "board", "-o", "views", "--count", "5", "--scale", "0.25"], root)
    demo = root / "demo"
    base = {
        "board": root / "board.board.json",
        "kit": root / "kit.json",
        "camera": demo / "calibration" / "camera.json",
        "plane": demo / "calibration" / "plane.json",
        "photo": demo / "markers" / "loaded.jpg",
        "photo2": demo / "markers" / "unloaded.jpg",
        "view": root / "views" / "board_000.jpg",
        "view1": root / "views" / "board_001.jpg",
        "view2": root / "views" / "board_002.jpg",
        "part_photo": demo / "lab" / "part_arc.jpg",
        "trials": demo / "diagnosis_trials.csv",
        "calibration": demo / "session_calibration.json",
        "design": demo / "part" / "half-circle.svg",
        "gcode": demo / "half_circle.gcode",
        "results": demo / "markers" / "measure.jsonl",
        "params": demo / "diagnosis_extended_params.json",
    }
    plan = root / "plan.csv"
    plan.write_text("trial,commanded_pin_deg\n" + "".join(f"{i},{10 * i}\n" for i in range(1, 9)))
    base["plan"] = plan
    template = next(
        r
        for r in (json.loads(t) for t in base["results"].read_text().splitlines() if t.strip())
        if "photo" in r
    )
    vision = root / "vision.jsonl"
    manual = root / "manual.csv"
    angles = [12.0, 25.5, 33.0, 47.2, 61.0, 75.4, 88.8, 102.3]
    vision.write_text(
        "".join(
            json.dumps({**template, "photo": f"p{i}.jpg", "bend_angle_deg": a}) + "\n"
            for i, a in enumerate(angles)
        )
    )
    manual.write_text(
        "photo,bend_angle_deg\n"
        + "".join(f"p{i}.jpg,{a + 0.2 * (-1) ** i:.3f}\n" for i, a in enumerate(angles))
    )
    base["manual"] = manual
    base["vision"] = vision
    return base


# ----------------------------------------------------------------------------- mutations


def _png(width: int, height: int, pixels: bytes | None = None) -> bytes:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    if pixels is None:
        pixels = b"".join(b"\x00" + b"\x80" * (3 * width) for _ in range(height))
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", ihdr)
        + chunk(b"IDAT", zlib.compress(pixels))
        + chunk(b"IEND", b"")
    )


def _tiff_cut(base: Path) -> bytes:
    import cv2

    img = cv2.imread(str(base))
    ok, data = cv2.imencode(".tiff", img)
    return data.tobytes()[: len(data) // 3]


def _cut_mid_line(data: bytes) -> bytes:
    """The first half of a file, cut inside a line (a cut at a line end is a valid file)."""
    cut = len(data) // 2
    while 0 < cut < len(data) and data[cut - 1 : cut] in (b"\n", b"\r"):
        cut += 3
    return data[:cut]


def _first_number_to(text: str, new: str) -> str:
    import re

    return re.sub(r'(":\s*)-?\d+(\.\d+)?([eE][-+]?\d+)?', lambda m: m.group(1) + new, text, count=1)


#: The key each JSON kind cannot do without (the spec's required data).
REQUIRED_KEYS = {
    "camera": "camera_matrix",
    "plane": "H_board_image",
    "board": "squares_x",
    "kit": "markers",
    "calibration": "samples",
}


def _drop_required_key(text: str, arg: str) -> str:
    obj = json.loads(text)
    obj.pop(REQUIRED_KEYS[arg])
    return json.dumps(obj)


def _csv_cell(text: str, value: str) -> str:
    lines = text.splitlines()
    cells = lines[1].split(",")
    cells[1] = value
    lines[1] = ",".join(cells)
    return "\n".join(lines) + "\n"


GENERIC = ("missing", "folder", "empty", "random_bytes", "nul_bytes", "cut_half", "not_utf8")
JSON_MUTATIONS = ("invalid_json", "array_top", "nan", "string_number", "huge_number", "drop_key")
CSV_MUTATIONS = ("header_only", "dup_header", "word_number", "nan_cell", "inf_cell", "no_column")
IMAGE_MUTATIONS = ("cut_jpeg", "one_pixel_png", "text_as_jpg", "cut_tiff", "bomb_png", "bad_crc")


def mutate(kind: str, src: Path, dest_dir: Path, mutation: str, seed: int, arg: str = "") -> Path:
    """Write the ``mutation`` of ``src`` (a file of ``kind``) into ``dest_dir``; its path."""
    rng = random.Random(seed)
    suffix = src.suffix
    dest = dest_dir / f"{mutation}{suffix}"
    data = src.read_bytes()
    text = data.decode("utf-8", "replace") if kind in ("json", "csv", "jsonl", "gcode") else ""
    out: bytes | None
    if mutation == "missing":
        return dest_dir / f"does_not_exist{suffix}"
    if mutation == "folder":
        dest.mkdir(parents=True, exist_ok=True)
        return dest
    table: dict[str, Callable[[], bytes]] = {
        "empty": lambda: b"",
        "random_bytes": lambda: bytes(rng.randrange(256) for _ in range(4096)),
        "nul_bytes": lambda: data[: len(data) // 2] + b"\x00" * 16 + data[len(data) // 2 :],
        "cut_half": lambda: _cut_mid_line(data),
        "not_utf8": lambda: data[: len(data) // 2] + b"\xff\xfe\xb0" + data[len(data) // 2 :],
        "invalid_json": lambda: text.replace(":", " ", 1).encode(),
        "array_top": lambda: b"[" + data + b"]",
        "nan": lambda: _first_number_to(text, "NaN").encode(),
        "string_number": lambda: _first_number_to(text, '"abc"').encode(),
        "huge_number": lambda: _first_number_to(text, "1e308").encode(),
        "drop_key": lambda: _drop_required_key(text, arg).encode(),
        "header_only": lambda: text.splitlines()[0].encode() + b"\n",
        "dup_header": lambda: (
            text.splitlines()[0]
            + ","
            + text.splitlines()[0].split(",")[-1]
            + "\n"
            + "\n".join(ln + "," + ln.split(",")[-1] for ln in text.splitlines()[1:])
            + "\n"
        ).encode(),
        "word_number": lambda: _csv_cell(text, "abc").encode(),
        "nan_cell": lambda: _csv_cell(text, "nan").encode(),
        "inf_cell": lambda: _csv_cell(text, "inf").encode(),
        "no_column": lambda: "\n".join(
            ",".join(ln.split(",")[:1] + ln.split(",")[2:]) for ln in text.splitlines()
        ).encode(),
        "cut_jpeg": lambda: data[: len(data) // 3],
        "one_pixel_png": lambda: _png(1, 1),
        "text_as_jpg": lambda: b"this is not a photo\n" * 10,
        "cut_tiff": lambda: _tiff_cut(src),
        "bomb_png": lambda: _png(100_000, 100_000, b"\x00")[:200],
        "bad_crc": lambda: _png(64, 64)[:-5] + b"\x00\x00\x00\x00\x00",
    }
    out = table[mutation]()
    if mutation in ("one_pixel_png", "bomb_png", "bad_crc"):
        dest = dest.with_suffix(".png")
    elif mutation == "cut_tiff":
        dest = dest.with_suffix(".tiff")
    elif mutation in ("cut_jpeg", "text_as_jpg"):
        dest = dest.with_suffix(".jpg")
    dest.write_bytes(out)
    return dest


# ----------------------------------------------------------------------------- commands

#: Per command: its argv template; ``{name}`` is a base file, ``{out}`` a fresh output path
#: (with the suffix after the colon). The file arguments fuzzed, with their kinds.
COMMANDS: dict[str, tuple[list[str], dict[str, str]]] = {
    "measure": (
        ["measure", "{photo}", "--kit", "{kit}", "--camera", "{camera}"],
        {"photo": "image", "kit": "json", "camera": "json"},
    ),
    "measure_plane": (
        ["measure", "{photo}", "--camera", "{camera}", "--plane", "{plane}"],
        {"plane": "json"},
    ),
    "calibrate": (
        ["calibrate", "{view}", "{view1}", "{view2}", "--board", "{board}", "-o", "{out:.json}"],
        {"view": "image", "board": "json"},
    ),
    "plane": (
        ["plane", "{view}", "--board", "{board}", "--camera", "{camera}", "-o", "{out:.json}"],
        {"view": "image", "board": "json", "camera": "json"},
    ),
    "markers_learn": (["markers", "learn", "{photo}", "-o", "{out:.json}"], {"photo": "image"}),
    "part": (
        ["part", "{part_photo}", "--plane", "{plane}", "--camera", "{camera}"],
        {"part_photo": "image"},
    ),
    "simulate": (["simulate", "{plan}", "-o", "{out:.csv}"], {"plan": "csv"}),
    "simulate_params": (
        ["simulate", "{plan}", "--params", "{params}", "-o", "{out:.csv}"],
        {"params": "json"},
    ),
    "diagnose": (["diagnose", "{trials}"], {"trials": "csv"}),
    "fit": (["fit", "{trials}", "-o", "{out:.json}"], {"trials": "csv"}),
    "gcode": (
        ["gcode", "{design}", "-o", "{out:.gcode}", "--material", "{calibration}"],
        {"design": "svg", "calibration": "json"},
    ),
    "bend": (["bend", "{gcode}", "--port", "sim://", "--quiet"], {"gcode": "gcode"}),
    "agreement": (["agreement", "{manual}", "{vision}"], {"manual": "csv", "vision": "jsonl"}),
    "report": (
        ["report", "{results}", "-o", "{out:.html}", "--no-thumbnails"],
        {"results": "jsonl"},
    ),
    "batch": (
        [
            "batch",
            "{photo}",
            "--kind",
            "machine",
            "-o",
            "{out:.jsonl}",
            "--workers",
            "1",
            "--quiet",
        ],
        {"photo": "image"},
    ),
    "track": (["track", "{results}", "--design", "{design}"], {}),
    "targets": (
        ["targets", "charuco", "--board", "{board}", "-o", "{out:.png}"],
        {"board": "json"},
    ),
    "targets_kit": (["targets", "markers", "--kit", "{kit}", "-o", "{out:.png}"], {"kit": "json"}),
    "render": (
        [
            "render",
            "bender",
            "--pin-deg",
            "30",
            "--bend-deg",
            "20",
            "-o",
            "{outdir}",
            "--scale",
            "0.1",
            "--camera",
            "{camera}",
        ],
        {"camera": "json"},
    ),
}

#: Outputs that get the read-only-folder / parent-is-a-file / existing-folder cases.
OUTPUT_COMMANDS: dict[str, list[str]] = {
    "gcode": ["gcode", "{design}", "--material", "{calibration}", "-o"],
    "targets": ["targets", "charuco", "-o"],
    "report": ["report", "{results}", "--no-thumbnails", "-o"],
    "agreement_plot": ["agreement", "{manual}", "{vision}", "--plot"],
    "measure_overlay": ["measure", "{photo}", "--overlay"],
    "plane_rectified": [
        "plane",
        "{view}",
        "--board",
        "{board}",
        "--camera",
        "{camera}",
        "--rectified",
    ],
    "bend_journal": ["bend", "{gcode}", "--port", "sim://", "--quiet", "--journal"],
    "batch": ["batch", "{photo}", "--kind", "machine", "--workers", "1", "--quiet", "-o"],
    "fit": ["fit", "{trials}", "-o"],
    "simulate": ["simulate", "{plan}", "-o"],
    "calibrate": ["calibrate", "{view}", "{view1}", "{view2}", "--board", "{board}", "-o"],
}
_OUT_SUFFIX = {
    "gcode": ".gcode",
    "targets": ".png",
    "report": ".html",
    "agreement_plot": ".png",
    "measure_overlay": ".png",
    "plane_rectified": ".png",
    "bend_journal": ".jsonl",
    "batch": ".jsonl",
    "fit": ".json",
    "simulate": ".csv",
    "calibrate": ".json",
}

#: Bad option values: (name, argv, the option the message must name).
OPTION_CASES: list[tuple[str, list[str], str]] = [
    (
        "session_camera_url",
        ["session", "--simulate", "--camera", "ftp://nowhere", "-o", "{out:.json}"],
        "--camera",
    ),
    (
        "session_angles_empty",
        ["session", "--simulate", "--angles", "", "-o", "{out:.json}"],
        "--angles",
    ),
    (
        "session_angles_word",
        ["session", "--simulate", "--angles", "5,x", "-o", "{out:.json}"],
        "--angles",
    ),
    (
        "session_angles_one",
        ["session", "--simulate", "--angles", "5,5", "-o", "{out:.json}"],
        "--angles",
    ),
    (
        "session_plane_no_camera",
        ["session", "--simulate", "--plane", "{plane}", "-o", "{out:.json}"],
        "--plane",
    ),
    (
        "session_port_missing",
        ["session", "--camera", "folder:///nonexistent", "-o", "{out:.json}"],
        "--port",
    ),
    (
        "plane_px_per_mm",
        [
            "plane",
            "{view}",
            "--board",
            "{board}",
            "--camera",
            "{camera}",
            "--rectified",
            "{out:.png}",
            "--px-per-mm",
            "1000",
        ],
        "--px-per-mm",
    ),
    (
        "bend_port_missing",
        ["bend", "{gcode}", "--port", "/dev/does-not-exist", "--quiet"],
        "/dev/does-not-exist",
    ),
    ("bend_port_url", ["bend", "{gcode}", "--port", "ftp://nowhere", "--quiet"], "ftp://nowhere"),
    (
        "bend_resume_no_journal",
        ["bend", "{gcode}", "--port", "sim://", "--resume", "--journal", "{out:.jsonl}"],
        ".jsonl",
    ),
    (
        "batch_workers_zero",
        ["batch", "{photo}", "-o", "{out:.jsonl}", "--workers", "0"],
        "--workers",
    ),
    (
        "batch_measure_bad",
        ["batch", "{photo}", "-o", "{out:.jsonl}", "--measure", "nope:nothing"],
        "--measure",
    ),
    ("fit_model", ["fit", "{trials}", "-o", "{out:.json}", "--model", "quintic"], "--model"),
    (
        "simulate_effect",
        ["simulate", "{plan}", "-o", "{out:.csv}", "--effect", "warp=1"],
        "--effect",
    ),
    (
        "simulate_effect_nan",
        ["simulate", "{plan}", "-o", "{out:.csv}", "--effect", "backlash=nan"],
        "--effect",
    ),
    (
        "simulate_noise_negative",
        ["simulate", "{plan}", "-o", "{out:.csv}", "--noise-deg", "-1"],
        "--noise-deg",
    ),
    ("agreement_tol_nan", ["agreement", "{manual}", "{vision}", "--tol-deg", "nan"], "--tol-deg"),
    (
        "render_scale_zero",
        [
            "render",
            "bender",
            "--pin-deg",
            "30",
            "--bend-deg",
            "20",
            "-o",
            "{outdir}",
            "--scale",
            "0",
        ],
        "--scale",
    ),
    (
        "gcode_divisions_zero",
        ["gcode", "{design}", "-o", "{out:.gcode}", "--divisions", "0"],
        "--divisions",
    ),
    ("calibrate_same_in_out", ["calibrate", "{view}", "--board", "{board}", "-o", "{view}"], "-o"),
]


def _fill(template: list[str], files: dict[str, Path], work: Path, counter: list[int]) -> list[str]:
    out = []
    for part in template:
        if part.startswith("{out"):
            counter[0] += 1
            suffix = part[5:-1] if ":" in part else ""
            out.append(str(work / f"out{counter[0]}{suffix}"))
        elif part == "{outdir}":
            counter[0] += 1
            out.append(str(work / f"outdir{counter[0]}"))
        elif part.startswith("{") and part.endswith("}"):
            out.append(str(files[part[1:-1]]))
        else:
            out.append(part)
    return out


def _kind_of(name: str) -> str:
    return {
        "board": "json",
        "kit": "json",
        "camera": "json",
        "plane": "json",
        "calibration": "json",
        "params": "json",
        "photo": "image",
        "photo2": "image",
        "view": "image",
        "view1": "image",
        "view2": "image",
        "part_photo": "image",
        "trials": "csv",
        "plan": "csv",
        "manual": "csv",
        "results": "jsonl",
        "vision": "jsonl",
        "design": "svg",
        "gcode": "gcode",
    }[name]


def _wrong_kind(name: str, base: dict[str, Path]) -> Path:
    """A valid file of another kind than ``name`` wants."""
    kind = _kind_of(name)
    if kind == "json":
        return base["calibration"] if name != "calibration" else base["camera"]
    if kind == "image":
        return base["camera"]
    if kind == "csv":
        return base["calibration"]
    if kind == "jsonl":
        return base["camera"]  # (a calibration JSON is a report's input too)
    if kind == "svg":
        return base["trials"]
    return base["photo"]


def build_cases(base: dict[str, Path], work: Path, *, quick: bool) -> list[Case]:
    cases: list[Case] = []
    counter = [0]
    seed = 0
    for command, (template, fuzzed) in COMMANDS.items():
        for arg, kind in fuzzed.items():
            mutations = list(GENERIC) + ["wrong_kind", "unreadable"]
            mutations += {
                "json": JSON_MUTATIONS,
                "csv": CSV_MUTATIONS,
                "jsonl": JSON_MUTATIONS[:2],
                "image": IMAGE_MUTATIONS,
            }.get(kind, [])
            if kind == "image":
                mutations = [m for m in mutations if m not in ("not_utf8", "nul_bytes")]
            if kind == "csv":
                mutations = [m for m in mutations if m != "cut_half"]
            if arg == "params":  # every key of a params JSON has a default: none is required
                mutations = [m for m in mutations if m != "drop_key"]
            if quick:
                mutations = mutations[::4]
            for mutation in mutations:
                seed += 1
                d = work / "in" / f"{command}_{arg}_{mutation}"
                d.mkdir(parents=True, exist_ok=True)
                files = dict(base)
                unprivileged = False
                if mutation == "wrong_kind":
                    bad = d / _wrong_kind(arg, base).name
                    shutil.copy(_wrong_kind(arg, base), bad)
                elif mutation == "unreadable":
                    bad = d / base[arg].name
                    shutil.copy(base[arg], bad)
                    bad.chmod(0)
                    unprivileged = True
                else:
                    try:
                        bad = mutate(kind, base[arg], d, mutation, seed, arg)
                    except (KeyError, IndexError, ValueError, json.JSONDecodeError):
                        continue
                files[arg] = bad
                argv = _fill(template, files, work, counter)
                cases.append(
                    Case(
                        f"{command}/{arg}/{mutation}", argv, (str(bad),), unprivileged=unprivileged
                    )
                )
    outs = list(OUTPUT_COMMANDS.items())
    for command, template in outs:
        for problem in ("readonly_folder", "parent_is_file", "existing_folder"):
            if quick and problem == "existing_folder":
                continue
            d = work / "outs" / f"{command}_{problem}"
            d.mkdir(parents=True, exist_ok=True)
            if problem == "readonly_folder":
                d.chmod(0o555)
                target = d / f"result{_OUT_SUFFIX[command]}"
                names = (str(d),)
            elif problem == "parent_is_file":
                (d / "afile").write_text("x")
                target = d / "afile" / f"result{_OUT_SUFFIX[command]}"
                names = (str(target), str(d / "afile"))
            else:
                target = d / f"result{_OUT_SUFFIX[command]}"
                target.mkdir()
                names = (str(target),)
            argv = _fill(template, base, work, counter) + [str(target)]
            cases.append(
                Case(
                    f"{command}/output/{problem}",
                    argv,
                    names,
                    unprivileged=problem == "readonly_folder",
                )
            )
    for name, template, option in OPTION_CASES:
        if quick and len(cases) % 2:
            pass
        argv = _fill(template, base, work, counter)
        cases.append(Case(f"option/{name}", argv, (option,)))
    cases += _unusual_valid(base, work, counter)
    for c in cases:
        c.argv = [a for a in c.argv]
    return cases


def _unusual_valid(base: dict[str, Path], work: Path, counter: list[int]) -> list[Case]:
    """Inputs a user may well have that are not wrong: they must still work."""
    d = work / "unusual"
    d.mkdir(parents=True, exist_ok=True)
    trials = base["trials"].read_text()
    crlf = d / "trials crlf.csv"
    crlf.write_bytes(trials.replace("\n", "\r\n").encode())
    bom = d / "trials_bom.csv"
    bom.write_bytes(b"\xef\xbb\xbf" + trials.encode())
    accents = d / "essai à froid.csv"
    accents.write_text(trials)
    upper = d / "LOADED.JPG"
    shutil.copy(base["photo"], upper)
    spaced = d / "my kit.json"
    shutil.copy(base["kit"], spaced)
    o = lambda s: str(work / f"unusual_out{s}")  # noqa: E731
    return [
        Case("valid/fit_crlf", ["fit", str(crlf), "-o", o("1.json")], (), expect_ok=True),
        Case("valid/fit_bom", ["fit", str(bom), "-o", o("2.json")], (), expect_ok=True),
        Case("valid/diagnose_accents", ["diagnose", str(accents)], (), expect_ok=True),
        Case(
            "valid/measure_upper_suffix",
            ["measure", str(upper), "--kit", str(spaced), "--camera", str(base["camera"])],
            (),
            expect_ok=True,
        ),
        Case(
            "valid/simulate_stdout", ["simulate", str(base["plan"]), "-o", "-"], (), expect_ok=True
        ),
    ]


# ----------------------------------------------------------------------------- running


def run_case(case: Case, cwd: Path, env: dict[str, str]) -> Outcome:
    cmd = [EXE, *case.argv]
    if case.unprivileged and os.geteuid() == 0:
        # root without the capabilities that override file permissions
        cmd = [
            "setpriv",
            "--inh-caps=-all",
            "--bounding-set=-dac_override,-dac_read_search",
            "--",
            *cmd,
        ]
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, cwd=cwd, env=env, capture_output=True, timeout=240, stdin=subprocess.DEVNULL
        )
        code, err = proc.returncode, proc.stderr.decode("utf-8", "replace")
    except subprocess.TimeoutExpired:
        code, err = -9, "timed out after 240 s"
    return Outcome(case, code, err, time.perf_counter() - t0)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.fuzz_inputs", description=__doc__)
    p.add_argument("--quick", action="store_true", help="a quarter of the file mutations")
    p.add_argument("--only", help="run only the cases whose name contains this")
    p.add_argument("--keep", type=Path, help="build the corpus here and keep it")
    args = p.parse_args(argv)
    root = args.keep or Path(tempfile.mkdtemp(prefix="cvm_fuzz_"))
    root.mkdir(parents=True, exist_ok=True)
    root.chmod(0o777)
    base = make_base(root)
    work = root / "corpus"
    shutil.rmtree(work, ignore_errors=True)
    work.mkdir()
    cases = build_cases(base, work, quick=args.quick)
    if args.only:
        cases = [c for c in cases if args.only in c.name]
    env = dict(os.environ, MPLCONFIGDIR=str(root / "mpl"), HOME=str(root))
    outcomes = []
    for case in cases:
        out = run_case(case, root, env)
        outcomes.append(out)
        flag = "ok  " if out.passed else "FAIL"
        print(
            f"{flag} {case.name}: exit {out.code}, {len(out.lines)} line(s): "
            f"{(out.lines or [''])[-1][:150]}",
            flush=True,
        )
    if not args.keep:
        for r, ds, _ in os.walk(root):
            for d in ds:
                os.chmod(os.path.join(r, d), 0o777)
        shutil.rmtree(root, ignore_errors=True)
    return _report(outcomes, argv, args.quick)


def _report(outcomes: list[Outcome], argv: list[str] | None, quick: bool) -> dict:
    bad = [o for o in outcomes if not o.case.expect_ok]
    valid = [o for o in outcomes if o.case.expect_ok]
    tracebacks = sum(o.traceback for o in outcomes)
    exit0 = sum(o.code == 0 for o in bad)
    not2 = sum(o.code != 2 for o in bad)
    multi = sum(len(o.lines) != 1 for o in bad if o.code == 2)
    unnamed = sum(not o.named for o in bad if o.code == 2 and len(o.lines) == 1)
    passed = sum(o.passed for o in bad)
    valid_ok = sum(o.passed for o in valid)
    by_kind = Counter(o.case.name.split("/")[-1] for o in bad if not o.passed)
    failures = [
        [o.case.name, o.code, len(o.lines), (o.lines or [""])[-1][:160]]
        for o in outcomes
        if not o.passed
    ]
    return finish(
        __file__,
        SECTION,
        argv,
        quick=quick,
        metrics=[
            Metric("bad inputs run", len(bad), "", target=None, met=None),
            Metric(
                "bad inputs answered right (exit 2, one line naming the file or option)",
                passed,
                "",
                target=f"= {len(bad)}",
                met=passed == len(bad),
            ),
            Metric("tracebacks", tracebacks, "", target="= 0", met=tracebacks == 0),
            Metric("bad inputs accepted (exit 0)", exit0, "", target="= 0", met=exit0 == 0),
            Metric(
                "bad inputs with an exit code other than 2", not2, "", target="= 0", met=not2 == 0
            ),
            Metric(
                "exit 2 with more than one stderr line", multi, "", target="= 0", met=multi == 0
            ),
            Metric(
                "exit 2 whose line does not name the file or option",
                unnamed,
                "",
                target="= 0",
                met=unnamed == 0,
            ),
            Metric(
                "valid-but-unusual inputs that work",
                valid_ok,
                "",
                target=f"= {len(valid)}",
                met=valid_ok == len(valid),
            ),
        ],
        tables=[
            Table("failures", ["case", "exit", "stderr lines", "last stderr line"], failures),
            Table("failures by mutation", ["mutation", "count"], sorted(by_kind.items())),
        ],
        notes=[
            "each case is one `cvmeasure` process; the permission cases run without the "
            "capabilities that let root read and write everything (setpriv)",
            "a CSV cut at half is not in the corpus: cut at a line end it is a shorter valid "
            "file, which no reader can tell apart; nor a params JSON without a key (each has a "
            "default)",
            f"{len(outcomes)} runs, {sum(o.seconds for o in outcomes):.0f} s in total",
        ],
    )


if __name__ == "__main__":
    main()
