"""Serial transports chosen by URL, as pyserial does.

``open_link(url)`` accepts everything :func:`serial.serial_for_url` does (a
device path such as ``/dev/ttyUSB0`` or ``COM3``, ``loop://``, ``socket://host:port``,
``spy://...``) plus our own ``sim://``: a :class:`~cvmeasure.driver.double.FakeTinyG`
started on a fresh pseudo-terminal and opened through pyserial like a real
port. ``sim://`` options are URL query parameters::

    sim://?speedup=50&footer=440&line_report=parsed&fault=stall@40&fault=drop_byte@12:5

(``fault=KIND@LINE[:BYTE_INDEX]``; see :class:`~cvmeasure.driver.double.Fault`).
A port that does not exist raises :class:`~cvmeasure.errors.InputError` naming it.
"""

from __future__ import annotations

import errno
import logging
import math
from dataclasses import dataclass
from typing import Any
from urllib.parse import parse_qs, urlsplit

import serial

try:  # POSIX: pyserial's flush() raises termios.error when the port has vanished
    from termios import error as _TermiosError
except ImportError:  # pragma: no cover - Windows
    _TermiosError = OSError  # type: ignore[misc,assignment]

from cvmeasure.driver.double import LINE_REPORTS, FakeTinyG, Fault
from cvmeasure.errors import DeviceError, InputError

__all__ = ["Link", "open_link", "parse_sim_url", "DEFAULT_BAUD"]

log = logging.getLogger(__name__)

#: TinyG's USB baud rate.
DEFAULT_BAUD = 115200


@dataclass
class Link:
    """An open serial link to a board (and the double behind it, for ``sim://``).

    Attributes
    ----------
    url : what was asked for.
    serial : the open pyserial object.
    double : the :class:`FakeTinyG` started for a ``sim://`` URL, else None.
    xonxoff : whether software flow control is on (host side, tty level).
    """

    url: str
    serial: Any
    double: FakeTinyG | None = None
    xonxoff: bool = True

    def write(self, data: bytes) -> None:
        """Write all of ``data``; a vanished port raises DeviceError."""
        try:
            self.serial.write(data)
            self.serial.flush()
        except serial.SerialTimeoutException as exc:
            raise DeviceError(f"{self.url}: write timed out (flow control stuck?)") from exc
        except (serial.SerialException, OSError, _TermiosError) as exc:
            raise DeviceError(f"{self.url}: port gone ({exc})") from exc

    def read_available(self) -> bytes:
        """Whatever has arrived (waits up to the port timeout for the first byte)."""
        try:
            waiting = self.serial.in_waiting
            return bytes(self.serial.read(max(1, waiting)))
        except (serial.SerialException, OSError, TypeError, _TermiosError) as exc:
            raise DeviceError(f"{self.url}: port gone ({exc})") from exc

    def close(self) -> None:
        try:
            self.serial.close()
        finally:
            if self.double is not None:
                self.double.close()

    def __enter__(self) -> Link:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def parse_sim_url(url: str) -> dict[str, Any]:
    """Keyword arguments of :class:`FakeTinyG` from a ``sim://`` URL.

    Raises
    ------
    InputError
        An unknown option or a malformed value (naming the URL).
    """
    query = parse_qs(urlsplit(url).query, keep_blank_values=True)
    kwargs: dict[str, Any] = {}
    faults: list[Fault] = []
    try:
        for key, values in query.items():
            if key == "speedup":
                kwargs["speedup"] = float(values[-1])
                if not 0 < kwargs["speedup"] < math.inf:
                    raise ValueError(f"speedup must be a finite number > 0, got {values[-1]!r}")
            elif key == "footer":
                kwargs["footer_style"] = values[-1]
            elif key == "line_report":
                if values[-1] not in LINE_REPORTS:
                    raise ValueError(f"line_report must be one of {', '.join(LINE_REPORTS)}")
                kwargs["line_report"] = values[-1]
            elif key == "fault":
                for v in values:
                    kind, _, rest = v.partition("@")
                    line, _, extra = rest.partition(":")
                    f = Fault(kind, int(line))  # type: ignore[arg-type]
                    if extra:
                        if kind == "stall":
                            f = Fault(kind, int(line), duration_s=float(extra))  # type: ignore[arg-type]
                        else:
                            f = Fault(kind, int(line), byte_index=int(extra))  # type: ignore[arg-type]
                    faults.append(f)
            else:
                raise ValueError(f"unknown option {key!r} (speedup, footer, line_report, fault)")
    except ValueError as exc:
        raise InputError(url, f"bad sim:// URL: {exc}") from None
    kwargs["faults"] = tuple(faults)
    return kwargs


def open_link(
    url: str,
    *,
    baudrate: int = DEFAULT_BAUD,
    xonxoff: bool = True,
    timeout_s: float = 0.02,
    write_timeout_s: float = 10.0,
    double: FakeTinyG | None = None,
) -> Link:
    """Open the board at ``url`` (8N1, software flow control by default).

    Parameters
    ----------
    url : a device path or pyserial URL, or ``sim://[?options]``.
    xonxoff : honour the board's XON/XOFF (TinyG ``$ex=1``).
    timeout_s : read timeout of the port (the reader polls).
    write_timeout_s : how long a write may stay blocked by XOFF before it fails.
    double : an already running double to attach to a ``sim://`` link instead
        of starting one (the caller keeps ownership).

    Raises
    ------
    InputError
        The port does not exist or cannot be opened, or the URL is malformed.
    """
    started: FakeTinyG | None = None
    target = url
    if url.lower().startswith("sim://"):
        if double is None:
            started = FakeTinyG(**parse_sim_url(url)).start()
            double = started
        target = double.port
    try:
        port = serial.serial_for_url(
            target,
            baudrate=baudrate,
            xonxoff=xonxoff,
            timeout=timeout_s,
            write_timeout=write_timeout_s,
        )
    except ValueError as exc:
        if started:
            started.close()
        raise InputError(url, f"cannot open port: {exc}") from None
    except (serial.SerialException, OSError) as exc:
        if started:
            started.close()
        code = getattr(exc, "errno", None)
        if code == errno.ENOENT or "No such file" in str(exc):
            raise InputError(url, "no such serial port") from None
        raise InputError(url, f"cannot open serial port: {exc}") from None
    return Link(url=url, serial=port, double=started, xonxoff=xonxoff)
