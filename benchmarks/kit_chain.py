"""The kit chain as a user runs it (issue 42): print -> calibrate -> plane -> heights -> measure.

Every step of the measuring side is a ``cvmeasure`` process with its defaults:
``targets charuco`` and ``targets markers`` (the printed board and kit),
``render board`` + ``calibrate`` (the lens from 12 board views), ``plane`` (a photo
of the board lying on the plate from the bender photos' pose), ``markers heights``
(the kit's heights from a bend sweep) and ``measure --plane``.

The bender photos come from :mod:`cvmeasure_datasets.discs3d`, a forward projector
that shares no geometry code with the measurement (each disc a 3D circle at its
true height, projected point by point through the renderer's lens, blurred,
noised, JPEG-compressed); the board photo of the plane from the photo lab at the
very same pose. Three kinds of markers, on several camera poses (square and
tilted, different distances):

* ``flat``: flat stickers, measured with ``--flat-kit``;
* ``3d``: caps at the built-in kit's heights, measured with the built-in kit;
* ``off``: caps standing up to 10 % off their nominal heights (each drawn
  uniformly), measured with the nominal kit (what the issue found: tenths of a
  degree) and with the heights measured by ``markers heights`` from 8 bend photos
  and 2 of the straight wire.

And the wrong kit: flat stickers measured with the 3D kit, caps with ``--flat-kit``:
how many photos carry the ``kit_heights_mismatch`` warning naming the heights.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from benchmarks import Metric, Table, finish

SECTION = "Kit chain: print, calibrate, plane, heights, measure (issue 42)"
SCALE = 1 / 3
#: Camera poses of the bender photos (machine frame): square, tilted, farther and tilted.
POSES = (
    dict(distance_mm=550.0, offset_mm=(-10.0, 0.0)),
    dict(distance_mm=520.0, offset_mm=(20.0, 30.0), yaw_deg=40.0, tilt_deg=8.0,
         tilt_direction_deg=120.0),
    dict(distance_mm=620.0, offset_mm=(-30.0, -20.0), yaw_deg=-25.0, tilt_deg=12.0,
         tilt_direction_deg=250.0),
)  # fmt: skip
#: Poses of the photo lab's scenes (every effect on: 3D wire, supports, depth of field,
#: motion blur, Bayer, textured plate, stray objects), its default distance.
PHOTOLAB_POSES = (
    dict(distance_mm=850.0, offset_mm=(-10.0, 0.0)),
    dict(distance_mm=850.0, offset_mm=(-10.0, 0.0), yaw_deg=30.0, tilt_deg=8.0,
         tilt_direction_deg=120.0),
)  # fmt: skip
SWEEP = [(p, 0.85 * p) for p in (-100, -70, -40, -15, 15, 40, 70, 100)]
STRAIGHT = [(-30.0, 0.0), (30.0, 0.0)]
KEYS = ("pin_angle_deg", "bend_angle_deg")


def _cli(*args: str) -> subprocess.CompletedProcess:
    """One ``cvmeasure`` process (the installed entry point of this interpreter)."""
    cmd = [sys.executable, "-m", "cvmeasure", *args]
    return subprocess.run(cmd, capture_output=True, text=True, check=False)


def _ok(done: subprocess.CompletedProcess) -> subprocess.CompletedProcess:
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(done.args[2:5])}... exit {done.returncode}: {done.stderr}")
    return done


def _check_angles(rng: np.random.Generator, n: int) -> list[tuple[float, float]]:
    """Random loaded bends: pin in +-(10..110) deg, the bend 5-15 % short of it."""
    pins = rng.uniform(10.0, 110.0, n) * rng.choice([-1.0, 1.0], n)
    return [(float(p), float(p * rng.uniform(0.85, 0.95))) for p in pins]


def _off_kit(nominal, rng: np.random.Generator):
    """The caps as built: each off its nominal height by a uniform -10..+10 %."""
    return replace(
        nominal,
        markers=tuple(
            replace(m, height_mm=round(m.height_mm * (1 + rng.uniform(-0.1, 0.1)), 3))
            for m in nominal.markers
        ),
    )


def _render(folder: Path, name: str, pin: float, bend: float, kit, pose, seed: int, scenes: str):
    """One bender photo of ``kit`` (its heights as built) from ``pose``: its path and truth."""
    import cv2

    import cvmeasure_datasets
    from cvmeasure_datasets.discs3d import DiscScene, render_discs_at_heights

    if scenes == "discs3d":
        bgr, truth = render_discs_at_heights(
            DiscScene(pin, bend, kit=kit, pose=pose),
            camera=cvmeasure_datasets.default_camera().scaled(SCALE),
            seed=seed,
        )
        path = folder / f"{name}.png"  # already JPEG-compressed by the scene: kept lossless
        cv2.imwrite(str(path), bgr)
        return path, truth
    photo = cvmeasure_datasets.render_bender_photo(
        pin_angle_deg=pin,
        bend_angle_deg=bend,
        kit=kit,
        pose=pose,
        scale=SCALE,
        seed=seed,
        effects=cvmeasure_datasets.SceneEffects.all_on(),
    )
    return photo.save(folder / name)[0], photo.truth


def _board_on_plate(folder: Path, pose, seed: int) -> Path:
    """A photo of the board lying on the plate from ``pose`` (photo lab; as a user takes it)."""
    import cvmeasure_datasets
    from benchmarks._calibrated import BOARD
    from cvmeasure_datasets.optics import Pose

    rot, t_mm = pose.extrinsics("machine")
    flip = np.diag([1.0, -1.0, -1.0])
    sx, sy = BOARD.squares_x * BOARD.square_mm, BOARD.squares_y * BOARD.square_mm
    target = np.array([pose.offset_mm[0], pose.offset_mm[1], 0.0])
    origin = target - flip @ np.array([sx / 2, sy / 2, 0.0])
    board_pose = Pose.from_extrinsics(rot @ flip, rot @ origin + t_mm, "board")
    view = cvmeasure_datasets.render_board_view(
        board=BOARD,
        camera=cvmeasure_datasets.default_camera().scaled(SCALE),
        pose=board_pose,
        seed=seed,
    )
    return view.save(folder / "board_on_plate")[0]


def _measure(photos: list[Path], plane: Path, kit_args: list[str]) -> list[dict]:
    done = _cli("measure", *map(str, photos), "--plane", str(plane), *kit_args, "--json")
    if done.returncode not in (0, 2):
        raise RuntimeError(done.stderr)
    return [json.loads(line) for line in done.stdout.splitlines() if line.startswith("{")]


def _score(records: list[dict], truths: dict[str, dict]) -> dict:
    errs, z, warned = [], [], 0
    for r in records:
        t = truths[r["photo"]]
        for key in KEYS:
            e = (r[key] - t[key] + 180.0) % 360.0 - 180.0
            errs.append(e)
            z.append(abs(e) / max(r["uncertainty_deg"][key], 1e-12))
        codes = [w["code"] if isinstance(w, dict) else str(w) for w in r["warnings"]]
        warned += any(
            c == "kit_heights_mismatch" and "height" in w.get("message", "")
            for c, w in zip(codes, r["warnings"], strict=True)
            if isinstance(w, dict)
        )
    return {
        "n_photos": len(records),
        "errors": errs,
        "z": z,
        "warned": warned,
        "all_warnings": [w for r in records for w in r["warnings"]],
    }


def _p95(values) -> float:
    return float(np.percentile(np.abs(values), 95)) if len(values) else math.nan


def _pose_run(work: Path, i: int, pose, camera: Path, board: Path, args, rng, scenes: str) -> dict:
    from cvmeasure.kit import default_kit

    folder = work / f"{scenes}{i}"
    folder.mkdir()
    plane = folder / "plane.json"
    _ok(_cli("plane", str(_board_on_plate(folder, pose, 5000 + i)), "--board", str(board),
             "--camera", str(camera), "-o", str(plane)))  # fmt: skip
    nominal = default_kit()
    out: dict = {}
    check = _check_angles(rng, args.photos)
    # flat stickers and caps at the nominal heights: the kit that describes them, and the wrong one
    for kind, true_kit, flat in (("flat", nominal.flat(), True), ("3d", nominal, False)):
        truths, paths = {}, []
        for j, (pin, bend) in enumerate(check):
            path, truth = _render(
                folder, f"{kind}{j:02d}", pin, bend, true_kit, pose, 100 * i + j, scenes
            )
            truths[str(path)] = truth
            paths.append(path)
        right = ["--flat-kit"] if flat else []
        wrong = [] if flat else ["--flat-kit"]
        out[kind] = _score(_measure(paths, plane, right), truths)
        out[f"{kind}, wrong kit"] = _score(_measure(paths, plane, wrong), truths)
    # caps off their nominal heights: the nominal kit, then the heights measured by the step
    off = _off_kit(nominal, rng)
    truths, paths, sweep, straight = {}, [], [], []
    for j, (pin, bend) in enumerate(check):
        path, truth = _render(folder, f"off{j:02d}", pin, bend, off, pose, 100 * i + 50 + j, scenes)
        truths[str(path)] = truth
        paths.append(path)
    for j, (pin, bend) in enumerate(SWEEP):
        sweep.append(_render(folder, f"sweep{j:02d}", pin, bend, off, pose, 900 + j, scenes)[0])
    for j, (pin, bend) in enumerate(STRAIGHT):
        straight.append(_render(folder, f"straight{j}", pin, bend, off, pose, 950 + j, scenes)[0])
    out["off, nominal kit"] = _score(_measure(paths, plane, []), truths)
    measured_kit = folder / "kit_heights.json"
    t0 = time.perf_counter()
    done = _cli("markers", "heights", *map(str, sweep),
                *[a for s in straight for a in ("--straight", str(s))],
                "--plane", str(plane), "-o", str(measured_kit), "--json")  # fmt: skip
    if done.returncode not in (0, 2) or not measured_kit.exists():
        raise RuntimeError(f"markers heights: exit {done.returncode}: {done.stderr}")
    heights = json.loads(done.stdout)
    heights["photos_refused"] = done.stderr.count("cvmeasure markers heights:")
    heights["seconds"] = time.perf_counter() - t0
    heights["true_mm"] = {m.role: m.height_mm for m in off.markers}
    out["off, measured heights"] = _score(_measure(paths, plane, ["--kit", str(measured_kit)]),
                                          truths)  # fmt: skip
    out["heights"] = heights
    return out


def _surfacing(work: Path) -> dict:
    """Every photo warning of a simulated calibration session, looked for where the operator
    looks: the console summary, the calibration JSON (provenance.warnings) and the HTML
    report; and `report` on the session log."""
    (work / "surf").mkdir()
    cal = work / "surf" / "cal.json"
    done = _ok(_cli("session", "--simulate", "-o", str(cal), "--angles", "10,30,60",
                    "--scale", "0.2", "--quiet"))  # fmt: skip
    log = [json.loads(line) for line in (work / "surf" / "cal_session" / "session.jsonl").open()]
    produced = [
        (r[f"photo_{w}"], x["code"])
        for r in log
        if r.get("event") == "sample"
        for w in ("loaded", "unloaded")
        for x in r[w]["warnings"]
    ]
    doc = json.loads(cal.read_text())
    in_cal = {(x["photo"], x["code"]) for x in doc["provenance"].get("warnings", [])}
    report = cal.with_suffix(".html").read_text()
    page = work / "surf" / "log.html"
    _ok(_cli("report", str(work / "surf" / "cal_session" / "session.jsonl"), "-o", str(page),
             "--quiet"))  # fmt: skip
    log_page = page.read_text()
    missing = {
        "console": sum(code not in done.stdout for _, code in produced),
        "calibration JSON": sum((p, c) not in in_cal for p, c in produced),
        "session report": sum(c not in report or p not in report for p, c in produced),
        "report of the log": sum(c not in log_page for _, c in produced),
    }
    return {"produced": len(produced), "missing": missing}


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.kit_chain", description=__doc__)
    p.add_argument("--quick", action="store_true", help="fewer photos per pose (about 3 min)")
    p.add_argument("--photos", type=int, help="check photos per pose and kind (default 12)")
    p.add_argument(
        "--photolab-photos", type=int, help="the same in the photo lab's scenes (default 5)"
    )
    p.add_argument("--seed", type=int, default=42)
    args = p.parse_args(argv)
    args.photos = args.photos or (6 if args.quick else 12)
    args.photolab_photos = args.photolab_photos or (3 if args.quick else 5)
    from cvmeasure_datasets.optics import Pose

    rng = np.random.default_rng(args.seed)
    t0 = time.perf_counter()
    runs = []
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        sheet = work / "board.pdf"
        _ok(_cli("targets", "charuco", "-o", str(sheet)))
        _ok(_cli("targets", "markers", "-o", str(work / "kit.pdf")))
        board = work / "board.pdf.board.json"
        if not board.exists():
            board = next(work.glob("*.board.json"))
        _ok(_cli("render", "board", "--count", "12", "--scale", f"{SCALE:.6f}",
                 "--seed", "7", "-o", str(work / "views")))  # fmt: skip
        camera = work / "camera.json"
        _ok(_cli("calibrate", *map(str, sorted((work / "views").glob("*.jpg"))),
                 "--board", str(board), "-o", str(camera)))  # fmt: skip
        surfacing = _surfacing(work)
        for i, pose_kw in enumerate(POSES):
            run = _pose_run(work, i, Pose(**pose_kw), camera, board, args, rng, "discs3d")
            runs.append(("discs3d", run))
        lab = argparse.Namespace(**{**vars(args), "photos": args.photolab_photos})
        for i, pose_kw in enumerate(PHOTOLAB_POSES[: 1 if args.quick else None]):
            run = _pose_run(work, i, Pose(**pose_kw), camera, board, lab, rng, "photolab")
            runs.append(("photolab", run))
    return _report(runs, surfacing, args, argv, time.perf_counter() - t0)


def _pool(runs: list[tuple[str, dict]], kinds: list[str]) -> dict:
    pooled = {k: {"errors": [], "z": [], "n": 0, "warned": 0} for k in [*kinds, "wrong kit"]}
    for _, run in runs:
        for k in kinds:
            pooled[k]["errors"] += run[k]["errors"]
            pooled[k]["z"] += run[k]["z"]
            pooled[k]["n"] += run[k]["n_photos"]
        for k in ("flat, wrong kit", "3d, wrong kit"):
            pooled["wrong kit"]["n"] += run[k]["n_photos"]
            pooled["wrong kit"]["warned"] += run[k]["warned"]
    return pooled


def _report(runs: list[tuple[str, dict]], surfacing: dict, args, argv, seconds: float) -> dict:
    kinds = ["flat", "3d", "off, nominal kit", "off, measured heights"]
    pooled = _pool(runs, kinds)
    right_false = sum(run[k]["warned"] for _, run in runs for k in ("flat", "3d"))
    right_n = sum(run[k]["n_photos"] for _, run in runs for k in ("flat", "3d"))
    rows, metrics = [], []
    for scenes in ("discs3d", "photolab", "all"):
        subset = [r for r in runs if scenes in ("all", r[0])]
        if not subset:
            continue
        part = _pool(subset, kinds)
        for k in kinds:
            e, z = part[k]["errors"], np.asarray(part[k]["z"])
            rows.append([scenes, k, part[k]["n"], round(_p95(e), 4),
                         round(float(np.max(np.abs(e))), 4),
                         round(100 * float(np.mean(z <= 2.0)), 1)])  # fmt: skip
    for k in kinds:
        e, z = pooled[k]["errors"], np.asarray(pooled[k]["z"])
        within = float(np.mean(z <= 2.0)) if len(z) else math.nan
        target = k != "off, nominal kit"
        metrics.append(
            Metric(
                f"pin/bend p95, {k}",
                round(_p95(e), 4),
                "deg",
                target="<= 0.02" if target else None,
                met=(_p95(e) <= 0.02) if target else None,
            )  # fmt: skip
        )
        metrics.append(
            Metric(
                f"within stated 2 sigma, {k}",
                round(100 * within, 1),
                "%",
                target="90-98" if target else None,
                met=(0.90 <= within <= 0.98) if target else None,
            )  # fmt: skip
        )
    wk = pooled["wrong kit"]
    share = wk["warned"] / max(wk["n"], 1)
    metrics.append(Metric("wrong kit warned, naming heights", round(100 * share, 1), "%",
                          target=">= 95", met=share >= 0.95))  # fmt: skip
    metrics.append(Metric("right kit warned kit_heights_mismatch (false)", right_false,
                          f"of {right_n} photos", target="0", met=right_false == 0))  # fmt: skip
    lost = sum(surfacing["missing"].values())
    metrics.append(Metric("session warnings missing from console, cal.json or reports", lost,
                          f"of {surfacing['produced']} x 4 places", target="0",
                          met=lost == 0))  # fmt: skip
    height_rows = []
    for i, (scenes, run) in enumerate(runs):
        h = run["heights"]
        for role, true in h["true_mm"].items():
            height_rows.append([f"{scenes} {i}", role, true, h["heights_mm"][role], h["height_sigma_mm"][role],
                                h["nominal_mm"][role]])  # fmt: skip
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[
            Table(
                "angles per kind (pooled over poses)",
                ["scenes", "kind", "photos", "p95_deg", "max_deg", "within_2sigma_pct"],
                rows,
            ),
            Table(
                "heights measured by `markers heights` (mm)",
                ["pose", "role", "true", "measured", "sigma", "nominal"],
                height_rows,
            ),
        ],  # fmt: skip
        notes=[
            f"{len(runs)} camera poses; check photos per pose and kind: {args.photos} (discs3d), "
            f"{args.photolab_photos} (photo lab); {SCALE:.3f} scale (1536 x 1024 px); seed "
            f"{args.seed}; {seconds:.0f} s in all.",
            "Scenes: cvmeasure_datasets.discs3d (forward projection, no geometry code shared "
            "with the measurement) and the photo lab's 3D scenes with every effect "
            "(SceneEffects.all_on: discs ray-traced at their heights on printed supports, 3D "
            "wire, depth of field, motion blur, Bayer, textured plate, 8 stray objects); the "
            "plane's board photo from the photo lab at the same pose. "
            "Lens from `cvmeasure calibrate` on 12 `render board` views; every measuring step "
            "a `cvmeasure` process with its defaults.",
            "'off': caps drawn uniformly within +-10 % of their nominal heights, once per pose; "
            "the heights step sees 8 loaded bends (pin +-15..100 deg) and 2 straight-wire photos.",
            "'wrong kit': flat stickers measured with the built-in 3D kit and caps at the "
            "nominal heights measured with --flat-kit; warned = the photo's record carries "
            "kit_heights_mismatch, whose message names both sets of heights.",
        ],
    )


if __name__ == "__main__":
    main()
