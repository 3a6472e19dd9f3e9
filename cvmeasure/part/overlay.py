"""Pictures of a part measurement: the photo with the found centreline, and the deviation plot.

Pure functions returning images (ndarray) or PNG bytes; the CLI writes them.

matplotlib is imported only when an overlay is drawn (half a second or more on import).
"""

from __future__ import annotations

import io

import cv2
import numpy as np

from cvmeasure.part.measure import PartMeasurement

__all__ = ["draw_overlay", "deviation_plot_png"]


def draw_overlay(image_bgr8: np.ndarray, measurement: PartMeasurement) -> np.ndarray:
    """The photo with the centreline (red), chord vertices (yellow) and wire ends (green).

    Parameters
    ----------
    image_bgr8 : ndarray (H, W, 3) uint8, the photo.
    measurement : what :func:`~cvmeasure.part.measure.measure_part` returned.
    """
    img = np.ascontiguousarray(image_bgr8.copy())
    h, w = img.shape[:2]
    thick = max(1, round(max(h, w) / 1500))
    shift = 4  # sub-pixel drawing: coordinates in 1/16 px
    pts = np.round(measurement.centreline_px * (1 << shift)).astype(np.int32)
    cv2.polylines(img, [pts.reshape(-1, 1, 2)], False, (0, 0, 255), thick, cv2.LINE_AA, shift)
    r = 4 * thick
    for end in (pts[0], pts[-1]):
        cv2.circle(
            img, tuple(int(v) for v in end), r << shift, (0, 200, 0), thick, cv2.LINE_AA, shift
        )
    if measurement.vertices_px is not None:
        vpx = measurement.vertices_px
        for v in np.round(vpx * (1 << shift)).astype(np.int32):
            cv2.circle(
                img, tuple(int(c) for c in v), r << shift, (0, 220, 255), thick, cv2.LINE_AA, shift
            )
    res = measurement.result
    label = f"{res.method}: R {res.radius_mm:.2f} mm, arc {res.arc_angle_deg:.2f} deg"
    if res.segment_bend_deg is not None:
        label += f", bend/chord {res.segment_bend_deg:.3f} deg"
    scale = max(0.5, max(h, w) / 2000)
    cv2.putText(
        img,
        label,
        (20, int(40 * scale)),
        cv2.FONT_HERSHEY_SIMPLEX,
        scale,
        (0, 0, 0),
        4 * thick,
        cv2.LINE_AA,
    )
    cv2.putText(
        img,
        label,
        (20, int(40 * scale)),
        cv2.FONT_HERSHEY_SIMPLEX,
        scale,
        (255, 255, 255),
        thick,
        cv2.LINE_AA,
    )
    return img


def deviation_plot_png(measurement: PartMeasurement, *, title: str | None = None) -> bytes:
    """PNG of the deviation from the design along the part (needs a comparison)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cmp = measurement.comparison
    if cmp is None:
        raise ValueError("the measurement has no design comparison to plot")
    dev = cmp.deviation
    fig, axes = plt.subplots(
        2 if cmp.bends is not None else 1, 1, figsize=(8, 6 if cmp.bends is not None else 3.5)
    )
    axes = np.atleast_1d(axes)
    ax = axes[0]
    ax.plot(dev.arc_length_mm, dev.distance_mm, lw=1.0, color="tab:red")
    ax.axhline(0.0, color="0.5", lw=0.8)
    ax.set_xlabel("along the part (mm)")
    ax.set_ylabel("deviation from design (mm)")
    ax.set_title(title or f"{measurement.source}: max {dev.max_mm:.3f} mm, RMS {dev.rms_mm:.3f} mm")
    if cmp.bends is not None:
        b = cmp.bends
        k = np.arange(1, len(b.error_deg) + 1)
        axes[1].bar(k, b.error_deg, color="tab:blue")
        axes[1].axhline(0.0, color="0.5", lw=0.8)
        axes[1].set_xlabel("vertex (design order)")
        axes[1].set_ylabel("bend error (deg)")
        axes[1].set_title(
            f"bend per chord: seed absolute {b.seed_absolute_error_deg:.3f} deg, "
            f"relative {b.seed_relative_error_pct:.2f} %"
        )
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    return buf.getvalue()
