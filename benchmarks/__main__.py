"""Run every benchmark (or the named ones) and rewrite RESULTS.md.

Each ``benchmarks/<name>.py`` runs in its own process (``python -m
benchmarks.<name> [--quick]``), writes ``results/<name>.json``; afterwards
RESULTS.md is regenerated from every result JSON, with the machine, the
versions and this command. A benchmark that fails is recorded as failed in its
section (with its exit code and last error line) and the run goes on.
"""

from __future__ import annotations

import argparse
import ast
import datetime as _dt
import json
import os
import subprocess
import sys
import time
from collections.abc import Sequence
from typing import Any

from benchmarks import (
    BENCH_DIR,
    REPO_ROOT,
    RESULTS_DIR,
    SCHEDULE_ENV,
    format_table,
    write_results_md,
)

__all__ = ["discover", "main"]


def discover() -> list[str]:
    """Names of the benchmark scripts (``benchmarks/<name>.py``, not starting with '_')."""
    return sorted(p.stem for p in BENCH_DIR.glob("*.py") if not p.stem.startswith("_"))


#: Benchmarks that measure several cores at once: with ``--cores`` they run alone, last.
ALL_CORES = frozenset({"batch"})
#: Benchmarks whose targets are ratios of CPU times taken on one core that another process on
#: the other core skews (shared memory bandwidth and last-level cache slow a full decode and
#: our measurement by different amounts): with ``--cores`` they run alone (pinned to one core,
#: nothing else of this run on the others) after the parallel part, before ``ALL_CORES``.
TIMING_ALONE = frozenset({"decode_speed", "part_speed"})
#: Benchmarks that mostly wait on pseudo-terminals and child processes (about a third of a
#: core): with ``--cores`` they run one at a time in a lane of their own beside the pinned
#: queue, so the run's length is not their waiting added to everything else's computing.
SIDE_LANE = frozenset({"serial_faults", "serial_heldout", "kill_runs"})
#: Benchmarks of the parallel part that time a whole ``cvmeasure`` process on one core: the
#: side lane, unpinned, shares their core for a while (its kill runs start processes of their
#: own), so they start only once the side lane has ended.
AFTER_SIDE_LANE = frozenset({"diagnosis_session", "diagnosis_independent"})
_ALONE_OF_SIDE = (
    "in parallel: up to {} benchmarks at once, each pinned to a core of its own, "
    "after the side lane had ended"
)


def _command_of(name: str, quick: bool) -> list[str]:
    return [sys.executable, "-m", f"benchmarks.{name}"] + (["--quick"] if quick else [])


def _env_with(schedule: str) -> dict[str, str]:
    """This process's environment with ``SCHEDULE_ENV`` set to ``schedule``."""
    return {**os.environ, SCHEDULE_ENV: schedule}


def _last_line(stderr: str | None) -> str:
    err_lines = [ln for ln in (stderr or "").splitlines() if ln.strip()]
    return err_lines[-1] if err_lines else ""


def _run_one(
    name: str,
    quick: bool,
    timeout_s: float,
    schedule: str = "alone: no other benchmark of this run at the same time",
) -> tuple[int, float, str]:
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            _command_of(name, quick),
            cwd=REPO_ROOT,
            env=_env_with(schedule),
            stderr=subprocess.PIPE,
            text=True,
            timeout=timeout_s,
            check=False,
        )
    except subprocess.TimeoutExpired:
        return -1, time.perf_counter() - t0, f"timed out after {timeout_s:.0f} s"
    if proc.stderr:
        sys.stderr.write(proc.stderr)
    return proc.returncode, time.perf_counter() - t0, _last_line(proc.stderr)


def _previous_seconds(name: str) -> float:
    """How long the benchmark took last time (from its result JSON; 0 when unknown)."""
    try:
        data = json.loads((RESULTS_DIR / f"{name}.json").read_text(encoding="utf-8"))
        return float(data.get("seconds") or 0.0)
    except (OSError, ValueError, TypeError):
        return 0.0


def _start(
    name: str, quick: bool, schedule: str, core: int | None
) -> tuple[subprocess.Popen[bytes], Any]:
    """Start one benchmark, pinned to ``core`` (unless None); its stderr goes to a temp file."""
    import tempfile

    err = tempfile.TemporaryFile(mode="w+")
    print(f"--- {name} ({'side lane' if core is None else f'core {core}'})", flush=True)
    proc = subprocess.Popen(
        _command_of(name, quick),
        cwd=REPO_ROOT,
        stderr=err,
        env=_env_with(schedule),
        preexec_fn=None if core is None else (lambda c=core: os.sched_setaffinity(0, {c})),
    )
    return proc, err


def _run_pinned(
    names: Sequence[str],
    quick: bool,
    timeout_s: float,
    cores: Sequence[int],
    side: Sequence[str] = (),
) -> dict[str, tuple[int, float, str]]:
    """Run ``names`` at most ``len(cores)`` at a time, each pinned to a core of its own.

    Longest first (by the last run's seconds), so the queues end together. ``side``
    (``SIDE_LANE``: benchmarks that mostly wait) run one at a time beside them, unpinned;
    ``AFTER_SIDE_LANE`` ones start only when the side lane has ended.
    A child's stderr goes to a temporary file and is echoed when it ends.
    """
    queues: dict[str, list[str]] = {
        "pinned": sorted(names, key=_previous_seconds, reverse=True),
        "side": sorted(side, key=_previous_seconds, reverse=True),
    }
    schedule = (
        f"in parallel: up to {len(cores)} benchmarks at once, each pinned to a core of its own"
        + (", beside one that mostly waits on I/O (unpinned)" if side else "")
    )
    slots: list[tuple[str, int | None]] = [("pinned", c) for c in cores] + [("side", None)]
    running: dict[str, tuple[subprocess.Popen[bytes], tuple[str, int | None], float, Any]] = {}
    done: dict[str, tuple[int, float, str]] = {}
    while queues["pinned"] or queues["side"] or running:
        side_busy = bool(queues["side"]) or any(s[0] == "side" for _, s, _, _ in running.values())
        for slot in list(slots):
            name = _next_of(queues[slot[0]], side_busy and slot[0] == "pinned")
            if name is not None:
                slots.remove(slot)
                queues[slot[0]].remove(name)
                after = name in AFTER_SIDE_LANE and side
                note = _ALONE_OF_SIDE.format(len(cores)) if after else schedule
                proc, err = _start(name, quick, note, slot[1])
                running[name] = (proc, slot, time.perf_counter(), err)
        time.sleep(0.5)
        for name, (proc, slot, t0, err) in list(running.items()):
            elapsed = time.perf_counter() - t0
            code = proc.poll()
            if code is None and elapsed > timeout_s:
                proc.kill()
                code = proc.wait()
                done[name] = (-1, elapsed, f"timed out after {timeout_s:.0f} s")
            elif code is None:
                continue
            err.seek(0)
            text = err.read()
            err.close()
            if text:
                sys.stderr.write(text)
            done.setdefault(name, (code, elapsed, _last_line(text)))
            print(f"--- {name} ended ({elapsed:.0f} s, exit {code})", flush=True)
            del running[name]
            slots.append(slot)
    return done


def _next_of(queue: Sequence[str], side_busy: bool) -> str | None:
    """The first name of ``queue`` that may start now (``AFTER_SIDE_LANE`` ones wait)."""
    return next((n for n in queue if not (side_busy and n in AFTER_SIDE_LANE)), None)


def _mark_failed(name: str, code: int, last_line: str, command: str) -> None:
    """Record a failure in the benchmark's JSON (keeping the last good numbers, if any)."""
    from cvmeasure.fileio import atomic_write_json

    path = RESULTS_DIR / f"{name}.json"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, json.JSONDecodeError):
        data = {"name": name, "section": _declared_section(name), "metrics": [], "tables": []}
    when = _dt.datetime.now(_dt.UTC).isoformat(timespec="minutes")
    data["failed"] = (
        f"`{command}` exited with {code} on {when}: {last_line or 'no error message'}"
        + (" (numbers below are from the last successful run)" if data.get("metrics") else "")
    )
    atomic_write_json(path, data)


def _declared_section(name: str) -> str:
    """The ``SECTION = "..."`` a script declares (read without importing it)."""
    try:
        tree = ast.parse((BENCH_DIR / f"{name}.py").read_text(encoding="utf-8"))
    except (OSError, SyntaxError, ValueError):
        return f"{name} (benchmark)"
    for node in tree.body:
        if (
            isinstance(node, ast.Assign)
            and any(isinstance(t, ast.Name) and t.id == "SECTION" for t in node.targets)
            and isinstance(node.value, ast.Constant)
            and isinstance(node.value.value, str)
        ):
            return node.value.value
    return f"{name} (benchmark)"


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(
        prog="python -m benchmarks",
        description="Run the benchmarks (each in its own process) and rewrite benchmarks/RESULTS.md.",
    )
    p.add_argument("names", nargs="*", help="benchmarks to run (default: all)")
    p.add_argument("--quick", action="store_true", help="reduced sizes (each well under a minute)")
    p.add_argument("--list", action="store_true", help="list the benchmarks and exit")
    p.add_argument(
        "--render-only", action="store_true", help="rewrite RESULTS.md from results/*.json only"
    )
    p.add_argument(
        "--timeout",
        type=float,
        default=3600.0,
        help="seconds allowed per benchmark (default 3600)",
    )
    p.add_argument(
        "--cores",
        type=int,
        default=1,
        help="run up to N benchmarks at once, each pinned to a core of its own (Linux); "
        f"{', '.join(sorted(SIDE_LANE))} one at a time beside them (they mostly wait; "
        f"{', '.join(sorted(AFTER_SIDE_LANE))} start after them), "
        f"{', '.join(sorted(TIMING_ALONE))} then run alone after them, "
        f"{', '.join(sorted(ALL_CORES))} alone on every core, last (default 1: one at a time)",
    )
    args = p.parse_args(argv)
    available = discover()
    if args.list:
        print("\n".join(available))
        return 0
    unknown = [n for n in args.names if n not in available]
    if unknown:
        print(f"python -m benchmarks: unknown benchmark(s) {', '.join(unknown)}", file=sys.stderr)
        return 2
    command = "python -m benchmarks" + (" --quick" if args.quick else "")
    if args.cores > 1:
        command += f" --cores {args.cores}"
    if args.names:
        command += " " + " ".join(args.names)
    if args.render_only:
        path = write_results_md(command=None, refresh_preamble=True)
        print(f"wrote {path}")
        return 0
    names = list(args.names or available)
    outcomes: dict[str, tuple[int, float, str]] = {}
    if args.cores > 1 and hasattr(os, "sched_setaffinity"):
        cores = sorted(os.sched_getaffinity(0))[: args.cores]
        alone = [n for n in names if n in TIMING_ALONE] + [n for n in names if n in ALL_CORES]
        side = [n for n in names if n in SIDE_LANE]
        rest = [n for n in names if n not in alone and n not in side]
        outcomes.update(_run_pinned(rest, args.quick, args.timeout, cores, side))
        names = alone
    for name in names:
        print(f"--- {name}", flush=True)
        outcomes[name] = _run_one(name, args.quick, args.timeout)
    rows = []
    failed = 0
    for name in args.names or available:
        code, seconds, last = outcomes[name]
        if code != 0:
            failed += 1
            one = f"python -m benchmarks.{name}" + (" --quick" if args.quick else "")
            _mark_failed(name, code, last, one)
        rows.append([name, "ok" if code == 0 else f"FAILED ({code})", round(seconds, 1)])
    path = write_results_md(command=command)
    print()
    print(format_table(["benchmark", "status", "seconds"], rows))
    print(f"wrote {path}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
