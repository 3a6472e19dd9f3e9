"""What the TinyG double injects and records: faults, bends, machine snapshots.

The data side of :mod:`cvmeasure.testing.double`: the faults a test asks for, the bends
the simulated machine made, a snapshot of the machine, and the double's own counters.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

__all__ = [
    "BANNER",
    "FaultKind",
    "FAULT_KINDS",
    "LINE_REPORTS",
    "LineReport",
    "Fault",
    "BendRecord",
    "MachineState",
    "PlannedMove",
    "DoubleStats",
    "MIN_MOVE_S",
    "DEFAULT_MAX_RATE",
]

FaultKind = Literal["drop_byte", "malformed_reply", "alarm", "stall", "vanish", "error_status"]
#: The faults the double can inject.
FAULT_KINDS: tuple[str, ...] = (
    "drop_byte",
    "malformed_reply",
    "alarm",
    "stall",
    "vanish",
    "error_status",
)
#: How ``sr.line`` reads after a queue flush: ``"executing"`` (the line the machine was
#: running) or ``"parsed"`` (TinyG firmware: the last line it parsed, flushed ones included).
LineReport = Literal["executing", "parsed"]
LINE_REPORTS: tuple[str, ...] = ("executing", "parsed")

#: Shortest move TinyG plans (MIN_SEGMENT_USEC), machine seconds.
MIN_MOVE_S = 0.0025
#: Axis maximum rates (units/min) used for G0, as seen in Pensa's 2016 logs.
DEFAULT_MAX_RATE = {"x": 7500.0, "y": 10000.0, "z": 30000.0, "a": 7500.0}
BANNER = {"fv": 0.97, "fb": 440.21, "hp": 1, "hv": 8, "id": "cvmeasure-double"}


@dataclass(frozen=True)
class Fault:
    """One fault to inject, once.

    Attributes
    ----------
    kind : one of :data:`FAULT_KINDS`.
    at_line : the 1-based count of lines the board has received (JSON and
        G-code) at which it fires: ``drop_byte`` drops a byte of that line,
        ``malformed_reply`` garbles its reply, ``stall`` freezes the board when
        it reads it, ``vanish`` closes the port right after answering it (the
        answer may go with the port), ``alarm``
        trips the limit switch when its move starts executing, ``error_status``
        rejects that G-code line with status 130 (it is not run; the lines after
        it are, as TinyG does).
    byte_index : for ``drop_byte``, which byte of the line (0 = the first); past its
        end, the terminator is dropped and the line merges with the next.
    duration_s : for ``stall``, how long the board freezes (wall seconds).
    """

    kind: FaultKind
    at_line: int
    byte_index: int = 0
    duration_s: float = 1.0

    def __post_init__(self) -> None:
        if self.kind not in FAULT_KINDS:
            raise ValueError(f"unknown fault {self.kind!r}; use one of {', '.join(FAULT_KINDS)}")
        if self.at_line < 1:
            raise ValueError("at_line counts from 1")

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": self.kind,
            "at_line": self.at_line,
            "byte_index": self.byte_index,
            "duration_s": self.duration_s,
        }


@dataclass(frozen=True)
class BendRecord:
    """One bend the double executed (simulated), in execution order.

    ``feed_before_mm`` is the wire fed since the previous bend (or the start);
    angles are signed, machine frame (CCW positive), degrees.
    """

    line_number: int | None
    feed_before_mm: float
    pin_deg: float
    loaded_bend_deg: float
    unloaded_bend_deg: float

    def to_dict(self) -> dict[str, Any]:
        return dict(self.__dict__)


@dataclass(frozen=True)
class MachineState:
    """A snapshot of the double's machine.

    Attributes
    ----------
    pin_deg : X, the pin's rotation from home (signed, deg).
    feed_mm : Y, wire fed since power-up (mm).
    duck : Z (0 = pin up, 180 = ducked).
    stat : ``sr.stat`` (:class:`MachineStat`).
    line : ``sr.line``, the N word of the executing (or last executed) block.
    bend_angle_deg : the wire leg's angle at the die right now (loaded while the
        pin holds it, unloaded after release, 0 after a feed), deg.
    head_deg : the head's real rotation from home (signed, deg): while the pin holds a
        bend, X after the machine's command effects (play lost, an offset, a drift), where
        a photo sees the pin; X otherwise.
    holding : the pin is pressing the wire.
    bends : every bend executed so far.
    planner_depth : moves queued (including the executing one).
    rx_bytes : bytes waiting in the RX ring.
    """

    pin_deg: float
    feed_mm: float
    duck: float
    stat: int
    line: int
    bend_angle_deg: float
    holding: bool
    bends: tuple[BendRecord, ...]
    planner_depth: int
    rx_bytes: int
    head_deg: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        d = dict(self.__dict__)
        d["bends"] = [b.to_dict() for b in self.bends]
        return d


@dataclass
class PlannedMove:
    """A move in the double's planner (machine seconds, units of its axes)."""

    seq: int
    line_number: int | None
    text: str
    target: dict[str, float]
    duration_s: float
    rate: float
    start: dict[str, float] | None = None
    elapsed_s: float = 0.0


@dataclass
class DoubleStats:
    """The double's counters: bytes dropped, flow control, lines, faults, blocks run."""

    rx_dropped_bytes: int = 0
    rx_peak_bytes: int = 0
    xoff_sent: int = 0
    xon_sent: int = 0
    lines_received: int = 0
    faults_fired: list[str] = field(default_factory=list)
    completed: list[int | None] = field(default_factory=list)
    partial: list[int | None] = field(default_factory=list)
    #: every block that moved, in order: (its N word, start, end), the end being where
    #: it stopped (a block cut short ends on its path): what the machine did, whatever
    #: the label a corrupted block carried
    moves: list[tuple[int | None, dict[str, float], dict[str, float]]] = field(default_factory=list)
