"""Automatic detection of lateral chromatic aberration (red and blue magnified apart).

With the default edges, ``measure_machine_photo`` probes the discs' red and blue
edges against green; above LATERAL_CA_THRESHOLD it takes the edges in green and
warns. The rendered case is at half size (2304 x 1536): at 0.3 scale the fringes
(0.4 px at the corners) drown in JPEG chroma subsampling.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

from cvmeasure.colorimetry import srgb_encode
from cvmeasure.kit import ROLES, default_kit
from cvmeasure.markers.measure import (
    lateral_ca_estimate,
    measure_machine_photo,
)
from cvmeasure.markers.refine import channel_shifts_px

pytest.importorskip("cvmeasure_datasets.bender")
from cvmeasure_datasets.bender import render_bender_photo  # noqa: E402
from cvmeasure_datasets.lighting import Lighting  # noqa: E402
from cvmeasure_datasets.optics import Pose  # noqa: E402

CA = 5e-4
CENTRE_RMS_TOL_PX = 0.025  # half-size photo
ANGLE_TOL_DEG = 0.03


@functools.cache
def _half_size(ca: float):
    return render_bender_photo(
        pin_angle_deg=40.0,
        bend_angle_deg=35.0,
        lighting=Lighting(cct_k=5000.0, lateral_ca=ca),
        seed=2,
        pose=Pose(offset_mm=(60.0, 40.0)),
        scale=0.5,
    )


def _centre_rms_px(res, photo) -> float:
    d = [
        np.subtract(
            (res.markers[r].x_px, res.markers[r].y_px), photo.truth["markers"][r]["centre_px"]
        )
        for r in ROLES
    ]
    return float(np.sqrt(np.mean(np.sum(np.square(d), axis=1))))


def _ca_warnings(res) -> list[str]:
    return [w for w in res.warnings if w.code == "lateral_colour"]


def test_estimate_recovers_the_magnification_from_exact_shifts():
    k = 3e-4
    shape = (1001, 2001, 3)  # centre (1000, 500)
    centres = {"a": (1800.0, 100.0), "b": (300.0, 900.0), "c": (1000.0, 520.0)}
    shifts = {}
    for role, (x, y) in centres.items():
        v = np.array([x - 1000.0, y - 500.0])
        shifts[role] = {"red": tuple(k * v), "blue": tuple(-k * v)}
    shifts["c"] = {"red": shifts["c"]["red"]}  # a disc with no blue step
    assert lateral_ca_estimate(shifts, centres, shape) == pytest.approx(k, rel=1e-12)
    assert lateral_ca_estimate({}, centres, shape) is None


def test_channel_probe_measures_known_channel_offsets():
    # a grey disc on white, drawn with area-like anti-aliasing; red moved by (+0.6, -0.3) px,
    # blue by (-0.4, +0.2) px relative to green
    h = w = 81
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    centre, radius = (40.3, 39.8), 14.0
    offsets = {2: (0.6, -0.3), 1: (0.0, 0.0), 0: (-0.4, 0.2)}
    lin = np.empty((h, w, 3))
    for c, (dx, dy) in offsets.items():
        dist = np.hypot(xx - centre[0] - dx, yy - centre[1] - dy)
        inside = np.clip(radius - dist + 0.5, 0.0, 1.0)
        lin[..., c] = 0.85 - 0.8 * inside
    bgr = np.round(srgb_encode(lin) * 255.0).astype(np.uint8)
    disc = tuple(float(v) for v in srgb_encode(np.full(3, 0.05)) * 255.0)
    ring = tuple(float(v) for v in srgb_encode(np.full(3, 0.85)) * 255.0)
    got = channel_shifts_px(bgr, centre, radius, disc, ring)
    assert got["red"] == pytest.approx(offsets[2], abs=0.04)
    assert got["blue"] == pytest.approx(offsets[0], abs=0.04)


def test_lateral_ca_is_detected_and_measured_in_green():
    photo = _half_size(CA)
    kit = default_kit()
    res = measure_machine_photo(photo.bgr, kit, camera=photo.camera)
    (warning,) = _ca_warnings(res)
    assert warning.message.startswith("lateral chromatic aberration detected (")
    assert warning.message.endswith("px at the corners): edges taken in green")
    assert res.pin_angle_deg == pytest.approx(photo.truth["pin_angle_deg"], abs=ANGLE_TOL_DEG)
    assert res.bend_angle_deg == pytest.approx(photo.truth["bend_angle_deg"], abs=ANGLE_TOL_DEG)
    assert _centre_rms_px(res, photo) < CENTRE_RMS_TOL_PX
    # the same photo with luminance edges forced: no warning, and the fringes bias the centres
    luma = measure_machine_photo(photo.bgr, kit, camera=photo.camera, edge="luma")
    assert not _ca_warnings(luma)
    assert _centre_rms_px(luma, photo) > CENTRE_RMS_TOL_PX


def test_photo_without_lateral_ca_is_not_flagged(render):
    kit = default_kit()
    for photo in (_half_size(0.0), render(), render(pin=-80.0, bend=-70.0, seed=3)):
        res = measure_machine_photo(photo.bgr, kit, camera=photo.camera)
        assert not _ca_warnings(res)
        luma = measure_machine_photo(photo.bgr, kit, camera=photo.camera, edge="luma")
        assert res.bend_angle_deg == luma.bend_angle_deg  # the probe changed nothing
