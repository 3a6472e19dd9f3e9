"""The TinyG v8 serial protocol as pure functions: what goes on the wire, byte for byte.

Host side: :func:`encode_line` (a G-code line, checked: ASCII, no realtime or
control characters, ``\\n`` only), :func:`encode_json` (a JSON command),
:class:`LineSplitter` (received bytes -> lines, XON/XOFF stripped) and
:func:`parse_message` (one received line -> a typed message, never raising).
Device side (the double): :func:`format_response`, :func:`format_status_report`,
:func:`format_queue_report`, :func:`format_exception`, :func:`format_rx_report`.
Both sides: :func:`parse_block` (one G-code block into words) and
:func:`track_positions` (the machine position after every line of a job).

Message shapes (reference ``diwire-tinyg.md`` sections 2.2-2.3):

=====================================  ========================================
``{"r":{...},"f":[1,status,bytes]}``   :class:`Response` (``f`` may also sit
                                       inside ``r``; extra footer items ignored)
``{"sr":{...}}``                       :class:`StatusReport` (filtered fields)
``{"qr":n}`` (+ ``qi``, ``qo``)        :class:`QueueReport` (free planner slots)
``{"er":{"st":n,"msg":...}}``          :class:`ExceptionReport`
``{"rx":n}``                           :class:`RxReport` (free RX bytes)
anything else                          :class:`Unparsed` (logged, never an ack)
=====================================  ========================================

``bytes`` in a footer is the length of the line the board consumed, terminator
included: the host checks it against the head of its in-flight queue.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Any, Literal

from cvmeasure.gcode_line import MAX_LINE_CHARS, encode_line

__all__ = [
    "XON",
    "XOFF",
    "FEEDHOLD",
    "CYCLE_START",
    "QUEUE_FLUSH",
    "RESET",
    "REALTIME_BYTES",
    "RX_BUFFER_BYTES",
    "PLANNER_SLOTS",
    "PLANNER_HEADROOM",
    "XOFF_HIGH_WATER",
    "XON_LOW_WATER",
    "MAX_LINE_CHARS",
    "INPUT_LINE_MAX",
    "MachineStat",
    "Status",
    "STATUS_TEXT",
    "FooterStyle",
    "Response",
    "StatusReport",
    "QueueReport",
    "ExceptionReport",
    "RxReport",
    "Unparsed",
    "Message",
    "LineSplitter",
    "encode_line",
    "encode_json",
    "parse_message",
    "format_response",
    "format_status_report",
    "format_queue_report",
    "format_exception",
    "format_rx_report",
    "GcodeBlock",
    "GcodeError",
    "parse_block",
    "track_positions",
    "AXES",
]

XON = 0x11
XOFF = 0x13
#: Realtime characters, trapped by the board anywhere in the byte stream.
FEEDHOLD = b"!"
CYCLE_START = b"~"
QUEUE_FLUSH = b"%"
RESET = b"\x18"
REALTIME_BYTES = frozenset(b"!~%\x18")

#: TinyG 440 receive ring buffer; a byte arriving when it is full is dropped.
RX_BUFFER_BYTES = 254
#: Planner buffers, and the free ones below which the board stops reading lines.
PLANNER_SLOTS = 32
PLANNER_HEADROOM = 4
#: XON/XOFF watermarks of the RX buffer (80 % and 10 % of 254).
XOFF_HIGH_WATER = 203
XON_LOW_WATER = 25
#: The firmware's longest input line (this host sends at most MAX_LINE_CHARS).
INPUT_LINE_MAX = 255

#: Machine axes tracked by the driver (X pin deg, Y feed mm, Z pin duck, A rotation).
AXES = ("x", "y", "z", "a")


class MachineStat(IntEnum):
    """``sr.stat`` values of TinyG (``cmCombinedState``)."""

    INITIALIZING = 0
    READY = 1
    ALARM = 2
    STOP = 3
    END = 4
    RUN = 5
    HOLD = 6
    PROBE = 7
    CYCLE = 8
    HOMING = 9
    JOG = 10
    SHUTDOWN = 11


class Status(IntEnum):
    """The footer / exception status codes this project uses (TinyG 440 numbering)."""

    OK = 0
    UNRECOGNIZED_NAME = 100
    MALFORMED_COMMAND = 101
    BAD_NUMBER = 102
    INPUT_TOO_LONG = 107
    JSON_SYNTAX = 111
    GCODE_GENERIC = 130
    G_UNSUPPORTED = 131
    M_UNSUPPORTED = 132
    AXIS_NOT_CONFIGURED = 137
    FEEDRATE_MISSING = 152
    MINIMUM_TIME_MOVE = 202
    MACHINE_ALARMED = 203
    LIMIT_SWITCH_HIT = 204


STATUS_TEXT: dict[int, str] = {
    0: "OK",
    100: "unrecognized command or config name",
    101: "malformed command",
    102: "bad number format",
    107: "input exceeds max length",
    111: "JSON syntax error",
    130: "generic G-code input error",
    131: "G-code command unsupported",
    132: "M-code command unsupported",
    137: "axis specified that is not configured",
    152: "feedrate not specified",
    202: "minimum time move",
    203: "machine is alarmed",
    204: "limit switch hit",
}

FooterStyle = Literal["g2", "440", "446"]


# ---------------------------------------------------------------------------
# Host -> board


def encode_json(command: Mapping[str, Any]) -> bytes:
    """A JSON command line (compact, ``\\n``-terminated), e.g. ``{"sr":null}``.

    TinyG reads ``n`` / ``null`` as "report this value"; Python's ``None``
    serialises to ``null``.
    """
    if command.get("jv") == 0:
        raise ValueError("jv=0 silences every response and breaks flow control; use jv >= 1")
    text = json.dumps(dict(command), separators=(",", ":"), allow_nan=False)
    if len(text) + 1 > INPUT_LINE_MAX:
        raise ValueError(f"JSON command longer than {INPUT_LINE_MAX - 1} characters")
    if any(c in text for c in "!~%"):
        raise ValueError(f"JSON command {text!r} contains a realtime character")
    return text.encode("ascii") + b"\n"


# ---------------------------------------------------------------------------
# Board -> host: splitting and parsing


class LineSplitter:
    """Incremental splitter of received bytes into lines.

    XON/XOFF bytes are removed wherever they appear (a pty or a USB driver may
    pass them through); CR and LF both end a line; empty lines are dropped.
    """

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes; return the complete lines (without terminators)."""
        out: list[bytes] = []
        for byte in data:
            if byte in (XON, XOFF):
                continue
            if byte in (0x0A, 0x0D):
                if self._buf:
                    out.append(bytes(self._buf))
                    self._buf.clear()
                continue
            self._buf.append(byte)
        return out

    @property
    def pending(self) -> bytes:
        """Bytes of an unfinished line."""
        return bytes(self._buf)


@dataclass(frozen=True)
class Response:
    """The board's answer to one line: ``{"r":{...},"f":[rev,status,bytes,...]}``.

    Attributes
    ----------
    status : footer status code (0 = OK).
    nbytes : bytes the board consumed for the line, terminator included.
    body : the ``r`` object (the footer removed when it was nested inside).
    footer : the whole footer, as received.
    """

    status: int
    nbytes: int
    body: dict[str, Any]
    footer: tuple[int, ...]

    @property
    def ok(self) -> bool:
        return self.status == 0

    @property
    def is_banner(self) -> bool:
        """The start-up banner (after power-up or ^X): never an ack."""
        return str(self.body.get("msg", "")).upper() == "SYSTEM READY"


@dataclass(frozen=True)
class StatusReport:
    """``{"sr":{...}}``: the fields that changed (filtered) or all (verbose)."""

    fields: dict[str, Any]

    @property
    def stat(self) -> int | None:
        v = self.fields.get("stat")
        return None if v is None else int(v)

    @property
    def line(self) -> int | None:
        v = self.fields.get("line")
        return None if v is None else int(v)


@dataclass(frozen=True)
class QueueReport:
    """``{"qr":free}``: free planner buffers (32 = empty); ``qi``/``qo`` when triple."""

    free_slots: int
    added: int | None = None
    removed: int | None = None


@dataclass(frozen=True)
class ExceptionReport:
    """``{"er":{"st":code,"msg":text,...}}``: an asynchronous exception (alarm)."""

    status: int
    message: str
    fields: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class RxReport:
    """``{"rx":n}``: free bytes in the board's RX buffer (also sent after a flush)."""

    free_bytes: int


@dataclass(frozen=True)
class Unparsed:
    """A received line that is none of the above (malformed JSON, text mode)."""

    text: str
    reason: str


Message = Response | StatusReport | QueueReport | ExceptionReport | RxReport | Unparsed


def _as_int(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise TypeError(f"not a number: {value!r}")
    return int(value)


def parse_message(line: bytes | str) -> Message:
    """Parse one received line (without its terminator). Never raises.

    Examples
    --------
    >>> parse_message(b'{"r":{},"f":[1,0,11]}')
    Response(status=0, nbytes=11, body={}, footer=(1, 0, 11))
    >>> parse_message(b'{"qr":28}')
    QueueReport(free_slots=28, added=None, removed=None)
    """
    text = line.decode("ascii", errors="replace") if isinstance(line, bytes) else line
    text = text.strip()
    try:
        obj = json.loads(text)
    except (json.JSONDecodeError, ValueError):
        return Unparsed(text, "not JSON")
    if not isinstance(obj, dict):
        return Unparsed(text, "not a JSON object")
    try:
        if "r" in obj or "f" in obj:
            body = obj.get("r", {})
            if not isinstance(body, dict):
                return Unparsed(text, "'r' is not an object")
            body = dict(body)
            footer = obj.get("f", body.pop("f", None))
            if not isinstance(footer, list) or len(footer) < 3:
                return Unparsed(text, "response without a valid footer")
            items = tuple(_as_int(v) for v in footer)
            return Response(status=items[1], nbytes=items[2], body=body, footer=items)
        if "sr" in obj:
            if not isinstance(obj["sr"], dict):
                return Unparsed(text, "'sr' is not an object")
            return StatusReport(dict(obj["sr"]))
        if "qr" in obj:
            qi, qo = obj.get("qi"), obj.get("qo")
            return QueueReport(
                _as_int(obj["qr"]),
                None if qi is None else _as_int(qi),
                None if qo is None else _as_int(qo),
            )
        if "er" in obj:
            er = obj["er"]
            if not isinstance(er, dict) or "st" not in er:
                return Unparsed(text, "'er' without a status")
            return ExceptionReport(_as_int(er["st"]), str(er.get("msg", "")), dict(er))
        if "rx" in obj:
            return RxReport(_as_int(obj["rx"]))
    except TypeError as exc:
        return Unparsed(text, str(exc))
    return Unparsed(text, "unknown message")


# ---------------------------------------------------------------------------
# Board side: formatting (used by the double; tested byte for byte)


def _dumps(obj: Any) -> bytes:
    return json.dumps(obj, separators=(",", ":"), allow_nan=False).encode("ascii") + b"\n"


def _checksum(text: str) -> int:
    # A stand-in for the 440 footer's checksum (hosts ignore it): 31-hash mod 9999.
    h = 0
    for ch in text:
        h = (h * 31 + ord(ch)) % 9999
    return h


def format_response(
    body: Mapping[str, Any], status: int, nbytes: int, *, style: FooterStyle = "g2"
) -> bytes:
    """``{"r":body,"f":[...]}\\n``: footer ``[1,st,n]`` (g2 / Pensa), ``[1,st,n,cks]``
    (TinyG 440) or ``[2,st,n]`` (TinyG 446+ stream mode).

    Examples
    --------
    >>> format_response({}, 0, 11)
    b'{"r":{},"f":[1,0,11]}\\n'
    """
    head = json.dumps(dict(body), separators=(",", ":"), allow_nan=False)
    if style == "g2":
        footer: list[int] = [1, status, nbytes]
    elif style == "440":
        footer = [1, status, nbytes, _checksum(head)]
    elif style == "446":
        footer = [2, status, nbytes]
    else:
        raise ValueError(f"unknown footer style {style!r}; use g2, 440 or 446")
    return _dumps({"r": dict(body), "f": footer})


def _round(value: Any) -> Any:
    if isinstance(value, float):
        return 0.0 if math.isclose(value, 0.0, abs_tol=5e-4) else round(value, 3)
    return value


def format_status_report(fields: Mapping[str, Any]) -> bytes:
    """``{"sr":{...}}\\n`` with floats rounded to 3 decimals as TinyG prints them."""
    return _dumps({"sr": {k: _round(v) for k, v in fields.items()}})


def format_queue_report(free_slots: int) -> bytes:
    """``{"qr":n}\\n``."""
    return _dumps({"qr": int(free_slots)})


def format_exception(status: int, message: str, *, build: float = 440.21) -> bytes:
    """``{"er":{"fb":build,"st":code,"msg":text}}\\n``."""
    return _dumps({"er": {"fb": build, "st": int(status), "msg": message}})


def format_rx_report(free_bytes: int) -> bytes:
    """``{"rx":n}\\n``."""
    return _dumps({"rx": int(free_bytes)})


# ---------------------------------------------------------------------------
# G-code blocks


class GcodeError(ValueError):
    """A G-code block the board rejects; ``status`` is its footer code."""

    def __init__(self, status: int, message: str) -> None:
        self.status = int(status)
        super().__init__(message)


@dataclass(frozen=True)
class GcodeBlock:
    """One parsed G-code block (the subset the DIWire uses).

    Attributes
    ----------
    line_number : the ``N`` word, or None.
    g_codes : the G words in order (``(91.0, 1.0)`` for ``G91 G1``).
    m_codes : the M words in order.
    axes : axis letter (lower case) -> value, in the block's distance mode.
    feed : the ``F`` word (units per minute), or None.
    comment : text of a ``(...)`` or ``;`` comment.
    """

    line_number: int | None
    g_codes: tuple[float, ...] = ()
    m_codes: tuple[int, ...] = ()
    axes: dict[str, float] = field(default_factory=dict)
    feed: float | None = None
    comment: str = ""

    @property
    def motion(self) -> int | None:
        """0 (rapid) or 1 (feed) when the block names a motion mode."""
        for g in self.g_codes:
            if g in (0.0, 1.0):
                return int(g)
        return None

    @property
    def distance_mode(self) -> str | None:
        """``"absolute"`` (G90), ``"relative"`` (G91) or None when not set here."""
        mode = None
        for g in self.g_codes:
            if g == 90.0:
                mode = "absolute"
            elif g == 91.0:
                mode = "relative"
        return mode


_WORD = re.compile(r"([A-Za-z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_SUPPORTED_G = {0.0, 1.0, 4.0, 20.0, 21.0, 28.3, 90.0, 91.0}
_SUPPORTED_M = {0, 2, 30}


def parse_block(text: str) -> GcodeBlock:
    """Parse one G-code block (case-insensitive; comments end the block).

    Raises
    ------
    GcodeError
        Unknown letters, unsupported G/M codes or garbage, with TinyG's status.
    """
    comment = ""
    body = text
    for opener in ("(", ";"):
        pos = body.find(opener)
        if pos >= 0:
            comment = body[pos + 1 :].rstrip(")").strip()
            body = body[:pos]
    pos = 0
    line_number: int | None = None
    g_codes: list[float] = []
    m_codes: list[int] = []
    axes: dict[str, float] = {}
    feed: float | None = None
    stripped = body.strip()
    while pos < len(stripped):
        if stripped[pos].isspace():
            pos += 1
            continue
        m = _WORD.match(stripped, pos)
        if m is None:
            raise GcodeError(Status.GCODE_GENERIC, f"cannot read G-code near {stripped[pos:]!r}")
        letter, number = m.group(1).upper(), float(m.group(2))
        pos = m.end()
        if letter == "N":
            line_number = int(number)
        elif letter == "G":
            if round(number, 1) not in _SUPPORTED_G:
                raise GcodeError(Status.G_UNSUPPORTED, f"G{m.group(2)} unsupported")
            g_codes.append(round(number, 1))
        elif letter == "M":
            if int(number) not in _SUPPORTED_M:
                raise GcodeError(Status.M_UNSUPPORTED, f"M{m.group(2)} unsupported")
            m_codes.append(int(number))
        elif letter.lower() in AXES:
            axes[letter.lower()] = number
        elif letter == "F":
            feed = number
        elif letter == "P":
            axes["p"] = number
        else:
            raise GcodeError(Status.AXIS_NOT_CONFIGURED, f"word {letter} unsupported")
    return GcodeBlock(line_number, tuple(g_codes), tuple(m_codes), axes, feed, comment)


def track_positions(
    blocks: Sequence[GcodeBlock] | Iterable[GcodeBlock],
    start: Mapping[str, float] | None = None,
    *,
    relative: bool = False,
) -> list[dict[str, float]]:
    """The machine position after each block (G90/G91 and G28.3 honoured).

    Parameters
    ----------
    blocks : parsed blocks, in order.
    start : position before the first block (axis -> value; missing axes are 0).
    relative : the distance mode in force before the first block.

    Returns
    -------
    list of dict
        One ``{axis: value}`` per block (X deg, Y mm, Z, A), after the block.
    """
    pos = {a: float((start or {}).get(a, 0.0)) for a in AXES}
    rel = relative
    out: list[dict[str, float]] = []
    for block in blocks:
        mode = block.distance_mode
        if mode is not None:
            rel = mode == "relative"
        moved = {k: v for k, v in block.axes.items() if k in AXES}
        if 28.3 in block.g_codes:
            pos.update(moved)
        elif moved:
            for axis, value in moved.items():
                pos[axis] = pos[axis] + value if rel else value
        out.append(dict(pos))
    return out
