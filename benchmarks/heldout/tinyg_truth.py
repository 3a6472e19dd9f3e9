"""What the held-out controller really did: its truth log."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

__all__ = ["Executed", "Received", "TruthLog"]


@dataclass
class Executed:
    """One motion line as the runtime ran it.

    ``fraction`` is the share of the move's length that ran (1.0 = all of it; less when a
    hold was followed by a flush or a reset); positions are machine mm (X = pin deg).
    ``how`` is ``"done"``, ``"flushed"`` or ``"reset"``.
    """

    line: int
    text: str
    fraction: float
    start: dict[str, float]
    end: dict[str, float]
    t_start_s: float
    t_end_s: float
    how: str


@dataclass
class Received:
    """One line the parser took from the RX buffer (after any RX fault), with its status."""

    line: int | None
    text: str
    nbytes: int
    status: int
    t_s: float
    queued: bool


@dataclass
class TruthLog:
    """Everything the controller did, in order; times are seconds since it started."""

    executed: list[Executed] = field(default_factory=list)
    received: list[Received] = field(default_factory=list)
    events: list[dict] = field(default_factory=list)
    position: dict[str, float] = field(default_factory=dict)
    faults: list[dict] = field(default_factory=list)

    def executed_lines(self, min_fraction: float = 0.0) -> list[int]:
        """Line numbers of the moves that ran (more than ``min_fraction`` of them), in order."""
        return [e.line for e in self.executed if e.fraction > min_fraction]

    def to_json(self) -> dict:
        """The log as plain JSON types."""
        return {
            "executed": [asdict(e) for e in self.executed],
            "received": [asdict(r) for r in self.received],
            "events": list(self.events),
            "position": dict(self.position),
            "faults": list(self.faults),
        }

    @classmethod
    def from_json(cls, data: dict) -> TruthLog:
        """Read a log written by :meth:`to_json`."""
        return cls(
            executed=[Executed(**e) for e in data["executed"]],
            received=[Received(**r) for r in data["received"]],
            events=list(data["events"]),
            position=dict(data["position"]),
            faults=list(data["faults"]),
        )
