"""Faults the held-out TinyG controller can inject, and their command-line spelling.

A fault fires once, at a G-code line number (``kind@N``) or at a time after the controller
started (``kind@t2.5``), with an optional argument after a colon:

=========  ===========================================================  ==================
kind       what happens                                                 argument
=========  ===========================================================  ==================
stall      the runtime freezes when line N starts to execute (reports,  seconds (default:
           reading and realtime characters still work; holds wait)      until ^X reset)
noack      line N is executed but its ``r`` response is swallowed       -
xoff       XOFF sent when line N is read, no XON for a while            seconds (default 3)
error      line N is answered with an error status and not queued       status (default 130)
drop       one byte of line N is lost on RX (the LF: the line merges    byte index in the
           with the next one)                                           line (default -1 = LF)
garble     one byte of line N is flipped on RX (XOR with 0x01)          byte index (default 1)
gone       the port vanishes when line N starts to execute; the board   seconds until the port
           keeps running its queue; the port comes back later           is back (default 1)
=========  ===========================================================  ==================
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["FAULT_KINDS", "Fault", "parse_fault"]

FAULT_KINDS = ("stall", "noack", "xoff", "error", "drop", "garble", "gone")


@dataclass
class Fault:
    """One injected fault; ``line`` or ``at_s`` says when, ``arg`` how (see the module table)."""

    kind: str
    line: int | None = None
    at_s: float | None = None
    arg: float | None = None
    fired: bool = False

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"unknown fault kind {self.kind!r} (one of {', '.join(FAULT_KINDS)})")
        if (self.line is None) == (self.at_s is None):
            raise ValueError("a fault needs exactly one of a line number or a time")

    @property
    def spec(self) -> str:
        """The fault's command-line spelling."""
        when = f"{self.line}" if self.line is not None else f"t{self.at_s:g}"
        return f"{self.kind}@{when}" + ("" if self.arg is None else f":{self.arg:g}")


def parse_fault(spec: str) -> Fault:
    """Parse ``kind@N[:arg]`` or ``kind@t<seconds>[:arg]``.

    Raises
    ------
    ValueError
        With the spec named, when it is not of that form.
    """
    try:
        kind, rest = spec.split("@", 1)
        when, _, arg = rest.partition(":")
        value = float(arg) if arg else None
        if when.startswith("t"):
            return Fault(kind, at_s=float(when[1:]), arg=value)
        return Fault(kind, line=int(when), arg=value)
    except ValueError as exc:
        raise ValueError(f"bad fault {spec!r}: {exc}") from exc
