"""RAW path vs JPEG: bend/pin angle errors on the photo lab's 16-bit linear renders and their JPEGs.

Each bender photo is rendered once with ``linear=True``; the JPEG (what a camera
writes) and the 16-bit linear TIFF (``*.linear.tiff``, what a RAW decode gives:
linear, white-balanced, no gamma, no JPEG) go through the same batch
measurement (``cvmeasure.batch``, kind ``machine``). Lightings vary (warm, cool,
dim, strong white-balance error), so the colour segmentation is exercised.
"""

from __future__ import annotations

import argparse
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from benchmarks import Metric, Table, finish

SECTION = "RAW path vs JPEG (issue 9)"

LIGHTINGS = {
    "workshop 5000 K": {},
    "warm 3000 K": {"cct_k": 3000.0, "wb_error_k": 400.0},
    "cool 6500 K": {"cct_k": 6500.0, "wb_error_k": -400.0},
    "dim (exposure 0.35)": {"exposure": 0.35},
    "bad white balance (+1500 K)": {"wb_error_k": 1500.0},
}


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.raw", description=__doc__)
    p.add_argument("--quick", action="store_true", help="1152x768 renders, 1 photo per lighting")
    p.add_argument("--per-lighting", type=int, help="photos per lighting (default 3, quick 1)")
    args = p.parse_args(argv)
    from cvmeasure.batch import run_batch
    from cvmeasure.fileio import read_jsonl
    from cvmeasure_datasets.bender import render_bender_photo
    from cvmeasure_datasets.lighting import Lighting

    scale = 0.25 if args.quick else 0.5
    per = args.per_lighting or (1 if args.quick else 3)
    rng = np.random.default_rng(2024)
    t0 = time.perf_counter()
    work = Path(tempfile.mkdtemp(prefix="cvmeasure-bench-raw-"))
    truth: dict[str, dict] = {}
    rows = []
    try:
        files = []
        for li, (name, kwargs) in enumerate(LIGHTINGS.items()):
            for k in range(per):
                pin = float(rng.uniform(-120, 120))
                bend = pin * float(rng.uniform(0.75, 0.95))
                rendered = render_bender_photo(
                    pin_angle_deg=pin,
                    bend_angle_deg=bend,
                    lighting=Lighting(**kwargs),
                    seed=100 * li + k,
                    scale=scale,
                    linear=True,
                )
                stem = f"l{li}_{k}"
                jpg, _t = rendered.save(work / stem)
                tiff = rendered.save_linear_tiff(work / f"{stem}.linear.tiff")
                for path in (jpg, tiff):
                    truth[path.name] = {**rendered.truth, "bench_lighting": name}
                    files.append(path)
        out = work / "results.jsonl"
        summary = run_batch(files, out, kind="machine", workers=1)
        records = read_jsonl(out)
        size = rendered.bgr.shape
    finally:
        shutil.rmtree(work, ignore_errors=True)

    errors: dict[tuple[str, str], list[float]] = {}
    misses: dict[str, int] = {"jpeg": 0, "linear": 0}
    for rec in records:
        name = Path(rec["photo"]).name
        kind = "linear" if ".linear." in name else "jpeg"
        t = truth[name]
        if not rec["ok"]:
            misses[kind] += 1
            continue
        for key in ("bend_angle_deg", "pin_angle_deg"):
            err = abs(rec[key] - t[key])
            errors.setdefault((kind, t["bench_lighting"]), []).append(err)
            errors.setdefault((kind, "all"), []).append(err)

    def stat(kind: str, lighting: str, q: float) -> float:
        values = errors.get((kind, lighting), [])
        return float(np.percentile(values, q)) if values else float("nan")

    for lighting in [*LIGHTINGS, "all"]:
        rows.append(
            [
                lighting,
                stat("jpeg", lighting, 50),
                stat("jpeg", lighting, 95),
                stat("linear", lighting, 50),
                stat("linear", lighting, 95),
            ]
        )
    p95_jpeg, p95_linear = stat("jpeg", "all", 95), stat("linear", "all", 95)
    n_photos = len(records) // 2
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=[
            Metric("photo size", f"{size[1]}x{size[0]}", "px"),
            Metric("photos per file type", n_photos, ""),
            Metric("p95 angle error, JPEG", p95_jpeg, "deg"),
            Metric("p95 angle error, linear 16-bit (RAW path)", p95_linear, "deg"),
            Metric(
                "RAW path no worse than JPEG (p95 linear <= p95 JPEG + 0.005 deg)",
                p95_linear - p95_jpeg,
                "deg",
                target="<= 0.005",
                met=bool(p95_linear <= p95_jpeg + 0.005),
            ),
            Metric(
                "misses (linear, JPEG)",
                f"{misses['linear']}, {misses['jpeg']}",
                "photos",
                target="0, 0",
                met=misses["linear"] == 0 and misses["jpeg"] == 0,
            ),
        ],
        tables=[
            Table(
                "angle errors (bend and pin) by lighting, deg",
                ["lighting", "JPEG median", "JPEG p95", "linear median", "linear p95"],
                rows,
            )
        ],
        notes=[
            f"{summary.measured} files measured in {summary.seconds:.1f} s; renders from "
            "cvmeasure_datasets.render_bender_photo(linear=True), seeds 100*lighting+k",
        ],
        seconds=time.perf_counter() - t0,
    )


if __name__ == "__main__":
    main()
