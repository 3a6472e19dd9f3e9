"""A raised cap's step wall: "shade" edges count it alike on every disc colour.

A cap's coloured top stands on its white ring by a step; the camera sees that step's
wall on the side facing its foot point, just outside the top's edge. The images here
are drawn supersampled: the top (radius r) and, on the -x side only, the wall (the
hull of the top and of the same circle moved ``WALL_PX`` along -x), shaded darker
than the top. Where the wall counts once as disc, the fitted outline is that hull:
its circle's centre lies ``WALL_PX / 2`` towards -x of the top's (the cos component
of ``WALL_PX * max(0, -cos t)``), whatever the disc's colour.
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np
import pytest

from cvmeasure.colorimetry import srgb_encode_floats
from cvmeasure.errors import InputError
from cvmeasure.geometry import fit_circle_robust
from cvmeasure.kit import MarkerKit, default_kit
from cvmeasure.markers import measure_machine_photo
from cvmeasure.markers.circles import edge_mode_cov
from cvmeasure.markers.refine import disc_edge_points

CENTRE = (60.3, 59.6)
R_PX = 18.0
RING_RATIO = 1.5
WALL_PX = 1.0
SUPER = 8
#: linear RGB of two kit colours: the dark green origin and the light orange pin
GREEN = (0.0, 0.155, 0.06)
ORANGE = (0.871, 0.262, 0.0)


def _cap_image(disc_rgb, wall_shade, size=121, ring=0.8):
    """8-bit sRGB BGR image of one cap: white ring, coloured top, its wall ``wall_shade``
    times the top's colour on the -x side, blurred 1 px (a lens) after supersampling."""
    n = size * SUPER
    c = (np.arange(n) + 0.5) / SUPER - 0.5
    x, y = np.meshgrid(c, c)
    dx, dy = x - CENTRE[0], y - CENTRE[1]
    top = dx**2 + dy**2 < R_PX**2
    wall = ((dx + WALL_PX) ** 2 + dy**2 < R_PX**2) & ~top & (dx < 0)
    rim = dx**2 + dy**2 < (RING_RATIO * R_PX) ** 2
    img = np.full((n, n, 3), 0.1)
    img[rim] = ring
    img[top] = disc_rgb
    img[wall] = np.asarray(disc_rgb) * wall_shade
    img = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA)
    img = cv2.GaussianBlur(img, (0, 0), 1.0)
    enc = np.asarray(srgb_encode_floats(img.reshape(-1).tolist())).reshape(img.shape)
    return np.clip(np.round(255 * enc[..., ::-1]), 0, 255).astype(np.uint8)


def _fit(bgr, edge):
    """The disc's circle refitted three times on its ``edge`` points, and those points."""
    centre, r = CENTRE, R_PX
    for _ in range(3):
        pts = disc_edge_points(bgr, centre, r, RING_RATIO, edge=edge).points_px
        fit = fit_circle_robust(pts)
        centre, r = fit.centre, fit.radius
    return fit, pts


def _centre_x(bgr, edge):
    return _fit(bgr, edge)[0].centre[0]


@pytest.mark.parametrize("wall_shade", [0.0, 0.3])
def test_shade_edges_count_a_dark_wall_once_on_every_disc(wall_shade):
    # the hull's centre, WALL_PX / 2 towards the wall, within 0.03 px for both colours
    for disc in (GREEN, ORANGE):
        x = _centre_x(_cap_image(disc, wall_shade), "shade")
        assert abs(x - (CENTRE[0] - WALL_PX / 2)) < 0.03, (disc, x)


def test_luminance_edges_count_a_light_discs_wall_more():
    # in luminance the wall weighs (ring - wall) / (ring - disc): about 1.15 on the dark
    # green disc, about 1.7 on the orange one, so the two centres part by about 0.27 px
    # on a 1 px wall: the pin-to-origin angle error the shade edges remove
    green = _centre_x(_cap_image(GREEN, 0.0), "luma")
    orange = _centre_x(_cap_image(ORANGE, 0.0), "luma")
    assert abs(green - (CENTRE[0] - WALL_PX / 2)) < 0.1, green
    assert orange < green - 0.2, (green, orange)
    shade = [_centre_x(_cap_image(d, 0.0), "shade") for d in (GREEN, ORANGE)]
    assert abs(shade[0] - shade[1]) < 0.04, shade


def test_the_luminance_walls_are_not_stated_as_the_shade_edges_bias():
    # the orange disc's shade circle sits where the wall counts once (0.03 px, above);
    # luminance counts its wall 1.7 times, 0.3 px towards the foot point (-x here). That
    # is luminance's own wall, not a bias of the shade centre: with the foot point given,
    # the edge-mode term leaves it out and states what remains across it (under 0.02 px),
    # where the two readings' half difference would state about 0.2 px
    bgr = _cap_image(ORANGE, 0.0)
    shade, _ = _fit(bgr, "shade")
    _, luma_pts = _fit(bgr, "luma")
    plain = edge_mode_cov(luma_pts, shade)
    walls = edge_mode_cov(luma_pts, shade, wall_towards=np.array([CENTRE[0] - 400.0, CENTRE[1]]))
    assert np.sqrt(plain[0, 0]) > 0.15, plain
    assert np.sqrt(np.trace(walls)) < 0.02, walls
    # a foot point along y: the wall lies across that direction and is taken in full
    across = edge_mode_cov(luma_pts, shade, wall_towards=np.array([CENTRE[0], CENTRE[1] + 400]))
    assert np.sqrt(across[0, 0]) > 0.15, across


def test_a_wall_lit_as_the_top_reads_alike_in_shade_and_luminance():
    # a wall as light as the top is disc in any weighting: the hull, either way
    for disc in (GREEN, ORANGE):
        bgr = _cap_image(disc, 1.0)
        for edge in ("luma", "shade"):
            assert abs(_centre_x(bgr, edge) - (CENTRE[0] - WALL_PX / 2)) < 0.03, (disc, edge)


def test_a_kit_with_stepped_faces_is_measured_in_shade_by_default():
    pytest.importorskip("cvmeasure_datasets.discs3d")
    from cvmeasure_datasets.discs3d import DiscScene, render_discs_at_heights

    from .test_marker_heights import SQUARE, _camera, true_plane

    kit = default_kit()
    stepped = replace(kit, markers=tuple(replace(m, step_mm=0.3) for m in kit.markers))
    assert stepped.has_steps and not kit.has_steps
    assert MarkerKit.from_dict(stepped.to_dict()) == stepped
    bgr, _ = render_discs_at_heights(DiscScene(-60.0, -50.0, pose=SQUARE), camera=_camera(), seed=3)
    plane = true_plane(_camera(), SQUARE)

    def pin(kit, **kw):
        return measure_machine_photo(bgr, kit, plane=plane, **kw).pin_angle_deg

    assert pin(stepped) == pin(stepped, edge="shade")
    assert pin(stepped) != pin(stepped, edge="luma")
    # flush faces (the built-in kit): luminance edges
    assert pin(kit) == pin(kit, edge="luma")


def test_a_negative_step_is_refused():
    data = default_kit().to_dict()
    data["markers"][0]["step_mm"] = -0.1
    with pytest.raises(InputError, match="step_mm"):
        MarkerKit.from_dict(data)
