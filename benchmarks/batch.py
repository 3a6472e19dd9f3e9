"""Batch throughput: photos per second on 1 and 2 workers (spawn pool, Dask), and kill/resume.

Rendered bender photos (``datasets.render_bender_photo``, 4608x3072 JPEG at
full size) are measured with the real machine-photo pipeline
(``cvmeasure.batch``, kind ``machine``). A few distinct photos are rendered
(rendering costs ~25 s per full-size photo) and copied to the batch size, so
every file is a separate photo to the batch. Target (issue 9): on 2 cores,
throughput within 90 % of (single-core rate x cores). Rates are best-of-rounds,
1-worker and 2-worker runs interleaved, because the machine is shared.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks import REPO_ROOT, RESULTS_DIR, Metric, Table, finish

SECTION = "Batch throughput and resume (issue 9)"


def _photos(folder: Path, *, scale: float, distinct: int, total: int) -> list[Path]:
    """``total`` photo files in ``folder``: copies of ``distinct`` renders (cached across runs)."""
    from datasets.bender import render_bender_photo

    cache = Path(tempfile.gettempdir()) / f"cvmeasure-bench-batch-s{scale:g}"
    cache.mkdir(parents=True, exist_ok=True)
    sources = []
    for i in range(distinct):
        path = cache / f"render_{i}.jpg"
        if not path.exists():
            rendered = render_bender_photo(
                pin_angle_deg=20.0 + 35.0 * i, bend_angle_deg=15.0 + 30.0 * i, seed=i, scale=scale
            )
            written, _truth = rendered.save(cache / f"render_{i}")
            if written != path:
                shutil.move(written, path)
        sources.append(path)
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for k in range(total):
        dst = folder / f"photo_{k:04d}.jpg"
        shutil.copyfile(sources[k % distinct], dst)
        out.append(dst)
    return out


def _cli_batch(folder: Path, out: Path, *extra: str) -> dict:
    """Run ``cvmeasure batch`` in a fresh process (as a user does); return its JSON summary."""
    if out.exists():
        out.unlink()
    cmd = [sys.executable, "-m", "cvmeasure", "batch", str(folder), "--kind", "machine",
           "-o", str(out), "--quiet", "--json", *extra]  # fmt: skip
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    proc = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, check=False)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise RuntimeError(f"cvmeasure batch failed ({proc.returncode}): {proc.stderr[-400:]}")
    summary = json.loads(proc.stdout)
    # CPU of the CLI process and its pool workers (reaped by it), whole run
    summary["cpu_s"] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return summary


def _kill_and_resume(folder: Path, n: int, work: Path) -> dict:
    """Kill a real batch subprocess mid-way, resume it; count lost and repeated photos."""
    from cvmeasure.fileio import read_jsonl

    out = work / "resume.jsonl"
    cmd = [sys.executable, "-m", "cvmeasure", "batch", str(folder), "--kind", "machine",
           "-o", str(out), "--workers", "2", "--quiet"]  # fmt: skip
    proc = subprocess.Popen(cmd, cwd=REPO_ROOT, start_new_session=True)
    deadline = time.monotonic() + 600
    while time.monotonic() < deadline and proc.poll() is None:
        if out.exists() and out.read_bytes().count(b"\n") >= n // 3:
            break
        time.sleep(0.01)
    os.killpg(proc.pid, signal.SIGKILL)
    proc.wait()
    before = len(read_jsonl(out, skip_partial_last=True)) if out.exists() else 0
    done = subprocess.run(
        cmd[:-1] + ["--json"], cwd=REPO_ROOT, capture_output=True, text=True, check=False
    )
    summary = json.loads(done.stdout) if done.returncode == 0 else {}
    keys = [r["photo_key"] for r in read_jsonl(out)]
    return {
        "done_before_kill": before,
        "resumed_measured": summary.get("measured"),
        "records": len(keys),
        "lost": n - len(set(keys)),
        "repeated": len(keys) - len(set(keys)),
    }


def _dask_summary(folder: Path, out: Path) -> dict:
    from distributed import LocalCluster

    with LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        dashboard_address=None,
        silence_logs=50,
    ) as cluster:
        return _cli_batch(folder, out, "--scheduler", cluster.scheduler_address)


def _plot(rows: list[list], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6, 3.2), dpi=110, layout="constrained")
    ax = fig.add_subplot(1, 1, 1)
    labels = [r[0] for r in rows]
    ax.bar(
        labels,
        [r[2] for r in rows],
        color=["#777777", "#1f5f9f", "#c07020", "#2a8a2a"][: len(rows)],
    )
    if rows:
        ax.axhline(2 * rows[0][2], color="#b03020", ls="--", lw=1, label="2 x single-core rate")
        ax.axhline(0.9 * 2 * rows[0][2], color="#b03020", ls=":", lw=1, label="90 % of that")
    ax.set_ylabel("photos / s")
    ax.set_title("Batch throughput")
    ax.legend(fontsize=7)
    fig.savefig(path)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.batch", description=__doc__)
    p.add_argument("--quick", action="store_true", help="2304x1536 photos, 40 per batch")
    p.add_argument(
        "--photos", type=int, help="photos in the 2-worker batch (default 200, quick 40)"
    )
    p.add_argument("--rounds", type=int, default=2, help="interleaved rounds (best is kept)")
    args = p.parse_args(argv)
    import cv2

    scale = 0.5 if args.quick else 1.0
    n = args.photos or (40 if args.quick else 200)
    cores = len(os.sched_getaffinity(0))
    t0 = time.perf_counter()
    work = Path(tempfile.mkdtemp(prefix="cvmeasure-bench-batch-"))
    folder = work / "photos"
    try:
        photos = _photos(folder, scale=scale, distinct=2 if args.quick else 3, total=n)
        size = cv2.imread(str(photos[0])).shape
        load_before = os.getloadavg()[0]
        one: list[dict] = []
        two: list[dict] = []
        for _ in range(args.rounds):
            one.append(_cli_batch(folder, work / "w1.jsonl", "--workers", "1"))
            two.append(_cli_batch(folder, work / "w2.jsonl", "--workers", "2"))
        dask = _dask_summary(folder, work / "dask.jsonl")
        resume = _kill_and_resume(folder, n, work)
        load_after = os.getloadavg()[0]
    finally:
        shutil.rmtree(work, ignore_errors=True)

    def best(runs: list[dict], key: str) -> float:
        return max(float(r[key] or 0.0) for r in runs)

    best1, best2 = best(one, "photos_per_s"), best(two, "photos_per_s")
    steady1, steady2 = best(one, "steady_photos_per_s"), best(two, "steady_photos_per_s")
    efficiency = best2 / (2 * best1)
    cpu1 = min(r["cpu_s"] for r in one) / n
    cpu2 = min(r["cpu_s"] for r in two) / n
    steady_eff = steady2 / (2 * steady1)
    rows = [
        ["1 worker", n, best1, steady1, 1.0],
        ["2 workers, spawn pool", n, best2, steady2, best2 / best1],
        [
            "2 workers, Dask LocalCluster",
            n,
            float(dask["photos_per_s"]),
            float(dask["steady_photos_per_s"] or 0.0),
            float(dask["photos_per_s"]) / best1,
        ],
    ]
    plot = RESULTS_DIR / "batch_scaling.png"
    RESULTS_DIR.mkdir(parents=True, exist_ok=True)
    _plot(rows, plot)
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=[
            Metric("photo size", f"{size[1]}x{size[0]}", "px"),
            Metric(f"{n} photos, 1 worker", best1, "photos/s"),
            Metric("single-core time per photo (steady)", 1.0 / steady1, "s"),
            Metric(f"{n} photos, 2 workers (spawn pool)", best2, "photos/s"),
            Metric(
                "2-worker throughput / (2 x single-core), whole batch",
                efficiency,
                "",
                target=">= 0.90",
                met=efficiency >= 0.90,
            ),
            Metric(
                "the same, steady state (start-up excluded)",
                steady_eff,
                "",
                target=">= 0.90",
                met=steady_eff >= 0.90,
            ),
            Metric("CPU per photo, 1 worker (whole run)", cpu1, "s"),
            Metric("CPU per photo, 2 workers (whole run)", cpu2, "s"),
            Metric(
                "CPU-time efficiency 1 worker / 2 workers (idle-machine projection)",
                cpu1 / cpu2,
                "",
                target=">= 0.90",
                met=cpu1 / cpu2 >= 0.90,
            ),
            Metric(
                "2 workers, Dask LocalCluster, whole batch",
                float(dask["photos_per_s"]) / (2 * best1),
                "of 2 x single-core",
            ),
            Metric(
                "photos lost after kill + resume",
                resume["lost"],
                "photos",
                target="0",
                met=resume["lost"] == 0,
            ),
            Metric(
                "photos measured twice after kill + resume",
                resume["repeated"],
                "photos",
                target="0",
                met=resume["repeated"] == 0,
            ),
        ],
        tables=[
            Table(
                "throughput by backend (photos/s)",
                ["run", "photos", "whole batch", "steady state", "speed-up"],
                rows,
            ),
            Table(
                "kill and resume (real subprocess, SIGKILL)",
                ["done before kill", "measured on resume", "records", "lost", "repeated"],
                [
                    [
                        resume["done_before_kill"],
                        resume["resumed_measured"],
                        resume["records"],
                        resume["lost"],
                        resume["repeated"],
                    ]
                ],  # fmt: skip
            ),
        ],
        plots=[plot],
        notes=[
            f"{cores} cores; load average {load_before:.1f} before and {load_after:.1f} after the run: "
            "the machine is shared with other jobs, so wall-clock speed-ups measure the share of "
            "the CPUs the batch got, not the batch; CPU time per photo (this process's reaped "
            "children: the CLI and its pool workers) shows what parallelism costs, and on an idle "
            "machine the 2-worker throughput would be about (CPU efficiency) x 2 x single-core",
            f"each run is `cvmeasure batch --kind machine --json` in a fresh process; best of "
            f"{args.rounds} interleaved rounds; 'whole batch' includes the workers' start-up "
            "(imports, ~3 s for colour-science on first use), 'steady state' excludes it",
        ],
        seconds=time.perf_counter() - t0,
    )


if __name__ == "__main__":
    main()
