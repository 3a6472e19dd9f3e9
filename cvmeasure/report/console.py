"""The console's warning summary: every typed warning a run produced, grouped by code.

A command that measures several photos prints each photo's warnings beside its
result and, at the end, :func:`warning_summary`: one line per warning code with
how many photos gave it and one example message, so a warning given on every
photo (a plane from another pose, a kit whose heights are not the markers') is
not lost in a long table.
"""

from __future__ import annotations

from collections.abc import Iterable

from cvmeasure.warning import StageWarning

__all__ = ["warning_summary"]


def warning_summary(
    items: Iterable[tuple[str, StageWarning]], n_photos: int | None = None
) -> list[str]:
    """Lines summarising ``(source, warning)`` pairs: a header, then one line per code.

    ``source`` names where the warning was given (a photo); ``n_photos`` how many
    photos the run measured (default: those with a warning). Empty without warnings.

    >>> w = StageWarning("plane_scale", "the plane is from another pose", "plane")
    >>> warning_summary([("a.jpg", w), ("b.jpg", w)])[1]
    '  plane_scale on 2 of 2 photos (a.jpg, b.jpg): the plane is from another pose'
    """
    pairs = list(items)
    if not pairs:
        return []
    sources = list(dict.fromkeys(src for src, _ in pairs))
    total = max(n_photos or 0, len(sources))
    by_code: dict[str, list[tuple[str, StageWarning]]] = {}
    for src, w in pairs:
        by_code.setdefault(w.code, []).append((src, w))
    lines = [f"warnings: {len(by_code)} kind(s) on {len(sources)} of {total} photo(s)"]
    for code, got in by_code.items():
        on = list(dict.fromkeys(src for src, _ in got))
        names = ", ".join(on[:3]) + (", ..." if len(on) > 3 else "")
        lines.append(f"  {code} on {len(on)} of {total} photos ({names}): {got[0][1].message}")
    return lines
