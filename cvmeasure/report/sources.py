"""What ``cvmeasure report`` is given: results JSON Lines, a session log or a calibration.

:func:`read_report_input` reads the file once and says what it holds: per-photo
results (``measure`` / ``batch`` JSON Lines), a calibration session's log
(``session.jsonl``: its bends' loaded and unloaded records, photo paths made
relative to the log's folder so their overlays are found), or a calibration JSON
(``session`` / ``fit`` output: the calibration report). Any other JSON file is
refused by naming what kind of file it is.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cvmeasure.errors import InputError
from cvmeasure.fileio import read_jsonl, sniff_kind

__all__ = ["ReportInput", "read_report_input", "session_log_records"]


@dataclass(frozen=True)
class ReportInput:
    """The records to report and what they came from (``kind``: "results", "session log",
    "calibration"); ``calibration`` the document itself for a calibration JSON."""

    kind: str
    records: list[dict[str, Any]]
    calibration: dict[str, Any] | None = None


def read_report_input(path: str | os.PathLike[str]) -> ReportInput:
    """Read ``path`` and say what it holds (see the module doc).

    Raises
    ------
    InputError
        Not JSON at all, a JSON file of another kind (named), or no records.
    """
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise InputError(
            p, "not a text file (give a results .jsonl, session.jsonl or calibration JSON)"
        ) from None
    except OSError as exc:
        raise InputError(p, f"cannot read: {exc.strerror or exc}") from None
    try:
        doc = json.loads(text)
    except (json.JSONDecodeError, RecursionError):
        doc = None  # JSON Lines (or broken, or nested too deeply): read line by line below
    if isinstance(doc, dict) and len(text.strip().splitlines()) > 1:
        kind = sniff_kind(p) or "a JSON document"
        if kind.startswith("a calibration JSON"):
            return ReportInput("calibration", [], doc)
        if not kind.startswith("JSON Lines"):
            raise InputError(
                p,
                f"this is {kind}, not results: report takes the JSON Lines of `measure`/`batch`, "
                "a session log (session.jsonl) or a calibration JSON",
            )
    # A cut last line is a write the report cannot see; say so rather than drop a record.
    if text and not text.endswith("\n") and _last_line_cut(text):
        raise InputError(
            p,
            "its last line is cut (a write interrupted?): run the command that wrote it again, "
            "or delete that line",
        )
    records = read_jsonl(p)
    if not records:
        raise InputError(p, "no records")
    if not all(isinstance(r, dict) for r in records):
        raise InputError(p, "every line must be a JSON object")
    if any("event" in r for r in records):
        return ReportInput("session log", session_log_records(records, p.parent))
    return ReportInput("results", records)


def _last_line_cut(text: str) -> bool:
    """Whether the text's last line (no newline after it) is not a whole JSON value."""
    try:
        json.loads(text.rsplit("\n", 1)[-1])
    except (json.JSONDecodeError, RecursionError):
        return True
    return False


def session_log_records(log: list[dict[str, Any]], folder: Path) -> list[dict[str, Any]]:
    """A session log's bends as report records: each photo's record (its path joined to the
    session folder, so its overlay is found) and the bend's trial record."""
    out: list[dict[str, Any]] = []
    for r in log:
        if r.get("event") != "sample":
            continue
        trial = int(r.get("step", 0)) + 1
        for which in ("loaded", "unloaded"):
            rec = dict(r.get(which) or {})
            rel = r.get(f"photo_{which}")
            if rel:
                rec["photo"] = str(folder / rel)
            rec.update({"kind": f"machine ({which})", "trial": trial})
            out.append(rec)
        u_lo = ((r.get("loaded") or {}).get("uncertainty_deg") or {}).get("bend_angle_deg")
        u_un = ((r.get("unloaded") or {}).get("uncertainty_deg") or {}).get("bend_angle_deg")
        unc = {}
        if u_lo is not None and u_un is not None:
            unc = {
                "loaded_bend_deg": u_lo,
                "unloaded_bend_deg": u_un,
                "springback_deg": (u_lo**2 + u_un**2) ** 0.5,
            }
        out.append(
            {
                "kind": "calibration bend",
                "trial": trial,
                # the session's target is the wanted loaded angle, not the part's: no verdict
                "wanted_loaded_deg": r.get("target_deg"),
                "uncertainty_deg": unc,
                "commanded_pin_deg": r.get("commanded_pin_deg"),
                "loaded_bend_deg": (r.get("loaded") or {}).get("bend_angle_deg"),
                "unloaded_bend_deg": (r.get("unloaded") or {}).get("bend_angle_deg"),
                "springback_deg": r.get("springback_deg"),
                "direction": r.get("direction"),
            }
        )
    return out
