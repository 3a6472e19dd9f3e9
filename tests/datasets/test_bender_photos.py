"""Bender photos: truth angles, frame orientation, marker centres against fitted disc edges."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.kit import default_kit
from cvmeasure_datasets import Lighting, Pose, render_bender_photo
from cvmeasure_datasets.bender import bender_wire_polyline
from cvmeasure_datasets.checks import check_disc_centre


@pytest.mark.parametrize(
    ("pin_deg", "bend_deg"), [(-60.0, 35.0), (120.0, -47.5), (0.0, 0.0), (-170.0, 179.0)]
)
def test_truth_angles_follow_the_spec_definitions(pin_deg, bend_deg):
    photo = render_bender_photo(pin_angle_deg=pin_deg, bend_angle_deg=bend_deg, scale=0.0625)
    m = photo.truth["markers"]
    assert photo.truth["pin_angle_deg"] == pytest.approx(pin_deg, abs=1e-9)
    assert photo.truth["bend_angle_deg"] == pytest.approx(bend_deg, abs=1e-9)
    assert (m["origin"]["x_mm"], m["origin"]["y_mm"]) == (0.0, 0.0)
    assert m["axis"]["x_mm"] < -50 and m["axis"]["y_mm"] == 0.0
    a = np.array([m["wire_a"]["x_mm"], m["wire_a"]["y_mm"]])
    b = np.array([m["wire_b"]["x_mm"], m["wire_b"]["y_mm"]])
    assert np.degrees(np.arctan2(*(b - a)[::-1])) == pytest.approx(bend_deg, abs=1e-9)


def test_wire_wraps_the_die_then_leaves_at_the_bend_angle():
    poly, start, direction = bender_wire_polyline(90.0)
    rho = 8.0 + 1.5
    assert np.allclose(poly[0], [-160.0, -rho]) and np.allclose(start, [rho, 0.0], atol=1e-12)
    assert np.allclose(direction, [0.0, 1.0], atol=1e-12)
    arc = poly[2:-1]
    assert np.allclose(np.hypot(arc[:, 0], arc[:, 1]), rho)
    seg = np.linalg.norm(np.diff(poly, axis=0), axis=1)
    assert np.all(seg > 0)


def test_photo_is_not_mirrored():
    """Pin at +90 deg (machine +y) appears above the origin; the axis marker to its left."""
    photo = render_bender_photo(pin_angle_deg=90.0, bend_angle_deg=20.0, scale=0.125)
    m = photo.truth["markers"]
    o, p, a = (np.array(m[r]["centre_px"]) for r in ("origin", "pin", "axis"))
    assert p[1] < o[1] - 10 and abs(p[0] - o[0]) < 1.0
    assert a[0] < o[0] - 50 and abs(a[1] - o[1]) < 1.0
    # and the pixels there really are the kit's colours
    for role in ("origin", "pin", "axis"):
        x, y = np.round(m[role]["centre_px"]).astype(int)
        rgb = photo.bgr[y, x, ::-1].astype(int)
        assert np.abs(rgb - np.array(default_kit().by_role(role).srgb)).max() < 40


def test_marker_centres_match_fitted_disc_edges_under_tilt():
    """An ellipse fitted to each disc's edge lands on the truth's ellipse centre (< 0.03 px).

    Under perspective that is not the projected disc centre; the truth gives both,
    and their difference here is several times the fit error.
    """
    pose = Pose(
        tilt_deg=40.0, tilt_direction_deg=200.0, yaw_deg=15.0, distance_mm=450.0, offset_mm=(-5, 0)
    )
    photo = render_bender_photo(
        pin_angle_deg=-100.0,
        bend_angle_deg=40.0,
        pose=pose,
        lighting=Lighting.clean(blur_px=0.0),
        scale=0.25,
        linear=True,
    )
    gaps, errors = [], []
    for role in ("origin", "axis", "pin", "wire_a", "wire_b"):
        check = check_disc_centre(photo, role)
        assert check.error_px < 0.03, role
        assert check.fitted_mean_axis_px == pytest.approx(check.true_mean_axis_px, abs=0.1)
        errors.append(check.error_px)
        gaps.append(check.perspective_shift_px)
    # the two centres really differ at this tilt, by more than the fit's error
    assert min(gaps) > 0.05 and max(errors) < 0.5 * min(gaps)


def test_occlusion_hides_part_of_a_marker():
    kw = dict(
        pin_angle_deg=-60.0, bend_angle_deg=35.0, scale=0.125, lighting=Lighting.clean(), seed=2
    )
    free = render_bender_photo(**kw)
    hidden = render_bender_photo(occlude={"wire_b": 1.0, "pin": 0.4}, **kw)
    m = hidden.truth["markers"]
    assert m["wire_b"]["occluded_fraction"] == 1.0 and m["pin"]["occluded_fraction"] == 0.4
    x, y = np.round(m["wire_b"]["centre_px"]).astype(int)
    assert hidden.bgr[y, x].max() < 80 < free.bgr[y, x].max()
    # 40 % of the pin marker's ring diameter is covered: the changed area is a band
    changed = np.abs(hidden.bgr.astype(int) - free.bgr.astype(int)).max(axis=2) > 30
    r = m["pin"]["ring_r_px"]
    x, y = m["pin"]["centre_px"]
    yy, xx = np.mgrid[0 : changed.shape[0], 0 : changed.shape[1]]
    inside = np.hypot(xx - x, yy - y) < r - 1
    frac = changed[inside].mean()
    assert 0.25 < frac < 0.5  # a 0.4-diameter cap covers ~37 % of the disc's area
    with pytest.raises(ValueError):
        render_bender_photo(occlude={"pin": 1.5}, **kw)
