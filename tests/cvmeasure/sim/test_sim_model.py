"""The forward model, its effects and its inverse."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.sim import (
    EFFECT_NAMES,
    Effect,
    SimParams,
    max_reachable_deg,
    parse_effect,
    pin_command_for_angle,
    simulate,
)
from cvmeasure.sim.kinematics import head_geometry, pin_angle_for_loaded_deg
from cvmeasure.sim.model import simulate_drift_rates, simulate_rows

CMDS = np.array([-120.0, -60.0, -25.0, 25.0, 60.0, 120.0])


def test_directions_are_mirror_images_and_signed():
    res = simulate(CMDS)
    np.testing.assert_allclose(res.loaded_bend_deg[:3], -res.loaded_bend_deg[:2:-1], atol=1e-12)
    assert np.all(np.sign(res.loaded_bend_deg) == np.sign(CMDS))
    assert np.all(res.springback_deg > 0)  # opens back towards straight
    np.testing.assert_allclose(
        res.springback_deg,
        np.sign(res.loaded_bend_deg) * (res.loaded_bend_deg - res.unloaded_bend_deg),
    )
    np.testing.assert_array_equal(res.pin_deg, CMDS)


def test_dead_zone_gives_no_bend():
    p = SimParams()
    res = simulate([0.0, p.approach_deg - 0.5, -(p.approach_deg - 0.5)], p)
    np.testing.assert_array_equal(res.loaded_bend_deg, 0.0)
    np.testing.assert_array_equal(res.unloaded_bend_deg, 0.0)


def test_loaded_angle_follows_tangent_construction():
    p = SimParams()
    geom = head_geometry(p)
    phi = pin_angle_for_loaded_deg(geom, 90.0)
    from cvmeasure.sim.kinematics import contact_angle_deg

    cmd = float(phi - contact_angle_deg(geom) + p.approach_deg)
    assert simulate([cmd], p).loaded_bend_deg[0] == pytest.approx(90.0, abs=1e-9)


def _delta(effect, cmds=CMDS, **kw):
    base = simulate(cmds, **kw)
    eff = simulate(cmds, effects=[effect], **kw)
    return base, eff


def test_backlash_and_offset_and_scale_change_pin_travel():
    _, b = _delta(Effect("backlash", 1.5))
    np.testing.assert_allclose(np.abs(b.pin_deg), np.abs(CMDS) - 1.5)
    _, o = _delta(Effect("offset", 2.0))
    np.testing.assert_allclose(o.pin_deg, CMDS + 2.0)
    _, s = _delta(Effect("scale", 0.04))
    np.testing.assert_allclose(s.pin_deg, CMDS * 1.04)


def test_drift_accumulates_with_bend_index():
    cmds = np.full(10, 60.0)
    _, d = _delta(Effect("drift", 0.1), cmds)
    np.testing.assert_allclose(d.pin_deg, 60.0 - 0.1 * np.arange(10))
    assert np.all(np.diff(d.unloaded_bend_deg) < 0)  # the helix: every bend a bit less


def test_springback_asymmetry_only_changes_unloaded():
    base, eff = _delta(Effect("springback_asymmetry", 0.3))
    np.testing.assert_allclose(eff.loaded_bend_deg, base.loaded_bend_deg)
    ratio = eff.springback_deg / base.springback_deg
    np.testing.assert_allclose(ratio, np.where(CMDS > 0, 1.3, 0.7), rtol=1e-9)


def test_camera_tilt_foreshortens_measured_angles():
    tau = 20.0
    base, eff = _delta(Effect("camera_tilt", tau))
    expected = np.degrees(
        np.arctan2(
            np.sin(np.radians(base.loaded_bend_deg)) * np.cos(np.radians(tau)),
            np.cos(np.radians(base.loaded_bend_deg)),
        )
    )
    np.testing.assert_allclose(eff.loaded_bend_deg, expected)
    np.testing.assert_allclose(eff.pin_deg, base.pin_deg)


def test_axis_offset_breaks_symmetry_with_cos_shape():
    cmds = np.array([30.0, -30.0, 140.0, -140.0])
    base, eff = _delta(Effect("axis_offset", 0.3), cmds)
    d = np.abs(eff.loaded_bend_deg) - np.abs(base.loaded_bend_deg)
    # small angles: one direction gains what the other loses; sign flips at large angles
    assert d[0] * d[1] < 0 and d[2] * d[3] < 0
    assert np.sign(d[0]) != np.sign(d[2])
    # cw - ccw difference of ~3 deg at small angles for 0.3 mm (reference section 2.1)
    assert abs(d[0] - d[1]) == pytest.approx(3.1, abs=0.6)


def test_effect_bounds_and_parsing():
    assert parse_effect("backlash=1.2") == Effect("backlash", 1.2)
    assert parse_effect("none") == Effect("none")
    with pytest.raises(ValueError, match="unknown effect"):
        parse_effect("wobble=1")
    with pytest.raises(ValueError, match="physical bounds"):
        Effect("backlash", -1.0)
    with pytest.raises(ValueError, match="NAME=VALUE"):
        parse_effect("backlash")
    for name in EFFECT_NAMES:  # every spec name can be simulated
        e = Effect.from_dict(Effect(name, 0.0).to_dict())
        assert simulate(CMDS, effects=[e]).loaded_bend_deg.shape == CMDS.shape


@pytest.mark.parametrize(
    "effects",
    [(), (Effect("backlash", 1.0),), (Effect("springback_asymmetry", -0.3), Effect("offset", 1.0))],
)
def test_inverse_round_trip(effects):
    targets = np.array([-150.0, -90.0, -5.0, 0.0, 3.0, 45.0, 90.0, 130.0])
    cmd = pin_command_for_angle(targets, SimParams(), effects)
    res = simulate(cmd, SimParams(), effects)
    np.testing.assert_allclose(res.unloaded_bend_deg, targets, atol=1e-6)
    assert pin_command_for_angle(90.0) == pytest.approx(
        float(pin_command_for_angle(np.array([90.0]))[0])
    )


def test_inverse_ignores_camera_and_refuses_unreachable():
    tilt = (Effect("camera_tilt", 20.0),)
    assert pin_command_for_angle(60.0, effects=tilt) == pytest.approx(pin_command_for_angle(60.0))
    with pytest.raises(ValueError, match="reachable"):
        pin_command_for_angle(max_reachable_deg() + 1.0)


def test_invalid_command():
    with pytest.raises(ValueError, match="finite"):
        simulate([np.nan])


def test_pin_angle_in_machine_frame():
    p = SimParams()
    from cvmeasure.sim.kinematics import contact_angle_deg as contact

    phi_c = contact(head_geometry(p))
    res = simulate([p.approach_deg, -p.approach_deg, 0.0, 100.0], p)
    # at first contact the pin sits at phi_c below the wire (ccw) or mirrored above it (cw)
    np.testing.assert_allclose(res.pin_angle_deg[:2], [phi_c, -phi_c], atol=1e-9)
    assert res.pin_angle_deg[2] == pytest.approx(phi_c - p.approach_deg)  # home
    assert res.pin_angle_deg[3] == pytest.approx(phi_c - p.approach_deg + 100.0)
    # backlash moves the pin
    moved = simulate([100.0], p, [Effect("backlash", 2.0)]).pin_angle_deg[0]
    assert moved == pytest.approx(res.pin_angle_deg[3] - 2.0)


@pytest.mark.parametrize("command_deg", [40.0, 100.0, 150.0, -40.0, -100.0, -150.0])
@pytest.mark.parametrize("offset_mm", [0.3, -0.5])
def test_pin_is_read_from_the_origin_marker_when_the_head_axis_is_off_it(command_deg, offset_mm):
    """The marker sits on the die at the nominal axis; an axis offset moves the orbit.

    The head turns by the same angle about its own (offset) axis, so the pin centre is
    ``(0, e) + R_p (cos phi, sin phi)`` in the machine frame (``phi`` the head's angle,
    mirrored for a clockwise bend) and a photo reads ``atan2`` of that from the marker:
    about ``(e / R_p) cos(phi)`` rad off ``phi``, up to 2.4 deg at 0.5 mm on a 12 mm orbit.
    """
    p = SimParams()
    head = simulate([command_deg], p).pin_angle_deg[0]  # the head's angle: no offset
    seen = simulate([command_deg], p, [Effect("axis_offset", offset_mm)]).pin_angle_deg[0]
    a = np.radians(head)
    expected = np.degrees(
        np.arctan2(offset_mm + p.pin_orbit_mm * np.sin(a), p.pin_orbit_mm * np.cos(a))
    )
    assert seen == pytest.approx(expected, abs=1e-9)
    first_order = head + np.degrees(offset_mm / p.pin_orbit_mm * np.cos(a))
    assert seen == pytest.approx(first_order, abs=0.05)
    assert abs(seen - head) > 0.5 * abs(np.degrees(offset_mm / p.pin_orbit_mm * np.cos(a)))


def test_compliance_lag_follows_the_load():
    p = SimParams()
    cmds = np.array([30.0, 60.0, 90.0, 120.0])
    base = simulate(cmds, p)
    eff = simulate(cmds, p, [Effect("compliance", 0.4)])
    lag = base.pin_deg - eff.pin_deg
    # lag = k * (M / l) * R_p cos(phi - theta) at the lagged position (fixed point): the
    # pin force is normal to the leg, its arm about the head axis is R_p cos(phi - theta)
    from cvmeasure.sim.springback import springback_law

    arm_mm = p.pin_orbit_mm * np.cos(np.radians(eff.pin_angle_deg - eff.loaded_bend_deg))
    assert np.all((arm_mm > 0.6 * p.pin_orbit_mm) & (arm_mm < p.pin_orbit_mm))
    torque_nm = springback_law(p).moment_nmm / eff.lever_mm * arm_mm / 1e3
    np.testing.assert_allclose(lag, 0.4 * torque_nm, rtol=1e-4)
    # grows as the lever shortens, until the arm turning away from the leg wins (120 deg)
    assert np.all(np.diff(lag[:3]) > 0) and lag[3] < lag[2]
    # no load before contact: no lag
    assert simulate([5.0], p, [Effect("compliance", 0.4)]).pin_deg[0] == 5.0


def test_a_springback_asymmetry_loads_the_drive_in_the_same_ratio():
    # springback differing by direction is a wire whose strength differs by direction:
    # the moment, hence the pin torque and the drive's wind-up, differ in the same ratio
    p = SimParams()
    cmds = np.array([60.0, -60.0, 100.0, -100.0])
    from cvmeasure.sim.springback import springback_law

    alpha = 0.3
    eff = simulate(cmds, p, [Effect("compliance", 0.4), Effect("springback_asymmetry", alpha)])
    lag = np.abs(cmds) - np.abs(eff.pin_deg)
    arm_mm = p.pin_orbit_mm * np.cos(np.radians(eff.pin_angle_deg - eff.loaded_bend_deg))
    torque_nm = springback_law(p).moment_nmm / eff.lever_mm * np.abs(arm_mm) / 1e3
    strength = 1.0 + np.sign(cmds) * alpha
    np.testing.assert_allclose(lag, 0.4 * strength * torque_nm, rtol=1e-4)
    assert lag[0] / lag[1] == pytest.approx(1.3 / 0.7, rel=0.05)
    # without compliance the asymmetry moves released angles only
    alone = simulate(cmds, p, [Effect("springback_asymmetry", alpha)])
    np.testing.assert_array_equal(alone.loaded_bend_deg, simulate(cmds, p).loaded_bend_deg)


def test_backlash_general_form_loses_play_on_reversals_only():
    cmds = np.array([60.0, 60.0, -60.0, -60.0, 60.0])
    every = simulate(cmds, effects=[Effect("backlash", 1.0)]).pin_deg
    np.testing.assert_allclose(np.abs(every), 59.0)  # the narrow form: every bend
    rev = Effect("backlash", 1.0, (("same_direction_share", 0.0),))
    got = simulate(cmds, effects=[rev]).pin_deg
    np.testing.assert_allclose(np.abs(got), [59.0, 60.0, 59.0, 60.0, 59.0])
    assert Effect.from_dict(rev.to_dict()) == rev


def test_drift_narrow_form_is_the_spec_helix_whatever_the_direction():
    # the spec's drift keeps its meaning: bend k loses d k, both directions alike,
    # bend_index taken as given (so the inverse of one bend at index k works)
    cmds = np.array([60.0, 60.0, -60.0, -60.0, 60.0])
    got = simulate(cmds, effects=[Effect("drift", 0.1)]).pin_deg
    np.testing.assert_allclose(got, [60.0, 59.9, -59.8, -59.7, 59.6])
    one = simulate([60.0], effects=[Effect("drift", 0.1)], bend_index=[7]).pin_deg
    np.testing.assert_allclose(one, [59.3])


def test_drift_shifts_home_in_the_sense_of_the_lost_steps():
    cmds = np.array([60.0, 60.0, -60.0, -60.0, 60.0])
    home = Effect("drift", 0.1, (("home_shift", 1.0),))
    got = simulate(cmds, effects=[home]).pin_deg
    # home moves back by 0.1 per ccw bend: later ccw bends are short, cw bends long
    np.testing.assert_allclose(got, [60.0, 59.9, -60.2, -60.1, 60.0])
    # re-homing (bend_index back to 0) resets the shift
    again = simulate(cmds, effects=[home], bend_index=[0, 1, 0, 1, 2]).pin_deg
    np.testing.assert_allclose(again, [60.0, 59.9, -60.0, -59.9, 60.2])
    # half of the loss shifts home, half shortens every later bend
    half = Effect("drift", 0.1, (("home_shift", 0.5),))
    got = simulate(cmds, effects=[half]).pin_deg
    np.testing.assert_allclose(got, [60.0, 59.9, -60.0, -59.9, 59.8])
    # load-dependent: bends under more torque lose more steps
    loaded = Effect("drift", 0.1, (("load_exponent", 2.0),))
    small = simulate([20.0, 20.0], effects=[loaded]).pin_deg
    large = simulate([120.0, 120.0], effects=[loaded]).pin_deg
    assert 0 < 20.0 - small[1] < 120.0 - large[1]


def test_camera_tilt_about_any_axis():
    from cvmeasure.sim.model import apply_camera_tilt_deg

    # about the feed axis the narrow form; about the axis along the leg nothing changes
    t = np.array([30.0, 60.0, -45.0])
    narrow = np.degrees(np.arctan2(np.sin(np.radians(t)) * np.cos(0.3), np.cos(np.radians(t))))
    np.testing.assert_allclose(apply_camera_tilt_deg(t, np.degrees(0.3), 0.0), narrow)
    assert apply_camera_tilt_deg(90.0, 20.0, 90.0) == pytest.approx(90.0)  # leg on the axis
    oblique = apply_camera_tilt_deg(np.array([0.0, 45.0, 90.0]), 20.0, 45.0)
    # a leg on the axis keeps its direction but the feed leg's image turns: 45 reads 43.2
    assert oblique[0] == 0.0 and oblique[1] == pytest.approx(43.22, abs=0.01)
    assert oblique[2] == pytest.approx(86.44, abs=0.01)
    e = parse_effect("camera_tilt=15,tilt_axis_deg=40")
    assert e.shape_value("tilt_axis_deg") == 40.0
    with pytest.raises(ValueError, match="bounds"):
        Effect("camera_tilt", 15.0, (("tilt_axis_deg", 120.0),))


def test_span_bow_is_the_beam_theory_tip_slope_over_the_chord():
    # moment falling linearly from the die (M) to the pin (0) over the span l: the tangent
    # at the pin leads the chord by (1 / l) int_0^l s kappa(s) ds, kappa = M (1 - s/l) / EI
    from cvmeasure.sim.springback import springback_law

    law = springback_law(SimParams())
    lever = np.array([5.7, 8.0, 10.8])
    s = (np.arange(20_000) + 0.5) / 20_000  # s / l
    kappa = law.moment_nmm * (1.0 - s) / law.bending_stiffness_nmm2
    integral = np.degrees(lever * np.mean(s * kappa))  # (1/l) int s kappa ds, l factored
    np.testing.assert_allclose(law.span_bow_deg(90.0, lever), integral, rtol=1e-6)
    # a cantilever below the elastic threshold: half the chord angle
    assert law.span_bow_deg(0.1, 10.0) == pytest.approx(0.05)


def test_span_bow_share_moves_loaded_and_released_alike():
    cmd = np.array([-110.0, -40.0, 30.0, 95.0])
    straight = simulate(cmd)
    assert np.array_equal(straight.loaded_bend_deg, simulate(cmd, SimParams()).loaded_bend_deg)
    bowed = simulate(cmd, SimParams(span_bow_share=1.0))
    d_loaded = bowed.loaded_bend_deg - straight.loaded_bend_deg
    d_released = bowed.unloaded_bend_deg - straight.unloaded_bend_deg
    np.testing.assert_allclose(d_released, d_loaded, atol=1e-9)
    assert np.all(np.sign(d_loaded) == np.sign(cmd)) and np.all(np.abs(d_loaded) > 0.1)
    np.testing.assert_array_equal(bowed.pin_deg, straight.pin_deg)  # the head is not moved


def test_a_negative_span_bow_share_is_refused():
    with pytest.raises(ValueError, match="span_bow_share must be >= 0"):
        SimParams(span_bow_share=-0.5)


def test_span_bow_brings_the_loaded_angle_to_the_independent_models():
    # the independent physical model (cvmeasure_datasets.physical_bender, nominal machine,
    # its own hardening law) bows its span: simulate's straight leg is 0.16-0.32 deg short
    # of its loaded angle (falling with the bend), with the bow within 0.02 deg
    from cvmeasure_datasets import physical_bender as pb

    machine = pb.Machine()
    targets = np.array([5.0, 10.0, 20.0, 40.0, 60.0, 80.0, 100.0, 130.0])
    cmd = np.round(pb._nominal_command(machine, targets), 1)
    truth = pb.bend(cmd, machine).loaded_deg
    straight = simulate(cmd).loaded_bend_deg - truth
    bowed = simulate(cmd, SimParams(span_bow_share=1.0)).loaded_bend_deg - truth
    assert np.all(straight < -0.15), straight
    assert np.max(np.abs(bowed)) < 0.02, bowed


@pytest.mark.parametrize(
    "shape",
    [
        (),
        (("home_shift", 1.0),),
        (("home_shift", 1.0), ("step_deg", 0.06)),
        (("home_shift", 1.0), ("load_exponent", 1.0), ("step_deg", 0.03)),
        (("home_shift", 0.5), ("load_exponent", 2.0), ("step_deg", 0.12)),
    ],
)
def test_simulate_drift_rates_is_simulate_at_each_rate(shape):
    # the batched form a whole-step drift's profile uses: each row the very numbers of
    # simulate at that rate (a plan of mixed directions re-homed twice, beside other
    # effects and the span's bow)
    rng = np.random.default_rng(4)
    cmd = rng.choice([-1.0, 1.0], 40) * rng.uniform(20.0, 140.0, 40)
    index = np.concatenate([np.arange(15), np.arange(10), np.arange(15)]).astype(float)
    params = SimParams().replace(span_bow_share=1.0)
    rest = (Effect("camera_tilt", 2.0, (("tilt_axis_deg", 30.0),)), Effect("compliance", 0.002))
    rates = np.concatenate([np.geomspace(0.01, 0.5, 17), [0.0, 0.045, 0.09]])
    batch = simulate_drift_rates(
        cmd, params, (*rest, Effect("drift", 0.1, shape)), rates, bend_index=index
    )
    for k, rate in enumerate(rates):
        one = simulate(cmd, params, (*rest, Effect("drift", float(rate), shape)), bend_index=index)
        for name in ("pin_deg", "loaded_bend_deg", "unloaded_bend_deg", "pin_angle_deg"):
            np.testing.assert_array_equal(getattr(batch, name)[k], getattr(one, name))
    with pytest.raises(ValueError, match="drift"):
        simulate_drift_rates(cmd, params, rest, rates, bend_index=index)


def test_a_strength_by_direction_moves_the_loaded_leg_in_its_general_form():
    """``loaded_deg`` per unit of asymmetry: the stronger direction's loaded (and released)
    bend moves by ``loaded_deg * alpha``, the weaker one's by minus that; the narrow form
    leaves the loaded bend alone."""
    p = SimParams()
    cmd = [60.0, -60.0, 120.0, -120.0]
    narrow = simulate(cmd, p, [Effect("springback_asymmetry", 0.4)])
    general = simulate(cmd, p, [Effect("springback_asymmetry", 0.4, (("loaded_deg", -1.0),))])
    np.testing.assert_allclose(narrow.loaded_bend_deg, simulate(cmd, p).loaded_bend_deg)
    shift = np.abs(general.loaded_bend_deg) - np.abs(narrow.loaded_bend_deg)
    np.testing.assert_allclose(shift, [-0.4, 0.4, -0.4, 0.4], atol=1e-9)
    # the springback is the narrow form's (the leg moves, the release from it does not)
    np.testing.assert_allclose(general.springback_deg, narrow.springback_deg, atol=0.02)


@pytest.mark.parametrize(
    "effects",
    [
        (Effect("backlash", 0.8), Effect("scale", 0.01)),
        (Effect("camera_tilt", 2.0, (("tilt_axis_deg", 30.0),)), Effect("offset", 0.3)),
        (Effect("axis_offset", 0.4), Effect("compliance", 0.002)),
        (Effect("springback_asymmetry", 0.05, (("loaded_deg", 1.5),)),),
        (Effect("drift", 0.05, (("home_shift", 0.5), ("load_exponent", 2.0))),),
    ],
)
def test_simulate_rows_is_simulate_at_each_row(effects):
    # the batched form a fit's forward differences use: each row (the strength, the
    # die's radius or one effect's value stepped) the very numbers of simulate with that
    # row's model
    rng = np.random.default_rng(5)
    cmd = rng.choice([-1.0, 1.0], 30) * rng.uniform(20.0, 140.0, 30)
    index = np.concatenate([np.arange(18), np.arange(12)]).astype(float)
    base = SimParams().replace(span_bow_share=1.0)
    params_rows = [
        base,
        base.replace(yield_mpa=base.yield_mpa * 1.001, uts_mpa=base.uts_mpa * 1.001),
    ]
    params_rows.append(base.replace(die_radius_mm=1.7))
    effects_rows = [effects, effects, effects]
    for k, e in enumerate(effects):
        params_rows.append(base)
        stepped = Effect(e.name, e.value * 1.01 + 1e-6, e.shape)
        effects_rows.append((*effects[:k], stepped, *effects[k + 1 :]))
    batch = simulate_rows(cmd, params_rows, effects_rows, bend_index=index)
    for k, (p, e) in enumerate(zip(params_rows, effects_rows, strict=True)):
        one = simulate(cmd, p, e, bend_index=index)
        for name in ("pin_deg", "loaded_bend_deg", "unloaded_bend_deg", "pin_angle_deg"):
            np.testing.assert_array_equal(getattr(batch, name)[k], getattr(one, name))


def test_simulate_rows_refuses_rows_that_cannot_share_a_run():
    cmd = np.array([30.0, -60.0, 90.0])
    base = SimParams()
    with pytest.raises(ValueError, match="params"):
        simulate_rows(cmd, [base, base.replace(pin_radius_mm=4.0)], [(), ()])
    with pytest.raises(ValueError, match="effects"):
        simulate_rows(cmd, [base, base], [(Effect("offset", 0.1),), (Effect("scale", 0.1),)])
    with pytest.raises(ValueError, match="compliance"):
        simulate_rows(
            cmd, [base, base], [(Effect("compliance", 0.0),), (Effect("compliance", 0.001),)]
        )


@pytest.mark.parametrize(
    ("effect", "refused"),
    [("compliance=50", True), ("axis_offset=9", True), ("compliance=1.5", False)],
)
def test_the_cli_checks_a_sized_effect_on_the_built_in_machine(tmp_path, capsys, effect, refused):
    """``Effect`` checks only the sign of an effect with a size; the command line checks its
    bounds on the machine simulated (a DIWire's: compliance 0-2 deg/(N m), axis offset
    +-1 mm), with one line and exit 2."""
    from cvmeasure.cli import main

    plan = tmp_path / "plan.csv"
    plan.write_text("trial,commanded_pin_deg\n0,30\n1,60\n")
    out = tmp_path / "out.csv"
    code = main(["simulate", str(plan), "--effect", effect, "-o", str(out)])
    err = capsys.readouterr().err
    assert code == (2 if refused else 0)
    assert out.exists() != refused
    if refused:
        assert "outside its physical bounds" in err and len(err.strip().splitlines()) == 1


def test_simulate_checks_a_sized_effect_on_the_machine_it_simulates():
    """A sized effect's bounds are the machine's: compliance 50 deg/(N m) is refused on a
    DIWire (0-2), while a 1.5 mm wire's bound is (1.5 / 3)^-3 = 8x larger, so 10 is within
    it there."""
    from cvmeasure.sim.effects import effect_spec_for

    with pytest.raises(ValueError, match="outside its physical bounds"):
        simulate([30.0], SimParams(), [Effect("compliance", 50.0)])
    thin = SimParams().replace(wire_diameter_mm=1.5)
    upper = effect_spec_for("compliance", thin).upper
    assert upper == pytest.approx(8 * effect_spec_for("compliance", None).upper, rel=1e-12)
    res = simulate([30.0, 60.0], thin, [Effect("compliance", 10.0)])
    assert np.all(np.isfinite(res.unloaded_bend_deg))
    with pytest.raises(ValueError, match="outside its physical bounds"):
        simulate([30.0], thin, [Effect("compliance", 1.01 * upper)])
