"""Agreement: seeded synthetic readings whose true bias, spread and variance split are known."""

import json

import numpy as np
import pytest

from cvmeasure.agreement import (
    ManualReading,
    Tolerance,
    agreement,
    bland_altman,
    gauge_rr,
    load_manual,
)
from cvmeasure.cli import main
from cvmeasure.errors import InputError
from cvmeasure.fileio import append_jsonl

BIAS, SD_VISION, SD_REPEAT = 0.30, 0.20, 0.50
READER_OFFSETS = np.array([-0.35, 0.05, 0.40])


def synthetic(n_photos=400, repeats=2, seed=1, slope=0.0, offsets=READER_OFFSETS):
    """Vision = true*(1+slope) + BIAS + noise; manual = true + reader offset + repeat noise."""
    rng = np.random.default_rng(seed)
    true = rng.uniform(10, 150, n_photos)
    vision = true * (1 + slope) + BIAS + rng.normal(0, SD_VISION, n_photos)
    manual = []
    for i, t in enumerate(true):
        for j, off in enumerate(offsets):
            for k in range(repeats):
                value = t + off + rng.normal(0, SD_REPEAT)
                manual.append(ManualReading(f"p{i:04d}.jpg", value, f"r{j}", str(k)))
    return {f"p{i:04d}.jpg": v for i, v in enumerate(vision)}, manual


def test_bland_altman_recovers_bias_and_limits_with_replicates():
    vision, manual = synthetic()
    result = agreement(manual, vision)
    ba = result.bland_altman
    expected_bias = BIAS - READER_OFFSETS.mean()
    # one vision reading vs one manual reading (any reader): vision noise, repeat noise and
    # the spread of the readers' offsets around their mean
    expected_sd = np.sqrt(
        SD_VISION**2 + SD_REPEAT**2 + np.mean((READER_OFFSETS - READER_OFFSETS.mean()) ** 2)
    )
    assert ba.n == 400 and ba.n_readings == 2400
    assert ba.bias_ci_deg[0] < expected_bias < ba.bias_ci_deg[1]
    assert abs(ba.bias_deg - expected_bias) < 0.03
    assert abs(ba.sd_deg - expected_sd) / expected_sd < 0.06
    assert ba.loa_low_deg == pytest.approx(ba.bias_deg - 1.959964 * ba.sd_deg, abs=1e-6)
    assert ba.loa_low_ci_deg[0] < expected_bias - 1.96 * expected_sd < ba.loa_low_ci_deg[1]
    assert ba.loa_high_ci_deg[0] < expected_bias + 1.96 * expected_sd < ba.loa_high_ci_deg[1]
    # about 95 % of single-reading differences fall inside the limits
    diffs = np.array([vision[r.photo] - r.bend_angle_deg for r in manual])
    inside = np.mean((diffs > ba.loa_low_deg) & (diffs < ba.loa_high_deg))
    assert 0.93 < inside < 0.97
    assert not ba.proportional_bias


def test_proportional_bias_is_detected():
    vision, manual = synthetic(n_photos=150, repeats=1, slope=0.01, seed=4)
    ba = agreement(manual, vision).bland_altman
    assert ba.proportional_bias and ba.slope_p < 1e-6
    # d = 0.01*true + ...; against the mean (about true) the slope is about 0.01
    assert ba.slope_ci[0] < 0.01 < ba.slope_ci[1]


def test_gauge_rr_splits_repeatability_and_reproducibility():
    vision, manual = synthetic(n_photos=300, repeats=3, seed=7)
    rr = agreement(manual, vision).manual_rr
    assert (rr.parts, rr.readers, rr.repeats) == (300, 3, 3)
    assert abs(rr.repeatability_sd_deg - SD_REPEAT) / SD_REPEAT < 0.04
    # fixed reader offsets: the ANOVA estimate is their sample SD (ddof 1)
    assert abs(rr.reader_sd_deg - READER_OFFSETS.std(ddof=1)) < 0.05
    assert rr.interaction_sd_deg < 0.1
    part_sd = np.sqrt((150 - 10) ** 2 / 12)  # uniform 10..150 deg
    assert abs(rr.part_sd_deg - part_sd) / part_sd < 0.1
    assert rr.grr_percent < 2 and rr.ndc > 50


def test_gauge_rr_one_reader_and_unbalanced():
    rng = np.random.default_rng(3)
    parts = np.repeat(np.arange(50), 4)
    values = parts * 2.0 + rng.normal(0, 0.3, parts.size)
    rr = gauge_rr(values, parts, ["only"] * parts.size)
    assert abs(rr.repeatability_sd_deg - 0.3) < 0.05 and rr.reproducibility_sd_deg == 0
    assert any("one reader" in n for n in rr.notes)
    with pytest.raises(ValueError, match="balanced"):
        gauge_rr(values[:-1], parts[:-1], ["a", "b"] * 99 + ["a"])


def test_tolerance_verdict_default_and_configured():
    vision, manual = synthetic(n_photos=60, repeats=1, seed=9, offsets=np.array([0.0]))
    res = agreement(manual, vision)
    # bias 0.3 and SD 0.54: limits reach about 1.36 deg, outside +-1 deg
    assert not res.tolerance.loa_within_absolute and res.tolerance.verdict == "outside tolerance"
    loose = agreement(manual, vision, tolerance=Tolerance(relative=None, absolute_deg=3.0))
    assert loose.tolerance.n_within == loose.tolerance.n_pairs == 60
    assert loose.tolerance.verdict == "within tolerance"
    assert loose.tolerance.reason == "all 60 readings and the limits of agreement pass"
    failing = res.tolerance.n_pairs - res.tolerance.n_within
    assert failing > 0  # with limits at ~1.36 deg some single readings exceed 1 deg
    assert res.tolerance.reason == (
        f"{failing} of 60 readings fail the tolerance; "
        "the 95 % limits of agreement exceed the absolute tolerance"
    )
    # 10 % relative on a 5 deg bend is 0.5 deg: a 0.8 deg difference fails only relatively
    tol = Tolerance()
    assert list(tol.within(np.array([0.8, 0.8]), np.array([5.0, 50.0]))) == [False, True]


def test_bland_altman_needs_three_photos():
    with pytest.raises(ValueError, match="at least 3"):
        bland_altman([1.0, 2.0], [[1.0], [2.0]])


def write_inputs(tmp_path, vision, manual, *, extra_vision=()):
    csv = tmp_path / "manual.csv"
    lines = ["photo,bend_angle_deg,reader,repeat"]
    lines += [f"photos/{r.photo},{r.bend_angle_deg:.4f},{r.reader},{r.repeat}" for r in manual]
    csv.write_text("\n".join(lines) + "\n")
    jsonl = tmp_path / "vision.jsonl"
    for name, value in vision.items():
        append_jsonl(jsonl, {"photo": f"/somewhere/{name}", "ok": True, "bend_angle_deg": value})
    for rec in extra_vision:
        append_jsonl(jsonl, rec)
    return csv, jsonl


def test_cli_json_and_plot(tmp_path, capsys):
    vision, manual = synthetic(n_photos=40, repeats=2, seed=12)
    csv, jsonl = write_inputs(
        tmp_path, vision, manual, extra_vision=[{"photo": "x.jpg", "ok": False, "error": "nope"}]
    )
    plot = tmp_path / "ba.png"
    assert main(["agreement", str(csv), str(jsonl), "--json", "--plot", str(plot)]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["n"] == 40 and {"bias_deg", "loa_low_deg", "loa_high_deg"} <= set(out)
    assert abs(out["bias_deg"] - (BIAS - READER_OFFSETS.mean())) < 0.2
    assert out["manual_rr"]["readers"] == 3
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["agreement", str(csv), str(jsonl)]) == 0
    text = capsys.readouterr().out
    assert "limits of agreement" in text and "tolerance" in text


def test_cli_bad_inputs_exit_2(tmp_path, capsys):
    vision, manual = synthetic(n_photos=5, repeats=1, seed=2)
    csv, jsonl = write_inputs(tmp_path, vision, manual)
    bad = tmp_path / "bad.csv"
    bad.write_text("photo,angle\np0000.jpg,3\n")
    assert main(["agreement", str(bad), str(jsonl)]) == 2
    assert "bad.csv: missing column(s) bend_angle_deg" in capsys.readouterr().err
    bad.write_text("photo,bend_angle_deg\np0000.jpg,twelve\n")
    assert main(["agreement", str(bad), str(jsonl)]) == 2
    assert "line 2" in capsys.readouterr().err
    other = tmp_path / "other.csv"
    other.write_text("photo,bend_angle_deg\nzzz.jpg,3\nyyy.jpg,4\nxxx.jpg,5\n")
    assert main(["agreement", str(other), str(jsonl)]) == 2
    assert "other.csv: only 0 photo(s) match" in capsys.readouterr().err
    corrupt = tmp_path / "corrupt.jsonl"
    corrupt.write_text('{"photo": "a.jpg"}\n{oops\n{"photo": "b.jpg"}\n')
    assert main(["agreement", str(csv), str(corrupt)]) == 2
    assert "corrupt.jsonl: corrupt JSON on line 2" in capsys.readouterr().err


def test_load_manual_matches_by_file_name(tmp_path):
    p = tmp_path / "m.csv"
    p.write_text("photo,bend_angle_deg\nsub/dir/a.jpg,12.5\n")
    assert load_manual(p) == [ManualReading("a.jpg", 12.5)]
    p.write_text("photo,bend_angle_deg\n")
    with pytest.raises(InputError, match="no readings"):
        load_manual(p)
