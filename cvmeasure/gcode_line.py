"""One G-code line as the bytes sent to TinyG, checked: the rule jobs and the driver share.

Jobs are written on the design and material side (:mod:`cvmeasure.gcode`) and streamed by
:mod:`cvmeasure.driver`; both check every line with :func:`encode_line`, so it sits here,
below both, and neither imports the other for it.
"""

from __future__ import annotations

__all__ = ["MAX_LINE_CHARS", "comment_text", "encode_line"]

#: Longest line this host sends (the firmware's own limit is 255 characters).
MAX_LINE_CHARS = 80

# realtime characters, text-mode switches and control characters: the board acts on them
_FORBIDDEN = set("!~%$?") | {chr(c) for c in range(32)} | {chr(127)}


def encode_line(text: str) -> bytes:
    """One G-code line as the bytes to send: the text plus ``\\n``.

    Raises
    ------
    ValueError
        Empty, longer than :data:`MAX_LINE_CHARS`, not ASCII, or containing a
        realtime character (``! ~ %``), ``$``, ``?`` or a control character:
        any of these would be acted on by the board's interrupt or switch it to
        text mode, so it is never sent as part of a line.
    """
    if not text:
        raise ValueError("empty G-code line")
    if len(text) > MAX_LINE_CHARS:
        raise ValueError(f"G-code line longer than {MAX_LINE_CHARS} characters: {text[:40]!r}...")
    bad = sorted({c for c in text if c in _FORBIDDEN or ord(c) > 126})
    if bad:
        raise ValueError(f"G-code line {text!r} contains forbidden character(s) {bad!r}")
    return text.encode("ascii") + b"\n"


def comment_text(text: str) -> str:
    """``text`` fit for a job file's comment lines: unprintable characters and those the
    board acts on (``! ~ % $ ?``) dropped, so a header never acts on the machine."""
    return "".join(c for c in text if c.isprintable() and c not in "!~%$?")
