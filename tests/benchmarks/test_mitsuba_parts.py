"""The Mitsuba part benchmark's bookkeeping: the truth is the rendered arc, the score is fair."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

mi = pytest.importorskip("mitsuba", reason="mitsuba not installed (pip install cvmeasure[heldout])")

from benchmarks.heldout.mitsuba_scenes import (  # noqa: E402
    PartScene,
    _lifted,
    part_axis_mm,
    part_truth,
    render_part,
)
from benchmarks.mitsuba_parts import part_rig, score  # noqa: E402
from cvmeasure.part.compare import point_to_polyline  # noqa: E402


def _board_png(tmp_path: Path) -> Path:
    cli = str(Path(sys.executable).with_name("cvmeasure"))
    out = tmp_path / "board.png"
    subprocess.run([cli, "targets", "charuco", "-o", str(out)], capture_output=True, check=True)
    return out


def _fit_circle(xy: np.ndarray) -> tuple[np.ndarray, float]:
    a = np.column_stack([2 * xy, np.ones(len(xy))])
    sol, *_ = np.linalg.lstsq(a, (xy**2).sum(axis=1), rcond=None)
    centre = sol[:2]
    return centre, float(math.sqrt(sol[2] + centre @ centre))


def test_rendered_arc_has_the_truth_radius_and_chords(tmp_path: Path) -> None:
    rig = part_rig(480, 320)
    scene = PartScene(
        radius_mm=60.0,
        arc_angle_deg=120.0,
        wire_diameter_mm=3.0,
        yaw_deg=0.0,
        rig=rig,
        spp=4,
        chords=8,
        sheet_rgb=(0.02, 0.02, 0.02),
    )
    truth = part_truth(scene)
    assert truth["segment_bend_deg"] == pytest.approx(15.0)
    assert truth["chord_mm"] == pytest.approx(2 * 60.0 * math.sin(math.radians(7.5)))
    jpg, truth2 = render_part(scene, _board_png(tmp_path), tmp_path)
    assert truth2 == truth
    # bright steel on the black card: back-project its pixels to the wire's axis plane
    img = cv2.imread(str(jpg), cv2.IMREAD_GRAYSCALE).astype(float)
    k = rig.matrix()
    rot, t = rig.world_to_camera()
    ys, xs = np.nonzero(img > 80)
    rays = rot.T @ np.linalg.inv(k) @ np.vstack([xs, ys, np.ones_like(xs)])
    eye = -rot.T @ t
    z = 0.05 + scene.wire_diameter_mm / 2.0
    s = (z - eye[2]) / rays[2]
    world = eye[:2, None] + s * rays[:2]
    on_matte = (world[0] > 60.0) & (world[0] < 235.0) & (np.abs(world[1]) < 90.0)
    assert on_matte.sum() > 50
    centre, radius = _fit_circle(world[:, on_matte].T)
    # the arc's midpoint sits over the matte's centre, its centre R - sagitta / 2 behind it
    back = 60.0 - truth["height_mm"] / 2.0
    assert centre == pytest.approx([140.0 - back, 0.0], abs=1.0)
    # pixels of 0.8 mm along chords inside the circle: the fit is within 1.5 %, not the truth
    assert radius == pytest.approx(60.0, rel=0.015)
    # and the axis the benchmark scores against is the one drawn: every steel pixel on the
    # matte lies within the wire's radius (and a pixel, 0.8 mm) of it
    _, gap, _ = point_to_polyline(world[:, on_matte].T, part_axis_mm(scene)[:, :2])
    assert np.abs(gap).max() < scene.wire_diameter_mm / 2.0 + 0.8


def test_score_counts_refusals_warnings_and_silent_misses() -> None:
    truth = {"radius_mm": 50.0, "segment_bend_deg": 10.0}
    good = {"radius_mm": 50.1, "segment_bend_deg": 10.02, "divisions": 9, "warnings": []}
    assert score(truth, 0, good)["verdict"] == "ok"
    assert score(truth, 2, {})["verdict"] == "refused"
    off = {"radius_mm": 50.5, "segment_bend_deg": 10.0, "divisions": 9}
    gap = [{"code": "part_centreline_gap", "message": "..."}]
    # a centreline gap covers the bends, not the radius: 1 % off under it is silent
    assert score(truth, 0, {**off, "warnings": gap})["verdict"] == "silent"
    inconsistent = [{"code": "part_arc_inconsistent", "message": "..."}]
    assert score(truth, 0, {**off, "warnings": inconsistent})["verdict"] == "warned"
    bent = {"radius_mm": 50.0, "segment_bend_deg": 10.2, "divisions": 9}
    assert score(truth, 0, {**bent, "warnings": gap})["verdict"] == "warned"
    assert score(truth, 0, {**bent, "warnings": []})["verdict"] == "silent"
    # part_lifted covers a miss only as far as the effect it states on that quantity
    lifted = [{"code": "part_lifted", "message": "..."}]
    small = {"effect_radius_pct": 0.4, "effect_segment_bend_deg": 0.05}
    assert score(truth, 0, {**off, "warnings": lifted, "lift": small})["verdict"] == "silent"
    large = {"effect_radius_pct": 1.5, "effect_segment_bend_deg": 0.05}
    assert score(truth, 0, {**off, "warnings": lifted, "lift": large})["verdict"] == "warned"
    assert score(truth, 0, {**bent, "warnings": lifted, "lift": large})["verdict"] == "silent"
    assert score(truth, 0, {**bent, "warnings": lifted})["verdict"] == "silent"
    # the radius error in the circle's stated sigmas (None without one)
    circled = {**off, "warnings": [], "circle": {"radius_sigma_mm": 0.25}}
    assert score(truth, 0, circled)["radius_z"] == pytest.approx(2.0)
    assert score(truth, 0, {**off, "warnings": []})["radius_z"] is None
    # and in the part's stated sigmas (radius_sigma_mm, segment_bend_sigma_deg)
    stated = {**bent, "warnings": [], "radius_sigma_mm": 0.5, "segment_bend_sigma_deg": 0.1}
    got = score(truth, 0, stated)
    assert got["radius_z_stated"] == pytest.approx((bent["radius_mm"] - truth["radius_mm"]) / 0.5)
    assert got["bend_z_stated"] == pytest.approx(got["bend_err_deg"] / 0.1)
    assert got["radius_sigma_pct"] == pytest.approx(100.0 * 0.5 / bent["radius_mm"])
    assert score(truth, 0, {**bent, "warnings": []})["bend_z_stated"] is None


def test_a_lifted_part_is_the_flat_one_tilted_rigidly() -> None:
    ang = np.radians(np.linspace(-50.0, 50.0, 9))
    flat = np.column_stack([70.0 * np.cos(ang), 70.0 * np.sin(ang)])
    up = _lifted(flat, 2.5)
    assert up[0] == pytest.approx([*flat[0], 0.0])
    assert up[-1, 2] == pytest.approx(2.5)
    # every distance of the part is kept: the 3D shape (radius, bends) is the truth's
    d_flat = np.linalg.norm(flat[:, None] - flat[None], axis=-1)
    flat3 = np.column_stack([flat, np.zeros(len(flat))])
    d_up = np.linalg.norm(up[:, None] - up[None], axis=-1)
    assert d_up == pytest.approx(np.linalg.norm(flat3[:, None] - flat3[None], axis=-1), abs=1e-9)
    assert d_flat.max() > 100.0
