"""Springback compensation models against a known bender (affine springback, nonlinear motion)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from cvmeasure.driver.session import nominal_pin_for_loaded_deg
from cvmeasure.material.compensation import (
    SPRINGBACK_MODELS,
    Compensation,
    CompensationRangeError,
    CompensationRangeWarning,
    fit_compensation,
    fit_motion,
    fit_springback,
)

DEAD_ZONE_DEG = 8.0
SB_A_DEG, SB_B = 1.45, 0.0096  # the seed FEA's affine springback (1.5-2.7 deg over 5-130 deg)
STANDARD = (5, 10, 15, 20, 30, 45, 60, 75, 90, 110, 130)


def loaded_of_pin(pin_deg):
    """A smooth nonlinear motion function with a dead zone (magnitudes, deg)."""
    p = np.maximum(np.abs(pin_deg) - DEAD_ZONE_DEG, 0.0)
    return np.sign(pin_deg) * (1.3 * p + 0.001 * p**2)


def final_of_loaded(loaded_deg):
    return np.sign(loaded_deg) * (np.abs(loaded_deg) - (SB_A_DEG + SB_B * np.abs(loaded_deg)))


def pin_for_loaded(loaded_deg):
    return brentq(lambda p: loaded_of_pin(p) - loaded_deg, DEAD_ZONE_DEG + 1e-9, 300.0)


def trials(angles=STANDARD, noise_deg=0.0, seed=0):
    rng = np.random.default_rng(seed)
    rows = []
    for sign in (1, -1):
        for a in angles:
            pin = sign * pin_for_loaded(a)
            loaded = float(loaded_of_pin(pin))
            unloaded = float(final_of_loaded(loaded))
            rows.append(
                (pin, loaded + rng.normal(0, noise_deg), unloaded + rng.normal(0, noise_deg))
            )
    return np.array(rows).T


@pytest.mark.parametrize("model", SPRINGBACK_MODELS)
def test_compensated_bends_land_on_target(model):
    comp = fit_compensation(*trials(noise_deg=0.01, seed=3), model=model)
    for target in (9.0, -9.0, 4.0, 27.5, -63.0, 120.0):
        pin = comp.compensate(target)
        final = float(final_of_loaded(loaded_of_pin(pin)))
        # motion interpolation between knots dominates; 0.1 deg is the target
        assert final == pytest.approx(target, abs=0.1), (model, target)


def test_interpolants_are_exact_at_knots_but_scored_out_of_sample():
    pin, loaded, unloaded = trials()
    sel = loaded > 0
    curve = fit_springback(unloaded[sel], loaded[sel], model="linear")
    assert curve.rmse_deg == pytest.approx(0.0, abs=1e-12)
    assert len(curve.loao_errors_deg) == len(STANDARD) - 2
    # the true curve is affine in the loaded angle, hence (almost) linear: tiny LOAO error
    assert curve.loao_rmse_deg < 0.01
    # a curve with a kink is not: leaving out the kink's knot must show the error
    kinked = unloaded[sel] + np.where(unloaded[sel] > 40, 0.0, 0.5 * (40 - unloaded[sel]) / 40)
    curve2 = fit_springback(kinked, loaded[sel], model="linear")
    assert curve2.loao_max_deg > 0.05


def test_physical_model_recovers_the_simulations_law():
    from cvmeasure.sim import SimParams, simulate
    from cvmeasure.sim.springback import springback_law

    law = springback_law(SimParams())
    bends = simulate(-np.linspace(18.0, 150.0, 9))  # clockwise, noiseless
    curve = fit_springback(
        -bends.unloaded_bend_deg, -bends.loaded_bend_deg, model="physical", direction="cw"
    )
    b, k = curve.coef
    assert b == pytest.approx(law.wrap_slope, rel=1e-5)
    assert k == pytest.approx(float(law.intercept_deg(1.0)), rel=1e-5)
    assert curve.loao_max_deg < 1e-4  # the law is the model: exact out of sample too
    final = np.array([3.0, 77.7])
    assert final[0] < curve.domain_deg[0]  # 3 deg is below the data: warned, not silent
    with pytest.warns(CompensationRangeWarning, match="extrapolated"):
        loaded = curve.loaded_for_final_deg(final, outside="warn")
    pins = [nominal_pin_for_loaded_deg(a, "cw") for a in loaded]
    assert np.allclose(simulate(pins).unloaded_bend_deg, -final, atol=1e-4)


def test_cubic_on_quick_mode_flags_one_dof():
    pin, loaded, unloaded = trials(angles=(10, 20, 45, 75, 110))
    sel = loaded > 0
    curve = fit_springback(unloaded[sel], loaded[sel], model="cubic")
    assert any("1 residual degree" in n for n in curve.notes)


def test_never_extrapolates_silently():
    comp = fit_compensation(*trials(), model="pchip")
    lo, hi = comp.domain_deg("ccw")
    assert lo == pytest.approx(5 - SB_A_DEG - SB_B * 5)
    with pytest.raises(CompensationRangeError, match="outside the calibrated range"):
        comp.compensate(hi + 1.0)
    with pytest.warns(CompensationRangeWarning, match="extrapolated"):
        pin = comp.compensate(-(lo - 0.2), outside="warn")
    assert float(final_of_loaded(loaded_of_pin(pin))) == pytest.approx(-(lo - 0.2), abs=0.05)
    with pytest.warns(CompensationRangeWarning, match="clamped"):
        assert comp.compensate(hi + 5, outside="clamp") == pytest.approx(comp.compensate(hi))
    assert comp.compensate(0.0) == 0.0


def test_one_direction_only_refuses_the_other():
    pin, loaded, unloaded = trials()
    sel = loaded > 0
    comp = fit_compensation(pin[sel], loaded[sel], unloaded[sel])
    with pytest.raises(CompensationRangeError, match="no springback calibration for cw"):
        comp.compensate(-20.0)


def test_repeats_are_averaged_and_round_trip():
    pin, loaded, unloaded = trials(noise_deg=0.02, seed=5)
    pin2, loaded2, unloaded2 = trials(noise_deg=0.02, seed=6)
    comp = fit_compensation(
        np.r_[pin, pin2], np.r_[loaded, loaded2], np.r_[unloaded, unloaded2], model="pchip"
    )
    assert len(comp.springback["ccw"].final_deg) == len(STANDARD)
    again = Compensation.from_dict(comp.to_dict())
    assert again.compensate(33.0) == comp.compensate(33.0)


def test_bad_arguments():
    with pytest.raises(ValueError, match="unknown springback model"):
        fit_springback([1, 2], [2, 3], model="spline")
    with pytest.raises(ValueError, match="at least 4 distinct"):
        fit_springback([1, 2, 3], [2, 3, 4], model="cubic")
    with pytest.raises(ValueError, match="not be invertible"):
        fit_motion([10, 20, 30], [15, 14, 40])
