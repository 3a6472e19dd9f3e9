"""URL-selected transports: device paths, sim://, loop://, socket:// (a real TCP bridge)."""

from __future__ import annotations

import os
import select
import socket
import threading

import pytest
import serial

from cvmeasure.design import arc_points_mm
from cvmeasure.driver.stream import StreamConfig, stream_job
from cvmeasure.driver.transport import open_link
from cvmeasure.errors import InputError
from cvmeasure.gcode import design_job
from cvmeasure.testing.double import FakeTinyG, Fault
from cvmeasure.testing.protocol_sim import parse_sim_url


def test_parse_sim_url():
    kw = parse_sim_url("sim://?speedup=50&footer=440&fault=stall@40:0.5&fault=drop_byte@12:5")
    assert kw["speedup"] == 50.0 and kw["footer_style"] == "440"
    assert kw["faults"] == (
        Fault("stall", 40, duration_s=0.5),
        Fault("drop_byte", 12, byte_index=5),
    )
    for bad in (
        "sim://?speed=2",
        "sim://?fault=melt@3",
        "sim://?speedup=fast",
        "sim://?fault=stall@0",
    ):
        with pytest.raises(InputError, match="bad sim:// URL"):
            parse_sim_url(bad)


def test_missing_device_and_unknown_scheme_are_input_errors(tmp_path):
    with pytest.raises(InputError, match="no such serial port"):
        open_link(str(tmp_path / "ttyUSB9"))
    with pytest.raises(InputError, match="cannot open port"):
        open_link("warp://nowhere")


@pytest.mark.parametrize("footer", ["g2", "440", "446"])
def test_every_footer_style_streams(footer):
    job = design_job(arc_points_mm((0, 0), 60.0, 90.0, 90.0, chords=5))
    with open_link(f"sim://?speedup=300&footer={footer}") as link:
        result = stream_job(link, job.lines)
        assert result.executed_line == len(job.lines)
        assert len(link.double.machine_state().bends) == 4


def _bridge(server: socket.socket, port_path: str, stop: threading.Event) -> None:
    """A TCP <-> serial bridge (what ser2net does) in front of the double's pty."""
    conn, _ = server.accept()
    ser = serial.Serial(port_path, 115200, timeout=0)
    fd = ser.fileno()
    try:
        while not stop.is_set():
            ready, _, _ = select.select([conn, fd], [], [], 0.05)
            if conn in ready:
                data = conn.recv(4096)
                if not data:
                    return
                ser.write(data)
            if fd in ready:
                data = os.read(fd, 4096)
                if data:
                    conn.sendall(data)
    finally:
        ser.close()
        conn.close()


def test_socket_url_through_a_tcp_bridge():
    job = design_job(arc_points_mm((0, 0), 60.0, 90.0, 90.0, chords=5))
    server = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()
    with FakeTinyG(speedup=300.0) as board:
        t = threading.Thread(target=_bridge, args=(server, board.port, stop), daemon=True)
        t.start()
        host, port = server.getsockname()
        with open_link(f"socket://{host}:{port}", xonxoff=False) as link:
            result = stream_job(link, job.lines, config=StreamConfig(stall_timeout_s=2.0))
        stop.set()
        t.join(timeout=2)
        assert result.executed_line == len(job.lines)
        assert board.stats.rx_dropped_bytes == 0
        completed, _ = board.executed_lines()
        assert completed == list(range(0, len(job.lines) + 1))
    server.close()
