"""Demo step: the seed paper's half circle (R 100 mm, 20 chords of 9 degrees) against its design."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cvmeasure_datasets.demo.report import DemoRow, DemoSection

__all__ = ["demo_step", "HALF_CIRCLE_SVG"]

#: The design: a half circle of radius 100 mm (SVG, mm user units).
HALF_CIRCLE_SVG = (
    '<svg xmlns="http://www.w3.org/2000/svg" width="240mm" height="140mm" viewBox="0 0 240 140">'
    '<path id="half-circle" d="M 20 120 A 100 100 0 0 1 220 120" fill="none" stroke="black"/>'
    "</svg>\n"
)


def demo_step(out_dir: Path, *, seed: int) -> DemoSection:
    """Render the half circle at half size, measure it, compare with its design."""
    import cv2

    import cvmeasure_datasets
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.design import load_design
    from cvmeasure.fileio import atomic_write_bytes, atomic_write_json, atomic_write_text
    from cvmeasure.part.measure import measure_part
    from cvmeasure.part.options import PartOptions
    from cvmeasure.part.overlay import deviation_plot_png, draw_overlay

    out = Path(out_dir) / "part"
    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    design_path = atomic_write_text(out / "half-circle.svg", HALF_CIRCLE_SVG)
    design = load_design(design_path).wire()
    photo = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.arc_part(100.0, 180.0, 20),
        board=board,
        sheet="light",
        seed=seed,
        scale=0.5,
    )
    m = measure_part(
        photo.bgr,
        board,
        photo.camera,
        options=PartOptions(divisions=20),
        design=design,
        design_source=str(design_path),
        source="half-circle (rendered)",
    )
    truth = photo.truth
    files = [str(atomic_write_json(out / "half-circle.json", m.to_dict()))]
    ok, png = cv2.imencode(".png", draw_overlay(photo.bgr, m))
    if ok:
        files.append(str(atomic_write_bytes(out / "half-circle-overlay.png", png.tobytes())))
    files.append(str(atomic_write_bytes(out / "half-circle-deviation.png", deviation_plot_png(m))))
    cmp = m.comparison
    rows = [
        DemoRow("radius (ours)", m.result.radius_mm, truth["radius_mm"], "mm", 0.003 * 100.0),
        DemoRow("arc angle (ours)", m.result.arc_angle_deg, truth["arc_angle_deg"], "deg", 0.6),
        DemoRow("bend per chord, arc/20 (ours)", m.result.segment_bend_deg, 9.0, "deg", 0.03),
        DemoRow(
            "worst vertex bend error vs design",
            float(np.max(np.abs(cmp.bends.error_deg))) if cmp and cmp.bends else float("nan"),
            0.0,
            "deg",
            0.1,
        ),
        DemoRow(
            "deviation from design, RMS",
            cmp.deviation.rms_mm if cmp else float("nan"),
            0.0,
            "mm",
            0.1,
        ),
        DemoRow(
            "seed absolute error (design - measured)",
            cmp.bends.seed_absolute_error_deg if cmp and cmp.bends else float("nan"),
            0.0,
            "deg",
            0.03,
        ),
    ]
    for name in ("seed_ellipse", "seed_sagitta"):
        if name in m.methods:
            rows.append(DemoRow(f"radius ({name} method)", m.methods[name].radius_mm, 100.0, "mm"))
    return DemoSection(
        title="finished part: the seed's half circle vs its design",
        rows=rows,
        files=files,
        notes=[
            "R 100 mm half circle bent in 20 chords (9 deg each), light sheet, 2304x1536 px",
            "the seed's methods run on the wire's outline, as in the paper (no tolerance: for comparison)",
        ],
    )
