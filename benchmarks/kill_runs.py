"""Kill -9 at random moments: sessions and batches resume with nothing lost, doubled or re-bent.

Issue 43. Two kinds of run, each a ``cvmeasure`` process killed with SIGKILL at a
random moment and then run again with the same command until it finishes:

* **session** (``cvmeasure session --simulate``): afterwards the session log must
  hold exactly one sample per calibration angle (none lost, none doubled), and no
  step may be bent on wire already bent: every ``bend`` record must follow a ``fed``
  record (fresh wire out) after the previous bend;
* **batch** (``cvmeasure batch`` with 2 worker processes): the worker processes of
  the killed batch must be gone within 3 s, and after the re-run the results file
  must hold exactly one successful record per photo.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

from benchmarks import Metric, Table, finish

SECTION = "Kills: sessions and batches killed with SIGKILL, then resumed"

EXE = str(Path(sys.executable).with_name("cvmeasure"))
ANGLES = "15,35,60"
#: Time a killed batch's workers get to notice and exit (s).
WORKER_GRACE_S = 3.0


def _children(pid: int) -> set[int]:
    """Every descendant process of ``pid`` (from /proc)."""
    out: set[int] = set()
    todo = [pid]
    while todo:
        p = todo.pop()
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                kids = (task / "children").read_text().split()
            except OSError:
                continue
            for k in kids:
                if int(k) not in out:
                    out.add(int(k))
                    todo.append(int(k))
    return out


def _alive(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    return "\nState:\tZ" not in status


def _bends_on_used_wire(records: list[dict]) -> list[int]:
    fed_since_bend, twice = False, []
    for r in records:
        if r.get("event") == "fed":
            fed_since_bend = True
        elif r.get("event") == "bend":
            if not fed_since_bend:
                twice.append(r["step"])
            fed_since_bend = False
    return twice


def _records(path: Path) -> list[dict]:
    out = []
    for line in path.read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue  # a line torn by the kill
    return out


def session_run(work: Path, seed: int, env: dict[str, str]) -> dict:
    rng = random.Random(seed)
    out = work / f"cal{seed}.json"
    argv = [
        EXE,
        "session",
        "--simulate",
        "-o",
        str(out),
        "--angles",
        ANGLES,
        "--quiet",
        "--seed",
        str(seed),
    ]
    log = work / f"cal{seed}_session" / "session.jsonl"
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    # kill when the log has grown to a random number of records (a random moment in the plan)
    target = rng.randint(1, 14)
    deadline = time.monotonic() + 300
    while proc.poll() is None and time.monotonic() < deadline:
        if log.exists() and log.read_text().count("\n") >= target:
            time.sleep(rng.uniform(0.0, 0.6))
            break
        time.sleep(0.02)
    killed = proc.poll() is None
    if killed:
        proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    proc.stderr.close()
    resumes = 0
    code = None
    while resumes < 3:
        resumes += 1
        done = subprocess.run(argv, env=env, capture_output=True, timeout=600)
        code = done.returncode
        if code == 0:
            break
    records = _records(log)
    samples = Counter(r["step"] for r in records if r.get("event") == "sample")
    n_steps = 2 * len(ANGLES.split(","))
    return {
        "kind": "session",
        "seed": seed,
        "killed": killed,
        "kill_after_records": target,
        "exit": code,
        "lost": sum(1 for s in range(n_steps) if samples[s] == 0),
        "doubled": sum(c - 1 for c in samples.values() if c > 1),
        "bent_twice": len(_bends_on_used_wire(records)),
        "steps_rebent_on_fresh_wire": sum(
            1 for r in records if r.get("event") == "fed" and r.get("refeed")
        ),
        "left_over": 0,
    }


def batch_run(work: Path, photos: list[Path], seed: int, env: dict[str, str]) -> dict:
    rng = random.Random(seed)
    out = work / f"batch{seed}.jsonl"
    argv = [
        EXE,
        "batch",
        *map(str, photos),
        "--kind",
        "machine",
        "-o",
        str(out),
        "--workers",
        "2",
        "--quiet",
    ]
    proc = subprocess.Popen(argv, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    kids: set[int] = set()
    deadline = time.monotonic() + 120
    target = rng.randint(0, len(photos) - 2)
    while proc.poll() is None and time.monotonic() < deadline:
        kids |= _children(proc.pid)
        lines = out.read_text().count("\n") if out.exists() else 0
        if len(kids) >= 2 and lines >= target:
            time.sleep(rng.uniform(0.0, 0.5))
            kids |= _children(proc.pid)
            break
        time.sleep(0.02)
    killed = proc.poll() is None
    if killed:
        proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=30)
    time.sleep(WORKER_GRACE_S)
    left = [k for k in kids if _alive(k)]
    for k in left:  # leave nothing behind for the next run
        try:
            os.kill(k, signal.SIGKILL)
        except OSError:
            pass
    done = subprocess.run(argv, env=env, capture_output=True, timeout=600)
    records = _records(out) if out.exists() else []
    ok = Counter(Path(r["photo"]).name for r in records if r.get("ok"))
    return {
        "kind": "batch",
        "seed": seed,
        "killed": killed,
        "kill_after_records": target,
        "exit": done.returncode,
        "lost": sum(1 for p in photos if ok[p.name] == 0),
        "doubled": sum(c - 1 for c in ok.values() if c > 1),
        "bent_twice": 0,
        "steps_rebent_on_fresh_wire": 0,
        "left_over": len(left),
        "workers_seen": len(kids),
    }


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.kill_runs", description=__doc__)
    p.add_argument("--quick", action="store_true", help="1 session and 2 batch kills")
    p.add_argument("--sessions", type=int, help="session kills (default 11)")
    p.add_argument("--batches", type=int, help="batch kills (default 9)")
    args = p.parse_args(argv)
    n_sessions = args.sessions if args.sessions is not None else (1 if args.quick else 11)
    n_batches = args.batches if args.batches is not None else (2 if args.quick else 9)
    work = Path(tempfile.mkdtemp(prefix="cvm_kill_"))
    env = dict(os.environ, MPLCONFIGDIR=str(work / "mpl"))
    rows = []
    try:
        if n_batches:
            subprocess.run(
                [EXE, "demo", "-o", str(work / "demo")],
                env=env,
                check=True,
                capture_output=True,
                timeout=600,
            )
            photos = sorted((work / "demo" / "session" / "photos").glob("*.jpg"))[:10]
        for i in range(n_batches):
            rows.append(batch_run(work, photos, 100 + i, env))
            print(rows[-1], flush=True)
        for i in range(n_sessions):
            rows.append(session_run(work, i, env))
            print(rows[-1], flush=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    return _report(rows, argv, args.quick)


def _report(rows: list[dict], argv: list[str] | None, quick: bool) -> dict:
    sessions = [r for r in rows if r["kind"] == "session"]
    batches = [r for r in rows if r["kind"] == "batch"]
    lost = sum(r["lost"] for r in rows)
    doubled = sum(r["doubled"] for r in rows)
    twice = sum(r["bent_twice"] for r in sessions)
    left = sum(r["left_over"] for r in batches)
    unfinished = sum(r["exit"] != 0 for r in rows)
    return finish(
        __file__,
        SECTION,
        argv,
        quick=quick,
        metrics=[
            Metric("session kills", sum(r["killed"] for r in sessions), "", target=None, met=None),
            Metric("batch kills", sum(r["killed"] for r in batches), "", target=None, met=None),
            Metric("records lost", lost, "", target="= 0", met=lost == 0),
            Metric("records doubled", doubled, "", target="= 0", met=doubled == 0),
            Metric("steps bent twice on the same wire", twice, "", target="= 0", met=twice == 0),
            Metric(
                "worker processes left after a killed batch", left, "", target="= 0", met=left == 0
            ),
            Metric(
                "runs not finished by the re-run", unfinished, "", target="= 0", met=unfinished == 0
            ),
        ],
        tables=[
            Table(
                "runs",
                [
                    "kind",
                    "seed",
                    "killed",
                    "kill after records",
                    "exit",
                    "lost",
                    "doubled",
                    "bent twice",
                    "re-bent on fresh wire",
                    "workers left",
                ],
                [
                    [
                        r["kind"],
                        r["seed"],
                        r["killed"],
                        r["kill_after_records"],
                        r["exit"],
                        r["lost"],
                        r["doubled"],
                        r["bent_twice"],
                        r["steps_rebent_on_fresh_wire"],
                        r["left_over"],
                    ]
                    for r in rows
                ],
            )
        ],
        notes=[
            f"sessions: `cvmeasure session --simulate --angles {ANGLES}` (6 bends), killed when "
            "its log reached a random number of records plus up to 0.6 s",
            "batches: `cvmeasure batch` of 10 photos with 2 spawned workers, killed after a "
            f"random number of records; workers counted alive {WORKER_GRACE_S:g} s later",
        ],
    )


if __name__ == "__main__":
    main()
