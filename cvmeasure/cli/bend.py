"""``cvmeasure bend``: stream a G-code job to the bender, journalled and resumable."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.options import positive_float, positive_int

__all__ = ["register", "run"]


def line_number(text: str) -> int:
    """A G-code line number as the refusal names it (``N1837``) or bare (``1837``)."""
    try:
        return positive_int(text[1:] if text[:1] in ("N", "n") else text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be a line number such as N1837 (or 1837), got {text!r}"
        ) from None


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "bend",
        help="stream a G-code job to the bender (TinyG) over serial",
        description="Stream JOB to the board at --port (a device such as /dev/ttyUSB0, a "
        "pyserial URL such as socket://host:port, or sim:// for the built-in double) in JSON "
        "mode, one line (at most 200 bytes) in flight, every ack checked against its line. "
        "A fault (lost byte, malformed reply, alarm, stall, port gone) stops the job safely "
        "(feedhold + flush) and the journal records the line; --resume continues from what "
        "the board has done. Exit 0 done, 1 stopped on a fault, 2 bad job or missing port.",
    )
    p.add_argument("job", type=Path, help="G-code file (cvmeasure gcode)")
    p.add_argument("--port", required=True, help="serial device or URL (sim:// = the double)")
    p.add_argument("--resume", action="store_true", help="continue a stopped job")
    p.add_argument(
        "--force",
        action="store_true",
        help="resume even though a corrupted line reached the machine (check the part first)",
    )
    p.add_argument(
        "--from-line",
        type=line_number,
        metavar="N",
        help="with --resume: continue at line N (N1837 or 1837), on your word after checking the part, when "
        "the board cannot prove which lines ran (the refusal names the choices)",
    )
    p.add_argument("--journal", type=Path, help="journal file (default: JOB.journal.jsonl)")
    p.add_argument("--no-xonxoff", action="store_true", help="switch software flow control off")
    p.add_argument(
        "--stall-timeout-s", type=positive_float, default=5.0, help="silence that is a stall"
    )
    p.add_argument("--quiet", action="store_true", help="no progress on stderr")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


#: How a complete job ends: a program end (M2, M30) or the ``(end)`` comment `gcode` writes.
_END_MARKERS = ("M2", "M02", "M30", "(END)")


def _check_complete(path: Path, text: str) -> None:
    """Refuse a job cut short (a copy or download that did not finish): it bends half a part.

    A job is complete when its last line is an end marker (M2, M30, ``(end)``) or the
    file ends with a line break; a last line without its line break and without an
    end marker is where a cut file stops.
    """
    from cvmeasure.errors import InputError

    lines = [t.strip().upper() for t in text.splitlines() if t.strip()]
    last = lines[-1] if lines else ""
    words = last.split()
    if words and words[0].startswith("N") and len(words) > 1:
        words = words[1:]
    ended = bool(words) and (words[0] in _END_MARKERS or " ".join(words).startswith("(END"))
    if not ended and not text.endswith(("\n", "\r")):
        raise InputError(
            path,
            f"the job's last line {last[:40]!r} has no line break and the job no end line "
            "(M2, M30, (end)): the file looks cut short; add the end line if it is complete",
        )


def run(args: argparse.Namespace) -> int:
    from cvmeasure.driver.stream import StreamConfig, prepare_job, stream_job
    from cvmeasure.driver.transport import open_link
    from cvmeasure.errors import InputError

    try:
        text = args.job.read_text(encoding="ascii")
    except FileNotFoundError:
        raise InputError(args.job, "G-code file not found") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(args.job, f"cannot read G-code: {exc}") from None
    _check_complete(args.job, text)
    job = prepare_job(text.splitlines(), source=str(args.job))
    journal = args.journal or args.job.with_name(args.job.name + ".journal.jsonl")
    if args.from_line is not None and not args.resume:
        raise InputError("--from-line", "only applies with --resume")
    if args.resume and not journal.is_file():
        raise InputError(journal, "no journal to resume from")
    config = StreamConfig(stall_timeout_s=args.stall_timeout_s)

    on_terminal = sys.stderr.isatty()

    def progress(sent: int, total: int, executed: int | None) -> None:
        if args.quiet:
            return
        if on_terminal and (sent == total or sent % 20 == 0):  # one line, redrawn
            print(f"\rsent {sent}/{total}, executing N{executed}", end="", file=sys.stderr)
        elif not on_terminal and (sent == total or sent % 200 == 0):  # a log: whole lines
            print(f"sent {sent}/{total}, executing N{executed}", file=sys.stderr)

    with open_link(args.port, xonxoff=not args.no_xonxoff) as link:
        try:
            result = stream_job(
                link,
                job,
                journal=journal,
                resume=args.resume,
                config=config,
                progress=progress,
                source=str(args.job),
                force=args.force,
                from_line=args.from_line,
            )
        finally:
            if not args.quiet and on_terminal:
                print(file=sys.stderr)
    if args.json:
        print(json.dumps({"journal": str(journal), **result.to_dict()}, indent=2))
    else:
        for note in result.notes:
            print(f"warning: {note}", file=sys.stderr)
        where = f" (resumed at line {result.resumed_from + 1})" if args.resume else ""
        print(
            f"done: {result.lines_total} lines, N{result.executed_line} executed{where}, "
            f"{result.seconds:.1f} s; journal {journal}"
        )
    return 0
