"""Finished part: our fit against the seed paper's ellipse and sagitta methods.

Renders the seed's half circle (R 100 mm, 20 chords of 9 degrees) on a light
sheet, measures it, and draws the wire outline with what each method sees:
the seed's fitted ellipse, its minimum enclosing circle and the end points
where they meet, the rotated bounding box, and our chord vertices with the
circle through them. Prints the radius and the bend per chord of each method.

Run: ``python docs/examples/plot_part_methods.py [out.png]`` (about 10 s).
"""

from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import PartOptions

board = CharucoBoardSpec(14, 10, 20.0, 15.0)
photo = cvmeasure_datasets.render_part_photo(
    part=cvmeasure_datasets.arc_part(100.0, 180.0, 20),
    board=board,
    sheet="light",
    seed=7,
    scale=0.5,
)
m = measure_part(photo.bgr, board, photo.camera, options=PartOptions(divisions=20))
print(f"{'method':<8} {'radius_mm':>10} {'bend/chord_deg':>15}   (truth 100 mm, 9 deg)")
for name, res in m.methods.items():
    print(f"{name:<8} {res.radius_mm:10.3f} {res.segment_bend_deg:15.4f}")

fig, ax = plt.subplots(figsize=(7, 5))
c = m.centreline_mm
ax.plot(c[:, 0], c[:, 1], color="0.3", lw=3, alpha=0.4, label="centreline")
v = m.vertices_mm
ax.plot(v[:, 0], v[:, 1], "o-", color="tab:red", ms=3, lw=1, label="ours: chord vertices")
t = np.linspace(0, 2 * np.pi, 720)
cx, cy = m.circle.centre_mm
ax.plot(
    cx + m.circle.radius_mm * np.cos(t),
    cy + m.circle.radius_mm * np.sin(t),
    color="tab:red",
    lw=0.8,
)
ell = m.seed_arcs.get("seed_ellipse")
if ell is not None and ell.ellipse is not None:
    (ex, ey), (a, b), ang = (
        ell.ellipse.centre_mm,
        ell.ellipse.semi_axes_mm,
        np.radians(ell.ellipse.angle_deg),
    )
    ax.plot(
        ex + a * np.cos(t) * np.cos(ang) - b * np.sin(t) * np.sin(ang),
        ey + a * np.cos(t) * np.sin(ang) + b * np.sin(t) * np.cos(ang),
        color="tab:green",
        lw=0.8,
        label="seed: ellipse through the hull",
    )
    ax.plot(*ell.end_points_mm.T, "s", color="tab:green", label="seed: circle x ellipse ends")
ax.set_aspect("equal")
ax.invert_yaxis()  # board frame: y down as in the photo
ax.set_xlabel("board x (mm)")
ax.set_ylabel("board y (mm)")
ax.legend(loc="lower right", fontsize=8)
ax.set_title("half circle R 100 mm, 20 chords: ours vs the seed's ellipse")
fig.tight_layout()
out = sys.argv[1] if len(sys.argv) > 1 else "part_methods.png"
fig.savefig(out, dpi=110)
print(f"wrote {out}")
