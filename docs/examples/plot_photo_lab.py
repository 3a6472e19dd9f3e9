"""The photo lab in one picture: a bender photo, a finished part and a calibration view.

Each photo is drawn with its ground truth on top (marker centres, the wire's
centreline, the board's inner corners), so what "exact truth" means is visible.

Run: ``python docs/examples/plot_photo_lab.py [-o photo_lab.png]``
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import cvmeasure_datasets  # noqa: E402
from cvmeasure.board import CharucoBoardSpec  # noqa: E402
from cvmeasure_datasets.optics import project_frame_points  # noqa: E402


def main(argv: list[str] | None = None) -> Path:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("-o", "--out", type=Path, default=Path("photo_lab.png"))
    p.add_argument("--seed", type=int, default=7)
    args = p.parse_args(argv)

    pose = cvmeasure_datasets.Pose(
        tilt_deg=15.0, tilt_direction_deg=230.0, yaw_deg=10.0, distance_mm=600.0
    )
    bender = cvmeasure_datasets.render_bender_photo(
        pin_angle_deg=-110.0,
        bend_angle_deg=55.0,
        pose=pose,
        lighting=cvmeasure_datasets.Lighting.random(args.seed),
        seed=args.seed,
        scale=0.25,
    )
    part = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.saddle_part(200.0, 20.0, 13),
        sheet="dark",
        seed=args.seed,
        scale=0.25,
    )
    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    view = cvmeasure_datasets.render_board_view(
        board=board,
        pose=cvmeasure_datasets.random_board_poses(3, args.seed)[2],
        seed=args.seed,
        scale=0.25,
    )

    fig, axes = plt.subplots(1, 3, figsize=(18, 4.4))
    for ax, photo, title in zip(
        axes,
        (bender, part, view),
        ("bender: marker centres", "part: wire centreline", "board: inner corners"),
        strict=True,
    ):
        ax.imshow(photo.bgr[..., ::-1])
        ax.set_title(title)
        ax.set_axis_off()
    for role, m in bender.truth["markers"].items():
        axes[0].plot(*m["centre_px"], "+", color="k", ms=8)
        axes[0].annotate(
            role, m["centre_px"], xytext=(6, -6), textcoords="offset points", fontsize=7
        )
    axes[0].text(
        5, 20, f"bend {bender.truth['bend_angle_deg']:.1f} deg, pin {bender.truth['pin_angle_deg']:.1f} deg",
        color="w", fontsize=8,
    )  # fmt: skip
    rot = np.asarray(part.truth["pose"]["R_cam_frame"])
    tvec = np.asarray(part.truth["pose"]["tvec_mm"])
    line = project_frame_points(
        part.camera, rot, tvec, np.asarray(part.truth["part"]["centreline_mm"])
    )
    axes[1].plot(line[:, 0], line[:, 1], "r.-", lw=0.8, ms=3)
    corners = np.asarray(view.truth["corners_px"])
    axes[2].plot(corners[:, 0], corners[:, 1], "r+", ms=4)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    plt.close(fig)
    print(f"wrote {args.out}")
    return args.out


if __name__ == "__main__":
    main()
