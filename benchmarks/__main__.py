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
import subprocess
import sys
import time
from collections.abc import Sequence

from benchmarks import BENCH_DIR, REPO_ROOT, RESULTS_DIR, format_table, write_results_md

__all__ = ["discover", "main"]


def discover() -> list[str]:
    """Names of the benchmark scripts (``benchmarks/<name>.py``, not starting with '_')."""
    return sorted(p.stem for p in BENCH_DIR.glob("*.py") if not p.stem.startswith("_"))


def _run_one(name: str, quick: bool, timeout_s: float) -> tuple[int, float, str]:
    cmd = [sys.executable, "-m", f"benchmarks.{name}"] + (["--quick"] if quick else [])
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, cwd=REPO_ROOT, stderr=subprocess.PIPE, text=True, timeout=timeout_s, check=False
        )
    except subprocess.TimeoutExpired:
        return -1, time.perf_counter() - t0, f"timed out after {timeout_s:.0f} s"
    err_lines = [ln for ln in (proc.stderr or "").splitlines() if ln.strip()]
    if proc.stderr:
        sys.stderr.write(proc.stderr)
    return proc.returncode, time.perf_counter() - t0, err_lines[-1] if err_lines else ""


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
        default=1800.0,
        help="seconds allowed per benchmark (default 1800)",
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
    if args.names:
        command += " " + " ".join(args.names)
    if args.render_only:
        path = write_results_md(command=None, refresh_preamble=True)
        print(f"wrote {path}")
        return 0
    rows = []
    failed = 0
    for name in args.names or available:
        print(f"--- {name}", flush=True)
        code, seconds, last = _run_one(name, args.quick, args.timeout)
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
