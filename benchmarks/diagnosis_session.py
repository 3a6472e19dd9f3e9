"""The operator's chain: calibration session -> diagnose -> follow-up -> diagnose (issue 37).

The data a user has is the calibration session. Every case is a default-mode session's
plan (``SessionConfig(mode).plan()``, quick / standard / high; the commands as the
session sends them) bent on a machine with one cause hidden (or none), measured with
noise of 0.02-0.1 deg per angle (loaded, released and the pin on the loaded photo), and
diagnosed with the defaults. A reported tie holding the truth is given its follow-up
plan, bent on the same machine after the session, appended and diagnosed again: named
right then counts as named right (the issue's score after that round).

Machines (generators):

- ``sim``: :mod:`cvmeasure.sim` with the machine's strength and die radius drawn off the
  datasheet and the cause's general form drawn (the model the diagnosis fits);
- ``physical``: ``cvmeasure_datasets.physical_bender``, the project's independent model
  (it imports nothing from :mod:`cvmeasure.sim`), with its outside-catalogue mechanisms;
- ``heldout``: ``benchmarks/heldout/bender_physics.py``, written outside the project from
  the physics and the seed paper without reading the diagnosis (when present).

The trials are made by the machine models directly (a session with ``--simulate``
renders 88 photos); one documented end-to-end process chain per mode (``cvmeasure
session --simulate`` -> ``cvmeasure fit`` -> ``cvmeasure diagnose --follow-up-csv``) is
run too (``--chain``), and its result reported.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from benchmarks import Metric, Table, finish
from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import Cause, Diagnosis, diagnose
from cvmeasure.driver.plan import swept_plan
from cvmeasure.driver.session import SessionConfig, nominal_pin_for_loaded_deg
from cvmeasure.material.bender_calibration import MODES
from cvmeasure.sim import EFFECTS, Effect, SimParams, params_from_json, params_to_json, simulate
from cvmeasure_datasets import physical_bender as pb

SECTION = "Diagnosis on the calibration session (issue 37)"
SEED0 = 3_700_000
MODES_RUN: tuple[str, ...] = ("quick", "standard", "high")
CATALOGUE: tuple[str, ...] = pb.CATALOGUE
OUTSIDE: tuple[str, ...] = pb.OUTSIDE
NOISE_RANGE_DEG = (0.02, 0.1)
#: The follow-up's noise has its own stream: the case's seed plus this.
FOLLOW_UP_SEED_OFFSET = 5_000_000
#: The coverage sample's extra machines (beyond the main sample's ``--reps``) start here.
SEED_COVERAGE = 3_800_000
#: The dead zone's spread over machines (deg, one standard deviation) in the coverage
#: sample drawn again with it varied: the tolerance the diagnosis states and carries
#: (:data:`cvmeasure.diagnose.fitting.UNFITTED_PRIOR_SD`: the home switch's repeatability
#: and placement, the pin's, the orbit's and the wire's tolerances). The sim generator
#: otherwise builds every machine with the nominal dead zone, which no machine has and
#: which the intervals do not assume (they carry its tolerance), so there they hold the
#: truth more often than 95 % by construction.
DEAD_ZONE_SD_DEG = 0.25
#: Causes whose generator form can mean the same as the fitted parameter (an interval
#: scored against the truth: :func:`_sim_effect`); the coverage sample draws more of them.
COVERAGE_CAUSES: tuple[str, ...] = (
    "backlash",
    "offset",
    "scale",
    "springback_asymmetry",
    "axis_offset",
    "compliance",
)
#: The machines diagnosed under two params descriptions start here.
SEED_DESCRIPTIONS = 3_900_000
#: The no-effect session a description is fitted from has its own noise stream.
NO_EFFECT_SEED_OFFSET = 6_000_000
#: A hidden cause whose whole noise-free signal on the session is below this (sum over
#: every reading of (change / noise)^2, the chi-square 1-dof 95 % point) is below the
#: session's detection limit: even a test that knew its exact shape would find it less
#: than half the time, so the honest answer is "no effect" (or the cause itself).
DETECTION_CHI2 = 3.84
DETECTION_NOTE = (
    "below the detection limit: a hidden catalogue cause whose whole noise-free signal on "
    f"the session (sum over every reading of (change / noise)^2) is below {DETECTION_CHI2} "
    "is scored named right when no effect is named (the honest reading of a session that "
    "does not show it), as well as when it is named; it is still counted as a case (a "
    "mechanism outside the catalogue below it is scored flagged when nothing is named)"
)


def session_commands(mode: str, *, swept: bool = False) -> np.ndarray:
    """Signed pin commands (deg) of a default session in ``mode``, as the session sends
    them (the nominal model's inverse for the wanted loaded angle, rounded to 0.001);
    ``swept``: the former plan (every angle ccw rising, then cw)."""
    plan = swept_plan(MODES[mode]) if swept else SessionConfig(mode=mode).plan()
    return np.array([round(nominal_pin_for_loaded_deg(a, d), 3) for d, a in plan])


@dataclass(frozen=True)
class Case:
    """One machine and session: what was hidden and the measured trials."""

    generator: str
    mode: str
    seed: int
    name: str  # hidden mechanism ("none": nothing)
    truth: float | None  # the fitted parameter's true value, when it means the same
    noise_deg: float
    trials: TrialTable
    machine: object  # the generator's machine (SimParams + effects, or a pb case)
    #: the hidden cause's whole signal on the session, sum over every reading of
    #: (its noise-free change / noise)^2 (None: not computed for this generator)
    signal_chi2: float | None = None


def _noisy(rng: np.random.Generator, noise: float, *columns: np.ndarray) -> list[np.ndarray]:
    """Each column with noise ``noise`` (deg); loaded and released share 30-70 % of it."""
    shared = float(rng.uniform(0.3, 0.7))
    n = columns[0].size
    common = rng.normal(0.0, noise * math.sqrt(shared), n)
    own = noise * math.sqrt(1.0 - shared)
    out = [c + common + rng.normal(0.0, own, n) for c in columns[:2]]
    out += [c + rng.normal(0.0, noise, n) for c in columns[2:]]
    return out


def _sim_effect(rng: np.random.Generator, name: str) -> tuple[Effect, float | None]:
    """A catalogue cause of typical size, its general form drawn like the independent
    model's; the truth is None where the form changes the parameter's meaning."""
    spec = EFFECTS[name]
    lo, hi = spec.typical
    value = float(rng.uniform(lo, hi))
    if spec.signed:
        value *= float(rng.choice([-1.0, 1.0]))
    shape: dict[str, float] = {}
    truth: float | None = value
    if name == "backlash":
        shape["same_direction_share"] = float(rng.choice([0.0, 1.0]))
        truth = value if shape["same_direction_share"] == 1.0 else None
    elif name == "drift":
        shape = {"home_shift": 1.0, "load_exponent": float(rng.choice([0.0, 1.0]))}
        truth = None
    elif name == "camera_tilt":
        shape["tilt_axis_deg"] = float(rng.uniform(-90.0, 90.0))
        truth = None
    return Effect(name, value, tuple(shape.items())), truth


def _sim_case(seed: int, name: str, mode: str, swept: bool, dead_zone_sd_deg: float) -> Case:
    rng = np.random.default_rng(seed)
    params = SimParams().replace(
        yield_mpa=float(rng.uniform(250.0, 320.0)),
        die_radius_mm=float(rng.uniform(1.3, 1.8)),
    )
    params = params.replace(uts_mpa=params.yield_mpa * 400.0 / 280.0)
    if dead_zone_sd_deg > 0:
        # a stream of its own: the same machine, cause and noise otherwise
        shift = float(np.random.default_rng([seed, 1]).normal(0.0, dead_zone_sd_deg))
        params = params.replace(approach_deg=params.approach_deg + shift)
    effects: tuple[Effect, ...] = ()
    truth = None
    if name != "none":
        effect, truth = _sim_effect(rng, name)
        effects = (effect,)
    noise = float(rng.uniform(*NOISE_RANGE_DEG))
    cmd = session_commands(mode, swept=swept)
    res = simulate(cmd, params, effects)
    loaded, unloaded, pin = _noisy(
        rng, noise, res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg
    )
    trials = TrialTable.from_arrays(cmd, loaded, unloaded, measured_pin_deg=pin, source="sim")
    chi2 = None
    if effects:
        ref = simulate(cmd, params, ())
        change = [
            a - b
            for a, b in zip(
                (res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg),
                (ref.loaded_bend_deg, ref.unloaded_bend_deg, ref.pin_angle_deg),
                strict=True,
            )
        ]
        chi2 = _signal_chi2(change, noise)
    return Case("sim", mode, seed, name, truth, noise, trials, (params, effects), chi2)


def _signal_chi2(change: list[np.ndarray], noise: float) -> float:
    """A hidden cause's whole noise-free signal on the session (:data:`DETECTION_CHI2`):
    the sum over every reading of (its change / noise)^2."""
    return float(sum(np.nansum((np.asarray(c) / noise) ** 2) for c in change))


def _pb_truth(hidden: pb.Hidden) -> float | None:
    if hidden.name not in ("offset", "scale", "backlash", "axis_offset", "compliance"):
        return None
    if hidden.name == "backlash" and hidden.params.get("same_direction_share", 1.0) != 1.0:
        return None
    return hidden.params[EFFECTS[hidden.name].param]


def _pb_case(seed: int, name: str, mode: str, swept: bool) -> Case:
    rng = np.random.default_rng(seed)
    machine = pb.draw_machine(rng)
    hidden = () if name == "none" else (pb.draw_hidden(rng, name),)
    noise = float(rng.uniform(*NOISE_RANGE_DEG))
    cmd = session_commands(mode, swept=swept)
    true = pb.bend(cmd, machine, hidden, rng)
    loaded, unloaded, pin = _noisy(
        rng,
        noise,
        true.loaded_deg,
        true.unloaded_deg,
        pb.loaded_pin_deg(machine, true.head_deg, hidden),
    )
    trials = TrialTable.from_arrays(cmd, loaded, unloaded, measured_pin_deg=pin, source="physical")
    truth = _pb_truth(hidden[0]) if hidden else None
    chi2 = None
    if hidden:  # the mean machine (scatter at its mean) with and without the mechanism
        on, off = pb.bend(cmd, machine, hidden), pb.bend(cmd, machine)
        change = [
            on.loaded_deg - off.loaded_deg,
            on.unloaded_deg - off.unloaded_deg,
            pb.loaded_pin_deg(machine, on.head_deg, hidden)
            - pb.loaded_pin_deg(machine, off.head_deg),
        ]
        chi2 = _signal_chi2(change, noise)
    return Case("physical", mode, seed, name, truth, noise, trials, (machine, hidden), chi2)


#: The held-out model's mechanisms outside the catalogue that act on a session's bends
#: (feed slip acts on parts only), each with a range of sizes chosen from its physics
#: before any diagnosis was run on it.
HELDOUT_OUTSIDE: dict[str, tuple[str, float, float]] = {
    "step_loss": ("step_loss_deg", 0.36, 0.72),  # one or two whole head steps per big bend
    "coil_set": ("coil_set_per_m", 1.0, 3.0),
    "thermal_softening": ("thermal_softening", 0.05, 0.15),
    "die_radius_error": ("die_radius_error_mm", 0.3, 0.6),
    "orbit_eccentricity": ("orbit_eccentricity_mm", 0.1, 0.3),
    "gear_runout": ("gear_runout_deg", 0.6, 1.5),
}
#: Held-out mechanisms that are a catalogue cause's general form, scored as that cause
#: (its truth None: the form changes the parameter's meaning): whole head steps lost under
#: load, shifting home, are the catalogue's drift in its general form (steps lost whole,
#: growing with the pin torque, shifting home: :mod:`cvmeasure.sim.effects`), as the
#: independent model's drift is that mechanism and is scored so.
GENERAL_FORMS: dict[str, str] = {"step_loss": "drift"}
#: The held-out model's field of each catalogue cause (contract meaning and units).
_HELDOUT_FIELD = {
    "backlash": "backlash_deg",
    "offset": "offset_deg",
    "scale": "scale",
    "drift": "drift_deg",
    "springback_asymmetry": "springback_asymmetry",
    "camera_tilt": "camera_tilt_deg",
    "axis_offset": "axis_offset_mm",
    "compliance": "compliance_deg_per_nm",
}


def _heldout_rows(cmd: np.ndarray, machine: object, noise: float, seed: int) -> TrialTable:
    from benchmarks.heldout import bender_physics as hb

    effects, _ = machine
    rows = hb.simulate_trials(cmd, "diwire", effects, noise, seed)
    return TrialTable.from_arrays(
        cmd,
        [r.loaded_bend_deg for r in rows],
        [r.unloaded_bend_deg for r in rows],
        measured_pin_deg=[r.measured_pin_deg for r in rows],
        source="heldout",
    )


def _heldout_case(seed: int, name: str, mode: str, swept: bool) -> Case:
    """A DIWire of the held-out model (``benchmarks/heldout``) with the cause drawn at a
    typical size; the noise is the model's own (each reading independent)."""
    from benchmarks.heldout.machine import Effects

    rng = np.random.default_rng(seed)
    values: dict[str, float] = {}
    truth: float | None = None
    if name in _HELDOUT_FIELD:
        effect, truth = _sim_effect(rng, name)
        values[_HELDOUT_FIELD[name]] = effect.value
        if name == "camera_tilt":
            values["tilt_axis_deg"] = dict(effect.shape)["tilt_axis_deg"]
        if name == "backlash":
            truth = effect.value  # the model loses it on every bend (the release reverses)
        if name == "springback_asymmetry":
            truth = None  # a back stress: the realised asymmetry differs from the share
    elif name in HELDOUT_OUTSIDE:
        key, lo, hi = HELDOUT_OUTSIDE[name]
        values[key] = float(rng.uniform(lo, hi))
    noise = float(rng.uniform(*NOISE_RANGE_DEG))
    cmd = session_commands(mode, swept=swept)
    machine = (Effects(**values), seed)
    trials = _heldout_rows(cmd, machine, noise, seed)
    chi2 = _heldout_signal_chi2(cmd, machine[0], noise) if values else None
    return Case("heldout", mode, seed, name, truth, noise, trials, machine, chi2)


def _heldout_signal_chi2(cmd: np.ndarray, effects: object, noise: float) -> float:
    """The hidden effect's whole signal on the session (see :data:`DETECTION_CHI2`): the
    held-out model run noise-free with it and without it, every reading compared."""
    from benchmarks.heldout import bender_physics as hb

    def readings(fx: object) -> np.ndarray:
        rows = hb.simulate_trials(cmd, "diwire", fx, 0.0, 0)
        return np.array(
            [[r.loaded_bend_deg, r.unloaded_bend_deg, r.measured_pin_deg] for r in rows]
        )

    change = readings(effects) - readings(None)
    return _signal_chi2([change], noise)


def make_case(
    generator: str,
    seed: int,
    name: str,
    mode: str,
    *,
    swept: bool = False,
    dead_zone_sd_deg: float = 0.0,
) -> Case:
    """The session of one machine; ``dead_zone_sd_deg`` (sim only): its dead zone drawn
    about the nominal with this spread (0: the nominal, as the diagnosis describes it)."""
    if generator == "sim":
        return _sim_case(seed, name, mode, swept, dead_zone_sd_deg)
    if generator == "physical":
        return _pb_case(seed, name, mode, swept)
    if generator == "heldout":
        return _heldout_case(seed, name, mode, swept)
    raise ValueError(f"unknown generator {generator!r}")


def follow_up_trials(case: Case, commands_deg: np.ndarray) -> TrialTable:
    """The case's session with the follow-up bends run after it on the same machine (its
    state continued: the whole sequence is bent in order), the new bends measured with
    the case's noise from their own stream."""
    rng = np.random.default_rng(case.seed + FOLLOW_UP_SEED_OFFSET)
    old = case.trials
    new = np.round(np.asarray(commands_deg, dtype=np.float64), 3)
    cmd = np.concatenate([old.commanded_pin_deg, new])
    n = len(old)
    if case.generator == "heldout":
        # the whole sequence again with the same seed: the session's rows come out the
        # same (the model's noise is drawn bend by bend), the new ones follow them
        more = _heldout_rows(cmd, case.machine, case.noise_deg, case.seed)
        return more
    if case.generator == "sim":
        params, effects = case.machine
        res = simulate(cmd, params, effects)
        cols = (res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg)
    else:
        machine, hidden = case.machine
        true = pb.bend(cmd, machine, hidden, rng)
        cols = (
            true.loaded_deg,
            true.unloaded_deg,
            pb.loaded_pin_deg(machine, true.head_deg, hidden),
        )
    loaded, unloaded, pin = _noisy(rng, case.noise_deg, *(c[n:] for c in cols))
    return TrialTable.from_arrays(
        cmd,
        np.concatenate([old.loaded_bend_deg, loaded]),
        np.concatenate([old.unloaded_bend_deg, unloaded]),
        measured_pin_deg=np.concatenate([old.measured_pin_deg, pin]),
        source=case.generator,
    )


def _names(d: dict) -> set[str]:
    return {c for c in d["causes"] if c in EFFECTS and c != "none"}


def run_case(case: Case) -> dict:
    """Diagnose the session, and a tie's follow-up round; the row scored."""
    t0 = time.perf_counter()
    result: Diagnosis = diagnose(case.trials)
    seconds = time.perf_counter() - t0
    d = result.to_dict()
    row = {
        "generator": case.generator,
        "mode": case.mode,
        "seed": case.seed,
        "hidden": case.name,
        "noise_deg": case.noise_deg,
        "n_trials": len(case.trials),
        "cause": d["cause"],
        "causes": list(d["causes"]),
        "tie": list(d["tie"]),
        "discovered": [t["term"] for t in d["discovered"]],
        "unnamed_flag": bool(d["leftover"]["unnamed_discrepancy"]),
        "refused": bool(d["lack_of_fit"] and d["lack_of_fit"]["refused"]),
        "seconds": seconds,
        "signal_chi2": case.signal_chi2,
        "below_detection": bool(case.signal_chi2 is not None and case.signal_chi2 < DETECTION_CHI2),
        "covered": None,
        "truth": case.truth,
        "interval": None,
        "after": None,
    }
    key = EFFECTS[case.name].param if case.name in EFFECTS else None
    if case.truth is not None and key in d["params"] and d["cause"] == case.name:
        lo, hi = d["intervals"][key]
        row["covered"] = bool(lo <= case.truth <= hi)
        row["interval"] = [lo, hi]
        row["estimate"] = d["params"][key]
    if d["tie"] and result.follow_up is not None:
        more = follow_up_trials(case, result.follow_up.commanded_pin_deg)
        again = diagnose(more, follow_up=False).to_dict()
        row["after"] = {
            "n_bends": result.follow_up.n_trials,
            "cause": again["cause"],
            "causes": list(again["causes"]),
            "tie": list(again["tie"]),
        }
    return row


def expected_name(row: dict) -> str:
    """The catalogue name right for the row's hidden mechanism (:data:`GENERAL_FORMS`)."""
    return GENERAL_FORMS.get(row["hidden"], row["hidden"])


def named_right(row: dict) -> bool:
    """The hidden cause named alone without a tie, or after the follow-up round; a cause
    below the session's detection limit (:data:`DETECTION_CHI2`) also when no effect is
    named (the honest reading of a session that does not show it)."""
    h = expected_name(row)
    if row["cause"] == h and not row["tie"]:
        return True
    if row.get("below_detection") and row["cause"] == "none" and not row["tie"]:
        return True
    after = row["after"]
    return (
        after is not None
        and (h in row["tie"] or row["cause"] == h)
        and after["cause"] == h
        and not after["tie"]
    )


def false_discovery(row: dict) -> bool:
    """Anything named (or discovered) on a machine with nothing hidden."""
    return row["cause"] != "none"


def _pct(x: float) -> float:
    return round(100.0 * float(x), 1)


def outside_flagged(row: dict) -> bool:
    """A mechanism outside the catalogue said to be there: unexplained, a discovered term,
    a term outside the catalogue in a tie, the leftover discrepancy flagged, or the
    simulation said not to describe the machine."""
    return (
        row["cause"] == "unexplained"
        or row["refused"]
        or bool(row["discovered"])
        or row["unnamed_flag"]
        or any(Cause.parse(t) is None for t in row["tie"])
    )


def _outside_right(row: dict) -> bool:
    """A mechanism outside the catalogue flagged and given no catalogue name alone; below
    the session's detection limit also when nothing is named."""
    return _undetected(row) or (outside_flagged(row) and not outside_misnamed(row))


def _undetected(row: dict) -> bool:
    """Below the session's detection limit (:data:`DETECTION_CHI2`) and nothing named: the
    honest reading of a session that does not show the mechanism."""
    return bool(row.get("below_detection")) and row["cause"] == "none" and not row["tie"]


def outside_misnamed(row: dict) -> bool:
    """A catalogue name given (not tied with a term outside it) for an outside mechanism."""
    tied_outside = any(Cause.parse(t) is None for t in row["tie"])
    return bool(_names(row)) and not tied_outside


# ----------------------------------------------------------------------------- processes


def _cli(*args: str, cwd: Path) -> tuple[subprocess.CompletedProcess, float]:
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "cvmeasure", *args],
        capture_output=True,
        text=True,
        check=False,
        cwd=cwd,
    )
    return proc, time.perf_counter() - t0


#: The hidden effect of each mode's end-to-end process chain (``--effect`` as a user types it).
CHAIN_EFFECTS = {"quick": "offset=1.0", "standard": "backlash=1.0", "high": "scale=0.03"}


def process_chain(mode: str, tmp: Path) -> list:
    """``cvmeasure session --simulate`` -> ``fit`` -> ``diagnose --follow-up-csv``, as
    processes with the defaults; the row of the table."""
    effect = CHAIN_EFFECTS[mode]
    out = tmp / mode / "cal.json"
    session, t_session = _cli(
        "session",
        "--simulate",
        "--mode",
        mode,
        "--effect",
        effect,
        "-o",
        str(out),
        "--quiet",
        cwd=tmp,
    )
    trials = out.with_name("cal_session") / "trials.csv"
    if session.returncode != 0:
        return [mode, effect, "session failed", session.stderr.strip()[-120:], "-", "-", "-"]
    fit, _ = _cli("fit", str(trials), "-o", str(tmp / mode / "fit.json"), cwd=tmp)
    follow = tmp / mode / "follow_up.csv"
    diag, t_diag = _cli("diagnose", str(trials), "--json", "--follow-up-csv", str(follow), cwd=tmp)
    if diag.returncode != 0:
        return [mode, effect, "diagnose failed", diag.stderr.strip()[-120:], "-", "-", "-"]
    d = json.loads(diag.stdout)
    return [
        mode,
        effect,
        f"{d['cause']}" + (f" (tie {'/'.join(d['tie'])})" if d["tie"] else ""),
        "ok" if fit.returncode == 0 else f"fit exit {fit.returncode}",
        "yes" if d.get("follow_up_csv") else "no",
        round(t_session, 1),
        round(t_diag, 2),
    ]


def _cli_diagnose_seconds(tmp: Path, n: int) -> tuple[float, float]:
    """Median wall and CPU time of ``cvmeasure diagnose`` on a standard session's trials,
    pinned to one core when ``taskset`` exists (the target is one core's; run alone, the
    benchmark is not pinned by the runner)."""
    case = make_case("sim", SEED0 - 1, "backlash", "standard")
    csv = case.trials.write_csv(tmp / "standard.csv")
    core = min(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 0
    pin = ["taskset", "-c", str(core)] if shutil.which("taskset") else []
    cmd = [*pin, sys.executable, "-m", "cvmeasure", "diagnose", str(csv), "--json"]
    # warm-up, writing the bytecode cache as an installed package has it (pip compiles
    # it at install); with PYTHONDONTWRITEBYTECODE set the timed runs would otherwise
    # compile every cvmeasure module they import, each time
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    subprocess.run(cmd, capture_output=True, check=False, env=env)
    wall, cpu = [], []
    for _ in range(n):
        r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        subprocess.run(cmd, capture_output=True, check=False, env=env)
        wall.append(time.perf_counter() - t0)
        r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpu.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
    return float(np.median(wall)), float(np.median(cpu))


# ------------------------------------------------------- two descriptions of one machine

#: SimParams' lengths (mm): a similar machine has every one of them k times larger, and then
#: the same strains, hence the same angles, at the same wire material.
LENGTH_FIELDS: tuple[str, ...] = (
    "wire_diameter_mm",
    "die_radius_mm",
    "pin_orbit_mm",
    "pin_radius_mm",
    "head_axis_x_mm",
    "head_axis_y_mm",
)
#: How a cause's parameter reads on a similar machine described k times larger: its value
#: times k**exponent for the same predictions (a length: 1; a compliance in deg per N m:
#: -3, the pin torque growing as k^3; every angle and ratio: 0).
SIMILARITY_EXPONENT: dict[str, float] = {"axis_offset_mm": 1.0, "compliance_deg_per_nm": -3.0}
#: The similar machine's sizes tried for every session (the machine described k times larger).
SIMILAR_SIZES: tuple[float, ...] = (2.0, 0.5)


def similar_params(params: SimParams, k: float) -> SimParams:
    """``params`` with every length ``k`` times larger: the similar machine, whose
    predictions of every angle are the same."""
    return params.replace(**{f: getattr(params, f) * k for f in LENGTH_FIELDS})


def description_agreement(a: dict, b: dict, k: float = 1.0) -> tuple[bool, float | None]:
    """Whether two diagnoses (``cvmeasure diagnose --json``) of one session, under two
    descriptions of the machine, say the same, and how far their intervals are apart.

    Parameters
    ----------
    a, b : dict
        The diagnosis under the first description and under the second.
    k : float
        The second description's size relative to the first (a similar machine; 1 when
        they are of one size): a parameter with a unit of length reads k times larger on
        it (:data:`SIMILARITY_EXPONENT`), and is compared so.

    Returns
    -------
    same : bool
        The same cause, named causes and tie.
    worst_sigma : float or None
        The largest |difference of an interval endpoint| over every parameter with an
        interval under both, in standard errors of the first's (its 95 % interval's
        width / 3.92); None when they have no interval in common.
    """
    same = (a["cause"], list(a["causes"]), sorted(a["tie"])) == (
        b["cause"],
        list(b["causes"]),
        sorted(b["tie"]),
    )
    worst = None
    for key, (lo, hi) in a["intervals"].items():
        if key not in b["intervals"]:
            continue
        f = k ** SIMILARITY_EXPONENT.get(key, 0.0)
        lo_b, hi_b = (v / f for v in b["intervals"][key])
        sigma = (hi - lo) / (2 * 1.96)
        if not sigma > 0:
            continue
        d = max(abs(lo_b - lo), abs(hi_b - hi)) / sigma
        worst = d if worst is None else max(worst, d)
    return same, worst


def _prediction_rms_deg(cmd: np.ndarray, a: Path, b: Path) -> float:
    """RMS difference (deg) of two params files' predictions of every angle (loaded,
    released, pin) on the commands: what the two descriptions disagree on."""
    (pa, ea), (pb_, eb) = params_from_json(a), params_from_json(b)
    ra, rb = simulate(cmd, pa, ea), simulate(cmd, pb_, eb)
    diff = np.concatenate(
        [
            ra.loaded_bend_deg - rb.loaded_bend_deg,
            ra.unloaded_bend_deg - rb.unloaded_bend_deg,
            ra.pin_angle_deg - rb.pin_angle_deg,
        ]
    )
    return float(np.sqrt(np.mean(diff**2)))


def _no_effect_session(case: Case) -> TrialTable:
    """The case's machine (its params) bent on the same session without the hidden cause,
    measured with the case's noise from its own stream: the session a user fits the
    machine's description from."""
    params, _ = case.machine
    rng = np.random.default_rng(case.seed + NO_EFFECT_SEED_OFFSET)
    cmd = case.trials.commanded_pin_deg
    res = simulate(cmd, params, ())
    loaded, unloaded, pin = _noisy(
        rng, case.noise_deg, res.loaded_bend_deg, res.unloaded_bend_deg, res.pin_angle_deg
    )
    return TrialTable.from_arrays(cmd, loaded, unloaded, measured_pin_deg=pin, source="sim")


def description_session(case: Case, tmp: Path) -> list[dict]:
    """One sim session diagnosed as processes (``cvmeasure diagnose --json --params``)
    under the machine's own description and under each second one: the similar machine
    at each of :data:`SIMILAR_SIZES`, and the params ``cvmeasure diagnose --save-params``
    writes from the machine's no-effect session (the built-in description's strength and
    die radius fitted, as a user without a params file gets one). One row per second
    description."""
    params, _ = case.machine
    where = tmp / f"desc_{case.seed}"
    where.mkdir(parents=True, exist_ok=True)
    trials = case.trials.write_csv(where / "trials.csv")
    no_effect = _no_effect_session(case).write_csv(where / "no_effect.csv")
    own = params_to_json(where / "own.json", params)
    seconds = [
        (
            f"similar x{k:g}",
            k,
            params_to_json(where / f"similar_{k:g}.json", similar_params(params, k)),
        )
        for k in SIMILAR_SIZES
    ]
    fitted = where / "fitted.json"
    fit, _ = _cli("diagnose", str(no_effect), "--json", "--save-params", str(fitted), cwd=where)
    if fit.returncode == 0:
        seconds.append(("fitted (no-effect session)", 1.0, fitted))
    out = {}
    for label, path in (("own", own), *((lab, p) for lab, _, p in seconds)):
        proc, _ = _cli("diagnose", str(trials), "--json", "--params", str(path), cwd=where)
        out[label] = json.loads(proc.stdout) if proc.returncode == 0 else None
    rows = []
    a = out["own"]
    for label, k, path in seconds:
        b = out[label]
        row = {
            "seed": case.seed,
            "mode": case.mode,
            "hidden": case.name,
            "noise_deg": case.noise_deg,
            "description": label,
            "prediction_rms_deg": _prediction_rms_deg(case.trials.commanded_pin_deg, own, path),
            "own": None if a is None else [a["cause"], a["causes"], a["tie"]],
            "second": None if b is None else [b["cause"], b["causes"], b["tie"]],
            "same": False,
            "worst_sigma": None,
        }
        if a is not None and b is not None:
            row["same"], row["worst_sigma"] = description_agreement(a, b, k)
        rows.append(row)
    if fit.returncode != 0:
        rows.append(
            {
                "seed": case.seed,
                "mode": case.mode,
                "hidden": case.name,
                "noise_deg": case.noise_deg,
                "description": "fitted (no-effect session)",
                "prediction_rms_deg": None,
                "own": None,
                "second": f"diagnose --save-params failed: {fit.stderr.strip()[-120:]}",
                "same": False,
                "worst_sigma": None,
            }
        )
    return rows


def description_cases(reps: int) -> list[tuple[int, str, str]]:
    """(seed, cause, mode) of the sessions diagnosed under two descriptions: ``reps`` per
    catalogue cause and none, the modes taken in turn (each cause in ``reps`` modes)."""
    out, seed = [], SEED_DESCRIPTIONS
    for i, name in enumerate((*CATALOGUE, "none")):
        for j in range(reps):
            out.append((seed, name, MODES_RUN[(i + j) % len(MODES_RUN)]))
            seed += 1
    return out


def description_metrics(rows: list[dict]) -> tuple[list[Metric], list[list]]:
    """The target's two rows (same names; the worst interval difference) and a row per
    (second description, hidden cause)."""
    same = float(np.mean([r["same"] for r in rows]))
    sig = [r["worst_sigma"] for r in rows if r["worst_sigma"] is not None]
    worst = max(sig) if sig else None
    n_sessions = len({r["seed"] for r in rows})
    pred = [r["prediction_rms_deg"] for r in rows if r["prediction_rms_deg"] is not None]
    metrics = [
        Metric(
            f"two descriptions of one machine: same named causes ({n_sessions} sessions, "
            f"{len(rows)} pairs)",
            _pct(same),
            "%",
            "100",
            same == 1.0,
        ),
        Metric.at_most(
            "two descriptions of one machine: worst interval endpoint difference",
            None if worst is None else round(worst, 3),
            "sigma",
            0.1,
        ),
        Metric(
            "two descriptions: their predictions' rms difference, largest / the session's noise",
            round(
                max(
                    r["prediction_rms_deg"] / r["noise_deg"]
                    for r in rows
                    if r["prediction_rms_deg"] is not None
                ),
                3,
            )
            if pred
            else None,
            "x",
        ),
    ]
    table = []
    kinds = dict.fromkeys(r["description"] for r in rows)
    for kind in kinds:
        for name in (*CATALOGUE, "none"):
            rs = [r for r in rows if r["description"] == kind and r["hidden"] == name]
            if not rs:
                continue
            s = [r["worst_sigma"] for r in rs if r["worst_sigma"] is not None]
            p_ = [
                r["prediction_rms_deg"] / r["noise_deg"]
                for r in rs
                if r["prediction_rms_deg"] is not None
            ]
            differ = Counter(
                f"{_said(r['own'])} -> {_said(r['second'])}" for r in rs if not r["same"]
            )
            table.append(
                [
                    kind,
                    name,
                    len(rs),
                    _pct(np.mean([r["same"] for r in rs])),
                    round(max(s), 3) if s else "-",
                    round(max(p_), 3) if p_ else "-",
                    ", ".join(f"{k} x{v}" for k, v in differ.most_common()) or "-",
                ]
            )
    return metrics, table


def _said(d: object) -> str:
    """A diagnosis's names in a few words (cause, or cause with its tie)."""
    if not isinstance(d, list):
        return str(d)
    cause, causes, tie = d
    label = "+".join(causes) if causes else cause
    return label + (f" (tie {'/'.join(tie)})" if tie else "")


def _error_rms_sigma(rows: list[dict]) -> float:
    """RMS over the rows of (estimate - truth) / sigma, sigma the 95 % interval's width /
    3.92 (the interval's mid where a row has no estimate)."""
    z = [
        (r.get("estimate", 0.5 * sum(r["interval"])) - r["truth"])
        / ((r["interval"][1] - r["interval"][0]) / 3.92)
        for r in rows
    ]
    return float(np.sqrt(np.mean(np.square(z))))


def coverage_table(rows: list[dict]) -> list[list]:
    """Per generator and cause, the intervals scored against the truth: how many, how many
    hold it, the rms of (estimate - truth) / sigma (sigma: the interval's width / 3.92; 1
    for an interval as wide as the errors, below 1 wider than they need) and the misses'
    truth and interval (which parameters miss, and by how much)."""
    out = []
    for gen in dict.fromkeys(r["generator"] for r in rows):
        for name in CATALOGUE:
            rs = [r for r in rows if r["generator"] == gen and r["hidden"] == name]
            scored = [r for r in rs if r["covered"] is not None]
            if not scored:
                continue
            misses = [r for r in scored if not r["covered"]]
            out.append(
                [
                    gen,
                    name,
                    EFFECTS[name].param,
                    len(scored),
                    _pct(np.mean([r["covered"] for r in scored])),
                    round(_error_rms_sigma(scored), 2),
                    "; ".join(
                        f"{r['mode']} truth {r['truth']:.4g} in "
                        f"[{r['interval'][0]:.4g}, {r['interval'][1]:.4g}]"
                        for r in misses
                    )
                    or "-",
                ]
            )
    return out


# ----------------------------------------------------------------------------- the run


def _cases(generators: tuple[str, ...], reps: int) -> list[tuple[str, int, str, str]]:
    out, seed = [], SEED0
    for gen in generators:
        outside = {"sim": [], "physical": [*OUTSIDE], "heldout": [*HELDOUT_OUTSIDE]}[gen]
        names = [*CATALOGUE, "none", "none", *outside]
        for mode in MODES_RUN:
            for name in names:
                for _ in range(reps):
                    out.append((gen, seed, name, mode))
                    seed += 1
    return out


def _coverage_cases(extra_reps: int) -> list[tuple[int, str, str]]:
    """(seed, cause, mode) of the coverage sample's extra sim machines: ``extra_reps`` per
    (cause in :data:`COVERAGE_CAUSES`, mode), seeds from :data:`SEED_COVERAGE`."""
    out, seed = [], SEED_COVERAGE
    for mode in MODES_RUN:
        for name in COVERAGE_CAUSES:
            for _ in range(extra_reps):
                out.append((seed, name, mode))
                seed += 1
    return out


def coverage_interval(k: int, n: int) -> tuple[float, float]:
    """Clopper-Pearson 95 % interval (%) of a coverage of ``k`` of ``n`` intervals: with 40-50
    intervals a 95 % method reads anywhere from about 88 to 100 %."""
    lo = float(stats.beta.ppf(0.025, k, n - k + 1)) if k > 0 else 0.0
    hi = float(stats.beta.ppf(0.975, k + 1, n - k)) if k < n else 1.0
    return _pct(lo), _pct(hi)


def per_cause_table(per_cause: list[list]) -> Table:
    """The per-hidden-cause table of :func:`_generator_metrics`'s rows (one generator or more)."""
    return Table(
        "per hidden cause (modes quick, standard, high together)",
        ["generator", "hidden", "cases", "right %", "follow-ups run", "instead"],
        per_cause,
    )


def coverage_metrics(label: str, covered: list[bool], *, target: bool) -> list[Metric]:
    """The share of 95 % intervals holding the truth, with its Clopper-Pearson interval;
    ``target``: scored against the issue's 90-98 % band."""
    if not covered:
        return []
    cov = float(np.mean(covered))
    lo, hi = coverage_interval(int(sum(covered)), len(covered))
    return [
        Metric(
            f"{label} ({len(covered)} named)",
            _pct(cov),
            "%",
            "90-98" if target else None,
            (0.90 <= cov <= 0.98) if target else None,
        ),
        Metric(f"{label}: binomial 95 % interval (Clopper-Pearson), low", lo, "%"),
        Metric(f"{label}: binomial 95 % interval (Clopper-Pearson), high", hi, "%"),
    ]


def _generator_metrics(
    gen: str, rows: list[dict], coverage_rows: list[dict] = ()
) -> tuple[list[Metric], list[list]]:
    """The generator's metrics and per-cause rows; ``coverage_rows``: more cases whose
    intervals are scored beside the rows' own (the coverage sample), nothing else.

    The intervals' 90-98 % band is the issue's target on the independent models (the
    physical and the held-out); on the sim, whose machines have the nominal dead zone
    the intervals carry a tolerance of, it is reported without a target (and again with
    the dead zone drawn within that tolerance, :data:`DEAD_ZONE_SD_DEG`, in ``main``)."""
    cat = [r for r in rows if expected_name(r) in CATALOGUE]
    null = [r for r in rows if r["hidden"] == "none"]
    out = [r for r in rows if expected_name(r) in (*OUTSIDE, *HELDOUT_OUTSIDE)]
    right = float(np.mean([named_right(r) for r in cat]))
    first = float(np.mean([r["cause"] == expected_name(r) and not r["tie"] for r in cat]))
    false = float(np.mean([false_discovery(r) for r in null]))
    covered = [r["covered"] for r in (*cat, *coverage_rows) if r["covered"] is not None]
    metrics = [
        Metric(
            f"{gen}: catalogue causes named right (after the follow-up round)",
            _pct(right),
            "%",
            ">= 95",
            right >= 0.95,
        ),
        Metric(f"{gen}: named right before any follow-up", _pct(first), "%"),
        Metric(
            f"{gen}: no-effect sessions, false discoveries",
            _pct(false),
            "%",
            "<= 5",
            false <= 0.05,
        ),
        # the flagged rows below count this flag: read them against its false-alarm rate
        Metric(
            f"{gen}: no-effect sessions, unnamed-discrepancy flag raised",
            _pct(np.mean([r["unnamed_flag"] for r in null])),
            "%",
        ),
    ]
    label = f"{gen}: 95 % intervals holding the truth"
    if gen == "sim":
        label += ", the dead zone nominal"
    metrics += coverage_metrics(label, covered, target=gen != "sim")
    if out:
        mis = float(np.mean([outside_misnamed(r) for r in out]))
        flag = float(np.mean([outside_flagged(r) or _undetected(r) for r in out]))
        metrics += [
            Metric(f"{gen}: outside the catalogue, misnamed", _pct(mis), "%", "<= 10", mis <= 0.1),
            Metric(
                f"{gen}: outside the catalogue, flagged (or nothing named below the "
                "detection limit)",
                _pct(flag),
                "%",
                ">= 80",
                flag >= 0.8,
            ),
        ]
    table = []
    for name in dict.fromkeys((*CATALOGUE, "none", *OUTSIDE, *HELDOUT_OUTSIDE)):
        rs = [r for r in rows if r["hidden"] == name]
        if not rs:
            continue
        catalogue = GENERAL_FORMS.get(name, name) in CATALOGUE or name == "none"
        ok = [named_right(r) if catalogue else _outside_right(r) for r in rs]
        got = Counter(
            r["cause"] + (f" (tie {'/'.join(r['tie'])})" if r["tie"] else "")
            for r, right_ in zip(rs, ok, strict=True)
            if not right_
        )
        table.append(
            [
                gen,
                name + (f" (as {GENERAL_FORMS[name]})" if name in GENERAL_FORMS else ""),
                len(rs),
                _pct(np.mean(ok)),
                sum(r["after"] is not None for r in rs),
                ", ".join(f"{k} x{v}" for k, v in got.most_common()) or "-",
            ]
        )
    return metrics, table


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.diagnosis_session", description=__doc__)
    p.add_argument("--quick", action="store_true", help="one machine per (cause, mode)")
    p.add_argument("--reps", type=int, default=3, help="machines per (cause, mode) (default 3)")
    p.add_argument(
        "--generators", default="sim,physical", help="comma-separated: sim, physical, heldout"
    )
    p.add_argument("--no-chain", action="store_true", help="skip the end-to-end process chains")
    p.add_argument(
        "--coverage-reps",
        type=int,
        default=10,
        help="sim machines per (cause, mode) whose intervals are scored, for the coverage "
        "row: the main sample's and more of the causes in COVERAGE_CAUSES (default 10)",
    )
    p.add_argument(
        "--description-reps",
        type=int,
        default=2,
        help="sim sessions per cause (and none) diagnosed under two params descriptions, "
        "the modes in turn (default 2)",
    )
    args = p.parse_args(argv)
    reps = 1 if args.quick else args.reps
    generators = tuple(args.generators.split(","))
    rows = [run_case(make_case(g, s, n, m)) for g, s, n, m in _cases(generators, reps)]
    extra_reps = 0 if args.quick else max(args.coverage_reps - reps, 0)
    coverage_rows = (
        [
            run_case(make_case("sim", seed, name, mode))
            for seed, name, mode in _coverage_cases(extra_reps)
        ]
        if "sim" in generators
        else []
    )
    # the same sim machines' intervals again, each machine's dead zone drawn within the
    # tolerance the intervals carry (the rest of the machine, its cause and noise the same)
    drawn = [(s, n, m) for _, s, n, m in _cases(("sim",), reps) if n in COVERAGE_CAUSES]
    drawn_rows = (
        [
            run_case(make_case("sim", seed, name, mode, dead_zone_sd_deg=DEAD_ZONE_SD_DEG))
            for seed, name, mode in (*drawn, *_coverage_cases(extra_reps))
        ]
        if "sim" in generators
        else []
    )
    metrics: list[Metric] = []
    per_cause: list[list] = []
    for gen in generators:
        m, t = _generator_metrics(
            gen,
            [r for r in rows if r["generator"] == gen],
            coverage_rows if gen == "sim" else (),
        )
        metrics += m
        per_cause += t
        if gen == "sim":
            metrics += coverage_metrics(
                f"sim: 95 % intervals holding the truth, the dead zone drawn "
                f"(sd {DEAD_ZONE_SD_DEG} deg)",
                [r["covered"] for r in drawn_rows if r["covered"] is not None],
                target=False,
            )
    chains: list[list] = []
    desc_rows: list[dict] = []
    with tempfile.TemporaryDirectory() as tmp:
        wall, cpu = _cli_diagnose_seconds(Path(tmp), 3 if args.quick else 7)
        if not args.no_chain:
            chains = [process_chain(mode, Path(tmp)) for mode in MODES_RUN]
        for seed, name, mode in description_cases(1 if args.quick else args.description_reps):
            desc_rows += description_session(make_case("sim", seed, name, mode), Path(tmp))
    desc_metrics, desc_table = description_metrics(desc_rows)
    metrics += desc_metrics
    metrics += [
        Metric.at_most("cvmeasure diagnose on a standard session (44 bends), wall", wall, "s", 1.0),
        Metric("cvmeasure diagnose on a standard session, CPU", round(cpu, 3), "s"),
        Metric(
            "diagnose() per session, median (library)",
            round(float(np.median([r["seconds"] for r in rows])), 3),
            "s",
        ),
    ]
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[
            per_cause_table(per_cause),
            Table(
                "identifiability: each cause's signature with the machine's strength, die "
                "radius and dead zone projected out: share left, nearest other cause (|cosine|)",
                ["mode", "plan", "cause", "left", "left rms deg", "nearest", "|cosine|"],
                identifiability_rows(),
            ),
            Table(
                "end-to-end process chain per mode (session --simulate -> fit -> diagnose)",
                ["mode", "effect", "diagnosis", "fit", "follow-up plan", "session s", "diagnose s"],
                chains,
            ),
            Table(
                "95 % intervals scored against the truth, per cause (main and coverage samples)",
                [
                    "generator",
                    "hidden",
                    "parameter",
                    "scored",
                    "holding %",
                    "rms error / sigma",
                    "misses",
                ],
                coverage_table(
                    [
                        *rows,
                        *coverage_rows,
                        *({**r, "generator": "sim, dead zone drawn"} for r in drawn_rows),
                    ]
                ),
            ),
            Table(
                "two descriptions of one machine (sim; cvmeasure diagnose --params own.json vs "
                "the second): same names, worst interval endpoint difference, predictions' "
                "rms difference over the noise",
                [
                    "second description",
                    "hidden",
                    "sessions",
                    "same names %",
                    "worst |d| / sigma",
                    "pred. rms / noise",
                    "differing (own -> second)",
                ],
                desc_table,
            ),
        ],
        notes=[
            f"seeds from {SEED0}, {reps} per (generator, cause, mode); noise 0.02-0.1 deg per "
            "angle (loaded, released, pin); the session's plan of each mode "
            "(cvmeasure.driver.plan.diagnosis_plan)",
            "named right: the hidden cause named alone without a tie, or a tie holding it "
            "named right after its follow-up bends were run on the same machine",
            DETECTION_NOTE,
            "intervals: only causes whose generator form means the same as the fitted parameter",
            f"the sim coverage row: the main sample's intervals and those of {extra_reps} more "
            f"machines per (cause, mode) of {', '.join(COVERAGE_CAUSES)} (seeds from "
            f"{SEED_COVERAGE}; the causes whose interval is scored), {reps + extra_reps} in "
            "all; every other row is scored on the main sample alone",
            "the intervals' 90-98 % band is the issue's target on the independent models "
            "(physical, and the held-out one in its own section); the sim builds every machine "
            "with the nominal dead zone, which the intervals do not assume (they carry its "
            f"{DEAD_ZONE_SD_DEG} deg tolerance, which play lost on every bend cannot be told "
            "apart from): its row is reported without the target, and again on the same "
            "machines with each one's dead zone drawn within that tolerance (a stream of its "
            "own; the rest of each machine, its cause and noise the same)",
            "two descriptions of one machine: sim sessions, "
            f"{1 if args.quick else args.description_reps} per cause and none (the modes in "
            f"turn), seeds from {SEED_DESCRIPTIONS}, diagnosed as processes (cvmeasure diagnose --json "
            "--params) under the machine's own params and under each second description: the "
            f"similar machine (every length x{' and x'.join(f'{k:g}' for k in SIMILAR_SIZES)}; "
            "a parameter in mm, or in deg per N m, compared after its similarity scaling), "
            "and the params cvmeasure diagnose --save-params writes from the machine's "
            "no-effect session (another noise draw) with the built-in description; same "
            "names: cause, named causes and tie all equal; sigma: the own interval's width / "
            "3.92",
        ],
        extra={
            "rows": rows,
            "coverage_rows": coverage_rows,
            "dead_zone_drawn_rows": drawn_rows,
            "description_rows": desc_rows,
        },
    )


#: The causes and general forms compared on each plan (name, value, shape).
_VARIANTS: tuple[tuple[str, str, float, tuple], ...] = (
    ("backlash", "backlash", 1.5, ()),
    ("backlash on reversals", "backlash", 1.5, (("same_direction_share", 0.0),)),
    ("offset", "offset", 1.5, ()),
    ("scale", "scale", 0.03, ()),
    ("drift", "drift", 0.04, ()),
    ("drift shifting home", "drift", 0.04, (("home_shift", 1.0),)),
    ("springback_asymmetry", "springback_asymmetry", 0.4, ()),
    ("camera_tilt", "camera_tilt", 18.0, ()),
    ("axis_offset", "axis_offset", 0.3, ()),
    ("compliance", "compliance", 0.4, ()),
)


def _signature(cmd: np.ndarray, params: SimParams, effects: tuple[Effect, ...]) -> np.ndarray:
    r = simulate(cmd, params, effects)
    return np.concatenate([r.loaded_bend_deg, r.unloaded_bend_deg, r.pin_angle_deg])


def identifiability_rows() -> list[list]:
    """Per mode and plan, each cause's signature (its change of every measured angle) with
    the machine's own parameters (strength, die radius, dead zone) projected out: the
    share of it left (0: the machine's tolerances explain it), that rest's rms (deg per
    angle: against the noise, what the plan can see) and its largest |cosine| with another
    cause's (1: the plan cannot tell them apart, whatever the noise)."""
    rows = []
    p0 = SimParams()
    for mode in MODES_RUN:
        for swept in (False, True):
            cmd = session_commands(mode, swept=swept)
            ref = _signature(cmd, p0, ())
            nuisance = np.column_stack(
                [
                    _signature(cmd, p0.replace(yield_mpa=308.0, uts_mpa=440.0), ()) - ref,
                    _signature(cmd, p0.replace(die_radius_mm=1.7), ()) - ref,
                    _signature(cmd, p0.replace(approach_deg=13.45), ()) - ref,
                ]
            )
            q, _ = np.linalg.qr(nuisance)
            sigs, left = {}, {}
            for label, name, value, shape in _VARIANTS:
                v = _signature(cmd, p0, (Effect(name, value, shape),)) - ref
                w = v - q @ (q.T @ v)
                left[label] = (
                    float(np.linalg.norm(w) / max(np.linalg.norm(v), 1e-12)),
                    float(np.sqrt(np.mean(w**2))),
                )
                sigs[label] = (name, w / max(np.linalg.norm(w), 1e-12))
            for label, (name, v) in sigs.items():
                rival, cos = max(
                    ((k, abs(float(v @ w))) for k, (n, w) in sigs.items() if n != name),
                    key=lambda t: t[1],
                )
                plan = "swept" if swept else "session"
                share, rms = left[label]
                rows.append(
                    [mode, plan, label, round(share, 3), round(rms, 3), rival, round(cos, 3)]
                )
    return rows


if __name__ == "__main__":
    main()
