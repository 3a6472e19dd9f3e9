"""JSON and text-mode commands of the held-out TinyG controller, and its reports.

JSON commands (``{"name":value}``): ``null``, ``""``, ``"n"`` or ``true`` read a value,
anything else sets it; ``{"sr":{...}}`` chooses the status-report fields, ``{"sr":null}``
asks for a full report, ``{"qr":null}`` the free planner buffers, ``{"rx":null}`` the free
RX bytes, ``{"qf":1}`` requests a queue flush, ``{"clear":null}`` clears an alarm,
``{"gc":"..."}`` runs a G-code block. Relaxed JSON (``{sr:n}``) is accepted. A ``$`` or
``?`` line switches the board to text mode (the pitfall every JSON host must avoid) and is
answered in text; the next ``{`` line switches back.
"""

from __future__ import annotations

import json
import re
from typing import TYPE_CHECKING

from benchmarks.heldout.tinyg_gcode import AXES

if TYPE_CHECKING:
    from benchmarks.heldout.tinyg_machine import TinyGMachine

__all__ = ["json_command", "queue_report", "status_report", "status_values", "text_command"]

STAT_UNRECOGNIZED = 100
STAT_JSON_SYNTAX = 111
_RELAXED_KEY = re.compile(r"([{,])\s*([A-Za-z_][A-Za-z0-9_]*)\s*:")
_RELAXED_VALUE = re.compile(r":\s*([ntf])\s*([,}])")


def _is_read(value: object) -> bool:
    """``null``, ``""``, ``"n"`` or ``true`` read a value (``1 == True`` must not count)."""
    return value is None or value is True or (isinstance(value, str) and value in ("", "n"))


_READ_ONLY = {"fv", "fb", "hv", "hp", "id"}


def _loads(text: str) -> object:
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        words = {"n": "null", "t": "true", "f": "false"}
        relaxed = _RELAXED_KEY.sub(r'\1"\2":', text)
        relaxed = _RELAXED_VALUE.sub(lambda m: ":" + words[m.group(1)] + m.group(2), relaxed)
        return json.loads(relaxed)


def status_values(m: TinyGMachine) -> dict[str, object]:
    """Every status-report field's current value."""
    pos = m.position()
    values: dict[str, object] = {f"pos{a}": round(pos[a], 3) for a in AXES}
    running = m.current is not None and m.motion == "run" and m.stall_until is None
    values.update(
        line=m.reported_line(),
        feed=round(m.model.feed_mm_min, 3),
        vel=round(m.current.rate_mm_min, 3) if running and m.current else 0.0,
        unit=0 if m.model.inches else 1,
        coor=1,
        dist=0 if m.model.absolute else 1,
        frmo=0,
        momo=m.model.motion if m.model.motion is not None else 0,
        stat=m.stat(),
    )
    return values


def status_report(m: TinyGMachine, now: float, full: bool = False) -> dict | None:
    """The ``sr`` to send now: the changed fields (``$sv=1``), all (``full`` or ``$sv=2``)."""
    values = status_values(m)
    fields = {k: values[k] for k in m.sr_fields if k in values}
    if not full and m.settings["sv"] == 1:
        fields = {k: v for k, v in fields.items() if m.last_sr.get(k) != v}
    m.last_sr.update(fields)
    m.last_sr_t = now
    return fields or None


def queue_report(m: TinyGMachine, force: bool = False) -> None:
    """``{"qr":n}`` when the free planner count changed (``$qv`` 1), with ``qi``/``qo`` at 2."""
    qv = m.settings["qv"]
    free = m.planner_free
    if qv == 0 or (free == m.last_qr and not force):
        return
    m.last_qr = free
    report: dict[str, int] = {"qr": free}
    if qv == 2:
        report.update(qi=m.qi, qo=m.qo)
    m.qi = m.qo = 0
    m.emit(report)


def _set_sr_fields(m: TinyGMachine, spec: dict) -> dict:
    for key, on in spec.items():
        if on in (True, "t", 1) and key not in m.sr_fields:
            m.sr_fields.append(key)
        elif on in (False, "f", 0) and key in m.sr_fields:
            m.sr_fields.remove(key)
    return spec


def _one(m: TinyGMachine, key: str, value: object, text: str, nbytes: int, now: float):
    """One name/value pair: (status, response value)."""
    if key == "gc":
        status, _ = m._gcode(str(value), nbytes, now)
        return status, value
    if key == "sr":
        if isinstance(value, dict):
            return 0, _set_sr_fields(m, value)
        values = status_values(m)
        return 0, {k: values[k] for k in m.sr_fields if k in values}
    if key == "qr":
        return 0, m.planner_free
    if key == "rx":
        return 0, m.rx_free
    if key == "qf":
        m.req_flush = True
        return 0, value
    if key in ("clear", "clr"):
        if m.machine == "alarm":
            m.machine = "stop"
        return 0, value
    if key == "sys":
        return 0, {k: m.settings[k] for k in ("fv", "fb", "hp", "hv", "id", "ej", "jv", "ex")}
    values = status_values(m)
    if key in values and _is_read(value):
        return 0, values[key]
    if key in m.settings:
        if _is_read(value) or key in _READ_ONLY:
            return 0, m.settings[key]
        try:
            m.settings[key] = type(m.settings[key])(value)  # type: ignore[call-arg]
        except (TypeError, ValueError):
            return 102, value
        return 0, m.settings[key]
    return STAT_UNRECOGNIZED, value


def json_command(m: TinyGMachine, text: str, nbytes: int, now: float) -> None:
    """Answer one JSON line with ``{"r":{...},"f":[...]}``."""
    try:
        obj = _loads(text)
    except json.JSONDecodeError:
        m.respond({}, STAT_JSON_SYNTAX, nbytes)
        return
    if not isinstance(obj, dict):
        m.respond({}, STAT_JSON_SYNTAX, nbytes)
        return
    body: dict = {}
    status = 0
    for key, value in obj.items():
        st, out = _one(m, key.lower(), value, text, nbytes, now)
        body[key] = out
        status = status or st
    m.respond(body, status, nbytes)


def text_command(m: TinyGMachine, text: str) -> None:
    """``$name``, ``$name=value``, ``$$``, ``?``: answered in text (the board is now in text mode)."""
    if text.startswith("?"):
        v = status_values(m)
        m.text_out(f"X position: {v['posx']}\nY position: {v['posy']}\nstat: {v['stat']}\n")
    elif text in ("$", "$$"):
        for k, v in m.settings.items():
            m.text_out(f"[{k}] {v}\n")
    elif text.startswith("$"):
        name, _, value = text[1:].partition("=")
        name = name.strip().lower()
        if name not in m.settings:
            m.text_out(f"{text[1:]} Unrecognized command or config name\n")
        else:
            if value and name not in _READ_ONLY:
                try:
                    m.settings[name] = type(m.settings[name])(value.strip())  # type: ignore[call-arg]
                except ValueError:
                    m.text_out("Bad number format\n")
            m.text_out(f"[{name}] {m.settings[name]}\n")
    m.text_out("tinyg [mm] ok> \n")
