"""A finished part measured on one core: `cvmeasure part` as a whole process, the library call after the decode, peak memory; 6-45 MP, light and dark sheets, flat and lifted parts, one and two photos (issue 40)."""

from __future__ import annotations

from benchmarks._photos import one_thread_env, pin_one_core

one_thread_env()  # one core: before numpy/OpenCV load their thread pools

import argparse  # noqa: E402
import compileall  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

import numpy as np  # noqa: E402

from benchmarks import Metric, Table, finish  # noqa: E402

SECTION = "Finished part on one core: whole process, after the decode, peak memory (issue 40)"

#: (label, scale of the renderer's 4608x3072 camera): 6, 14 and 45 megapixels.
SIZES: tuple[tuple[str, float], ...] = (("6 MP", 0.651), ("14 MP", 1.0), ("45 MP", 1.79))
#: Targets of issue 40 (4608x3072, one core, median).
PROCESS_TARGET_S = 1.5
LIBRARY_TARGET_S = 1.0
PEAK_TARGET_MB = 400.0
#: The board the flat parts lie beside (the parts benchmark's).
BOARD_DIMS = (14, 10, 20.0, 15.0)


def _flat_case(folder: Path, scale: float, sheet: str, seed: int) -> dict[str, Any]:
    """A 120 deg arc of 10 chords beside the board (the parts benchmark's scene): files."""
    import cv2

    import cvmeasure_datasets
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.camera_model import save_camera
    from cvmeasure.fileio import atomic_write_json

    board = CharucoBoardSpec(*BOARD_DIMS)
    bw, bh = board.size_mm
    pose = cvmeasure_datasets.Pose(
        tilt_deg=2.0,
        tilt_direction_deg=45.0,
        distance_mm=900.0,
        offset_mm=((bw + 10.0 + 250.0 - 20.0) / 2 + 10.0, bh / 2),
    )
    photo = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(60.0, 120.0, 10),
        board=board,
        sheet=sheet,
        pose=pose,
        seed=seed,
        scale=scale,
    )
    jpg = folder / f"flat_{sheet}_{scale}.jpg"
    cv2.imwrite(str(jpg), photo.bgr, [cv2.IMWRITE_JPEG_QUALITY, 92])
    camera = save_camera(folder / f"camera_{scale}.json", photo.camera)
    board_json = atomic_write_json(folder / "board.json", board.to_dict())
    return {
        "photo": jpg,
        "args": ["--board", str(board_json), "--camera", str(camera), "--divisions", "10"],
        "truth_radius_mm": float(photo.truth["radius_mm"]),
        "divisions": 10,
    }


def _lifted_case(folder: Path, scale: float, sheet: str, seed: int) -> dict[str, Any]:
    """A 3 mm round wire lifted 3 mm at one end, side lit, on a measured plane; and the same
    part slid 80 mm (the two-photo lift): files."""
    import cv2

    import cvmeasure_datasets
    from benchmarks._calibrated import plane_for_pose
    from cvmeasure_datasets.round_wire import render_round_wire

    part = cvmeasure_datasets.arc_part(60.0, 120.0, 8, wire_diameter_mm=3.0)
    verts = part.placed(30.0, (0.0, 0.0))
    pose = cvmeasure_datasets.Pose(
        tilt_deg=1.5, tilt_direction_deg=120.0, distance_mm=550.0, offset_mm=(20.0, -10.0)
    )
    camera = cvmeasure_datasets.default_camera().scaled(scale)
    kw = dict(
        camera=camera, pose=pose, wire_diameter_mm=3.0, lift_mm=3.0, lift_direction_deg=30.0,
        sheet=sheet, light_azimuth_deg=140.0, light_elev_deg=55.0,
    )  # fmt: skip
    paths = []
    for k, shift in enumerate((0.0, 80.0)):
        photo = render_round_wire(verts + np.array([shift, 0.0]), seed=seed + 31 * k, **kw)
        paths.append(folder / f"lifted_{sheet}_{scale}_{k}.jpg")
        cv2.imwrite(str(paths[-1]), photo.bgr, [cv2.IMWRITE_JPEG_QUALITY, 92])
    # the plane from a photo of the board on it (a user's `cvmeasure plane`), true lens
    plane = plane_for_pose(pose, camera, scale=scale, seed=seed, frame="board")
    plane_json = plane.save(folder / f"plane_{sheet}_{scale}.json")
    return {
        "photo": paths[0],
        "moved": paths[1],
        "plane": plane,
        "args": ["--plane", str(plane_json), "--wire-diameter-mm", "3", "--divisions", "8"],
        "truth_radius_mm": 60.0,
        "divisions": 8,
    }


#: Runs ``python -m cvmeasure ARGS`` in this process and, at exit, writes its peak resident
#: memory (VmHWM, KiB: this program's own, unlike ru_maxrss, which keeps the forking
#: parent's pages from before the exec) to the file named by the first argument.
_PEAK_WRAPPER = """
import atexit, runpy, sys
out = sys.argv.pop(1)
def peak():
    with open("/proc/self/status") as f, open(out, "w") as o:
        o.write(next(line for line in f if line.startswith("VmHWM")).split()[1])
atexit.register(peak)
sys.argv[0] = "cvmeasure"
runpy.run_module("cvmeasure", run_name="__main__", alter_sys=True)
"""


def _process(photo: Path, args: list[str]) -> tuple[float, float, float, dict]:
    """``cvmeasure part PHOTO ARGS --json`` as a child process on this core:
    (wall s, CPU s, its peak resident memory MB, result)."""
    peak_file = photo.with_suffix(".peak")
    t0 = time.perf_counter()
    child = subprocess.Popen(
        [sys.executable, "-c", _PEAK_WRAPPER, str(peak_file), "part", str(photo), *args, "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    out = child.stdout.read()  # the JSON; stderr is a line at most
    err = child.stderr.read()
    # reaped here, not by Popen: os.wait4 gives this child's own CPU time
    _, status, usage = os.wait4(child.pid, 0)
    child.returncode = os.waitstatus_to_exitcode(status)
    wall = time.perf_counter() - t0
    if child.returncode != 0:
        raise RuntimeError(f"cvmeasure part {photo}: {err.strip().splitlines()[-1:]}")
    peak_mb = int(peak_file.read_text()) / 1024.0
    return wall, usage.ru_utime + usage.ru_stime, peak_mb, json.loads(out)


def _library(case: dict[str, Any], moved: bool) -> tuple[float, Any]:
    """CPU seconds of measure_part on the decoded photo(s) (the decode not counted)."""
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.camera_model import load_camera
    from cvmeasure.imageio import read_photo
    from cvmeasure.part.measure import measure_part
    from cvmeasure.part.options import PartOptions, WireOptions

    image = read_photo(case["photo"]).bgr
    second = read_photo(case["moved"]).bgr if moved else None
    if "plane" in case:  # the round wire on a plane (--plane --wire-diameter-mm 3)
        kw = {"plane": case["plane"]}
        options = PartOptions(divisions=case["divisions"], wire=WireOptions(diameter_mm=3.0))
        board = camera = None
    else:
        board = CharucoBoardSpec(*BOARD_DIMS)
        camera = load_camera(case["args"][3])
        kw = {}
        options = PartOptions(divisions=case["divisions"])
    c0 = time.process_time()
    m = measure_part(image, board, camera, options=options, moved_image=second, **kw)
    return time.process_time() - c0, m


def _bytecode() -> None:
    """Compile cvmeasure's modules to bytecode first, as ``pip install`` does: a user's
    process starts from the .pyc files, while a checkout run with PYTHONDONTWRITEBYTECODE
    would compile every module it imports (~60, ~0.3 s CPU) in every process."""
    import cvmeasure

    compileall.compile_dir(Path(cvmeasure.__file__).parent, quiet=1)


def _rows(sizes, repeats: int, seed: int, quick: bool) -> list[dict[str, Any]]:
    rows = []
    warm = True
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for label, scale in sizes:
            for kind, make in (("flat", _flat_case), ("lifted", _lifted_case)):
                for sheet in ("light", "dark"):
                    if quick and kind == "lifted" and sheet == "light":
                        continue
                    case = make(folder, scale, sheet, seed)
                    if warm:  # the library's imports are not the library call's time
                        _library(case, False)
                        warm = False
                    photos = (1, 2) if kind == "lifted" else (1,)
                    for n in photos:
                        row = _row(label, kind, sheet, n, case, repeats)
                        rows.append(row)
                        print(
                            f"{label} {kind} {sheet} {n} photo(s): process "
                            f"{row['process_s']}, library {row['library_cpu_s']:.2f} s, "
                            f"peak {row['peak_mb']} MB, radius error "
                            f"{row['radius_err_pct']:+.3f} %",
                            flush=True,
                        )
    return rows


def _row(label: str, kind: str, sheet: str, n: int, case: dict, repeats: int) -> dict:
    lib = [_library(case, n == 2) for _ in range(repeats)]
    m = lib[-1][1]
    row: dict[str, Any] = {
        "size": label,
        "part": kind,
        "sheet": sheet,
        "photos": n,
        "library_cpu_s": float(np.median([t for t, _ in lib])),
        "radius_err_pct": 100.0 * (m.result.radius_mm / case["truth_radius_mm"] - 1.0),
        "warnings": sorted(w.code for w in m.warnings),
        "process_s": None,
        "process_cpu_s": None,
        "peak_mb": None,
    }
    if n == 1:  # the CLI's two photos need a board in both (--moved with --board)
        runs = [_process(case["photo"], case["args"]) for _ in range(repeats)]
        row["process_s"] = float(np.median([r[0] for r in runs]))
        row["process_cpu_s"] = float(np.median([r[1] for r in runs]))
        row["peak_mb"] = max(r[2] for r in runs)
        row["process_radius_mm"] = runs[-1][3]["radius_mm"]
    return row


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.part_speed", description=__doc__)
    p.add_argument(
        "--quick",
        action="store_true",
        help="14 MP only (the lifted part on the dark sheet only), one run per row",
    )
    p.add_argument("--repeats", type=int, default=None, help="runs per row (median)")
    p.add_argument("--seed", type=int, default=40)
    args = p.parse_args(argv)
    core = pin_one_core()
    _bytecode()
    sizes = [s for s in SIZES if s[0] == "14 MP"] if args.quick else list(SIZES)
    repeats = args.repeats or (1 if args.quick else 3)
    rows = _rows(sizes, repeats, args.seed, args.quick)
    # the targets are the case: an arc beside the board at 4608x3072
    flat14 = [r for r in rows if r["size"] == "14 MP" and r["part"] == "flat"]
    lifted14 = [r for r in rows if r["size"] == "14 MP" and r["part"] == "lifted"]
    proc = float(np.median([r["process_s"] for r in flat14]))
    proc_cpu = float(np.median([r["process_cpu_s"] for r in flat14]))
    lib = float(np.median([r["library_cpu_s"] for r in flat14]))
    peak = max(r["peak_mb"] for r in flat14)
    lifted_lib = float(np.median([r["library_cpu_s"] for r in lifted14]))
    lifted_peak = max(r["peak_mb"] for r in lifted14 if r["peak_mb"] is not None)
    cols = ["size", "part", "sheet", "photos", "process_s", "process_cpu_s", "library_cpu_s",
            "peak_mb", "radius_err_pct", "warnings"]  # fmt: skip
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=[
            Metric(
                "cvmeasure part, whole process, flat part, 4608x3072 (median wall)",
                proc,
                "s",
                target=f"<= {PROCESS_TARGET_S}",
                met=proc <= PROCESS_TARGET_S,
            ),
            Metric(
                "cvmeasure part, whole process, flat part, 4608x3072 (median CPU)", proc_cpu, "s"
            ),
            Metric(
                "measure_part after the decode, flat part, 4608x3072 (median CPU)",
                lib,
                "s",
                target=f"<= {LIBRARY_TARGET_S}",
                met=lib <= LIBRARY_TARGET_S,
            ),
            Metric(
                "peak memory of the process, flat part, 4608x3072 (largest)",
                peak,
                "MB",
                target=f"<= {PEAK_TARGET_MB:.0f}",
                met=peak <= PEAK_TARGET_MB,
            ),
            Metric(
                "measure_part after the decode, lifted round wire, 4608x3072 (median CPU)",
                lifted_lib,
                "s",
            ),
            Metric(
                "peak memory of the process, lifted round wire, 4608x3072 (largest)",
                lifted_peak,
                "MB",
            ),
        ],  # fmt: skip
        tables=[Table("per photo", cols, [[r[c] for c in cols] for r in rows])],
        notes=[
            f"one core ({core}; OMP/OpenBLAS/OpenCV threads 1); wall and CPU of "
            "`python -m cvmeasure part PHOTO ... --json` as a child process (its start-up, "
            "imports and decode included), the library call's CPU after read_photo",
            "cvmeasure's modules compiled to bytecode before the runs (as an installed "
            "package is), so no run pays for compiling them",
            "peak_mb: the child's VmHWM (its own peak resident memory, read at its exit)",
            "flat: a 120 deg arc of 10 chords (R 60 mm) beside a 14x10 ChArUco board, "
            "900 mm, JPEG q92 (cvmeasure_datasets.render_part_photo, true lens); lifted: "
            "a 3 mm round wire lifted 3 mm at one end, side lit, on a plane measured from "
            "a board photo (render_round_wire); 2 photos: the same part slid 80 mm "
            "(measure_part(moved_image=...); the CLI's --moved needs a board in both photos)",
            f"{repeats} run(s) per row, median",
        ],
    )


if __name__ == "__main__":
    main()
