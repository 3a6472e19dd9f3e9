"""Closed-loop correction: repeated parts converge, without oscillation, with a history."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest

from cvmeasure.contracts import Trial
from cvmeasure.driver.session import nominal_pin_for_loaded_deg
from cvmeasure.material.bender_calibration import (
    MODES,
    fit_calibration,
    load_calibration,
    save_calibration,
)
from cvmeasure.material.correct import (
    DEFAULT_GAIN,
    correct_calibration,
    corrected_pin_commands,
    corrections_of,
    job_vertex_offsets,
)
from cvmeasure.sim import Effect, SimParams, simulate


def default_calibration(model="linear"):
    """Calibration of the nominal simulated bender (no hidden effects), high mode, no noise."""
    pins = [nominal_pin_for_loaded_deg(a, d) for d in ("ccw", "cw") for a in MODES["high"]]
    r = simulate(pins)
    samples = [
        Trial(
            trial=str(i),
            commanded_pin_deg=float(p),
            loaded_bend_deg=float(r.loaded_bend_deg[i]),
            unloaded_bend_deg=float(r.unloaded_bend_deg[i]),
            target_deg=float(MODES["high"][i % len(MODES["high"])]),
        )
        for i, p in enumerate(pins)
    ]
    return fit_calibration(samples, model=model)


# a machine the calibration does not know: harder wire, gear play, home error, lost steps
HIDDEN = SimParams(yield_mpa=330.0)
EFFECTS = (Effect("backlash", 1.2), Effect("offset", 0.7), Effect("drift", 0.03))
NOISE_DEG = 0.03


def run_loop(cal, target, parts, *, seed=0, design="job", stated_sigma_deg=NOISE_DEG):
    """Bend ``parts`` parts, correcting after each; true bends of every part (parts, N)."""
    rng = np.random.default_rng(seed)
    made = []
    for _ in range(parts):
        pins = corrected_pin_commands(cal, target, job_vertex_offsets(cal, design, len(target)))
        true = simulate(pins, HIDDEN, EFFECTS).unloaded_bend_deg
        made.append(true)
        measured = true + rng.normal(0.0, NOISE_DEG, len(target))
        cal, _ = correct_calibration(
            cal, target, measured, sigma_deg=np.full(len(target), stated_sigma_deg), design=design
        )
    return cal, np.array(made)


def test_half_circle_converges_within_two_corrections_and_stays():
    target = np.full(20, 9.0)
    _, made = run_loop(default_calibration(), target, 27)
    err = np.abs(made - target)
    assert err[0].max() > 0.8  # the hidden machine is really off
    assert err[2].max() < 0.1  # after 2 corrections
    assert err[6].max() < 0.06  # converged
    # stable: 20 further corrections move no vertex by more than the noise's 95 % range
    assert np.abs(made[7:] - made[6]).max() < 2 * NOISE_DEG


def test_saddle_both_directions_and_mixed_angles():
    rng = np.random.default_rng(3)
    target = np.concatenate([np.full(6, 3.48), np.full(7, -3.48)])
    target = np.concatenate([target, rng.uniform(4, 40, 6) * rng.choice([-1, 1], 6)])
    _, made = run_loop(default_calibration(), target, 4, seed=1)
    assert np.abs(made[2] - target).max() < 0.1


def test_a_bend_in_the_dead_zone_is_reached_within_two_corrections():
    # the seed saddle's profile: 0.9 deg bends next to reversals, less than the machine's
    # backlash plus home offset, so the first part has none at all there
    target = np.array([-7.45, -4.47, -0.91, 2.72, 6.1, 8.36, 8.36, 6.1, 2.72, -0.91, -4.47, -7.45])
    cal, made = run_loop(default_calibration(), target, 3, seed=4)
    assert np.abs(made[0][[2, 9]]).max() < 0.05  # not bent at all
    first = corrections_of(cal)[0]
    assert first["unbent"][2] and first["unbent"][9] and sum(first["unbent"]) == 2
    assert np.abs(made[2] - target).max() < 0.1


def test_a_vertex_left_alone_keeps_its_pin_when_neighbouring_knots_move():
    """Knots moved at 10 and 14 deg change the curve at 12 deg; the job's 12 deg vertex,
    measured right, keeps its pin (its offset takes the interpolation back)."""
    cal = default_calibration()
    target = np.array([10.0, 12.0, 14.0])
    measured = target + np.array([-1.0, 0.0, -1.0])
    cal2, corr = correct_calibration(cal, target, measured, sigma_deg=np.full(3, 0.02))
    assert sorted(u["final_deg"] for u in corr.curve_updates) == [10.0, 14.0]
    before = np.asarray(corrected_pin_commands(cal, target))
    after = np.asarray(corr.pin_deg)
    assert after[1] == pytest.approx(before[1], abs=1e-9)
    # the curve alone (another job) does move at 12 deg
    assert abs(corrected_pin_commands(cal2, [12.0])[0] - before[1]) > 0.3
    # the corrected vertices move by gain * error through the model's slope, once
    slope = np.asarray(corr.model_final_per_pin)
    np.testing.assert_allclose((after - before)[[0, 2]] * slope[[0, 2]], DEFAULT_GAIN, rtol=1e-6)


def test_stated_sigmas_too_small_are_scaled_by_the_jobs_own_scatter():
    target = np.full(10, 12.0)
    # the photo states a third of the true noise: the job's repeats show it
    cal, made = run_loop(default_calibration(), target, 14, seed=5, stated_sigma_deg=0.01)
    factors = [c["noise_factor"] for c in corrections_of(cal)]
    assert factors[0] == 1.0  # no repeats yet
    assert 2.0 < factors[-1] < 4.5
    assert np.abs(made[7:] - made[6]).max() < 2 * NOISE_DEG
    cal, _ = run_loop(default_calibration(), target, 14, seed=5)  # honest sigmas
    assert corrections_of(cal)[-1]["noise_factor"] < 1.5


def _converged_job(target, parts, seed):
    cal, made = run_loop(default_calibration(), target, parts, seed=seed)
    return cal, made[-1]


def test_a_measurement_outlier_moves_no_pin_and_a_real_jump_is_followed():
    target = np.full(8, 15.0)
    cal, made = _converged_job(target, 8, seed=6)
    sig = np.full(8, NOISE_DEG)
    pins = corrected_pin_commands(cal, target, job_vertex_offsets(cal, "job", 8))
    rng = np.random.default_rng(7)
    # one photo measures vertex 3 1.5 deg off (its stated sigma normal): nothing moves
    measured = made + rng.normal(0.0, NOISE_DEG, 8)
    measured[3] += 1.5
    cal2, corr = correct_calibration(cal, target, measured, sigma_deg=sig, design="job")
    assert corr.suspect[3] and sum(corr.suspect) == 1
    assert corr.pin_deg == pytest.approx(pins, abs=0.05)  # the outlier would move it 1.35
    # the next part measures right: still nothing moves
    cal3, corr = correct_calibration(
        cal2, target, made + rng.normal(0.0, NOISE_DEG, 8), sigma_deg=sig, design="job"
    )
    assert not any(corr.suspect)
    assert corr.pin_deg == pytest.approx(pins, abs=0.05)  # the outlier would move it 1.35
    # a real jump of 0.5 deg at vertex 3, seen twice running: followed at the second part
    shifted = made.copy()
    shifted[3] -= 0.5
    cal4, corr = correct_calibration(
        cal3, target, shifted + rng.normal(0.0, NOISE_DEG, 8), sigma_deg=sig, design="job"
    )
    assert corr.suspect[3] and corr.pin_deg[3] == pytest.approx(pins[3], abs=0.05)
    _, corr = correct_calibration(
        cal4, target, shifted + rng.normal(0.0, NOISE_DEG, 8), sigma_deg=sig, design="job"
    )
    assert not corr.suspect[3]
    assert abs(corr.pin_deg[3]) > abs(pins[3]) + 0.3


def test_no_oscillation_error_shrinks_monotonically():
    target = np.full(12, 20.0)
    _, made = run_loop(default_calibration(), target, 4, seed=2)
    err = made - target
    big = np.abs(err[0]) > 5 * NOISE_DEG
    # every vertex approaches its target from the same side (no sign change beyond noise)
    assert np.all(np.sign(err[1][big]) * np.sign(err[0][big]) >= 0) or np.all(
        np.abs(err[1][big]) < 3 * NOISE_DEG
    )
    assert np.all(np.abs(err[1]) < np.abs(err[0]) + 3 * NOISE_DEG)


def test_history_round_trips_through_the_file(tmp_path):
    target = np.full(5, 30.0)
    cal, _ = run_loop(default_calibration(), target, 2, design="bracket.svg")
    history = corrections_of(cal)
    assert [c["design"] for c in history] == ["bracket.svg", "bracket.svg"]
    assert history[0]["curve_updates"][0]["direction"] == "ccw"
    assert history[0]["max_abs_error_deg"] > 0.5
    save_calibration(tmp_path / "cal2.json", cal)
    again = load_calibration(tmp_path / "cal2.json")
    assert corrections_of(again) == history
    np.testing.assert_allclose(
        job_vertex_offsets(again, "bracket.svg", 5), history[-1]["vertex_offset_deg"]
    )
    assert corrected_pin_commands(again, target, job_vertex_offsets(again, "bracket.svg", 5)) == (
        pytest.approx(
            corrected_pin_commands(cal, target, job_vertex_offsets(cal, "bracket.svg", 5))
        )
    )


def test_noise_only_errors_are_left_alone():
    cal = default_calibration()
    target = np.full(8, 15.0)
    measured = target + np.array([0.01, -0.02, 0.015, 0.0, -0.01, 0.02, -0.015, 0.005])
    cal2, corr = correct_calibration(cal, target, measured, sigma_deg=np.full(8, 0.02))
    assert corr.curve_updates == ()
    assert np.all(np.asarray(corr.vertex_offset_deg) == 0)
    assert corrected_pin_commands(cal2, target) == corrected_pin_commands(cal, target)


def test_a_reading_within_its_uncertainty_is_no_worst_error():
    """A vertex read 9.887 deg off at sigma 21 deg (a chord the photo did not show) lies
    within its dead band: the worst error quoted is the worst of the vertices read at
    0.02-0.05 deg beyond theirs, and the wide one is named apart. The band is the first
    look's 4 sigma; on the job's next part, at a pin that did not move, the pooled mean's
    2.5 sigma of the two parts' pooled sigma."""
    cal = default_calibration()
    target = np.full(6, 15.0)
    measured = target + np.array([0.3, -0.412, 0.05, 9.887, 0.25, -0.1])
    sigma = np.array([0.02, 0.02, 0.02, 21.0, 0.02, 0.05])
    cal2, corr = correct_calibration(cal, target, measured, sigma_deg=sigma, design="job")
    np.testing.assert_allclose(corr.band_deg, 4.0 * sigma, rtol=0, atol=1e-9)
    assert corr.within_band == (False, False, True, True, False, True)
    error = measured - target
    assert corr.resolved_max_abs_error_deg == np.abs(error[[0, 1, 4]]).max()
    assert corr.max_abs_error_deg == np.abs(error[3])  # the JSON's figure is unchanged
    assert corr.unresolved_vertices == (3,)
    assert corr.error_summary() == (
        "worst error 0.412 deg (1 more within their stated uncertainty, up to 9.887 deg at "
        "vertex 3, sigma 21.000 deg)"
    )
    record = corrections_of(cal2)[-1]
    assert record["band_deg"] == list(corr.band_deg)
    assert record["within_band"] == list(corr.within_band)
    # the next part, read the same: vertices 0, 1 and 4 were moved (a first look again),
    # 2, 3 and 5 kept their pins and pool two parts of equal sigmas
    _, corr = correct_calibration(cal2, target, measured, sigma_deg=sigma, design="job")
    pooled = corr.deadband_sigma * sigma / np.sqrt(2.0)
    band = np.where([False, False, True, True, False, True], pooled, 4.0 * sigma)
    np.testing.assert_allclose(corr.band_deg, band, rtol=0, atol=1e-9)
    assert corr.within_band == (False, False, False, True, False, False)
    assert corr.resolved_max_abs_error_deg == np.abs(error[[0, 1, 2, 4, 5]]).max()


def test_every_error_within_its_uncertainty_is_said_so():
    cal = default_calibration()
    target = np.full(4, 15.0)
    measured = target + np.array([0.01, -0.03, 0.02, 0.0])
    _, corr = correct_calibration(cal, target, measured, sigma_deg=np.full(4, 0.02))
    assert all(corr.within_band) and corr.resolved_max_abs_error_deg is None
    assert corr.unresolved_vertices == (1, 2, 0, 3)
    assert corr.error_summary(2, name_vertex=False) == (
        "every error within its stated uncertainty (up to 0.03 deg at sigma 0.02 deg)"
    )


def test_bad_arguments():
    cal = default_calibration()
    with pytest.raises(ValueError, match="gain"):
        correct_calibration(cal, [10.0], [10.5], gain=1.5)
    with pytest.raises(ValueError, match="measured"):
        correct_calibration(cal, [10.0, 12.0], [10.5])
    with pytest.raises(ValueError, match="refit"):
        correct_calibration(default_calibration("cubic"), [10.0], [10.5])


def _feeds(job_text):
    """The feed lengths (text after ``Y``) of a job's G-code, in order."""
    return [ln.split("Y")[1].split()[0] for ln in job_text.splitlines() if " Y" in ln]


def _photo_of_bent_part(tmp_path, chords, made_deg, board, seed):
    """A rendered JPEG of ``chords`` (N+1, 2; mm) bent by ``made_deg`` (N-1 machine bends)
    beside ``board``; its camera and board JSON written beside it. Returns the JPEG path."""
    import cvmeasure_datasets
    from cvmeasure.camera_model import save_camera
    from cvmeasure.fileio import atomic_write_json

    # the bent wire: fed from the first point, turning by minus each machine bend
    lengths = np.hypot(*np.diff(chords, axis=0).T)
    heading = np.concatenate([[0.0], np.cumsum(-np.radians(made_deg))])
    pts = np.vstack(
        [[0.0, 0.0], np.cumsum(lengths[:, None] * np.c_[np.cos(heading), np.sin(heading)], axis=0)]
    )
    # lying design face up (the board frame has y down, the design y up)
    photo = cvmeasure_datasets.render_part_photo(
        part=pts * np.array([1.0, -1.0]), board=board, seed=seed, scale=0.5
    )
    jpg, _ = photo.save(tmp_path / "part")
    save_camera(tmp_path / "camera.json", photo.camera)
    atomic_write_json(tmp_path / "board.json", board.to_dict())
    return jpg


def test_cli_corrects_from_a_rendered_part_photo(tmp_path, capsys, arc_svg):
    """`cvmeasure correct` on a JPEG of a part the hidden machine bent: errors seen, job moved."""
    import json

    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.cli import main
    from cvmeasure.design import load_design
    from cvmeasure.material.correct_part import target_bends_deg

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    design = arc_svg(tmp_path / "arc.svg", 55.0, 15.0, 165.0)
    chords = load_design(design).wire().chords(10)
    target = target_bends_deg(chords)
    cal = default_calibration()
    pins = corrected_pin_commands(cal, target)
    made = simulate(pins, HIDDEN, EFFECTS).unloaded_bend_deg
    jpg = _photo_of_bent_part(tmp_path, chords, made, board, seed=3)
    save_calibration(tmp_path / "cal.json", cal)
    # bent as `cvmeasure gcode arc.svg --divisions 10`: the same option plans the same polygon
    common = ["--design", str(design), "--divisions", "10"]
    common += ["--material", str(tmp_path / "cal.json")]
    common += ["--board", str(tmp_path / "board.json"), "--camera", str(tmp_path / "camera.json")]
    out = ["-o", str(tmp_path / "cal2.json"), "--gcode", str(tmp_path / "job2.gcode")]
    assert main(["correct", str(jpg), *common, *out, "--json"]) == 0
    corr = json.loads(capsys.readouterr().out)
    np.testing.assert_allclose(corr["error_deg"], made - target, atol=0.1)
    assert max(abs(e) for e in corr["error_deg"]) > 0.5
    cal2 = load_calibration(tmp_path / "cal2.json")
    assert corrections_of(cal2)[-1]["part"] == str(jpg)
    # the part's warnings travel with the correction, as `cvmeasure part` gives them
    part_args = ["--design", str(design), "--divisions", "10", *common[6:]]
    assert main(["part", str(jpg), *part_args, "--json"]) == 0
    part_warnings = json.loads(capsys.readouterr().out)["warnings"]
    assert part_warnings  # (a flat render still warns: the lift is not measured)
    assert corr["warnings"] == part_warnings
    assert corrections_of(cal2)[-1]["warnings"] == part_warnings
    # the machine under-bends: every corrected pin goes further
    new_pins = corr["pin_deg"]
    assert all(abs(n) > abs(p) for n, p in zip(new_pins, pins, strict=True))
    assert (tmp_path / "job2.gcode").read_text().count("G90 G1 X") == 9
    # the job the part was bent with sets the chord count; a file that is no job: exit 2
    (tmp_path / "job.gcode").write_text(
        "".join(f"N{i} G90 G1 X{p:.3f} F6000\n" for i, p in enumerate(pins))
    )
    assert main(["correct", str(jpg), *common, *out, "--job", str(tmp_path / "job.gcode")]) == 0
    (tmp_path / "other.gcode").write_text("N1 G0 Z0\n")
    code = main(["correct", str(jpg), *common, *out, "--job", str(tmp_path / "other.gcode")])
    assert code == 2
    assert "other.gcode" in capsys.readouterr().err


def test_a_part_registered_end_to_end_reversed_is_turned_back_by_the_job():
    from cvmeasure.material.correct_part import orient_to_job

    # random 21 of the closed-loop benchmark: nearly symmetric end to end, 2.4 deg off
    target = np.array([18.719, -5.63, -7.953, 4.169, 8.621, -3.111, 3.848, -17.8])
    made = target + np.array([-2.343, -0.296, -0.266, -2.288, -2.372, -0.155, -2.388, -0.096])
    sigma = np.linspace(0.01, 0.02, 8)
    measured, sig, turned = orient_to_job(target, -made[::-1], sigma)
    assert turned
    np.testing.assert_allclose(measured, made)
    np.testing.assert_allclose(sig, sigma[::-1])
    # registered right: kept; a design whose reversed reading is itself (both readings
    # equally far from the job): the registration's choice is kept
    assert not orient_to_job(target, made, sigma)[2]
    sym = np.array([5.0, 3.0, -3.0, -5.0])
    assert not orient_to_job(sym, sym + 0.3, sigma[:4])[2]


def test_a_group_mean_is_not_forced_on_a_member_whose_reading_disagrees():
    """Seven vertices of one wanted angle bent 0.3 deg over, the eighth right: the group's
    mean (0.26) corrects the curve, but the eighth, read right within its noise, keeps
    its pin (giving it the mean would bend it 0.23 deg under)."""
    cal = default_calibration()
    target = np.full(8, 15.0)
    truth = target + np.array([0.0, *[0.3] * 7])
    measured = truth + np.array([-0.02, 0.01, -0.01, 0.0, 0.02, -0.01, 0.01, 0.0])
    _, corr = correct_calibration(cal, target, measured, sigma_deg=np.full(8, 0.02))
    before = np.asarray(corrected_pin_commands(cal, target))
    moved_final = (np.asarray(corr.pin_deg) - before) * np.asarray(corr.model_final_per_pin)
    assert moved_final[0] == pytest.approx(0.0, abs=1e-9)
    # the others are corrected by the gain times their own (first-look, unshrunk) error
    np.testing.assert_allclose(moved_final[1:], -DEFAULT_GAIN * (measured - target)[1:], rtol=1e-6)


def test_a_settled_job_is_not_walked_about_by_noise():
    """After convergence, part-to-part changes stay within the noise's 2-sigma range.

    A pooled mean just past its dead band is corrected only by what it shows beyond its
    uncertainty; corrected whole, such noise-driven moves walked vertices by 0.077-0.086
    deg between consecutive parts on these seeds (noise sigma 0.03 deg)."""
    target = np.array([-7.45, -4.47, -0.91, 2.72, 6.1, 8.36, 8.36, 6.1, 2.72, -0.91, -4.47, -7.45])
    for seed in (0, 1, 3):
        _, made = run_loop(default_calibration(), target, 23, seed=seed)
        assert np.abs(made[2] - target).max() < 0.11  # converged after 2 corrections
        walk = np.abs(np.diff(made[3:], axis=0)).max()
        assert walk < 2 * NOISE_DEG, (seed, walk)


def test_cli_correct_measures_a_round_wire_as_part_does(tmp_path, capsys):
    """With ``--wire-diameter-mm`` the part is measured as ``cvmeasure part`` measures it
    (between the round wire's silhouette edges, its lift bounded): the same warnings, and
    the errors corrected those of the same reading (within 0.01 deg)."""
    import json

    import cvmeasure_datasets
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.camera_model import save_camera
    from cvmeasure.cli import main
    from cvmeasure.fileio import atomic_write_json
    from cvmeasure_datasets.effects import SceneEffects

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    part = cvmeasure_datasets.arc_part(55.0, 120.0, 8, wire_diameter_mm=3.0)
    photo = cvmeasure_datasets.render_part_photo(
        part=part, board=board, seed=4, scale=0.5, effects=SceneEffects(wire_3d=True)
    )
    jpg, _ = photo.save(tmp_path / "part")
    save_camera(tmp_path / "camera.json", photo.camera)
    atomic_write_json(tmp_path / "board.json", board.to_dict())
    save_calibration(tmp_path / "cal.json", default_calibration())
    pts = " ".join(f"{x:.4f},{-y:.4f}" for x, y in part.vertices_mm[:, :2])  # the design
    design = tmp_path / "arc.svg"
    design.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="400mm" height="400mm" '
        f'viewBox="-200 -200 400 400"><polyline fill="none" points="{pts}"/></svg>',
        encoding="utf-8",
    )
    seen = ["--board", str(tmp_path / "board.json"), "--camera", str(tmp_path / "camera.json")]
    wire = ["--design", str(design), "--divisions", "8", "--wire-diameter-mm", "3"]
    assert main(["part", str(jpg), *seen, *wire, "--json"]) == 0
    measured = json.loads(capsys.readouterr().out)
    out = ["-o", str(tmp_path / "cal2.json"), "--gcode", str(tmp_path / "job2.gcode")]
    material = ["--material", str(tmp_path / "cal.json")]
    assert main(["correct", str(jpg), *seen, *wire, *material, *out, "--json"]) == 0
    corr = json.loads(capsys.readouterr().out)
    assert corr["warnings"] == measured["warnings"]
    assert any(w["code"] == "part_lifted" for w in corr["warnings"])  # read as a round wire
    errors = sorted(abs(e) for e in measured["comparison"]["bends"]["error_deg"])
    np.testing.assert_allclose(sorted(abs(e) for e in corr["error_deg"]), errors, atol=0.01)


def test_cli_correct_feeds_the_next_job_by_the_jobs_rules(tmp_path, capsys, arc_svg):
    """A design bent in chords under the default 12 mm (`gcode --min-segment-mm 10`) about
    a 10 mm bend radius is corrected with the same options: the next job feeds the same
    lengths as the first and only its pins move (it was planned with the defaults: refused
    for its 10.5 mm chords, and without the radius' setback its feeds would differ)."""
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.cli import main
    from cvmeasure.design import load_design
    from cvmeasure.material.correct_part import target_bends_deg

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    design = arc_svg(tmp_path / "arc.svg", 50.0, 30.0, 150.0)
    chords = load_design(design).wire().chords(10)  # 10.5 mm each
    lengths = np.hypot(*np.diff(chords, axis=0).T)
    assert 10.0 < lengths.min() and lengths.max() < 12.0
    cal = default_calibration()
    save_calibration(tmp_path / "cal.json", cal)
    rules = ["--divisions", "10", "--min-segment-mm", "10", "--bend-radius-mm", "10"]
    plan = ["--design", str(design), *rules]
    job, flat = tmp_path / "job.gcode", tmp_path / "flat.gcode"
    cal_arg = ["--material", str(tmp_path / "cal.json")]
    assert main(["gcode", str(design), *rules, *cal_arg, "-o", str(job)]) == 0
    assert main(["gcode", str(design), *rules[:4], *cal_arg, "-o", str(flat)]) == 0
    made = simulate(corrected_pin_commands(cal, target_bends_deg(chords)), HIDDEN, EFFECTS)
    jpg = _photo_of_bent_part(tmp_path, chords, made.unloaded_bend_deg, board, seed=4)
    capsys.readouterr()
    seen = ["--board", str(tmp_path / "board.json"), "--camera", str(tmp_path / "camera.json")]
    out = ["-o", str(tmp_path / "cal2.json"), "--gcode", str(tmp_path / "job2.gcode")]
    material = ["--material", str(tmp_path / "cal.json"), "--job", str(job)]
    assert main(["correct", str(jpg), *plan, *material, *seen, *out]) == 0, capsys.readouterr().err

    def feeds(path):
        return _feeds(path.read_text())

    assert feeds(tmp_path / "job2.gcode") == feeds(job)
    assert len(feeds(job)) >= 10
    assert feeds(flat) != feeds(job)  # the radius' setback shows in the feeds


def test_the_api_chain_bends_measures_and_corrects_one_polygon(tmp_path, capsys, arc_svg):
    """``gcode_for -> save -> measure_part(job=) -> correct`` as the CLI chain: a design
    bent in chords under the default 12 mm is compared and corrected against the polygon
    ``gcode_for`` bent. The saved job keeps that polygon in its header, so ``cvmeasure part
    --job`` reads it without the options (it had none: the design's default plan was
    refused); the part is measured in the plan's chord count; the next job feeds the
    first's lengths and keeps the polygon too."""
    import cvmeasure
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.cli import main
    from cvmeasure.design import bend_angles_deg, chord_lengths_mm, load_design
    from cvmeasure.errors import InputError
    from cvmeasure.material.correct_part import target_bends_deg
    from cvmeasure.part.result import DivisionsSource
    from cvmeasure.wireplan import plan_from_job

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    design = arc_svg(tmp_path / "arc.svg", 50.0, 30.0, 150.0)
    chords = load_design(design).wire().chords(10)  # 10.5 mm each
    cal = default_calibration()
    rules = {"min_segment_mm": 10.0, "bend_radius_mm": 10.0}
    job = cvmeasure.gcode_for(design, cal, divisions=10, **rules)
    cvmeasure.save(tmp_path / "job.gcode", job)
    made = simulate(corrected_pin_commands(cal, target_bends_deg(chords)), HIDDEN, EFFECTS)
    jpg = _photo_of_bent_part(tmp_path, chords, made.unloaded_bend_deg, board, seed=4)
    seen = {"board": tmp_path / "board.json", "camera": tmp_path / "camera.json"}

    def same_polygon(a, b):  # chord lengths and turns: the header's polygon has its own frame
        np.testing.assert_allclose(chord_lengths_mm(a), chord_lengths_mm(b), atol=1e-3)
        np.testing.assert_allclose(bend_angles_deg(a), bend_angles_deg(b), atol=1e-3)

    # measured with the defaults, the symmetric arc's mirror image read backwards fits as
    # well: its vertices would be corrected in reverse order, so that is refused
    loose = cvmeasure.measure_part(jpg, **seen, design=design, job=tmp_path / "job.gcode")
    assert loose.comparison.registration.mirrored
    with pytest.raises(InputError, match="mirrored"):
        cvmeasure.correct(loose, design, cal, **rules)
    # as it left the machine
    as_bent = cvmeasure.PartOptions(allow_mirror=False)
    part = cvmeasure.measure_part(
        jpg, **seen, design=design, job=tmp_path / "job.gcode", options=as_bent
    )
    assert part.divisions_from is DivisionsSource.PLAN
    same_polygon(part.comparison.polygon_mm, chords)
    # without the job, the same rules plan the same polygon
    again = cvmeasure.measure_part(
        jpg, **seen, design=design, options=replace(as_bent, divisions=10), min_segment_mm=10.0,
    )  # fmt: skip
    same_polygon(again.comparison.polygon_mm, chords)
    fixed = cvmeasure.correct(part, design, cal, **rules)
    target = target_bends_deg(chords)
    np.testing.assert_allclose(
        fixed.correction.error_deg, made.unloaded_bend_deg - target, atol=0.1
    )

    assert _feeds(fixed.job.text()) == _feeds(job.text())
    same_polygon(plan_from_job(fixed.job.text(), "next").vertices_mm, chords)
    # the CLI reads the API's job: the polygon from its header, no options repeated
    args = ["--board", str(seen["board"]), "--camera", str(seen["camera"]), "--json"]
    capsys.readouterr()
    code = main(
        ["part", str(jpg), "--design", str(design), "--job", str(tmp_path / "job.gcode"), *args]
    )
    assert code == 0, capsys.readouterr().err
    record = json.loads(capsys.readouterr().out)
    assert record["divisions"] == 10
