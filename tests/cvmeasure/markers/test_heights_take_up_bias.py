"""Measured heights take up the centres' pose-constant bias: the angles' sigma against truth.

Synthetic sweeps and check photos on the plate, as in ``test_kit_heights_sigma``: caps
off their nominal heights, seen from a tilted camera; every centre carries a bias the
same on every photo from the pose (drawn once per pose: a disc's wall, shading, blur)
and fresh per-photo noise, and states both in its covariance as the measurement does
(the bias as its pose-constant part). Heights fitted to that sweep through the plane,
then check photos measured with them: the stated sigma (per-photo part plus the
heights' covariance through the geometry) must match the angles' errors; counting the
bias again, as if per photo, states it too wide.
"""

from __future__ import annotations

import math

import numpy as np

from cvmeasure.kit import ROLES, default_kit
from cvmeasure.markers.angles import machine_angles
from cvmeasure.markers.heights import heights_take_up_bias, move_to_heights, plane_heights_sigma
from cvmeasure.markers.kit_heights import SweepPhoto, measure_heights

from .test_kit_heights_sigma import CAMERA_MM, POSE, TRUE_FACTORS, _angle_error_deg, _machine

#: Per-photo noise (mm per axis) and the pose-constant bias's standard deviation (mm per
#: axis): the bias about the size of the noise, as the unseen-bias term states it on the
#: benchmark's renders.
NOISE_MM = 0.006
BIAS_MM = 0.006
OTHER_POSE = (POSE[0] + 1e-3, POSE[1] + np.array([0.0, 0.0, 5.0]))


def _photo(pin, bend, true_mm, kit_mm, bias, rng):
    seen = move_to_heights(_machine(pin, bend), true_mm, kit_mm, CAMERA_MM)
    return {r: c + bias[r] + rng.normal(0.0, NOISE_MM, 2) for r, c in seen.items()}


def _draws(n_poses: int, seed: int):
    """Per pose: the angles' errors of check photos and their sigmas, the bias taken up by
    the heights and counted again."""
    nominal = default_kit()
    nominal_mm = {r: nominal.height_mm(r) for r in ROLES}
    true_mm = {r: nominal_mm[r] * f for r, f in zip(ROLES, TRUE_FACTORS, strict=True)}
    noise = {r: np.eye(2) * NOISE_MM**2 for r in ROLES}
    bias_cov = {r: np.eye(2) * BIAS_MM**2 for r in ROLES}
    total = {r: noise[r] + bias_cov[r] for r in ROLES}
    rng = np.random.default_rng(seed)
    errors, taken_up, counted_again = [], [], []
    shots = [((p, 0.85 * p), False) for p in (-100, -70, -40, -15, 15, 40, 70, 100)]
    shots += [((-30.0, 0.0), True), ((30.0, 0.0), True)]
    for _ in range(n_poses):
        bias = {r: rng.normal(0.0, BIAS_MM, 2) for r in ROLES}
        sweep = [
            SweepPhoto(_photo(p, b, true_mm, nominal_mm, bias, rng), total, straight)
            for (p, b), straight in shots
        ]
        kit = measure_heights(sweep, nominal, CAMERA_MM, y_down=False, plane_pose=POSE).kit
        kit_mm = {r: kit.height_mm(r) for r in ROLES}
        for pin, bend in ((55.0, 48.0), (-80.0, -70.0), (20.0, 17.0), (-35.0, -31.0)):
            c = _photo(pin, bend, true_mm, kit_mm, bias, rng)
            errors.append(_angle_error_deg(c, pin, bend))
            for covs, out in ((heights_take_up_bias(total, bias_cov, kit, POSE), taken_up),
                              (total, counted_again)):  # fmt: skip
                a = machine_angles(c, covs, y_down=False)
                sigma = {"pin_angle_deg": a.pin_sigma_deg, "bend_angle_deg": a.bend_sigma_deg}
                sigma, _ = plane_heights_sigma(c, kit, CAMERA_MM, False, sigma, [], POSE)
                out.append([sigma["pin_angle_deg"], sigma["bend_angle_deg"]])
    return np.asarray(errors), np.asarray(taken_up), np.asarray(counted_again)


def test_measured_heights_sigma_holds_with_the_bias_taken_up():
    errors, taken_up, counted_again = _draws(40, seed=21)
    rms_new = np.sqrt(np.mean(np.square(errors / taken_up), axis=0))
    rms_old = np.sqrt(np.mean(np.square(errors / counted_again), axis=0))
    within = np.mean(np.abs(errors / taken_up) <= 2.0, axis=0)
    # 40 poses x 4 bends: error / stated sigma RMS within 0.8-1.25 (pin, bend; 1.11 and
    # 1.05 here, 94 and 95 % within 2 sigma) with the bias taken up by the heights;
    # counted again it states the sigma too wide (0.87 and 0.83, 98 %)
    assert np.all((rms_new > 0.8) & (rms_new < 1.25)), (rms_new, rms_old)
    assert np.all(within >= 0.88), within
    assert np.all(rms_old < 0.85 * rms_new), (rms_new, rms_old)


def test_bias_kept_unless_heights_measured_through_this_plane():
    """The pose-constant part is dropped only for heights measured through this plane: a
    kit with nominal heights, or heights measured through another plane, keeps it."""
    nominal = default_kit()
    covs = {r: np.eye(2) * 2e-4 for r in ROLES}
    bias = {r: np.eye(2) * 1.5e-4 for r in ROLES}
    kept = heights_take_up_bias(covs, bias, nominal, POSE)
    assert all(np.allclose(kept[r], covs[r]) for r in ROLES)
    nominal_mm = {r: nominal.height_mm(r) for r in ROLES}
    rng = np.random.default_rng(2)
    sweep = [
        SweepPhoto(_photo(p, 0.85 * p, nominal_mm, nominal_mm, dict.fromkeys(ROLES, 0.0), rng),
                   covs, False)
        for p in (-90, -45, 10, 60, 95)
    ]  # fmt: skip
    kit = measure_heights(sweep, nominal, CAMERA_MM, y_down=False, plane_pose=POSE).kit
    same = heights_take_up_bias(covs, bias, kit, POSE)
    assert all(np.allclose(same[r], covs[r] - bias[r]) for r in ROLES)
    other = heights_take_up_bias(covs, bias, kit, OTHER_POSE)
    assert all(np.allclose(other[r], covs[r]) for r in ROLES)
    assert math.isclose(float(np.trace(same["pin"])), 1e-4)
