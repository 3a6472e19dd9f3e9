"""Anti-aliasing of the rasteriser against brute-force supersampling."""

from __future__ import annotations

import numpy as np

from cvmeasure_datasets import Pose, default_camera
from cvmeasure_datasets.optics import project_frame_points
from cvmeasure_datasets.raster import Layer, box_coverage, rasterise, sdf_alpha, sdf_circle


def test_box_coverage_matches_supersampling():
    rng = np.random.default_rng(7)
    n = 400
    ang = rng.uniform(0, 2 * np.pi, n)
    dist = rng.uniform(-1.0, 1.0, n)
    gx, gy = np.cos(ang), np.sin(ang)
    exact = box_coverage(dist, gx, gy)
    # 400 x 400 sub-samples of the unit pixel
    s = (np.arange(400) + 0.5) / 400 - 0.5
    sx, sy = np.meshgrid(s, s)
    brute = np.array(
        [np.mean(d + a * sx + b * sy < 0) for d, a, b in zip(dist, gx, gy, strict=True)]
    )
    assert np.abs(exact - brute).max() < 4e-3


def test_sdf_alpha_is_a_symmetric_ramp_in_pixels():
    x = np.arange(-5, 6, dtype=float)
    sdf = np.tile(x * 0.1, (5, 1))  # 0.1 mm per pixel, edge at x = 0
    alpha = sdf_alpha(sdf)[2]
    assert np.allclose(alpha, np.clip(0.5 - x, 0, 1))


def test_rendered_disc_has_the_projected_area_and_centroid():
    """Total coverage of a disc equals its area in pixels; its centroid is the projected one."""
    cam = default_camera((576, 384))
    rot, t = Pose(distance_mm=400.0).extrinsics("machine")
    centre, radius = (12.0, -7.0), 9.0
    layer = Layer(
        (3.0 - 1, -16.0 - 1, 21.0 + 1, 2.0 + 1),
        lambda w: sdf_alpha(sdf_circle(w.u, w.v, centre, radius)),
        (1.0, 1.0, 1.0),
    )
    img = rasterise([layer], cam, rot, t)[..., 0].astype(np.float64)
    # fronto-parallel at 400 mm: scale f/z px per mm (distortion is tiny this near the centre)
    px = project_frame_points(cam, rot, t, np.array([centre]))[0]
    ys, xs = np.nonzero(img)
    mm_per_px = 400.0 / cam.fx
    area_px = np.pi * (radius / mm_per_px) ** 2
    assert abs(img.sum() / area_px - 1) < 2e-3
    cen = np.array([(img[ys, xs] * xs).sum(), (img[ys, xs] * ys).sum()]) / img.sum()
    assert np.linalg.norm(cen - px) < 0.02
