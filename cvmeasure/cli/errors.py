"""The one error path of every command: an exception becomes an exit code and one line.

Exit codes (spec): 0 success; 2 bad input (one stderr line naming the file or
option and the problem); 1 an internal error or a device fault; 130 interrupted;
141 the reader of standard output went away.

What counts as bad input, beyond :class:`~cvmeasure.errors.InputError`: a file
that cannot be read or written (permissions, a read-only or full disk, a folder
where a file was expected), text that is not text, and a value the libraries
refuse while computing on it (``ValueError``, OpenCV's ``cv2.error``, a result too
large for memory). Those are named by the file the operating system names, else by
the command's input files. Anything else is an internal error: one line, exit 1,
the traceback only with ``CVMEASURE_DEBUG=1``.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import re
import sys
import warnings
from collections.abc import Iterator
from pathlib import Path

from cvmeasure.errors import CvmeasureError, InputError

__all__ = [
    "OUTPUT_FILE_DESTS",
    "OUTPUT_FOLDER_DESTS",
    "classify_exit",
    "quiet_warnings",
    "quiet_c_stderr",
    "input_names",
]

#: Longest message printed for an exception the libraries raised (one line); the
#: project's own errors are printed whole.
_MAX_MESSAGE = 240
#: The temporary file of an atomic write (``.<name>.<random>.tmp``).
_ATOMIC_TMP = re.compile(r"^\..+\.[^.]+\.tmp$")
#: Warnings from these packages are numerical or decoder chatter, never news for the user.
_QUIET_MODULES = r"(numpy|scipy|skimage|sklearn|PIL|cv2|colour|matplotlib|pandas|rawpy)(\..*)?"

#: Argument names (argparse ``dest``) that name files a command writes.
OUTPUT_FILE_DESTS: frozenset[str] = frozenset(
    {"out", "output", "plot", "overlay", "rectified", "save_params", "report", "gcode"}
)
#: Per command, output arguments that are folders, not files.
OUTPUT_FOLDER_DESTS: dict[str, frozenset[str]] = {
    "render": frozenset({"out"}),
    "demo": frozenset({"out"}),
    "session": frozenset({"dir"}),
}


def _own_line(text: object) -> str:
    """Our own error's message on one line, whole: it is written for the operator, and its
    end often says what to do (a stopped job's "check the part ... --force")."""
    return " ".join(str(text).split())


def _one_line(text: object) -> str:
    line = _own_line(text)
    return line if len(line) <= _MAX_MESSAGE else line[: _MAX_MESSAGE - 3] + "..."


def _paths_in(args: argparse.Namespace) -> list[tuple[str, Path]]:
    out = []
    for dest, value in vars(args).items():
        values = value if isinstance(value, list) else [value]
        for v in values:
            if isinstance(v, Path):
                out.append((dest, v))
            elif isinstance(v, (list, tuple)):
                out.extend((dest, p) for p in v if isinstance(p, Path))
    return out


def input_names(args: argparse.Namespace, *, limit: int = 3) -> str:
    """The command's input files, for a message about an error none of them is named in."""
    outputs = OUTPUT_FILE_DESTS | OUTPUT_FOLDER_DESTS.get(getattr(args, "command", ""), frozenset())
    names = [str(p) for dest, p in _paths_in(args) if dest not in outputs]
    names += [
        str(v)
        for dest, value in vars(args).items()
        if dest in ("photos", "photo", "inputs")
        for v in (value if isinstance(value, list) else [value])
        if isinstance(v, str)
    ]
    names = list(dict.fromkeys(names))
    if not names:
        return f"cvmeasure {getattr(args, 'command', '')}".strip()
    if len(names) > limit:
        return ", ".join(names[:limit]) + f" (and {len(names) - limit} more)"
    return ", ".join(names)


def _is_output(path: Path, args: argparse.Namespace) -> bool:
    outputs = OUTPUT_FILE_DESTS | OUTPUT_FOLDER_DESTS.get(getattr(args, "command", ""), frozenset())
    for dest, p in _paths_in(args):
        if dest in outputs or dest in ("journal", "dir"):
            with contextlib.suppress(OSError, ValueError):
                if path.resolve() == p.resolve() or p.resolve() in path.resolve().parents:
                    return True
                if path.resolve() == p.resolve().parent:
                    return True
    return False


def _os_message(exc: OSError, args: argparse.Namespace) -> str:
    reason = exc.strerror or type(exc).__name__
    if exc.filename is None:
        return f"{input_names(args)}: {_one_line(reason)}"
    path = Path(os.fsdecode(exc.filename))
    if _ATOMIC_TMP.match(path.name):
        return f"{path.parent}: cannot write a file in this folder: {reason}"
    verb = "cannot write" if _is_output(path, args) else "cannot read"
    if isinstance(exc, FileNotFoundError):
        verb = "cannot write (its folder does not exist)" if verb == "cannot write" else "not found"
        return f"{path}: {verb}"
    return f"{path}: {verb}: {reason}"


def _is_cv2_error(exc: BaseException) -> bool:
    return type(exc).__module__.startswith("cv2") and type(exc).__name__ == "error"


def _cv2_message(exc: BaseException) -> str:
    text = str(exc)
    found = re.search(r"error: \((-?\d+):([^)]*)\)\s*(.*)", text, re.S)
    if found:
        return f"OpenCV cannot process it ({found.group(2).strip()}: {found.group(3).strip()})"
    return f"OpenCV cannot process it ({text})"


def classify_exit(exc: BaseException, args: argparse.Namespace) -> tuple[int | None, str | None]:
    """(exit code, the one stderr line) for an exception a command raised.

    ``(None, None)`` means "let it through" (``SystemExit``).
    """
    if isinstance(exc, SystemExit):
        return None, None
    if isinstance(exc, KeyboardInterrupt):
        return 130, "interrupted"
    if isinstance(exc, BrokenPipeError):
        return 141, None
    if isinstance(exc, InputError):
        return 2, _own_line(exc)
    if isinstance(exc, CvmeasureError):
        return 1, f"error: {_own_line(exc)}"
    if isinstance(exc, OSError):
        return 2, _one_line(_os_message(exc, args))
    if isinstance(exc, UnicodeError):
        return 2, f"{input_names(args)}: not text in the expected encoding (a binary file?)"
    if isinstance(exc, RecursionError):
        return 2, f"{input_names(args)}: nested too deeply to read (a damaged or hostile file?)"
    if isinstance(exc, MemoryError):
        return 2, f"{input_names(args)}: too large to process in this computer's memory"
    if _is_cv2_error(exc):
        return 2, _one_line(f"{input_names(args)}: {_cv2_message(exc)}")
    if isinstance(exc, (ValueError, OverflowError, ZeroDivisionError)):
        return 2, _one_line(f"{input_names(args)}: {exc}")
    return 1, _one_line(
        f"internal error on {input_names(args)}: {type(exc).__name__}: {exc} "
        "(please report it; CVMEASURE_DEBUG=1 shows where)"
    )


@contextlib.contextmanager
def quiet_warnings() -> Iterator[None]:
    """Numerical warnings and image decoders' warnings are not shown to the user.

    NumPy/SciPy ``RuntimeWarning`` (a NaN in a reduction, an overflow in an exp),
    SciPy's fit warnings and Pillow's EXIF and decompression warnings say nothing a
    user can act on; what matters reaches them as cvmeasure's own typed warnings.
    """
    if os.environ.get("CVMEASURE_DEBUG"):
        yield
        return
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        warnings.filterwarnings("ignore", module=_QUIET_MODULES)
        yield


@contextlib.contextmanager
def quiet_c_stderr() -> Iterator[None]:
    """File descriptor 2 goes nowhere; ``sys.stderr`` keeps the real stderr.

    C libraries (libjpeg, libpng, libtiff through OpenCV and Pillow) print their
    warnings with ``fprintf(stderr, ...)``, around Python. Their output is dropped;
    cvmeasure's own lines, written through ``sys.stderr``, are not. Child processes
    (batch workers) inherit the quiet descriptor.
    """
    if os.environ.get("CVMEASURE_DEBUG"):
        yield
        return
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError, AttributeError):
        yield
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 2)
    os.close(devnull)
    previous = sys.stderr
    stream = io.TextIOWrapper(
        io.FileIO(saved, "w", closefd=False),
        encoding=getattr(previous, "encoding", None) or "utf-8",
        errors="backslashreplace",
        line_buffering=True,
    )
    sys.stderr = stream
    try:
        yield
    finally:
        with contextlib.suppress(OSError, ValueError):
            stream.flush()
        sys.stderr = previous
        os.dup2(saved, 2)
        os.close(saved)
