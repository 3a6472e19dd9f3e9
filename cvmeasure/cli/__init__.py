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
import contextlib
import gc
import importlib
import os
import sys
from collections.abc import Iterator, Sequence

from cvmeasure import __version__
from cvmeasure.cli.errors import (
    OUTPUT_FILE_DESTS,
    OUTPUT_FOLDER_DESTS,
    classify_exit,
    quiet_c_stderr,
    quiet_warnings,
)

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
    "correct",
    "bend",
    "session",
    "agreement",
    "batch",
    "report",
    "track",
    "ui",
)


def build_parser(only: str | None = None) -> argparse.ArgumentParser:
    """The ``cvmeasure`` parser with every subcommand, or only ``only`` (the command
    being run: the other commands' modules, and what they import, are not loaded)."""
    from cvmeasure.cli.options import OneLineParser

    parser = OneLineParser(
        prog="cvmeasure",
        description="Computer-vision metrology and calibration for CNC wire bending.",
    )
    parser.add_argument("--version", action="version", version=f"cvmeasure {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineParser)
    for name in (only,) if only in COMMAND_MODULES else COMMAND_MODULES:
        importlib.import_module(f"cvmeasure.cli.{name}").register(sub)
    return parser


def _check_paths(args: argparse.Namespace) -> None:
    """Refuse, before anything runs, an output that is an input or a folder given as a file."""
    from pathlib import Path

    from cvmeasure.fileio import check_outputs

    folders = OUTPUT_FOLDER_DESTS.get(args.command, frozenset())
    outputs: dict[str, Path] = {}
    inputs: list[Path] = []
    for dest, value in vars(args).items():
        paths = [v for v in (value if isinstance(value, list) else [value]) if isinstance(v, Path)]
        paths = [p for p in paths if str(p) != "-"]
        if not paths:
            continue
        if dest in OUTPUT_FILE_DESTS or dest in folders:
            outputs[f"--{dest.replace('_', '-')}"] = paths[0]
        else:
            inputs.extend(p for p in paths if p.is_file())
    check_outputs(outputs, inputs, folders=[f"--{d.replace('_', '-')}" for d in folders])


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; return the exit code (tests call this directly)."""
    argv = list(argv) if argv is not None else sys.argv[1:]
    parser = build_parser(argv[0] if argv else None)
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    with quiet_warnings(), _data_on_stdout(args):
        try:
            _check_paths(args)
            return int(args.func(args) or 0)
        except BaseException as exc:  # noqa: BLE001 - every way out gets its one line
            code, message = classify_exit(exc, args)
            if code is None:
                raise
            if message is not None:
                print(f"cvmeasure {args.command}: {message}", file=sys.stderr)
            if code == 141:
                return _stdout_gone()
            if code == 1 and os.environ.get("CVMEASURE_DEBUG"):
                raise
            return code


@contextlib.contextmanager
def _data_on_stdout(args: argparse.Namespace) -> Iterator[None]:
    """With an output named ``-`` the data goes to stdout and the command's messages to stderr."""
    from cvmeasure.fileio import STDIO, set_stdout

    if not any(str(getattr(args, d, None)) == STDIO for d in OUTPUT_FILE_DESTS):
        yield
        return
    real = sys.stdout
    set_stdout(real)
    sys.stdout = sys.stderr
    try:
        yield
    finally:
        sys.stdout = real
        set_stdout(None)


def _stdout_gone() -> int:
    """The pipe reader left: send the rest of stdout nowhere and exit as SIGPIPE would."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())
    os.close(devnull)
    return 141


def console_main() -> None:
    """Entry point of the ``cvmeasure`` console script.

    The image and numerical libraries' own messages (libjpeg's "Corrupt JPEG data",
    libpng's and libtiff's warnings) are written by C code straight to file
    descriptor 2; they are sent nowhere, while cvmeasure's own stderr lines still
    reach the terminal (``CVMEASURE_DEBUG=1`` keeps everything).
    """
    with quiet_c_stderr():
        code = main()
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        code = _stdout_gone()
    # the process ends: the garbage collections of the interpreter's exit need not walk
    # every object it made (with numpy and scipy loaded, ~0.08 s of a diagnose's CPU)
    gc.collect()  # cyclic garbage (an unclosed file in a cycle) is finalised as at exit
    gc.freeze()
    sys.exit(code)
