"""The ``cvmeasure`` command: a thin layer over the library.

Each subcommand lives in its own module ``cvmeasure.cli.<name>`` with a
``register(subparsers)`` function that adds its parser and sets ``func`` to a
``run(args) -> int``. The modules contain no algorithms: they parse arguments,
call library functions, write outputs (atomically) and print.

Exit codes (spec): 0 success; 2 bad input (one line on stderr naming the file
and the problem); 1 internal error; 130 interrupted; 141 the reader of standard
output went away (``cvmeasure ... | head``), as a process killed by SIGPIPE.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from collections.abc import Sequence

from cvmeasure import __version__
from cvmeasure.errors import CvmeasureError, InputError

__all__ = ["main", "console_main", "build_parser", "COMMAND_MODULES"]

#: Subcommand modules, in the order ``--help`` lists them.
COMMAND_MODULES: tuple[str, ...] = (
    "demo",
    "targets",
    "render",
    "calibrate",
    "plane",
    "markers",
    "measure",
    "part",
    "simulate",
    "diagnose",
    "fit",
    "gcode",
    "bend",
    "session",
    "agreement",
    "batch",
    "report",
)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cvmeasure",
        description="Computer-vision metrology and calibration for CNC wire bending.",
    )
    parser.add_argument("--version", action="version", version=f"cvmeasure {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(f"cvmeasure.cli.{name}").register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit code (tests call this directly)."""
    parser = build_parser()
    args = parser.parse_args(list(argv) if argv is not None else None)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except InputError as exc:
        print(f"cvmeasure {args.command}: {exc}", file=sys.stderr)
        return 2
    except CvmeasureError as exc:
        print(f"cvmeasure {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"cvmeasure {args.command}: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return _stdout_gone()


def _stdout_gone() -> int:
    """The pipe reader left: send the rest of stdout nowhere and exit as SIGPIPE would."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return 141


def console_main() -> None:
    """Entry point of the ``cvmeasure`` console script."""
    code = main()
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        code = _stdout_gone()
    sys.exit(code)
