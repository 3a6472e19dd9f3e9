"""The G-code block parser and move model of the held-out TinyG controller.

Written from TinyG's documented behaviour (synthetos/TinyG wiki and status-code table):
lines end at CR or LF, the high bit of every byte is masked off, comments in ``(`` or
``;`` end the block, words are a letter and a number, a repeated word overrides the
earlier one (no error), ``N`` anywhere sets the model line number. X, Y, Z, A are linear
axes in mm (the DIWire's X is the pin in degrees, still a linear axis to TinyG).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

__all__ = [
    "AXES",
    "STAT_BAD_NUMBER",
    "STAT_FEEDRATE_MISSING",
    "STAT_GCODE_GENERIC",
    "STAT_G_UNSUPPORTED",
    "STAT_INPUT_TOO_LONG",
    "STAT_MIN_TIME_MOVE",
    "STAT_M_UNSUPPORTED",
    "STAT_OK",
    "Block",
    "ModelState",
    "Move",
    "parse_block",
    "plan_move",
]

AXES = ("x", "y", "z", "a")

STAT_OK = 0
STAT_BAD_NUMBER = 102
STAT_INPUT_TOO_LONG = 107
STAT_GCODE_GENERIC = 130
STAT_G_UNSUPPORTED = 131
STAT_M_UNSUPPORTED = 132
STAT_FEEDRATE_MISSING = 142
STAT_MIN_TIME_MOVE = 202

_WORD = re.compile(r"([A-Z])([+-]?(?:\d+\.?\d*|\.\d+))?")
_SUPPORTED_G = {0.0, 1.0, 20.0, 21.0, 90.0, 91.0, 4.0, 92.0}
_SUPPORTED_M = {0.0, 1.0, 2.0, 30.0}


@dataclass(frozen=True)
class Block:
    """One parsed line: its words (last value wins), or the TinyG status that rejected it."""

    status: int
    words: dict[str, float] = field(default_factory=dict)
    gcodes: tuple[float, ...] = ()
    mcodes: tuple[float, ...] = ()

    @property
    def line_number(self) -> int | None:
        n = self.words.get("N")
        return None if n is None else int(n)


@dataclass
class ModelState:
    """The G-code model (TinyG's ``gm``): modal state and the planned position, mm."""

    position: dict[str, float] = field(default_factory=lambda: dict.fromkeys(AXES, 0.0))
    absolute: bool = True
    inches: bool = False
    motion: int | None = None  # 0 = G0, 1 = G1
    feed_mm_min: float = 0.0
    line: int = 0


@dataclass
class Move:
    """A queued motion: from ``start`` to ``target`` (mm), lasting ``duration_s`` (machine time)."""

    line: int
    text: str
    start: dict[str, float]
    target: dict[str, float]
    duration_s: float
    rate_mm_min: float
    kind: str = "move"  # "move", "dwell", "stop" (M0/M1) or "end" (M2/M30)


def _clean(text: str) -> str:
    """Mask the high bit, cut the comment, drop whitespace, upper-case."""
    chars = []
    for ch in text:
        c = chr(ord(ch) & 0x7F)
        if c in "(;":
            break
        if not c.isspace():
            chars.append(c.upper())
    return "".join(chars)


def parse_block(text: str) -> Block:
    """Parse one G-code line (without its terminator) the way TinyG's parser does.

    Returns
    -------
    Block
        ``status`` 0 with the words, or the status code TinyG would answer.
    """
    body = _clean(text)
    if body.startswith("/"):
        body = body[1:]
    words: dict[str, float] = {}
    gcodes: list[float] = []
    mcodes: list[float] = []
    pos = 0
    while pos < len(body):
        m = _WORD.match(body, pos)
        if m is None:
            return Block(STAT_GCODE_GENERIC)
        if m.group(2) is None:
            return Block(STAT_BAD_NUMBER)
        letter, value = m.group(1), float(m.group(2))
        if letter == "G":
            if value not in _SUPPORTED_G:
                return Block(STAT_G_UNSUPPORTED)
            gcodes.append(value)
        elif letter == "M":
            if value not in _SUPPORTED_M:
                return Block(STAT_M_UNSUPPORTED)
            mcodes.append(value)
        elif letter not in "NXYZAFP":
            return Block(STAT_GCODE_GENERIC)
        else:
            words[letter] = value
        pos = m.end()
    return Block(STAT_OK, words, tuple(gcodes), tuple(mcodes))


def plan_move(
    block: Block,
    model: ModelState,
    text: str,
    vmax_mm_min: dict[str, float],
    min_move_s: float,
) -> tuple[int, Move | None]:
    """Apply a parsed block to the model; the move to queue, if any.

    Returns
    -------
    (status, move)
        ``move`` is None for a block that only sets modal state or the line number.
    """
    if block.line_number is not None:
        model.line = block.line_number
    for g in block.gcodes:
        if g in (20.0, 21.0):
            model.inches = g == 20.0
        elif g in (90.0, 91.0):
            model.absolute = g == 90.0
        elif g in (0.0, 1.0):
            model.motion = int(g)
    scale = 25.4 if model.inches else 1.0
    if "F" in block.words:
        model.feed_mm_min = block.words["F"] * scale
    line = model.line
    if 4.0 in block.gcodes:
        dwell = Move(
            line,
            text,
            dict(model.position),
            dict(model.position),
            block.words.get("P", 0.0),
            0.0,
            "dwell",
        )
        return STAT_OK, dwell
    for m in block.mcodes:
        kind = "end" if m in (2.0, 30.0) else "stop"
        return STAT_OK, Move(line, text, dict(model.position), dict(model.position), 0.0, 0.0, kind)
    axis_words = [a for a in AXES if a.upper() in block.words]
    if not axis_words:
        return STAT_OK, None
    if 92.0 in block.gcodes:  # G92 sets the position without motion
        for a in axis_words:
            model.position[a] = block.words[a.upper()] * scale
        return STAT_OK, None
    if model.motion is None:
        return STAT_GCODE_GENERIC, None
    target = dict(model.position)
    for a in axis_words:
        v = block.words[a.upper()] * scale
        target[a] = v if model.absolute else model.position[a] + v
    deltas = {a: target[a] - model.position[a] for a in AXES}
    length = math.sqrt(sum(d * d for d in deltas.values()))
    if length == 0.0:
        return STAT_OK, None
    if model.motion == 1:
        if model.feed_mm_min <= 0.0:
            return STAT_FEEDRATE_MISSING, None
        rate = model.feed_mm_min
        duration = length / rate * 60.0
    else:
        duration = max(abs(d) / vmax_mm_min[a] * 60.0 for a, d in deltas.items())
        rate = length / duration * 60.0
    if duration < min_move_s:
        return STAT_MIN_TIME_MOVE, None
    move = Move(line, text, dict(model.position), target, duration, rate)
    model.position = dict(target)
    return STAT_OK, move
