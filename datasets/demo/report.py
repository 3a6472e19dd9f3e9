"""What a demo step reports: measured quantities beside their truth, as a readable table."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = ["DemoRow", "DemoSection", "format_sections"]


@dataclass(frozen=True)
class DemoRow:
    """One measured quantity beside its ground truth."""

    quantity: str
    measured: float
    true: float | None
    unit: str
    tolerance: float | None = None

    @property
    def error(self) -> float | None:
        return None if self.true is None else self.measured - self.true

    @property
    def ok(self) -> bool | None:
        if self.tolerance is None or self.error is None:
            return None
        return abs(self.error) <= self.tolerance

    def to_dict(self) -> dict[str, Any]:
        return {
            "quantity": self.quantity,
            "measured": self.measured,
            "true": self.true,
            "error": self.error,
            "unit": self.unit,
            "tolerance": self.tolerance,
            "ok": self.ok,
        }


@dataclass
class DemoSection:
    """What one stage of the demo measured, and the files it wrote."""

    title: str
    rows: list[DemoRow] = field(default_factory=list)
    files: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    seconds: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        return {
            "title": self.title,
            "rows": [r.to_dict() for r in self.rows],
            "files": self.files,
            "notes": self.notes,
            "seconds": round(self.seconds, 3),
        }


def _fmt(value: float | None) -> str:
    if value is None:
        return "-"
    return f"{value:.4g}" if abs(value) < 1e4 else f"{value:.6g}"


def format_sections(sections: list[DemoSection]) -> str:
    """A readable plain-text table of every section."""
    lines: list[str] = []
    for s in sections:
        lines.append(f"== {s.title}  ({s.seconds:.1f} s)")
        lines.append(
            f"  {'quantity':<38} {'measured':>11} {'true':>11} {'error':>11} {'unit':<6} ok"
        )
        for r in s.rows:
            ok = {True: "yes", False: "NO", None: ""}[r.ok]
            lines.append(
                f"  {r.quantity:<38} {_fmt(r.measured):>11} {_fmt(r.true):>11} {_fmt(r.error):>11} {r.unit:<6} {ok}"
            )
        for note in s.notes:
            lines.append(f"  note: {note}")
        for f in s.files:
            lines.append(f"  wrote {f}")
    return "\n".join(lines)
