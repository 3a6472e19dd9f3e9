"""A picture for the person: the found markers, the machine frame and the angles on the photo."""

from __future__ import annotations

import math

import cv2
import numpy as np

from cvmeasure.imageio import to_bgr8
from cvmeasure.kit import MarkerKit
from cvmeasure.markers.measure import MachinePhotoResult

__all__ = ["draw_overlay", "OVERLAY_MAX_WIDTH_PX"]

#: Overlays wider than this are drawn on a reduced copy of the photo.
OVERLAY_MAX_WIDTH_PX = 2400


def draw_overlay(
    bgr: np.ndarray,
    result: MachinePhotoResult,
    kit: MarkerKit,
    *,
    max_width_px: int = OVERLAY_MAX_WIDTH_PX,
) -> np.ndarray:
    """Draw the markers, the machine frame (+x, +y) and the angles on a copy of the photo.

    Parameters
    ----------
    bgr : ndarray (H, W, 3), the photo the result was measured on.
    result : its measurement.
    kit : the kit (marker colours for the circles, names for the labels).
    max_width_px : larger photos are drawn on a reduced copy.

    Returns
    -------
    ndarray (h, w, 3), uint8 BGR.
    """
    img = to_bgr8(np.asarray(bgr))
    f = min(1.0, max_width_px / img.shape[1])
    out = cv2.resize(img, None, fx=f, fy=f, interpolation=cv2.INTER_AREA) if f < 1 else img.copy()
    thick = max(1, round(out.shape[1] / 800))
    font = 0.4 + out.shape[1] / 2400

    def pt(x: float, y: float) -> tuple[int, int]:
        return (round((x + 0.5) * f - 0.5), round((y + 0.5) * f - 0.5))

    m = result.markers
    o = np.array([m["origin"].x_px, m["origin"].y_px])
    a = np.array([m["axis"].x_px, m["axis"].y_px])
    ex = (o - a) / max(1e-9, float(np.linalg.norm(o - a)))
    ey = np.array([ex[1], -ex[0]])  # +x turned 90 deg counter-clockwise as seen (image y down)
    length = 0.6 * float(np.linalg.norm(o - a))
    cv2.arrowedLine(out, pt(*o), pt(*(o + ex * length)), (0, 0, 255), thick, cv2.LINE_AA, 0, 0.05)
    cv2.arrowedLine(out, pt(*o), pt(*(o + ey * length)), (0, 200, 0), thick, cv2.LINE_AA, 0, 0.05)
    cv2.putText(out, "+x", pt(*(o + ex * length * 1.05)), 0, font, (0, 0, 255), thick, cv2.LINE_AA)
    cv2.putText(out, "+y", pt(*(o + ey * length * 1.05)), 0, font, (0, 200, 0), thick, cv2.LINE_AA)
    for p, q in (("origin", "pin"), ("wire_a", "wire_b")):
        cv2.line(
            out,
            pt(m[p].x_px, m[p].y_px),
            pt(m[q].x_px, m[q].y_px),
            (255, 255, 0),
            thick,
            cv2.LINE_AA,
        )
    for role, mm in m.items():
        r, g, b = kit.by_role(role).srgb
        c = pt(mm.x_px, mm.y_px)
        cv2.circle(out, c, max(2, round(mm.r_px * f)), (0, 0, 0), thick + 2, cv2.LINE_AA)
        cv2.circle(out, c, max(2, round(mm.r_px * f)), (b, g, r), thick, cv2.LINE_AA)
        cv2.drawMarker(out, c, (0, 0, 0), cv2.MARKER_CROSS, max(6, round(mm.r_px * f * 0.5)), thick)
        label = f"{role}"
        off = round(mm.r_px * f * 1.6)
        cv2.putText(
            out, label, (c[0] + off, c[1] - off), 0, font, (0, 0, 0), thick + 2, cv2.LINE_AA
        )
        cv2.putText(
            out, label, (c[0] + off, c[1] - off), 0, font, (255, 255, 255), thick, cv2.LINE_AA
        )
    u = result.uncertainty_deg
    lines = [
        f"pin  {result.pin_angle_deg:+.3f} deg (+-{u['pin_angle_deg']:.3f})",
        f"bend {result.bend_angle_deg:+.3f} deg (+-{u['bend_angle_deg']:.3f})",
        f"method {result.method}/{result.space}, frame {result.frame}",
    ] + [f"! {w}" for w in result.warnings]
    step = math.ceil(30 * font)
    for i, text in enumerate(lines):
        y = step * (i + 1)
        cv2.putText(out, text, (10, y), 0, font, (0, 0, 0), thick + 2, cv2.LINE_AA)
        cv2.putText(out, text, (10, y), 0, font, (255, 255, 255), thick, cv2.LINE_AA)
    return out
