"""Machine frame, signed angles and their propagated uncertainty."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cvmeasure.kit import ROLES
from cvmeasure.markers.angles import (
    machine_angles,
    springback_deg,
    springback_sigma_deg,
    to_machine_frame,
)

ATOL_DEG = 1e-9


def _photo_centres(pin_deg: float, bend_deg: float, rot_deg: float, y_down: bool = True):
    """Marker centres in a photo whose machine +x is turned ``rot_deg`` CCW as seen."""
    machine = {
        "origin": (0.0, 0.0),
        "axis": (-70.0, 0.0),
        "pin": (18 * math.cos(math.radians(pin_deg)), 18 * math.sin(math.radians(pin_deg))),
        "wire_a": (12.0, 3.0),
    }
    b = math.radians(bend_deg)
    machine["wire_b"] = (12.0 + 40 * math.cos(b), 3.0 + 40 * math.sin(b))
    c, s = math.cos(math.radians(rot_deg)), math.sin(math.radians(rot_deg))
    out = {}
    for role, (x, y) in machine.items():
        xr, yr = c * x - s * y, s * x + c * y  # CCW as seen (y up)
        out[role] = (1000 + 8 * xr, 700 - 8 * yr) if y_down else (1000 + 8 * xr, 700 + 8 * yr)
    return out


@pytest.mark.parametrize("pin_deg", [0.0, 30.0, -45.0, 120.0, -179.0, 180.0])
@pytest.mark.parametrize("bend_deg", [0.0, 25.0, -90.0, 175.0])
@pytest.mark.parametrize("rot_deg", [0.0, 37.0, -150.0])
def test_signed_angles_in_the_machine_frame(pin_deg, bend_deg, rot_deg):
    for y_down in (True, False):
        a = machine_angles(_photo_centres(pin_deg, bend_deg, rot_deg, y_down), y_down=y_down)
        assert a.pin_angle_deg == pytest.approx(180.0 if pin_deg == -180 else pin_deg, abs=1e-9)
        assert a.bend_angle_deg == pytest.approx(bend_deg, abs=1e-9)
        assert -180.0 < a.pin_angle_deg <= 180.0
        assert a.pin_sigma_deg == 0.0 and a.bend_sigma_deg == 0.0


def test_counter_clockwise_as_seen_is_positive():
    # image y is down: a pin drawn *above* the +x axis in the photo is CCW, positive
    c = {
        "axis": (0, 500),
        "origin": (100, 500),
        "pin": (150, 450),
        "wire_a": (120, 500),
        "wire_b": (170, 450),
    }
    a = machine_angles(c)
    assert a.pin_angle_deg == pytest.approx(45.0, abs=ATOL_DEG)
    assert a.bend_angle_deg == pytest.approx(45.0, abs=ATOL_DEG)


def test_wrap_at_180():
    c = _photo_centres(179.9, -179.9, 90.0)
    a = machine_angles(c)
    assert a.pin_angle_deg == pytest.approx(179.9, abs=1e-9)
    assert a.bend_angle_deg == pytest.approx(-179.9, abs=1e-9)


def test_uncertainty_matches_monte_carlo():
    rng = np.random.default_rng(11)
    centres = _photo_centres(40.0, 30.0, 20.0)
    covs = {}
    for role in ROLES:
        m = rng.normal(size=(2, 2)) * 0.05
        covs[role] = m @ m.T + np.eye(2) * 0.01**2
    a = machine_angles(centres, covs)
    pins, bends = [], []
    for _ in range(4000):
        noisy = {r: rng.multivariate_normal(centres[r], covs[r]) for r in ROLES}
        b = machine_angles(noisy)
        pins.append(b.pin_angle_deg)
        bends.append(b.bend_angle_deg)
    assert np.std(pins) == pytest.approx(a.pin_sigma_deg, rel=0.06)
    assert np.std(bends) == pytest.approx(a.bend_sigma_deg, rel=0.06)


def test_degenerate_geometry_is_a_value_error():
    c = _photo_centres(10.0, 10.0, 0.0)
    c["axis"] = c["origin"]
    with pytest.raises(ValueError, match="axis->origin"):
        machine_angles(c)


def test_to_machine_frame_round_trip():
    c = _photo_centres(30.0, 20.0, 65.0)
    pts = to_machine_frame([c["pin"], c["axis"]], c["origin"], c["axis"])
    r = 18 * 8
    assert pts[0] == pytest.approx(
        [r * math.cos(math.radians(30)), r * math.sin(math.radians(30))], abs=1e-9
    )
    assert pts[1] == pytest.approx([-70 * 8, 0.0], abs=1e-9)


@pytest.mark.parametrize(
    ("loaded", "unloaded", "expected"),
    [
        (90.0, 85.0, 5.0),
        (-90.0, -85.0, 5.0),
        (30.0, 31.0, -1.0),
        (0.0, 2.0, 0.0),
        (179.0, -179.0, -2.0),
    ],
)
def test_springback_sign_convention(loaded, unloaded, expected):
    assert springback_deg(loaded, unloaded) == pytest.approx(expected, abs=1e-12)


def test_springback_sigma_adds_in_quadrature():
    assert springback_sigma_deg(0.003, 0.004) == pytest.approx(0.005, abs=1e-15)
