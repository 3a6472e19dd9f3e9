"""A held-out TinyG controller on a pseudo-terminal, for black-box tests of a G-code streamer.

The firmware model (:mod:`benchmarks.heldout.tinyg_machine`) runs in a thread on the master
side of a pty; a host opens the slave (or the ``link`` symlink) like ``/dev/ttyUSB0``.
The wire is modelled too: bytes leave the pty at the baud rate (115,200 8N1 = 11.5 bytes
per ms), and when the board has sent XOFF and the host's tty honours it (``IXON``), at
most ``xoff_slack_bytes`` more arrive, as with an FTDI chip that pauses within a few bytes.

Usage::

    with TinyGController(faults=[parse_fault("stall@1836:2")], link="/tmp/tinyg0") as board:
        subprocess.run(["cvmeasure", "bend", "job.nc", "--port", board.port])
        truth = board.truth()          # TruthLog: executed moves, received lines, events

    python -m benchmarks.heldout.tinyg_controller --link /tmp/tinyg0 --fault stall@1836 \\
        --truth truth.json             # runs until SIGINT/SIGTERM, then writes the log
"""

from __future__ import annotations

import argparse
import contextlib
import errno
import fcntl
import json
import os
import select
import signal
import sys
import termios
import threading
import time
import tty
from collections.abc import Sequence
from pathlib import Path

from benchmarks.heldout.tinyg_faults import Fault, parse_fault
from benchmarks.heldout.tinyg_machine import MachineConfig, TinyGMachine
from benchmarks.heldout.tinyg_truth import TruthLog

__all__ = ["TinyGController", "main"]


class TinyGController:
    """The TinyG model served on a pty.

    Parameters
    ----------
    faults
        Faults to inject (:func:`benchmarks.heldout.tinyg_faults.parse_fault`).
    config
        Sizes, speeds, footer style, ``speedup`` (machine seconds per real second).
    link
        Optional symlink to the slave device; it is removed while the port is gone and
        points at the new device when it comes back.
    baud
        Wire speed of the modelled serial link.
    xoff_slack_bytes
        Bytes that still arrive after an XOFF when the host honours XON/XOFF.
    """

    def __init__(
        self,
        faults: Sequence[Fault] = (),
        config: MachineConfig | None = None,
        link: str | os.PathLike[str] | None = None,
        baud: int = 115200,
        xoff_slack_bytes: int = 3,
    ) -> None:
        self.config = config or MachineConfig()
        self.faults = list(faults)
        self.link = Path(link) if link is not None else None
        self.bytes_per_s = baud / 10.0
        self.xoff_slack_bytes = xoff_slack_bytes
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._master: int | None = None
        self._slave: int | None = None
        self.slave_path = ""
        self.machine: TinyGMachine | None = None
        self.tx_lost_bytes = 0
        self._pending = bytearray()  # read from the pty, not yet through the wire

    # ------------------------------------------------------------------ public
    @property
    def port(self) -> str:
        """The device a host opens: the symlink when given, else the slave path."""
        return str(self.link) if self.link is not None else self.slave_path

    def start(self) -> TinyGController:
        """Open the pty and start the firmware thread."""
        self._open_pty()
        self.machine = TinyGMachine(self.config, self.faults, time.monotonic())
        self._thread = threading.Thread(target=self._run, name="heldout-tinyg", daemon=True)
        self._thread.start()
        return self

    def stop(self) -> None:
        """Stop the thread and close the pty (the truth log stays readable)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        self._close_pty()

    def __enter__(self) -> TinyGController:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()

    def truth(self) -> TruthLog:
        """A snapshot of the truth log, with the current machine position."""
        assert self.machine is not None
        with self._lock:
            log = TruthLog.from_json(json.loads(json.dumps(self.machine.truth.to_json())))
            log.position = {k: round(v, 6) for k, v in self.machine.position().items()}
        return log

    def elapsed_s(self) -> float:
        """Seconds since the controller started, on the truth log's clock."""
        assert self.machine is not None
        return time.monotonic() - self.machine.t0

    def status(self) -> dict[str, object]:
        """The machine's state now: ``stat``, ``line``, planner and RX occupancy, position."""
        assert self.machine is not None
        m = self.machine
        with self._lock:
            return {
                "stat": m.stat(),
                "line": m.reported_line(),
                "planner_moves": len(m.planner) + (m.current is not None),
                "rx_bytes": len(m.ring),
                "stalled": m.stall_until is not None,
                "xoff": m.xoff_sent,
                "position": m.position(),
            }

    def wait_idle(self, timeout_s: float = 10.0) -> bool:
        """Wait until nothing is queued or running; False on timeout."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            s = self.status()
            if s["planner_moves"] == 0 and s["rx_bytes"] == 0 and s["stat"] != 5:
                return True
            time.sleep(0.01)
        return False

    # ------------------------------------------------------------------ pty
    def _open_pty(self) -> None:
        master, slave = os.openpty()
        # Raw mode is set once through the slave (the pty's one termios); the host's own
        # open sets what it needs. Never tcsetattr the master: Linux applies it to the
        # slave and would clear the host's IXON.
        tty.setraw(slave)
        fcntl.fcntl(master, fcntl.F_SETFL, fcntl.fcntl(master, fcntl.F_GETFL) | os.O_NONBLOCK)
        self._master, self._slave = master, slave  # keep the slave open: the pty lives on
        self.slave_path = os.ttyname(slave)
        if self.link is not None:
            tmp = self.link.with_name(self.link.name + ".tmp")
            with contextlib.suppress(FileNotFoundError):
                tmp.unlink()
            os.symlink(self.slave_path, tmp)
            os.replace(tmp, self.link)

    def _close_pty(self) -> None:
        for fd in (self._master, self._slave):
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)
        self._master = self._slave = None
        self._pending.clear()  # bytes on the wire when the port vanished are lost
        if self.link is not None and self.link.is_symlink():
            with contextlib.suppress(FileNotFoundError):
                self.link.unlink()

    def _host_honours_xoff(self) -> bool:
        if self._slave is None:
            return False
        try:
            return bool(termios.tcgetattr(self._slave)[0] & termios.IXON)
        except termios.error:
            return False

    # ------------------------------------------------------------------ loop
    def _run(self) -> None:
        credit = 0.0
        last = time.monotonic()
        slack = 0
        back_at: float | None = None
        m = self.machine
        assert m is not None
        while not self._stop.is_set():
            now = time.monotonic()
            credit = min(credit + (now - last) * self.bytes_per_s, 64.0)
            last = now
            with self._lock:
                if back_at is not None and now >= back_at:
                    back_at = None
                    self._open_pty()
                    m.event(now, "port_back", device=self.slave_path)
                if self._master is not None:
                    credit, slack = self._receive(m, now, credit, slack)
                m.step(now)
                if m.port_gone_s is not None:
                    back_at = now + m.port_gone_s
                    m.port_gone_s = None
                    self._close_pty()
                self._write(m)
            self._wait(0.001)

    def _receive(self, m: TinyGMachine, now: float, credit: float, slack: int) -> tuple[float, int]:
        """Deliver bytes to the RX ISR one at a time at the wire's pace; after an XOFF, only
        ``xoff_slack_bytes`` more while the host's tty honours it. Returns (credit, slack)."""
        want = int(credit) - len(self._pending)
        if want > 0:
            self._pending += self._read(want)
        honours: bool | None = None
        i = 0
        while i < len(self._pending):
            if m.input_gated():
                if honours is None:
                    honours = self._host_honours_xoff()
                if honours:
                    if slack >= self.xoff_slack_bytes:
                        break
                    slack += 1
            else:
                slack = 0
            m.receive(self._pending[i : i + 1], now)
            i += 1
        del self._pending[:i]
        return credit - i, slack

    def _read(self, n: int) -> bytes:
        try:
            return os.read(self._master, n)  # type: ignore[arg-type]
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno in (errno.EIO, errno.EBADF):
                return b""
            raise

    def _write(self, m: TinyGMachine) -> None:
        if self._master is None:
            self.tx_lost_bytes += len(m.out) + len(m.flow_out)
            m.out.clear()
            m.flow_out.clear()
            return
        for buf, paused in ((m.flow_out, False), (m.out, m.host_xoff)):
            if paused or not buf:
                continue
            try:
                sent = os.write(self._master, bytes(buf))
            except BlockingIOError:
                sent = 0
            except OSError:
                sent = len(buf)  # nobody at the other end: the bytes are lost
                self.tx_lost_bytes += sent
            del buf[:sent]
        if len(m.out) > 1 << 16:  # no host reading for a long time: the oldest output is lost
            self.tx_lost_bytes += len(m.out) - (1 << 16)
            del m.out[: len(m.out) - (1 << 16)]

    def _wait(self, timeout_s: float) -> None:
        fd = self._master
        if fd is None:
            time.sleep(timeout_s)
            return
        with contextlib.suppress(OSError, ValueError):
            select.select([fd], [], [], timeout_s)


def main(argv: list[str] | None = None) -> int:
    """Run the controller until SIGINT/SIGTERM; write the truth log as JSON on exit."""
    p = argparse.ArgumentParser(prog="python -m benchmarks.heldout.tinyg_controller",
                                description=__doc__.splitlines()[0])  # fmt: skip
    p.add_argument("--link", help="symlink to create for the device (e.g. /tmp/tinyg0)")
    p.add_argument("--fault", action="append", default=[], help="kind@N[:arg] or kind@tS[:arg]")
    p.add_argument("--speedup", type=float, default=100.0, help="machine s per real s")
    p.add_argument("--footer", choices=("pensa", "440"), default="pensa")
    p.add_argument("--truth", help="truth-log JSON to write on exit (default: stdout)")
    args = p.parse_args(argv)
    try:
        faults = [parse_fault(s) for s in args.fault]
    except ValueError as exc:
        print(f"--fault: {exc}", file=sys.stderr)
        return 2
    cfg = MachineConfig(speedup=args.speedup, footer=args.footer)
    board = TinyGController(faults, cfg, link=args.link).start()
    print(board.port, flush=True)
    done = threading.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: done.set())
    done.wait()
    log = board.truth()
    board.stop()
    text = json.dumps(log.to_json(), indent=1)
    if args.truth:
        tmp = Path(args.truth + ".tmp")
        tmp.write_text(text)
        os.replace(tmp, args.truth)
    else:
        print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
