"""Demo step "bender photos": a rendered loaded/unloaded pair -> pin, bend and springback."""

from __future__ import annotations

import json
from pathlib import Path

from cvmeasure_datasets.demo.report import DemoRow, DemoSection

__all__ = ["demo_step"]

#: Render scale of the demo photos (4608 px * 0.35 = 1613 px wide).
DEMO_SCALE = 0.35
#: Tolerances (deg) of the demo rows at that scale.
PIN_TOL_DEG = 0.1
BEND_TOL_DEG = 0.05


def demo_step(out_dir: Path, *, seed: int) -> DemoSection:
    """Render a loaded and an unloaded photo of one bend, measure both, compare with the truth."""
    import cv2

    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_bytes, atomic_write_text
    from cvmeasure.kit import default_kit
    from cvmeasure.markers.angles import springback_deg
    from cvmeasure.markers.measure import measure_machine_photo, measure_trial
    from cvmeasure.markers.overlay import draw_overlay
    from cvmeasure_datasets.bender import render_bender_photo
    from cvmeasure_datasets.lighting import Lighting
    from cvmeasure_datasets.optics import Pose

    folder = Path(out_dir) / "markers"
    folder.mkdir(parents=True, exist_ok=True)
    kit = default_kit()
    pose = Pose(yaw_deg=12.0)
    photos = {
        "loaded": render_bender_photo(
            pin_angle_deg=52.0,
            bend_angle_deg=45.0,
            kit=kit,
            pose=pose,
            lighting=Lighting(cct_k=3000.0, wb_error_k=400.0),
            seed=seed,
            scale=DEMO_SCALE,
        ),
        "unloaded": render_bender_photo(
            pin_angle_deg=20.0,
            bend_angle_deg=41.2,
            kit=kit,
            pose=pose,
            lighting=Lighting(cct_k=3000.0, wb_error_k=400.0),
            seed=seed + 1,
            scale=DEMO_SCALE,
        ),
    }
    section = DemoSection("bender photos")
    results = {}
    for key, photo in photos.items():
        path, truth_path = photo.save(folder / key)
        section.files += [str(path), str(truth_path)]
        res = measure_machine_photo(photo.bgr, kit, camera=photo.camera, photo=str(path))
        results[key] = res
        ok, buf = cv2.imencode(".png", draw_overlay(photo.bgr, res, kit))
        if ok:
            section.files.append(
                str(atomic_write_bytes(folder / f"{key}.overlay.png", buf.tobytes()))
            )
    truth = {k: p.truth for k, p in photos.items()}
    section.rows += [
        DemoRow(
            "pin angle, loaded",
            results["loaded"].pin_angle_deg,
            truth["loaded"]["pin_angle_deg"],
            "deg",
            PIN_TOL_DEG,
        ),
        DemoRow(
            "bend angle, loaded",
            results["loaded"].bend_angle_deg,
            truth["loaded"]["bend_angle_deg"],
            "deg",
            BEND_TOL_DEG,
        ),
        DemoRow(
            "bend angle, unloaded",
            results["unloaded"].bend_angle_deg,
            truth["unloaded"]["bend_angle_deg"],
            "deg",
            BEND_TOL_DEG,
        ),
    ]
    trial = measure_trial(results["loaded"], results["unloaded"], trial=1)
    true_sb = springback_deg(truth["loaded"]["bend_angle_deg"], truth["unloaded"]["bend_angle_deg"])
    section.rows.append(
        DemoRow("springback", trial.springback_deg, true_sb, "deg", 2 * BEND_TOL_DEG)
    )
    lines = [json.dumps(r.to_dict()) for r in results.values()] + [json.dumps(trial.to_dict())]
    section.files.append(str(atomic_write_text(folder / "measure.jsonl", "\n".join(lines) + "\n")))
    u = trial.springback_sigma_deg
    section.notes.append(
        f"{photos['loaded'].bgr.shape[1]}x{photos['loaded'].bgr.shape[0]} px renders, 3000 K light, "
        f"camera white balance 400 K off; stated springback uncertainty {u:.4f} deg"
    )
    seed_notes = []
    for key, photo in photos.items():
        try:
            s = measure_machine_photo(photo.bgr, kit, method="seed_hough")
            seed_notes.append(
                f"{key}: bend error {s.bend_angle_deg - truth[key]['bend_angle_deg']:+.3f} deg"
            )
        except InputError as exc:
            seed_notes.append(f"{key}: failed ({exc.problem})")
    section.notes.append("seed paper's method on the same photos: " + "; ".join(seed_notes))
    return section
