"""Fixtures of the app tests: a real `cvmeasure ui --simulate` server process and designs.

The server runs as the operator runs it (a subprocess on a free port with its workspace
folder), so a test can kill it mid-session and start it again on the same folder.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

pytest.importorskip("fastapi", reason="the app needs the [app] extra (fastapi)")
httpx = pytest.importorskip("httpx", reason="the app tests need httpx")

#: Render scale of the simulated photos in the tests (small: fast, still measurable).
SCALE = 0.2
#: A polygon arc: 5 chords of 40 mm, 4 bends of 20 deg (equal chords, as the correction needs).
ARC_SVG = (
    '<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" viewBox="0 0 200 200">'
    '<path id="arc" d="M 10 180 L 50 180 L 87.588 166.319 L 118.229 140.608 L 138.229 105.967 '
    'L 145.175 66.575" fill="none" stroke="black"/></svg>\n'
)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Server:
    """A `cvmeasure ui --simulate` process on a workspace folder."""

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.port = free_port()
        self.proc: subprocess.Popen | None = None

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}"

    def start(self) -> Server:
        cmd = [sys.executable, "-m", "cvmeasure", "ui", "--simulate", "--port", str(self.port)]
        cmd += ["--dir", str(self.folder), "--scale", str(SCALE)]
        log = self.folder.parent / f"{self.folder.name}-server.log"
        with log.open("ab") as err:
            self.proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise RuntimeError(f"server exited: {log.read_text()[-2000:]}")
            try:
                if httpx.get(self.url + "/api/state", timeout=2).status_code == 200:
                    return self
            except httpx.HTTPError:
                time.sleep(0.2)
        raise RuntimeError("server did not answer within 60 s")

    def kill(self) -> None:
        """Kill -9: the server dies mid-whatever, as in a power loss."""
        if self.proc is not None and self.proc.poll() is None:
            os.kill(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10)

    def stop(self) -> None:
        if self.proc is not None and self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(10)
            except subprocess.TimeoutExpired:
                self.kill()


@pytest.fixture(scope="module")
def designs(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("designs")
    arc = folder / "arc.svg"
    arc.write_text(ARC_SVG, encoding="utf-8")
    notes = folder / "notes.txt"
    notes.write_text("not a drawing\n", encoding="utf-8")
    return {"arc": arc, "notes": notes}


def wait_for(check, timeout_s: float = 60.0, what: str = "condition"):
    """Poll ``check()`` until it returns a truthy value; return it."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        value = check()
        if value:
            return value
        time.sleep(0.1)
    raise AssertionError(f"timed out waiting for {what}")
