"""The ``sim://`` URL handler for pyserial: the TinyG double on a fresh pty.

pyserial's :func:`serial.serial_for_url` looks a ``PROTOCOL://`` URL up as
module ``protocol_PROTOCOL`` in each package of ``serial.protocol_handler_packages``
and opens that module's ``Serial`` class; :mod:`cvmeasure.driver.transport` adds
``cvmeasure.testing`` to that list. Opening ``sim://[?options]`` starts a
:class:`~cvmeasure.testing.double.FakeTinyG` and opens its pseudo-terminal like a
real port; closing the port stops the double. Options are URL query parameters::

    sim://?speedup=50&footer=440&line_report=parsed&fault=stall@40&fault=drop_byte@12:5

(``fault=KIND@LINE[:BYTE_INDEX]``, or ``stall@LINE:SECONDS``; see
:class:`~cvmeasure.testing.double.Fault`).
"""

from __future__ import annotations

import math
from typing import Any
from urllib.parse import parse_qs, urlsplit

import serial

from cvmeasure.errors import InputError
from cvmeasure.testing.double import LINE_REPORTS, FakeTinyG, Fault

__all__ = ["Serial", "parse_sim_url"]


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


class Serial(serial.Serial):
    """A pyserial port on a :class:`FakeTinyG` started from the ``sim://`` URL.

    Attributes
    ----------
    double : the running double (None until opened and after closing).
    """

    double: FakeTinyG | None = None

    def open(self) -> None:
        """Start the double the URL describes and open its pty (the port becomes the pty)."""
        url = self.port
        double = FakeTinyG(**parse_sim_url(url)).start()
        try:
            self.port = double.port
            super().open()
        except BaseException:
            double.close()
            raise
        self.double = double

    def close(self) -> None:
        """Close the pty, then stop the double."""
        try:
            super().close()
        finally:
            if self.double is not None:
                self.double.close()
                self.double = None
