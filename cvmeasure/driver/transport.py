"""Serial transports chosen by URL, as pyserial does.

``open_link(url)`` accepts everything :func:`serial.serial_for_url` does (a
device path such as ``/dev/ttyUSB0`` or ``COM3``, ``loop://``, ``socket://host:port``,
``spy://...``) plus ``sim://``: the TinyG double
(:class:`~cvmeasure.testing.double.FakeTinyG`) started on a fresh pseudo-terminal
and opened through pyserial like a real port. ``sim://`` is a pyserial URL handler
(:mod:`cvmeasure.testing.protocol_sim`): this module only adds its package's name to
``serial.protocol_handler_packages``, so the double is imported the first time a
``sim://`` URL is opened and never by the driver itself. ``sim://`` options are URL
query parameters::

    sim://?speedup=50&footer=440&line_report=parsed&fault=stall@40&fault=drop_byte@12:5

(``fault=KIND@LINE[:BYTE_INDEX]``; see :class:`~cvmeasure.testing.double.Fault`).
A port that does not exist raises :class:`~cvmeasure.errors.InputError` naming it.
"""

from __future__ import annotations

import errno
import logging
from dataclasses import dataclass
from typing import Any

import serial

try:  # POSIX: pyserial's flush() raises termios.error when the port has vanished
    from termios import error as _TermiosError
except ImportError:  # pragma: no cover - Windows
    _TermiosError = OSError  # type: ignore[misc,assignment]

from cvmeasure.errors import DeviceError, InputError

__all__ = ["Link", "open_link", "DEFAULT_BAUD", "SIM_HANDLER_PACKAGE"]

log = logging.getLogger(__name__)

#: The package holding pyserial's ``protocol_sim`` handler (the TinyG double).
SIM_HANDLER_PACKAGE = "cvmeasure.testing"
if SIM_HANDLER_PACKAGE not in serial.protocol_handler_packages:
    serial.protocol_handler_packages.append(SIM_HANDLER_PACKAGE)

#: TinyG's USB baud rate.
DEFAULT_BAUD = 115200


@dataclass
class Link:
    """An open serial link to a board (and the double behind it, for ``sim://``).

    Attributes
    ----------
    url : what was asked for.
    serial : the open pyserial object.
    double : the :class:`~cvmeasure.testing.double.FakeTinyG` started for a
        ``sim://`` URL (owned and stopped by the port), else None.
    xonxoff : whether software flow control is on (host side, tty level).
    """

    url: str
    serial: Any
    double: Any = None
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
        self.serial.close()  # a sim:// port stops its double

    def __enter__(self) -> Link:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def open_link(
    url: str,
    *,
    baudrate: int = DEFAULT_BAUD,
    xonxoff: bool = True,
    timeout_s: float = 0.02,
    write_timeout_s: float = 10.0,
    double: Any = None,
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
    target = url
    if double is not None and url.lower().startswith("sim://"):
        target = double.port
    try:
        port = serial.serial_for_url(
            target,
            baudrate=baudrate,
            xonxoff=xonxoff,
            timeout=timeout_s,
            write_timeout=write_timeout_s,
        )
    except InputError:
        raise
    except ValueError as exc:
        raise InputError(url, f"cannot open port: {exc}") from None
    except (serial.SerialException, OSError) as exc:
        code = getattr(exc, "errno", None)
        if code == errno.ENOENT or "No such file" in str(exc):
            raise InputError(url, "no such serial port") from None
        raise InputError(url, f"cannot open serial port: {exc}") from None
    return Link(url=url, serial=port, double=getattr(port, "double", None), xonxoff=xonxoff)
