"""Batch measurement: real photo files, real spawned workers, a real killed subprocess, Dask."""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import cv2
import numpy as np
import pytest

from cvmeasure.batch import (
    MeasureContext,
    detect_kind,
    done_keys,
    list_photos,
    measure_one,
    photo_key,
    run_batch,
)
from cvmeasure.cli import main
from cvmeasure.errors import InputError
from cvmeasure.fileio import read_jsonl
from cvmeasure.imageio import read_photo

REPO = Path(__file__).resolve().parents[2]


def disc_photos(folder: Path, n: int, *, size=(320, 240), seed=5, ext=".jpg"):
    """n photos of one dark disc on a light ground; returns {file name: (x, y, r) px}."""
    rng = np.random.default_rng(seed)
    folder.mkdir(parents=True, exist_ok=True)
    w, h = size
    truth = {}
    for i in range(n):
        r = float(rng.uniform(0.08, 0.15) * h)
        x = float(rng.uniform(r + 4, w - r - 4))
        y = float(rng.uniform(r + 4, h - r - 4))
        # anti-aliased disc, 8x supersampled inside its bounding box (exact area)
        ss = 8
        x0, y0 = int(x - r) - 2, int(y - r) - 2
        bw, bh = int(2 * r) + 5, int(2 * r) + 5
        yy, xx = np.mgrid[0 : bh * ss, 0 : bw * ss]
        px = x0 + (xx + 0.5) / ss - 0.5
        py = y0 + (yy + 0.5) / ss - 0.5
        inside = (px - x) ** 2 + (py - y) ** 2 <= r * r
        cover = np.zeros((h, w))
        cover[y0 : y0 + bh, x0 : x0 + bw] = inside.reshape(bh, ss, bw, ss).mean(axis=(1, 3))
        grey = 225 - 180 * cover + rng.normal(0, 2, (h, w))
        img = np.clip(np.dstack([grey, grey * 0.9, grey * 0.8]), 0, 255).astype(np.uint8)
        name = f"photo_{i:03d}{ext}"
        cv2.imwrite(str(folder / name), img)
        truth[name] = (x, y, r)
    return truth


def check_against_truth(records, truth):
    assert sorted(r["file_name"] for r in records) == sorted(truth)
    for rec in records:
        x, y, r = truth[rec["file_name"]]
        assert rec["ok"], rec["error"]
        assert abs(rec["x_px"] - x) < 0.15 and abs(rec["y_px"] - y) < 0.15
        assert abs(rec["r_px"] - r) < 0.5  # Otsu level on a blurred edge: area within 0.5 px radius


def test_list_photos_folder_glob_file_and_errors(tmp_path):
    disc_photos(tmp_path / "a", 3)
    (tmp_path / "a" / "notes.txt").write_text("not a photo")
    assert [p.name for p in list_photos(tmp_path / "a")] == [f"photo_{i:03d}.jpg" for i in range(3)]
    assert len(list_photos(str(tmp_path / "a" / "photo_00[01].jpg"))) == 2
    # the same photo named twice is listed once
    assert len(list_photos([tmp_path / "a", tmp_path / "a" / "photo_000.jpg"])) == 3
    (tmp_path / "empty").mkdir()
    with pytest.raises(InputError, match="empty: no photos found"):
        list_photos(tmp_path / "empty")
    with pytest.raises(InputError, match="nope: no such photo"):
        list_photos(tmp_path / "nope")


def test_serial_batch_measures_and_resume_measures_nothing_again(tmp_path):
    truth = disc_photos(tmp_path / "p", 5)
    out = tmp_path / "results.jsonl"
    photos = list_photos(tmp_path / "p")
    summary = run_batch(photos, out, kind="disc", workers=1)
    assert (summary.measured, summary.failed, summary.backend) == (5, 0, "serial")
    check_against_truth(read_jsonl(out), truth)
    before = out.read_bytes()
    again = run_batch(photos, out, kind="disc", workers=1)
    assert (again.measured, again.already_done) == (0, 5)
    assert out.read_bytes() == before
    # a photo changed on disk (new mtime/size) is measured again; the others are not
    changed = tmp_path / "p" / "photo_002.jpg"
    cv2.imwrite(str(changed), cv2.imread(str(changed))[:, ::-1])
    third = run_batch(photos, out, kind="disc", workers=1)
    assert third.measured == 1 and read_jsonl(out)[-1]["file_name"] == "photo_002.jpg"


def test_spawn_pool_gives_the_serial_results(tmp_path):
    truth = disc_photos(tmp_path / "p", 8, seed=9)
    photos = list_photos(tmp_path / "p")
    run_batch(photos, tmp_path / "serial.jsonl", kind="disc", workers=1)
    summary = run_batch(photos, tmp_path / "pool.jsonl", kind="disc", workers=2)
    assert summary.backend == "spawn-pool" and summary.workers == 2
    serial = {r["photo_key"]: r for r in read_jsonl(tmp_path / "serial.jsonl")}
    pool = read_jsonl(tmp_path / "pool.jsonl")
    check_against_truth(pool, truth)
    assert len({r["worker_pid"] for r in pool} - {os.getpid()}) >= 1
    for rec in pool:
        assert rec["x_px"] == serial[rec["photo_key"]]["x_px"]


def test_partial_last_line_is_repaired_before_appending(tmp_path):
    truth = disc_photos(tmp_path / "p", 3)
    photos = list_photos(tmp_path / "p")
    out = tmp_path / "r.jsonl"
    run_batch(photos[:2], out, kind="disc", workers=1)
    with open(out, "a") as fh:
        fh.write('{"photo": "cut by a kill')  # a write interrupted mid-line
    run_batch(photos, out, kind="disc", workers=1)
    check_against_truth(read_jsonl(out), truth)


def test_bad_photo_is_recorded_and_the_batch_goes_on(tmp_path):
    disc_photos(tmp_path / "p", 2)
    (tmp_path / "p" / "broken.jpg").write_bytes(b"\xff\xd8 truncated")
    out = tmp_path / "r.jsonl"
    assert main(["batch", str(tmp_path / "p"), "--kind", "disc", "-o", str(out), "--quiet"]) == 2
    records = {r["file_name"]: r for r in read_jsonl(out)}
    assert records["broken.jpg"]["ok"] is False
    assert "broken.jpg: unreadable photo" in records["broken.jpg"]["error"]
    assert records["photo_000.jpg"]["ok"] and records["photo_001.jpg"]["ok"]


def test_cli_json_summary_and_input_errors(tmp_path, capsys):
    disc_photos(tmp_path / "p", 2)
    out = tmp_path / "r.jsonl"
    assert (
        main(
            [
                "batch",
                str(tmp_path / "p"),
                "--kind",
                "disc",
                "-o",
                str(out),
                "--json",
                "--workers",
                "1",
            ]
        )
        == 0
    )
    summary = json.loads(capsys.readouterr().out)
    assert summary["measured"] == 2 and summary["failed"] == 0
    assert main(["batch", str(tmp_path / "nothing"), "--kind", "disc", "-o", str(out)]) == 2
    assert "nothing: no such photo" in capsys.readouterr().err
    bad_kit = tmp_path / "kit.json"
    bad_kit.write_text("{not json")
    assert main(["batch", str(tmp_path / "p"), "--kit", str(bad_kit), "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "kit.json" in err


def test_linear_16_bit_photo_measures_like_the_jpeg(tmp_path):
    """A linear photo (as RAW decodes to) goes through the same measurement as a JPEG."""
    truth = disc_photos(tmp_path / "j", 1, seed=21, ext=".png")
    png = tmp_path / "j" / "photo_000.png"
    srgb = cv2.imread(str(png)).astype(np.float32) / 255
    linear = np.where(srgb <= 0.04045, srgb / 12.92, ((srgb + 0.055) / 1.055) ** 2.4)
    lin_path = tmp_path / "j" / "photo_000.linear.tiff"
    cv2.imwrite(str(lin_path), np.round(linear * 65535).astype(np.uint16))
    recs = [measure_one(str(p), photo_key(p), "disc", MeasureContext()) for p in (png, lin_path)]
    x, y, r = truth["photo_000.png"]
    for rec in recs:
        assert rec["ok"], rec["error"]
        assert abs(rec["x_px"] - x) < 0.15 and abs(rec["y_px"] - y) < 0.15
    assert abs(recs[0]["r_px"] - recs[1]["r_px"]) < 0.05


@pytest.mark.parametrize("start_method", ["spawn", "forkserver"])
def test_real_raw_photo_goes_through_the_batch(shared_real, tmp_path, start_method):
    """RAW decoding in pool workers (rawpy deadlocks in plainly forked ones)."""
    dng = shared_real / "raw" / "Blackmagic.dng"
    jpg = tmp_path / "Blackmagic.jpg"
    cv2.imwrite(str(jpg), read_photo(dng).bgr8(), [cv2.IMWRITE_JPEG_QUALITY, 95])
    out = tmp_path / "r.jsonl"
    summary = run_batch([dng, jpg], out, kind="disc", workers=2, start_method=start_method)
    assert summary.failed == 0 and summary.backend == f"{start_method}-pool"
    rec = {r["file_name"]: r for r in read_jsonl(out)}
    assert rec["Blackmagic.dng"]["image_size_px"] == [4128, 2176]
    # the same scene through RAW and through its JPEG: the same largest blob, within 1 px
    for k in ("x_px", "y_px", "r_px"):
        assert abs(rec["Blackmagic.dng"][k] - rec["Blackmagic.jpg"][k]) < 1.0


def test_detect_kind_board_vs_machine(tmp_path):
    from cvmeasure.board import CharucoBoardSpec

    board = CharucoBoardSpec(squares_x=7, squares_y=5, square_mm=20.0, marker_mm=15.0)
    img = board.cv_board().generateImage((700, 500), marginSize=20)
    cv2.imwrite(str(tmp_path / "board.png"), img)
    disc_photos(tmp_path, 1)
    assert detect_kind(read_photo(tmp_path / "board.png")) == "part"
    assert detect_kind(read_photo(tmp_path / "photo_000.jpg")) == "machine"


@pytest.mark.slow
def test_killed_batch_resumes_and_measures_each_photo_exactly_once(tmp_path):
    truth = disc_photos(tmp_path / "p", 40, size=(640, 480), seed=13, ext=".png")
    out = tmp_path / "r.jsonl"
    cmd = [
        sys.executable,
        "-m",
        "cvmeasure",
        "batch",
        str(tmp_path / "p"),
        "--kind",
        "disc",
        "-o",
        str(out),
        "--workers",
        "2",
        "--quiet",
    ]
    proc = subprocess.Popen(cmd, cwd=REPO, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if out.exists() and out.read_bytes().count(b"\n") >= 6:
                break
            time.sleep(0.005)
        os.killpg(proc.pid, signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    first = len(done_keys(out))
    assert 6 <= first < 40, f"kill came too late to test resuming ({first} done)"
    resumed = subprocess.run(
        cmd[:-1] + ["--json"], cwd=REPO, capture_output=True, text=True, timeout=120
    )
    assert resumed.returncode == 0, resumed.stderr
    summary = json.loads(resumed.stdout)
    assert summary["already_done"] == first and summary["measured"] == 40 - first
    records = read_jsonl(out)
    keys = [r["photo_key"] for r in records]
    assert len(keys) == len(set(keys)) == 40  # nothing lost, nothing measured twice
    check_against_truth(records, truth)


@pytest.mark.slow
def test_a_batch_killed_alone_leaves_no_worker_behind(tmp_path):
    disc_photos(tmp_path / "p", 40, size=(640, 480), seed=21, ext=".png")
    out = tmp_path / "r.jsonl"
    cmd = [sys.executable, "-m", "cvmeasure", "batch", str(tmp_path / "p"), "--kind", "disc"]
    cmd += ["-o", str(out), "--workers", "2", "--quiet"]
    proc = subprocess.Popen(cmd, cwd=REPO, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if out.exists() and out.read_bytes().count(b"\n") >= 4:
                break
            time.sleep(0.005)
        os.kill(proc.pid, signal.SIGKILL)  # the batch only, not its process group
    finally:
        proc.wait(timeout=30)
    # its workers (same process group) notice within a fraction of a second
    deadline = time.monotonic() + 5.0
    alive = True
    while alive and time.monotonic() < deadline:
        try:
            os.killpg(proc.pid, 0)
            time.sleep(0.05)
        except ProcessLookupError:
            alive = False
    if alive:
        os.killpg(proc.pid, signal.SIGKILL)
    assert not alive, "batch workers outlived the batch by 5 s"


@pytest.mark.slow
def test_dask_local_cluster_on_loopback(tmp_path, capsys):
    from distributed import LocalCluster

    truth = disc_photos(tmp_path / "p", 6, seed=17)
    out = tmp_path / "r.jsonl"
    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=50,
    ) as cluster:
        address = cluster.scheduler_address
        assert address.startswith("tcp://127.0.0.1:")
        code = main(
            [
                "batch",
                str(tmp_path / "p"),
                "--kind",
                "disc",
                "-o",
                str(out),
                "--scheduler",
                address,
                "--json",
            ]
        )
    assert code == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["backend"] == "dask" and summary["workers"] == 2
    check_against_truth(read_jsonl(out), truth)
    assert {r["worker_pid"] for r in read_jsonl(out)}.isdisjoint({os.getpid()})


@pytest.mark.slow
def test_linear_render_goes_through_the_machine_measurement_like_its_jpeg(tmp_path):
    """The photo lab's 16-bit linear render (the RAW path) and its JPEG: same pipeline, same truth."""
    from cvmeasure_datasets.bender import render_bender_photo

    rendered = render_bender_photo(
        pin_angle_deg=52.0, bend_angle_deg=41.0, seed=3, scale=0.3, linear=True
    )
    jpg, _truth = rendered.save(tmp_path / "bend")
    tiff = rendered.save_linear_tiff(tmp_path / "bend.linear.tiff")
    assert read_photo(tiff).linear and not read_photo(jpg).linear
    out = tmp_path / "r.jsonl"
    summary = run_batch([jpg, tiff], out, kind="auto", workers=1)
    assert summary.failed == 0, summary.failures
    records = {Path(r["photo"]).name: r for r in read_jsonl(out)}
    for rec in records.values():
        assert rec["kind"] == "machine"
        assert abs(rec["bend_angle_deg"] - rendered.truth["bend_angle_deg"]) < 0.1
        assert abs(rec["pin_angle_deg"] - rendered.truth["pin_angle_deg"]) < 0.1


def test_custom_measurement_runs_in_spawned_workers(tmp_path, capsys):
    truth = disc_photos(tmp_path / "p", 4, seed=31)
    out = tmp_path / "r.jsonl"
    code = main(["batch", str(tmp_path / "p"), "--measure", "cvmeasure.batch:measure_disc",
                 "-o", str(out), "--workers", "2", "--quiet"])  # fmt: skip
    assert code == 0
    records = read_jsonl(out)
    assert {r["kind"] for r in records} == {"custom"}
    check_against_truth(records, truth)
    assert main(["batch", str(tmp_path / "p"), "--measure", "no.such:thing", "-o", str(out)]) == 2
    assert "--measure: 'no.such:thing' cannot be used as a measurement" in capsys.readouterr().err


def env_threads(photo, context):
    """A measurement reporting the thread limits its worker runs under."""
    return {k: os.environ.get(k) for k in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS")}


def test_spawned_workers_run_one_thread_each(tmp_path, monkeypatch):
    from cvmeasure import batch

    monkeypatch.setitem(batch.MEASURERS, "env", f"{__name__}:env_threads")
    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    disc_photos(tmp_path / "p", 3)
    summary = run_batch(list_photos(tmp_path / "p"), tmp_path / "r.jsonl", kind="env", workers=2)
    assert summary.failed == 0, summary.failures
    for rec in read_jsonl(tmp_path / "r.jsonl"):
        assert rec["OMP_NUM_THREADS"] == "1" and rec["OPENBLAS_NUM_THREADS"] == "1"
    assert "OMP_NUM_THREADS" not in os.environ  # the parent's environment is restored


@pytest.mark.slow
def test_part_photo_detected_and_measured_with_board_and_camera(tmp_path):
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.camera_model import save_camera
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure_datasets.parts import arc_part, render_part_photo

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    rendered = render_part_photo(part=arc_part(70.0, 120.0, 8), board=board, seed=3, scale=0.25)
    rendered.save(tmp_path / "p" / "part")
    save_camera(tmp_path / "camera.json", rendered.camera)
    atomic_write_json(tmp_path / "board.json", board.to_dict())
    out = tmp_path / "r.jsonl"
    args = ["batch", str(tmp_path / "p"), "-o", str(out), "--workers", "1", "--quiet"]
    # without the board and camera the part cannot be measured: recorded, exit 2
    assert main([*args]) == 2
    assert "needs the board (--board) and camera (--camera)" in read_jsonl(out)[0]["error"]
    out.unlink()
    extra = ["--camera", str(tmp_path / "camera.json"), "--board", str(tmp_path / "board.json")]
    assert main([*args, *extra, "--divisions", "8"]) == 0
    (rec,) = read_jsonl(out)
    assert rec["kind"] == "part"
    assert abs(rec["radius_mm"] - 70.0) < 0.7 and abs(rec["arc_angle_deg"] - 120.0) < 1.0
    assert abs(rec["segment_bend_deg"] - 15.0) < 0.2


def test_machine_photos_measured_on_a_plane(tmp_path, capsys):
    # a photo of a plate tilted 12 deg: with --plane the batch gives the true bend angle,
    # without it the tilt foreshortens it (as `cvmeasure measure --plane` does)
    from cvmeasure.camera_model import save_camera
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure_datasets.bender import render_bender_photo
    from cvmeasure_datasets.lighting import Lighting
    from cvmeasure_datasets.optics import Pose

    pose = Pose(tilt_deg=12.0, tilt_direction_deg=60.0, yaw_deg=25.0, offset_mm=(60.0, 40.0))
    photo = render_bender_photo(
        pin_angle_deg=40.0,
        bend_angle_deg=70.0,
        lighting=Lighting(cct_k=5000.0),
        pose=pose,
        seed=4,
        scale=0.3,
    )
    rot, t_mm = pose.extrinsics("machine")
    h = np.linalg.inv(photo.camera.camera_matrix @ np.column_stack((rot[:, 0], rot[:, 1], t_mm)))
    plane = atomic_write_json(tmp_path / "plane.json", {"H_board_image": h.tolist()})
    camera = save_camera(tmp_path / "camera.json", photo.camera)
    photos = tmp_path / "photos"
    photo.save(photos / "tilted")
    truth = photo.truth["bend_angle_deg"]
    argv = ["batch", str(photos), "--kind", "machine", "--camera", str(camera), "--workers", "1"]
    assert main([*argv, "--plane", str(plane), "-o", str(tmp_path / "on.jsonl"), "--quiet"]) == 0
    assert main([*argv, "-o", str(tmp_path / "off.jsonl"), "--quiet"]) == 0
    on = read_jsonl(tmp_path / "on.jsonl")[0]
    off = read_jsonl(tmp_path / "off.jsonl")[0]
    assert on["bend_angle_deg"] == pytest.approx(truth, abs=0.06)
    assert abs(off["bend_angle_deg"] - truth) > 0.3
    # a plane without a camera is refused before anything is measured
    no_cam = ["batch", str(photos), "--plane", str(plane), "-o", str(tmp_path / "x.jsonl")]
    assert main(no_cam) == 2
    assert "plane JSON has no camera" in capsys.readouterr().err
    assert not (tmp_path / "x.jsonl").exists()
