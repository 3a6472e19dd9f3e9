"""Marker angle accuracy under every lighting: ours vs the seed method on the same rendered photos, with the seed's thresholds as published and tuned (issue 8)."""

from __future__ import annotations

import argparse
import time
from dataclasses import replace
from typing import Any

import numpy as np

from benchmarks import RESULTS_DIR, Metric, Table, finish

SECTION = "Marker accuracy under every lighting: ours vs the seed method (issue 8)"

#: Light colour temperatures (K) of the sweep.
CCTS_K: tuple[float, ...] = (2700.0, 3500.0, 4500.0, 5500.0, 6500.0)
#: Target of issue 8: p95 angle error of the seed method / ours.
RATIO_TARGET = 10.0
#: Seed-method variants: how its fixed colour boxes are centred (the paper's widths always).
VARIANTS: dict[str, str] = {
    "seed": "boxes on the kit's nominal colours (no white balance)",
    "seed-ref": "boxes tuned on a reference photo (same light and camera settings)",
    "seed-self": "boxes tuned on the photo itself (an oracle: segmentation cannot fail on colour)",
}
#: The oracle variant's Hough centres with lens distortion removed (informative, no target).
LENS_VARIANT = "seed-self+lens"
DISC_FRACTION = 0.6  # pixels inside this fraction of a disc's radius give its observed colour
#: Render scale of the reference photos (only their colours are used).
REFERENCE_SCALE = 0.25


def observed_kit(bgr8: np.ndarray, truth: dict[str, Any], kit: Any) -> Any:
    """The kit with each marker's ``srgb`` replaced by its colour as the photo shows it.

    Median of the pixels inside ``DISC_FRACTION`` of each disc's true radius, no
    white balance: what a person tuning the seed's thresholds on this photo would
    read off. The seed's boxes (:func:`cvmeasure.markers.seed_baseline.seed_boxes`)
    are then centred on these colours.
    """
    from cvmeasure.kit import MarkerKit

    h, w = bgr8.shape[:2]
    markers = []
    for spec in kit.markers:
        t = truth["markers"][spec.role]
        cx, cy = t["centre_px"]
        r = DISC_FRACTION * float(t["r_px"])
        x0, x1 = max(0, int(cx - r)), min(w, int(cx + r) + 2)
        y0, y1 = max(0, int(cy - r)), min(h, int(cy + r) + 2)
        gy, gx = np.mgrid[y0:y1, x0:x1]
        inside = np.hypot(gx - cx, gy - cy) <= r
        b, g, rr = np.median(bgr8[y0:y1, x0:x1][inside], axis=0)
        markers.append(replace(spec, srgb=(int(round(rr)), int(round(g)), int(round(b)))))
    return MarkerKit(f"{kit.name}-observed", tuple(markers))


def _render(light: Any, seed: int, scale: float):
    """One photo under ``light`` with random pin and bend angles, yaw and place."""
    from cvmeasure_datasets import Pose, render_bender_photo

    rng = np.random.default_rng(seed)
    pin = float(rng.uniform(-120.0, 120.0))
    return render_bender_photo(
        pin_angle_deg=pin,
        bend_angle_deg=float(np.clip(pin * rng.uniform(0.8, 0.95), -110, 110)),
        lighting=light,
        pose=Pose(
            yaw_deg=float(rng.uniform(-180.0, 180.0)),
            distance_mm=float(rng.uniform(800.0, 900.0)),
            offset_mm=(float(rng.uniform(-30, 10)), float(rng.uniform(-20, 20))),
        ),
        seed=seed,
        scale=scale,
    )


def with_lens(result: Any, camera: Any) -> Any:
    """Angles of a result's marker centres after removing lens distortion (``camera``)."""
    from cvmeasure.markers import machine_angles

    centres = {
        role: camera.undistort_px(np.array([[m.x_px, m.y_px]]))[0]
        for role, m in result.markers.items()
    }
    return machine_angles(centres)


def _errors(res: Any, truth: dict[str, Any]) -> list[float]:
    """|measured - true| of the pin and bend angles, deg (wrapped)."""
    out = []
    for key in ("pin_angle_deg", "bend_angle_deg"):
        err = (float(getattr(res, key)) - float(truth[key]) + 180.0) % 360.0 - 180.0
        out.append(abs(err))
    return out


def _stats(values: list[float]) -> tuple[float | None, float | None, float | None]:
    if not values:
        return None, None, None
    v = np.asarray(values)
    return float(np.median(v)), float(np.percentile(v, 95)), float(np.max(v))


def _plot(records: list[dict[str, Any]], path) -> str:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = ["ours", *VARIANTS, LENS_VARIANT]
    colours = {"ours": "C2", "seed": "C3", "seed-ref": "C1", "seed-self": "C0", LENS_VARIANT: "C4"}
    fig, ax = plt.subplots(figsize=(8, 4.6), dpi=110)
    rng = np.random.default_rng(0)
    labelled: set[str] = set()
    for k, cct in enumerate(CCTS_K):
        for j, m in enumerate(methods):
            errs = [e for r in records if r["cct_k"] == cct and r[m] is not None for e in r[m]]
            missed = sum(1 for r in records if r["cct_k"] == cct and r[m] is None)
            x = k + (j - 2) * 0.17
            if errs:
                ax.scatter(
                    x + rng.uniform(-0.05, 0.05, len(errs)),
                    np.maximum(errs, 1e-5),
                    s=9,
                    color=colours[m],
                    alpha=0.7,
                    label=None if m in labelled else m,
                )
                labelled.add(m)
            if missed:
                ax.annotate(
                    f"{missed}\nmissed",
                    (x, 3e-5),
                    ha="center",
                    fontsize=6,
                    color=colours[m],
                )
    ax.set_yscale("log")
    ax.set_ylim(2e-5, 30)
    ax.set_xticks(range(len(CCTS_K)), [f"{c:.0f} K" for c in CCTS_K])
    ax.set_xlabel("light (camera white balance off by up to +-600 K)")
    ax.set_ylabel("|angle error|, deg (pin and bend)")
    ax.set_title("Marker angle errors: ours vs the seed method, same photos")
    ax.grid(True, axis="y", which="both", alpha=0.3)
    ax.legend(fontsize=7, loc="upper right", ncol=5)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return str(path)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.accuracy_vs_seed", description=__doc__)
    p.add_argument("--quick", action="store_true", help="2 photos per light at half size (~40 s)")
    p.add_argument("--n", type=int, help="photos per light (default 6, quick 2)")
    p.add_argument("--scale", type=float, help="render scale (default 1 = 4608x3072, quick 0.5)")
    p.add_argument("--seed", type=int, default=1200, help="first render seed (default 1200)")
    args = p.parse_args(argv)

    import cv2

    from cvmeasure.errors import InputError
    from cvmeasure.kit import default_kit
    from cvmeasure.markers import measure_machine_photo
    from cvmeasure.markers.colour import estimate_white
    from cvmeasure_datasets import Lighting

    cv2.setNumThreads(1)
    n = args.n or (2 if args.quick else 6)
    scale = args.scale or (0.5 if args.quick else 1.0)
    from benchmarks._calibrated import calibrated_camera

    kit = default_kit()
    camera, calibration = calibrated_camera(scale)  # as a user has it: from photos
    records: list[dict[str, Any]] = []
    t_start = time.perf_counter()
    for k, cct in enumerate(CCTS_K):
        for i in range(n):
            seed = args.seed + 100 * k + i
            light = replace(Lighting.random(seed), cct_k=cct)
            photo = _render(light, seed, scale)
            # the reference: another scene under the same light and camera settings
            ref = _render(light, seed + 50, REFERENCE_SCALE)
            img = cv2.imdecode(np.frombuffer(photo.jpeg_bytes, np.uint8), cv2.IMREAD_COLOR)
            kits = {
                "seed": kit,
                "seed-ref": observed_kit(ref.bgr, ref.truth, kit),
                "seed-self": observed_kit(img, photo.truth, kit),
            }
            rec: dict[str, Any] = {
                "cct_k": cct,
                "camera_wb_k": light.camera_wb_cct_k,
                "render_seed": seed,
            }
            try:
                rec["ours"] = _errors(measure_machine_photo(img, kit, camera=camera), photo.truth)
            except InputError as exc:
                rec["ours"] = None
                rec["ours_miss"] = str(exc)
                rec["white_clipped_fraction"] = estimate_white(img).clipped_fraction
            for name, variant_kit in kits.items():
                try:
                    res = measure_machine_photo(img, variant_kit, method="seed_hough")
                except InputError:
                    rec[name] = None
                    continue
                rec[name] = _errors(res, photo.truth)
                if name == "seed-self":
                    # the oracle's Hough centres with our lens model: what is left is Hough's
                    rec[LENS_VARIANT] = _errors(with_lens(res, camera), photo.truth)
            rec.setdefault(LENS_VARIANT, None)
            records.append(rec)
            shown = {
                m: "missed" if rec[m] is None else f"{max(rec[m]):.4f}" for m in ["ours", *VARIANTS]
            }
            print(f"{cct:.0f} K photo {i + 1}/{n}: max |err| deg {shown}", flush=True)

    methods = ["ours", *VARIANTS, LENS_VARIANT]
    summary_rows = []
    for m in methods:
        errs = [e for r in records if r[m] is not None for e in r[m]]
        med, p95, mx = _stats(errs)
        summary_rows.append([m, sum(r[m] is not None for r in records), len(records), med, p95, mx])
    per_light_rows = []
    for cct in CCTS_K:
        rows = [r for r in records if r["cct_k"] == cct]
        row: list[Any] = [f"{cct:.0f}"]
        for m in methods:
            errs = [e for r in rows if r[m] is not None for e in r[m]]
            _, p95, mx = _stats(errs)
            row += [f"{sum(r[m] is None for r in rows)}/{len(rows)}", p95, mx]
        per_light_rows.append(row)

    ours_all = [e for r in records if r["ours"] is not None for e in r["ours"]]
    _, ours_p95, _ = _stats(ours_all)
    metrics = [
        Metric("p95 angle error, ours (all lights)", ours_p95, "deg"),
        Metric("photos ours missed", sum(r["ours"] is None for r in records), f"of {len(records)}"),
    ]
    ratio_rows = []
    for m, what in VARIANTS.items():
        both = [r for r in records if r["ours"] is not None and r[m] is not None]
        _, p95_seed, _ = _stats([e for r in both for e in r[m]])
        _, p95_ours, _ = _stats([e for r in both for e in r["ours"]])
        ratio = p95_seed / p95_ours if both and p95_ours else None
        missed = sum(r[m] is None for r in records)
        ratio_rows.append([m, what, len(both), p95_ours, p95_seed, ratio, missed])
        metrics.append(Metric(f"photos the seed method missed, {m}", missed, f"of {len(records)}"))
        metrics.append(
            Metric(
                f"p95 ratio {m} / ours, photos both measured",
                ratio,
                "x",
                target=f">= {RATIO_TARGET:g}",
                met=None if ratio is None else ratio >= RATIO_TARGET,
            )
        )
    lens_errs = [e for r in records if r[LENS_VARIANT] is not None for e in r[LENS_VARIANT]]
    metrics.append(
        Metric(
            "p95 angle error, seed-self with our lens model (informative)",
            _stats(lens_errs)[1],
            "deg",
        )
    )
    plot = _plot(records, RESULTS_DIR / "accuracy_vs_seed.png")
    size = f"{round(4608 * scale)}x{round(3072 * scale)}"
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[
            Table(
                "seed / ours p95 on the photos both measured",
                [
                    "variant",
                    "seed boxes",
                    "photos",
                    "ours p95 deg",
                    "seed p95 deg",
                    "ratio",
                    "missed",
                ],
                ratio_rows,
            ),
            Table(
                "all photos (pin and bend pooled; errors of the photos each method measured)",
                ["method", "photos measured", "photos", "median deg", "p95 deg", "max deg"],
                summary_rows,
            ),
            Table(
                "per light: misses, p95 and max |error| (deg)",
                ["light K"] + [f"{m} {c}" for m in methods for c in ("missed", "p95", "max")],
                per_light_rows,
            ),
        ],
        plots=[plot],
        notes=[
            f"{n} photos per light at {size} (render scale {scale:g}) by "
            "cvmeasure_datasets.render_bender_photo: Lighting.random (camera white balance off by up to "
            "+-600 K, exposure 0.7-1.15, vignetting, shot+read noise, blur 0.5-1 px, JPEG "
            "80-96) with the light's colour temperature set; random pin/bend angles, yaw, "
            f"800-900 mm, camera square to the plate; the seed camera's lens (seeds from {args.seed}).",
            "ours: measure_machine_photo with the camera model calibrated from "
            f"{calibration['views']} rendered ChArUco photos (benchmarks/_calibrated.py; focal "
            f"length {calibration['focal_error_pct']:+.4f} % off the renderer's lens), lens "
            "distortion removed. "
            "seed: the paper's method (cvmeasure.markers.seed_baseline: the paper's LAB box "
            "widths, medianBlur(7), HoughCircles, first circle, arctan2 on raw pixel centres, "
            "no lens model).",
            "seed-ref: the boxes centred on each marker's colour as a reference photo shows it "
            "(another scene under the same light, white balance and exposure, rendered at "
            f"scale {REFERENCE_SCALE:g}; median of each disc, read at its true centre), as a "
            "user would tune the thresholds once per light and camera setting (not "
            "cvmeasure.markers.learn.learn_kit: it learns white-balanced colours for our "
            "pipeline, while the seed method thresholds the photo as it is). seed-self: "
            "centred on the photo's own colours (an oracle), so only the method's geometry "
            "(Hough centres, no lens model) is compared.",
            f"{LENS_VARIANT}: the seed-self Hough centres with lens distortion removed by the "
            "camera model before arctan2 (informative): its difference from seed-self is what "
            "the missing lens model costs (small here: the markers sit near the image centre, "
            "where the barrel distortion moves points by tenths of a pixel); the rest is the "
            "Hough centres' own error.",
            "The p95 ratio is computed on the photos where both methods found all five markers; "
            "photos a method missed are counted, not scored.",
            *[
                f"ours missed the photo at {r['cct_k']:.0f} K with the camera's white balance at "
                f"{r['camera_wb_k']:.0f} K (seed {r['render_seed']}; "
                f"{100 * r['white_clipped_fraction']:.0f} % of the brightest pixels, the white "
                f"the colour model adapts to, are clipped): {r['ours_miss']}"
                for r in records
                if r["ours"] is None
            ],
            f"total run {time.perf_counter() - t_start:.0f} s",
        ],
        extra={"records": records},
    )


if __name__ == "__main__":
    main()
