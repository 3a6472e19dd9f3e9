"""The operator's bench on the server: connection, set-up checks, and the shared plumbing.

:class:`Operator` owns the :class:`~cvmeasure.app.state.AppState`, the event bus, the bench
(:mod:`cvmeasure.app.rig`) and the workspace folder. Long actions run in threads and publish
the section of the state they change. The material session and the bend jobs live in
:mod:`cvmeasure.app.material` and :mod:`cvmeasure.app.bending`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import asdict
from pathlib import Path
from typing import Any

import cv2

from cvmeasure.app import adapter
from cvmeasure.app.bending import Bending
from cvmeasure.app.material import Material
from cvmeasure.app.rig import Rig, open_rig
from cvmeasure.app.state import (
    SECTIONS,
    AppState,
    Busy,
    Control,
    EventBus,
    KitCheck,
    LensState,
    LensView,
    MarkerCheck,
    PlaneCheck,
)
from cvmeasure.errors import InputError
from cvmeasure.fileio import atomic_write_json, read_json

__all__ = ["Operator", "Busy"]

log = logging.getLogger(__name__)

#: How long a command waits for an activity that is just ending to free the machine (s).
BUSY_WAIT_S = 2.0
#: The plate may lean this much before the plane check says "not square" (deg).
PLANE_TOLERANCE_DEG = 0.5


class Operator:
    """Server-side state and actions of the app (see the module notes).

    Parameters
    ----------
    folder : the workspace: session log, job journals, queue, calibration and camera files.
    simulated : makes the simulated bench (``--simulate``: the TinyG double and the photo
        lab, ``cvmeasure_datasets.simrig.SimRig``); None for a real bench only.
    """

    def __init__(self, folder: Path, *, simulated: Callable[[], Rig] | None = None) -> None:
        self.folder = Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.simulated = simulated
        self.simulate = simulated is not None
        self.state = AppState()
        self.bus = EventBus()
        self.control = Control()
        self.rig: Rig | None = None
        self.kit = adapter.default_kit()
        self._machine = threading.Lock()  # one machine activity at a time
        self._detections: list[Any] = []
        self._view_photos: list[Path] = []
        self.camera_model: Any = None

        self.material = Material(self)
        self.bending = Bending(self)
        self._restore_setup()
        self.material.restore()
        self.bending.restore()

    # ------------------------------------------------------------------ plumbing

    @property
    def calibration_path(self) -> Path:
        return self.folder / "calibration.json"

    @property
    def camera_path(self) -> Path:
        return self.folder / "camera.json"

    def publish(self, *sections: str) -> None:
        for name in sections:
            self.bus.publish(name, self.state.section(name))

    def snapshot(self) -> dict[str, Any]:
        return {name: self.state.section(name) for name in SECTIONS}

    def calibration(self) -> Any:
        """The current material calibration, or the nominal machine's before any session."""
        if self.calibration_path.is_file():
            return adapter.load_calibration(self.calibration_path)
        return adapter.default_calibration()

    def need_rig(self) -> Rig:
        if self.rig is None or self.state.connection.state != "operational":
            raise Busy("connect the bender and the camera first (Set up)")
        return self.rig

    def background(self, name: str, work: Callable[[], None], *, machine: bool = True) -> None:
        """Run ``work`` in a thread; with ``machine`` it holds the machine until done."""
        if machine and not self._machine.acquire(timeout=BUSY_WAIT_S):
            raise Busy("the machine is busy; wait for it or stop what it is doing")

        def run() -> None:
            try:
                work()
            except Exception:  # the thread must never die silently: log it
                log.exception("%s failed", name)
            finally:
                if machine:
                    self._machine.release()

        threading.Thread(target=run, name=f"app-{name}", daemon=True).start()

    def machine_busy(self) -> bool:
        """Whether another activity holds the machine (one that is just ending is waited for)."""
        if self._machine.acquire(timeout=BUSY_WAIT_S):
            self._machine.release()
            return False
        return True

    # ------------------------------------------------------------------ connection

    def connect(self, port: str, camera: str) -> None:
        if self.machine_busy():
            raise Busy("the machine is busy")
        if self.rig is not None:
            self.disconnect()
        if self.simulate and not port:
            port, camera = "sim://", "simulated"
        rig = open_rig(port, camera, self.folder, simulated=self.simulated)
        self.rig = rig
        atomic_write_json(self.folder / "connection.json", {"port": port, "camera": camera})
        c = self.state.connection
        c.state, c.port, c.camera, c.simulated = "operational", port, camera, rig.simulated
        c.message = "bender and camera connected" + (" (simulated)" if rig.simulated else "")
        if self.state.lens.guidance.startswith("connect"):
            self.state.lens.guidance = adapter.coverage_guidance([], rig.image_size_px)
        self.publish("connection", "lens")

    def disconnect(self) -> None:
        if self.rig is not None:
            try:
                self.rig.close()
            finally:
                self.rig = None
        c = self.state.connection
        c.state, c.message = "closed", "not connected"
        self.publish("connection")

    def link_lost(self, where: str) -> None:
        c = self.state.connection
        c.state, c.message = "lost", f"the link to the bender was lost {where}"
        self.publish("connection")

    def ensure_connected(self) -> None:
        """Connect again to the last bench used (after a restart), or reopen a lost link."""
        if self.state.connection.state == "lost":
            self.reconnect()
        elif self.rig is None and (self.folder / "connection.json").is_file():
            last = read_json(self.folder / "connection.json")
            self.connect(str(last.get("port", "")), str(last.get("camera", "")))

    def reconnect(self) -> None:
        if self.rig is None:
            raise Busy("connect first")
        self.rig.reconnect()
        c = self.state.connection
        c.state, c.message = "operational", "bender reconnected"
        self.publish("connection")

    # ------------------------------------------------------------------ set up: the lens

    def _restore_setup(self) -> None:
        if self.camera_path.is_file():
            self.camera_model = adapter.load_camera(self.camera_path)
            saved = self.folder / "setup.json"
            lens = LensState(good=True, verdict="camera calibrated: good", guidance="")
            if saved.is_file():
                d = read_json(saved)
                lens.verdict = str(d.get("verdict", lens.verdict))
                lens.good = bool(d.get("good", True))
                lens.rms_px = d.get("rms_px")
            self.state.lens = lens

    def take_lens_view(self) -> None:
        rig = self.need_rig()
        lens = self.state.lens
        if lens.busy:
            raise Busy("the camera is busy with the last photo")
        index = len(lens.views)
        lens.busy = True
        rig.hint = lens.guidance

        def work() -> None:
            self.publish("lens")
            try:
                path = rig.capture("board_view", f"view{index:02d}", self.folder / "lens", index)
                det = adapter.detect_board_view(cv2.imread(str(path)), path.name)
                usable = bool(getattr(det, "ok", True)) and len(det.corners_px) > 0
                if usable:
                    self._detections.append(det)
                    self._view_photos.append(path)
                note = f"{len(det.corners_px)} corners" if usable else "board not found"
                lens.views.append(LensView(index + 1, len(det.corners_px), usable, note))
                lens.guidance = adapter.coverage_guidance(self._detections, rig.image_size_px)
                n = len(self._detections)
                lens.verdict = (
                    f"camera calibrated: not yet, because {n} of "
                    f"{adapter.MIN_LENS_VIEWS} usable views are taken"
                    if n < adapter.MIN_LENS_VIEWS
                    else "camera calibrated: not yet, because it is not solved: press Solve"
                )
            finally:
                lens.busy = False
                self.publish("lens")

        self.background("lens-view", work, machine=False)

    def solve_lens(self) -> None:
        self.need_rig()
        lens = self.state.lens
        if len(self._detections) < adapter.MIN_LENS_VIEWS:
            raise Busy(f"take at least {adapter.MIN_LENS_VIEWS} usable views first")
        if lens.busy:
            raise Busy("the camera is busy")
        lens.busy = True

        def work() -> None:
            self.publish("lens")
            try:
                solved = adapter.solve_lens(self._view_photos)
                lens.rms_px = solved.rms_px
                lens.good = not solved.problems
                if lens.good:
                    lens.verdict = f"camera calibrated: good (RMS {solved.rms_px:.2f} px)"
                    lens.guidance = ""
                else:
                    lens.verdict = f"camera calibrated: not yet, because {solved.problems[0]}"
                adapter.save_camera(self.camera_path, solved.camera)
                self.camera_model = solved.camera
                atomic_write_json(
                    self.folder / "setup.json",
                    {"verdict": lens.verdict, "good": lens.good, "rms_px": lens.rms_px},
                )
            except InputError as exc:
                lens.good, lens.verdict = False, f"camera calibrated: not yet, because {exc}"
            finally:
                lens.busy = False
                self.publish("lens")

        self.background("lens-solve", work, machine=False)

    # ------------------------------------------------------------------ set up: plane, kit

    def check_plane(self) -> None:
        rig = self.need_rig()
        if self.camera_model is None:
            raise Busy("calibrate the camera first")

        path = rig.capture("plane", "plane", self.folder / "setup")
        plane = adapter.plane_check(cv2.imread(str(path)), self.camera_model, path.name)
        tilt = float(plane.tilt_deg)
        p = PlaneCheck(done=True, tilt_deg=tilt, good=tilt <= PLANE_TOLERANCE_DEG)
        if p.good:
            p.verdict = f"camera square to the plate: yes (tilt {tilt:.2f} deg)"
        else:
            side = _side_name(float(plane.tilt_direction_deg))
            p.verdict = (
                f"camera square to the plate: no, tilt {tilt:.2f} deg; the plate falls away "
                f"towards the {side} of the view: lift the {side} leg"
            )
        self.state.plane = p
        self.publish("plane")

    def check_kit(self) -> None:
        rig = self.need_rig()
        path = rig.capture("kit", "kit", self.folder / "setup")
        checks = []
        try:
            result = adapter.kit_check(path, self.kit, self.camera_model)
            heights = result.heights or "flat"
            for role, m in sorted(result.markers.items()):
                how = "flat" if heights in ("flat", "none") else f"at its height ({heights})"
                checks.append(MarkerCheck(role, True, f"found, r {m.r_px:.1f} px, {how}"))
            verdict = f"kit check: all {len(checks)} markers found"
            warnings = list(result.warnings)
            if warnings:  # e.g. the kit's heights not those the photo shows
                n = len(warnings)
                verdict += f", {n} warning{'s' if n > 1 else ''}: read below"
            good = not warnings
        except InputError as exc:
            verdict, good, warnings = f"kit check: not good, {exc}", False, []
        self.state.kit = KitCheck(
            done=True, markers=checks, verdict=verdict, good=good, warnings=warnings
        )
        self.publish("kit")

    def as_dict(self) -> dict[str, Any]:
        return asdict(self.state)


def _side_name(direction_deg: float) -> str:
    """The image side a direction points to (image frame, counter-clockwise as seen)."""
    d = direction_deg % 360.0
    if d < 45 or d >= 315:
        return "right"
    if d < 135:
        return "top"
    if d < 225:
        return "left"
    return "bottom"
