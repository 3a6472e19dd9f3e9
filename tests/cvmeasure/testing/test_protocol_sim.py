"""``sim://`` as a pyserial URL handler: the driver names the package, never imports it."""

from __future__ import annotations

import subprocess
import sys
import time

import serial

from cvmeasure.driver.transport import SIM_HANDLER_PACKAGE
from cvmeasure.testing.double import FakeTinyG
from cvmeasure.testing.protocol_sim import Serial


def test_importing_the_transport_does_not_import_the_double():
    code = (
        "import sys, serial, cvmeasure.driver.transport as t\n"
        "assert t.SIM_HANDLER_PACKAGE in serial.protocol_handler_packages\n"
        "print(sorted(m for m in sys.modules if m.startswith('cvmeasure.testing')))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "[]"


def test_serial_for_url_opens_a_double_and_closing_stops_it():
    assert SIM_HANDLER_PACKAGE in serial.protocol_handler_packages
    port = serial.serial_for_url("sim://?speedup=300", baudrate=115200, timeout=0.05)
    try:
        assert isinstance(port, Serial) and isinstance(port.double, FakeTinyG)
        assert port.port == port.double.port  # the pty, opened like a real device
        port.write(b'{"sr":null}\n')
        reply = b""
        deadline = time.monotonic() + 5.0
        while b'"sr"' not in reply and time.monotonic() < deadline:
            reply += port.read(256)
        assert b'{"r":{"sr":' in reply  # the double's status report answers the request
    finally:
        double = port.double
        port.close()
    assert port.double is None and double._thread is None  # the port stopped its double
