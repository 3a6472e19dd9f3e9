"""Diagnosis judged on an independent physical model of the bender, not on `simulate` (issue 13).

Every case comes from ``cvmeasure_datasets.physical_bender`` (Voce hardening by
strips, tangential wrap, elastic bow of the span, drive play on reversals,
quantised load-dependent step loss shifting home, camera tilt about any axis,
loaded and released photo of a bend sharing one error), which imports nothing
from :mod:`cvmeasure.sim`: the machine's geometry and material are drawn off the
datasheet, the noise is 0.02-0.1 deg per angle, and the plans are random orders,
sweeps and runs of repeated identical commands. Seeds start at ``SEED0`` (the
tests use seeds below 1000).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

import numpy as np

from benchmarks import Metric, Table, finish
from benchmarks.diagnosis_session import coverage_interval
from cvmeasure.contracts import TrialTable
from cvmeasure.diagnose import Cause, Diagnosis, diagnose
from cvmeasure.sim import EFFECTS
from cvmeasure_datasets import physical_bender as pb

SECTION = "Diagnosis on an independent physical model (issue 13)"

SEED0 = 700_000
N_TRIALS = 60
#: Pairs hidden together (general forms drawn by the generator).
PAIRS: tuple[tuple[str, str], ...] = (
    ("backlash", "springback_asymmetry"),
    ("offset", "drift"),
    ("camera_tilt", "scale"),
    ("axis_offset", "compliance"),
)
#: Catalogue causes whose generator parameter means what the fitted parameter means,
#: when the generator drew the narrow form (see ``_truth``).
_SAME_MEANING = ("offset", "scale", "backlash", "axis_offset", "compliance")


def _truth(hidden: pb.Hidden) -> float | None:
    """The true value of the fitted parameter, or None when the generator's form differs."""
    if hidden.name not in _SAME_MEANING:
        return None  # drift: quantised home shift; tilt: any axis; asymmetry: of strength
    if hidden.name == "backlash" and hidden.params.get("same_direction_share", 1.0) != 1.0:
        return None
    return hidden.params[EFFECTS[hidden.name].param]


def _run(seed: int, hidden: str | tuple[str, ...], plan: str) -> dict:
    case = pb.physical_case(seed, hidden, plan=plan, n_trials=N_TRIALS)
    t0 = time.perf_counter()
    result = diagnose(case.trials)
    seconds = time.perf_counter() - t0
    d = result.to_dict()
    row = {
        "seed": seed,
        "plan": plan,
        "hidden": [h.to_dict() for h in case.hidden],
        "noise_deg": case.noise_deg,
        "cause": d["cause"],
        "causes": list(d.get("causes", [])),
        "tie": list(d.get("tie", [])),
        "discovered": [t.get("term", "") for t in d.get("discovered", [])],
        "unnamed_flag": bool(d["leftover"]["unnamed_discrepancy"]),
        "refused": bool(d["lack_of_fit"] and d["lack_of_fit"]["refused"]),
        "gain": d["gain"],
        "baseline_rmse_deg": d["baseline_rmse_deg"],
        "extended_rmse_deg": d["extended_rmse_deg"],
        "seconds": seconds,
        "covered": [],
    }
    row["follow_up"] = _follow_up_outcome(case, result) if d["tie"] else None
    for h in case.hidden:
        truth = _truth(h)
        key = EFFECTS[h.name].param if h.name in EFFECTS else None
        if truth is not None and key in d["params"]:
            lo, hi = d["intervals"][key]
            row["covered"].append(bool(lo <= truth <= hi))
    return row


#: The follow-up's noise is drawn from the case's seed plus this (its own stream).
FOLLOW_UP_SEED_OFFSET = 5_000_000
#: ... and the pin readings it asks for from the case's seed plus this.
PIN_SEED_OFFSET = 6_000_000


def _follow_up_outcome(case: pb.PhysicalCase, result: Diagnosis) -> dict:
    """A tie's proposed follow-up run on the same machine after the case's bends (its
    state continued), appended and diagnosed again: what is named then."""
    plan = result.follow_up
    if plan is None:
        return {"proposed": False}
    more = pb.run_follow_up(case, plan.commanded_pin_deg, case.seed + FOLLOW_UP_SEED_OFFSET)
    trials = with_pin_read(case, more.trials, plan.read_pin)
    again = diagnose(trials, follow_up=False).to_dict()
    return {
        "proposed": True,
        "n_trials": plan.n_trials,
        "design": plan.design,
        "expected_separation_se": plan.expected_separation_se,
        "cause": again["cause"],
        "causes": list(again["causes"]),
        "tie": list(again["tie"]),
    }


def with_pin_read(case: pb.PhysicalCase, trials: TrialTable, read_pin: bool) -> TrialTable:
    """``trials`` (the case's bends, then the follow-up's) with the pin's angle read on
    the follow-up's loaded photos when its plan asks for it (``FollowUp.read_pin``): the
    true head rotation's pin (:func:`cvmeasure_datasets.physical_bender.loaded_pin_deg`) with the
    case's noise, from a stream of its own; the case's own bends keep what they had."""
    n = len(case.trials)
    if not read_pin or len(trials) == n:
        return trials
    head = pb.bend(trials.commanded_pin_deg, case.machine, case.hidden).head_deg
    rng = np.random.default_rng(case.seed + PIN_SEED_OFFSET)
    pin = pb.loaded_pin_deg(case.machine, head[n:], case.hidden) + rng.normal(
        0.0, case.noise_deg, len(trials) - n
    )
    return TrialTable.from_arrays(
        trials.commanded_pin_deg,
        trials.loaded_bend_deg,
        trials.unloaded_bend_deg,
        measured_pin_deg=np.concatenate([case.trials.measured_pin_deg, pin]),
        source="physical",
    )


def _catalogue_names(row: dict) -> set[str]:
    return {c for c in row["causes"] if c in EFFECTS and c != "none"}


def _tied_outside(row: dict) -> bool:
    """The result reports a tie between its named causes and a term outside the
    catalogue (the two cannot be told apart on this plan): a tie, not a pick."""
    return any(Cause.parse(t) is None for t in row["tie"])


def _picked_catalogue(row: dict) -> bool:
    """A catalogue name given and not reported as tied with a term outside it."""
    return bool(_catalogue_names(row)) and not _tied_outside(row)


def _cli_seconds(n: int) -> tuple[float, float, str]:
    """Median wall time and CPU time (user + sys) of ``cvmeasure diagnose`` on 100 trials,
    interpreter start included, pinned to one core when ``taskset`` exists.

    Run as a user runs it: Python's bytecode cache on (PYTHONDONTWRITEBYTECODE removed
    from the child's environment; a warm-up run writes the cache), as an installed
    package has its .pyc files. The CPU time is what the process itself used: on a
    loaded core the wall time also counts the time other processes ran."""
    case = pb.physical_case(SEED0 - 1, "backlash", plan="random", n_trials=100)
    core = min(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 0
    pin = ["taskset", "-c", str(core)] if shutil.which("taskset") else []
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    times, cpu, cause = [], [], "?"
    with tempfile.TemporaryDirectory() as tmp:
        csv = case.trials.write_csv(Path(tmp) / "t.csv")
        cmd = [*pin, sys.executable, "-m", "cvmeasure", "diagnose", str(csv), "--json"]
        subprocess.run(cmd, capture_output=True, check=False, env=env)  # warm-up
        for _ in range(n):
            t0 = time.perf_counter()
            r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
            proc = subprocess.run(cmd, capture_output=True, text=True, check=False, env=env)
            times.append(time.perf_counter() - t0)
            r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu.append(r1.ru_utime - r0.ru_utime + r1.ru_stime - r0.ru_stime)
            cause = json.loads(proc.stdout)["cause"] if proc.returncode == 0 else "error"
    return float(np.median(times)), float(np.median(cpu)), cause


def _pct(x: float) -> float:
    return round(100.0 * float(x), 1)


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.diagnosis_independent", description=__doc__
    )
    p.add_argument("--quick", action="store_true", help="one seed per case (about a minute)")
    args = p.parse_args(argv)
    reps = 1 if args.quick else 4
    seed = SEED0

    catalogue, null, outside, pairs = [], [], [], []
    for plan in pb.PLANS:
        for name in pb.CATALOGUE:
            for _ in range(reps):
                catalogue.append(_run(seed, name, plan))
                seed += 1
        for _ in range(4 * reps):
            null.append(_run(seed, "none", plan))
            seed += 1
        for name in pb.OUTSIDE:
            for _ in range(reps):
                outside.append(_run(seed, name, plan))
                seed += 1
        for pair in PAIRS:
            for _ in range(max(reps // 2, 1)):
                pairs.append(_run(seed, pair, plan))
                seed += 1

    def hidden_names(row: dict) -> tuple[str, ...]:
        return tuple(h["name"] for h in row["hidden"])

    # named right: the cause named is the hidden one and no tie is reported (a reported
    # tie that holds the truth is not a name); the lenient count takes such a tie too
    right = [r["cause"] == hidden_names(r)[0] and not r["tie"] for r in catalogue]
    right_or_tie = [
        r["cause"] == hidden_names(r)[0] or hidden_names(r)[0] in r["tie"] for r in catalogue
    ]
    # issue 37's score: a reported tie holding the truth counts as named when the tool's own
    # follow-up plan, bent on the same machine, then names it right
    right_after = [
        ok
        or (
            (r["cause"] == hidden_names(r)[0] or hidden_names(r)[0] in r["tie"])
            and bool(r["follow_up"] and r["follow_up"]["proposed"])
            and r["follow_up"]["cause"] == hidden_names(r)[0]
            and not r["follow_up"]["tie"]
        )
        for ok, r in zip(right, catalogue, strict=True)
    ]
    # issue 37's flag: unexplained, refused, a discovered term, the unnamed-discrepancy
    # flag, or a term outside the catalogue in a tie
    flagged_any = float(
        np.mean(
            [
                r["cause"] == "unexplained"
                or r.get("refused", False)
                or bool(r["discovered"])
                or r["unnamed_flag"]
                or _tied_outside(r)
                for r in outside
            ]
        )
    )
    # ties among the catalogue cases: one follow-up round proposed, run and diagnosed again
    tied = [r for r in catalogue if r["tie"]]
    run = [r for r in tied if r["follow_up"] and r["follow_up"]["proposed"]]
    after_right = [
        r["follow_up"]["cause"] == hidden_names(r)[0] and not r["follow_up"]["tie"] for r in run
    ]
    after_wrong = [
        r["follow_up"]["cause"] not in (hidden_names(r)[0], "none", "unexplained")
        and not r["follow_up"]["tie"]
        for r in run
    ]
    follow_sizes = [r["follow_up"]["n_trials"] for r in run]
    false_by_plan = {
        plan: float(np.mean([bool(_catalogue_names(r)) for r in null if r["plan"] == plan]))
        for plan in pb.PLANS
    }
    wrongly = float(np.mean([_picked_catalogue(r) for r in outside]))
    wrongly_or_tie = float(np.mean([bool(_catalogue_names(r)) for r in outside]))
    flagged = float(np.mean([bool(r["discovered"]) for r in outside]))
    unnamed_flag = float(
        np.mean([r["unnamed_flag"] or r["cause"] == "unexplained" for r in outside])
    )
    out_gain = float(np.median([r["gain"] for r in outside]))
    both = float(np.mean([_catalogue_names(r) == set(hidden_names(r)) for r in pairs]))
    covered = [c for r in catalogue + pairs for c in r["covered"]]
    coverage = float(np.mean(covered)) if covered else float("nan")
    t_cli, cpu_cli, cli_cause = _cli_seconds(3 if args.quick else 7)
    t_lib = float(np.median([r["seconds"] for r in catalogue + null + outside + pairs]))

    per_cause = []
    for name in pb.CATALOGUE:
        for plan in pb.PLANS:
            rs = [r for r in catalogue if hidden_names(r)[0] == name and r["plan"] == plan]
            wrong = Counter(r["cause"] for r in rs if r["cause"] != name)
            wrong.update("tie " + "/".join(r["tie"]) for r in rs if r["cause"] == name and r["tie"])
            per_cause.append(
                [
                    name,
                    plan,
                    len(rs),
                    _pct(np.mean([r["cause"] == name and not r["tie"] for r in rs])),
                    _pct(np.median([r["gain"] for r in rs])),
                    ", ".join(f"{k} x{v}" for k, v in wrong.most_common()) or "-",
                ]
            )
    per_null = []
    for plan in pb.PLANS:
        rs = [r for r in null if r["plan"] == plan]
        named = Counter(c for r in rs for c in _catalogue_names(r))
        per_null.append(
            [
                plan,
                len(rs),
                _pct(false_by_plan[plan]),
                ", ".join(f"{k} x{v}" for k, v in named.most_common()) or "-",
            ]
        )
    per_outside = []
    for name in pb.OUTSIDE:
        rs = [r for r in outside if hidden_names(r)[0] == name]
        named = Counter(c for r in rs if _picked_catalogue(r) for c in _catalogue_names(r))
        named.update("tie " + "/".join(r["tie"]) for r in rs if _tied_outside(r))
        per_outside.append(
            [
                name,
                len(rs),
                _pct(np.mean([_picked_catalogue(r) for r in rs])),
                _pct(np.mean([bool(r["discovered"]) for r in rs])),
                _pct(np.mean([r["unnamed_flag"] or r["cause"] == "unexplained" for r in rs])),
                _pct(np.median([r["gain"] for r in rs])),
                ", ".join(f"{k} x{v}" for k, v in named.most_common()) or "-",
            ]
        )
    per_pair = []
    for pair in PAIRS:
        rs = [r for r in pairs if hidden_names(r) == pair]
        per_pair.append(
            [
                " + ".join(pair),
                len(rs),
                _pct(np.mean([_catalogue_names(r) == set(pair) for r in rs])),
                "; ".join(",".join(r["causes"]) or "none" for r in rs),
            ]
        )

    worst_false = max(false_by_plan.values())
    metrics = [
        Metric(
            "catalogue causes in general forms named right",
            _pct(np.mean(right)),
            "%",
            ">= 95",
            bool(np.mean(right) >= 0.95),
        ),
        Metric(
            "catalogue causes named right after the follow-up round (issue 37's score: a "
            "tie holding the truth counts when its follow-up names it right)",
            _pct(np.mean(right_after)),
            "%",
            ">= 95",
            bool(np.mean(right_after) >= 0.95),
        ),
        Metric(
            "catalogue causes: named right or the truth in a reported tie",
            _pct(np.mean(right_or_tie)),
            "%",
        ),
        Metric(
            "catalogue causes: a held-out tie reported",
            _pct(np.mean([bool(r["tie"]) for r in catalogue])),
            "%",
        ),
        Metric(
            f"ties separated by one follow-up round: named right after it ({len(run)} of "
            f"{len(tied)} catalogue ties given a follow-up)",
            _pct(np.mean(after_right)) if run else float("nan"),
            "%",
        ),
        Metric(
            "ties after one follow-up round: a wrong cause named without a tie",
            _pct(np.mean(after_wrong)) if run else float("nan"),
            "%",
        ),
        Metric(
            "follow-up size (bends, median; range "
            + (f"{min(follow_sizes)}-{max(follow_sizes)})" if follow_sizes else "-)"),
            float(np.median(follow_sizes)) if follow_sizes else float("nan"),
            "bends",
        ),
        *(
            Metric(
                f"no-effect false discoveries, {plan} plan",
                _pct(false_by_plan[plan]),
                "%",
                "<= 5",
                bool(false_by_plan[plan] <= 0.05),
            )
            for plan in pb.PLANS
        ),
        # the flagged rows below count this flag: read them against its false-alarm rate
        Metric(
            "no-effect sessions: unnamed-discrepancy flag raised",
            _pct(np.mean([r["unnamed_flag"] for r in null])),
            "%",
        ),
        Metric(
            "outside the catalogue: wrongly given a catalogue name",
            _pct(wrongly),
            "%",
            "<= 10",
            bool(wrongly <= 0.10),
        ),
        Metric(
            "outside the catalogue: a catalogue name in the result, a tie with a term "
            "outside the catalogue counted as a name",
            _pct(wrongly_or_tie),
            "%",
        ),
        Metric(
            "outside the catalogue: flagged with a discovered term",
            _pct(flagged),
            "%",
            ">= 80",
            bool(flagged >= 0.80),
        ),
        Metric(
            "outside the catalogue: flagged (issue 37's score: unexplained, refused, a "
            "discovered term, the unnamed-discrepancy flag, or a term outside the catalogue "
            "in a tie)",
            _pct(flagged_any),
            "%",
            ">= 80",
            bool(flagged_any >= 0.80),
        ),
        Metric(
            "outside the catalogue: median held-out gain",
            _pct(out_gain),
            "%",
            ">= 60",
            bool(out_gain >= 0.60),
        ),
        Metric(
            "outside the catalogue: flagged unexplained or unnamed discrepancy (no term)",
            _pct(unnamed_flag),
            "%",
        ),
        Metric("two causes together: both named", _pct(both), "%", ">= 90", bool(both >= 0.90)),
        Metric(
            f"95 % intervals that hold the truth ({len(covered)} parameters)",
            _pct(coverage),
            "%",
            "90-98",
            bool(0.90 <= coverage <= 0.98),
        ),
        Metric(
            "the same, binomial 95 % interval (Clopper-Pearson), low",
            coverage_interval(int(sum(covered)), len(covered))[0],
            "%",
        ),
        Metric(
            "the same, binomial 95 % interval (Clopper-Pearson), high",
            coverage_interval(int(sum(covered)), len(covered))[1],
            "%",
        ),
        Metric(
            f"cvmeasure diagnose, 100 trials, whole process on one core (named: {cli_cause})",
            round(t_cli, 2),
            "s",
            "< 1",
            bool(t_cli < 1.0),
        ),
        Metric("the same, CPU time of the process (user + sys, median)", round(cpu_cli, 2), "s"),
        Metric(f"diagnose() per case, {N_TRIALS} trials (median)", round(t_lib, 3), "s"),
        Metric("worst no-effect false discovery rate over plans", _pct(worst_false), "%"),
    ]
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[
            Table(
                f"catalogue causes in general forms ({N_TRIALS} trials per case)",
                ["hidden", "plan", "cases", "named right %", "median gain %", "named instead"],
                per_cause,
            ),
            Table(
                "nothing hidden (the machine still differs from the datasheet)",
                ["plan", "cases", "a cause named %", "named"],
                per_null,
            ),
            Table(
                "mechanisms outside the catalogue",
                [
                    "hidden",
                    "cases",
                    "catalogue name given %",
                    "discovered term %",
                    "flagged unexplained %",
                    "median gain %",
                    "named",
                ],
                per_outside,
            ),
            Table("two causes together", ["hidden", "cases", "both named %", "named"], per_pair),
        ],
        notes=[
            f"seeds from {SEED0}, {reps} per (cause, plan); plans: {', '.join(pb.PLANS)}; "
            "machines drawn off the datasheet (cvmeasure_datasets.physical_bender.draw_machine)",
            "interval coverage counts the parameters whose generator form means the same as "
            "the fitted one (offset, scale, backlash lost on every bend, axis offset, "
            "compliance); drift (quantised home shift), tilt about any axis and the "
            "generator's strength asymmetry are excluded",
            "named right: the cause named is the hidden one and the result reports no "
            "held-out tie (`tie`: single causes whose held-out error is within one standard "
            "error over the CV groups of the named one's); a tie that holds the truth is "
            "counted only in the lenient metric 'named right or the truth in a reported tie'",
            "outside the catalogue, 'wrongly given a catalogue name' counts a catalogue name "
            "that the result does not tie with a term outside the catalogue (`tie` holding "
            "e.g. warm_up_45: on a sweep the named cause cannot be told from an order term); "
            "the row '... a tie with a term outside the catalogue counted as a name' counts "
            "every catalogue name",
            "a discovered term is an entry of the result's `discovered` list; `flagged "
            "unexplained` counts cause 'unexplained' or the leftover check's unnamed flag",
            "follow-up rows: each catalogue case whose result reports a tie and proposes a "
            "follow-up (`follow_up`) has it run on the same machine after its own bends "
            "(physical_bender.run_follow_up: trial order, direction history, home shift "
            "continued; noise from seed + 5,000,000; the pin read on its loaded photos when "
            "the plan asks, `read_pin`, noise from seed + 6,000,000), appended, and "
            "diagnosed again; "
            "named right after it = the hidden cause named and no tie. The row 'named "
            "right' above is without any follow-up",
        ],
        extra={"cases": catalogue + null + outside + pairs},
    )


if __name__ == "__main__":
    main()
