"""Calibrate material: the automatic session, live, pausable, and restored from its log.

The session is :func:`cvmeasure.driver.session.run_session` (through the adapter): its
append-only log is the truth. A pause or a stop takes effect between bends (never in the
middle of one); after a serial loss or a server restart the page offers "home, then continue
from bend N", and the continue runs the same session folder again, which homes the pin and
bends only what the log does not hold.
"""

from __future__ import annotations

import shutil
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2

from cvmeasure.app import adapter
from cvmeasure.app.state import Busy, MaterialState, MaterialStep
from cvmeasure.errors import CvmeasureError, DeviceError, InputError
from cvmeasure.fileio import atomic_write_bytes, atomic_write_json, read_json, write_csv_rows

if TYPE_CHECKING:
    from cvmeasure.app.operator import Operator

__all__ = ["Material", "MeasuringCamera"]

MODES = ("quick", "standard", "high")


class MeasuringCamera:
    """Wraps the session's camera: measures each photo as soon as it is taken and publishes
    its angles, so the page shows them before the session has finished the bend."""

    def __init__(self, camera: Any, on_photo: Any) -> None:
        self.camera = camera
        self.on_photo = on_photo

    def capture(self, name: str) -> Any:
        shot = self.camera.capture(name)
        self.on_photo(shot)
        return shot

    def close(self) -> None:
        self.camera.close()


class Material:
    def __init__(self, op: Operator) -> None:
        self.op = op
        self.folder = op.folder / "material"
        self._pause = threading.Event()
        self._resume = threading.Event()
        self._stop = threading.Event()

    @property
    def state(self) -> MaterialState:
        return self.op.state.material

    def _publish(self) -> None:
        self.op.publish("material")

    # ------------------------------------------------------------------ restore

    def restore(self) -> None:
        """Rebuild the state from the session log (after a restart the log is the truth)."""
        log_path = self.folder / "session.jsonl"
        if not log_path.is_file():
            return
        records = adapter.read_session_log(log_path)
        start = next((r for r in records if r.get("event") == "start"), None)
        if start is None:
            return
        cfg = start.get("config", {})
        s = self.state
        s.mode = str(cfg.get("mode", "quick"))
        s.angles_deg = list(cfg.get("angles_deg", [])) if s.mode == "custom" else []
        s.plan = [(str(d), float(a)) for d, a in start["plan"]]
        s.steps = [self._step(adapter.session_step_from_record(r)) for r in records
                   if r.get("event") == "sample"]  # fmt: skip
        done = {st.step for st in s.steps}  # 1-based
        missing = [i + 1 for i in range(len(s.plan)) if i + 1 not in done]
        if not missing and self.op.calibration_path.is_file():
            s.status = "done"
            s.calibration = str(self.op.calibration_path)
            s.message = f"session complete: {len(s.steps)} bends"
            self._result_from_file()
            return
        s.next_bend = missing[0] if missing else len(s.plan)
        s.status = "interrupted"
        s.message = (
            f"the session stopped before its end ({len(done)} of {len(s.plan)} bends logged): "
            f"home, then continue from bend {s.next_bend}"
        )

    def _result_from_file(self) -> None:
        cal = adapter.load_calibration(self.op.calibration_path)
        self.state.loo_score_deg = _loo(cal)
        saved = self.folder / "result.json"
        if saved.is_file():
            d = read_json(saved)
            self.state.diagnosis = str(d.get("diagnosis", ""))
            self.state.follow_up = bool(d.get("follow_up", False))
            self.state.verdict = str(d.get("verdict", ""))

    @staticmethod
    def _step(step: Any) -> MaterialStep:
        return MaterialStep(
            step=step.step + 1,
            direction=step.direction,
            target_deg=step.target_deg,
            loaded_deg=float(step.loaded.bend_angle_deg),
            unloaded_deg=float(step.unloaded.bend_angle_deg),
            springback_deg=float(step.springback_deg),
        )

    # ------------------------------------------------------------------ commands

    def start(self, mode: str, angles: list[float]) -> None:
        if mode not in MODES and not angles:
            raise InputError("mode", f"use one of {', '.join(MODES)}, or give angles")
        if angles and (len(set(angles)) < 2 or any(not 0 < a < 180 for a in angles)):
            raise InputError("angles", "give at least 2 different angles in (0, 180) deg")
        if self.state.status in ("running", "pausing", "paused"):
            raise InputError("session", "a session is already running")
        if self.state.status in ("interrupted", "lost", "stopped"):
            raise InputError(
                "session", "an unfinished session is waiting: continue it, or discard it first"
            )
        self.op.need_rig()
        if self.folder.exists():  # a finished session: keep it beside, start a new folder
            shutil.move(
                str(self.folder), str(self.folder.with_name(f"material-{int(time.time())}"))
            )
        s = self.state
        s.mode, s.angles_deg = ("custom" if angles else mode), list(angles)
        s.plan = adapter.session_plan(mode, angles)
        s.steps, s.next_bend = [], 1
        s.calibration, s.loo_score_deg, s.diagnosis, s.follow_up, s.verdict = (
            "",
            None,
            "",
            False,
            "",
        )
        self._run()

    def resume_session(self) -> None:
        """Home, then continue from the first bend the log does not hold."""
        if self.state.status not in ("interrupted", "lost", "stopped"):
            raise InputError("session", "there is no unfinished session to continue")
        self.op.ensure_connected()
        self._run()

    def discard(self) -> None:
        if self.state.status in ("running", "pausing", "paused"):
            raise InputError("session", "stop the session first")
        if self.folder.exists():
            shutil.move(
                str(self.folder), str(self.folder.with_name(f"material-{int(time.time())}"))
            )
        self.op.state.material = MaterialState(message="session discarded")
        self._publish()

    def pause(self) -> None:
        if self.state.status == "running":
            self._pause.set()
            self.state.status = "pausing"
            self.state.message = "pausing after this bend"
            self._publish()

    def resume(self) -> None:
        if self.state.status in ("pausing", "paused"):
            self._pause.clear()
            self._resume.set()
            self.state.status = "running"
            self.state.message = "running"
            self._publish()

    def stop(self) -> None:
        if self.state.status in ("running", "pausing", "paused"):
            self._stop.set()
            self._resume.set()
            self.state.message = "stopping after this bend"
            self._publish()

    # ------------------------------------------------------------------ the run

    def _run(self) -> None:
        rig = self.op.need_rig()
        if self.op.machine_busy():
            raise Busy("the machine is busy; wait for it or stop what it is doing")
        s = self.state
        self._pause.clear()
        self._resume.clear()
        self._stop.clear()
        s.status, s.message = "running", "bending"
        self._publish()
        self.op.background("material", lambda: self._work(rig))

    def _on_photo(self, shot: Any) -> None:
        try:
            result = adapter.measure_bender_photo(Path(shot.path), self.op.kit, shot.camera)
        except InputError as exc:
            self.state.message = f"photo {Path(shot.path).name}: {exc}"
            self._publish()
            return
        s = self.state
        s.last_photo_angle_deg = float(result.bend_angle_deg)
        s.last_photo_warnings = list(result.warnings)
        # the angles first (what the operator waits for), then the picture with them drawn
        self.op.bus.publish(
            "photo",
            {
                "photo": Path(shot.path).name,
                "bend_angle_deg": s.last_photo_angle_deg,
                "pin_angle_deg": float(result.pin_angle_deg),
            },
        )
        s.last_photo = self._overlay(Path(shot.path), result)
        self._publish()

    def _overlay(self, photo: Path, result: Any) -> str:
        """The photo with the markers and angles drawn (``<stem>.overlay.jpg``); its name."""

        bgr = cv2.imread(str(photo))
        ok, jpg = cv2.imencode(".jpg", adapter.bender_overlay(bgr, result, self.op.kit, 960))
        if not ok:
            return photo.name
        out = photo.with_name(photo.stem + ".overlay.jpg")
        atomic_write_bytes(out, jpg.tobytes())
        return out.name

    def _progress(self, done: int, total: int, step: Any) -> None:
        s = self.state
        s.steps.append(self._step(step))
        s.next_bend = done + 1
        s.message = f"bend {done} of {total} done"
        self._publish()
        if self._pause.is_set() and not self._stop.is_set():
            s.status, s.message = "paused", f"paused after bend {done} of {total}"
            self._publish()
            self._resume.wait()
            self._resume.clear()
        if self._stop.is_set() and done < total:
            raise adapter.session_interrupted(f"stopped by the operator after bend {done}")

    def _work(self, rig: Any) -> None:
        s = self.state
        camera = MeasuringCamera(rig.bender_camera(self.folder / "photos"), self._on_photo)
        try:
            result = adapter.run_material_session(
                adapter.streamed_bender(rig.link), camera, self.folder, mode=s.mode if s.mode != "custom" else "quick",
                angles=s.angles_deg, progress=self._progress,
            )  # fmt: skip
        except DeviceError as exc:
            self._halted("lost", f"the link was lost during bend {s.next_bend}: {exc}")
            self.op.link_lost(f"during calibration bend {s.next_bend}")
            return
        except CvmeasureError as exc:
            stopped = type(exc).__name__ == "SessionInterrupted"
            self._halted("stopped" if stopped else "failed", str(exc))
            return
        self._finish(result)

    def _halted(self, status: str, why: str) -> None:
        s = self.state
        done = {st.step for st in s.steps}
        missing = [i + 1 for i in range(len(s.plan)) if i + 1 not in done]
        s.next_bend = missing[0] if missing else len(s.plan)
        s.status = status
        s.message = f"{why}. Home, then continue from bend {s.next_bend}"
        self._publish()

    def _finish(self, result: Any) -> None:
        s = self.state
        cal = result.calibration
        adapter.save_calibration(self.op.calibration_path, cal)
        s.calibration = str(self.op.calibration_path)
        s.loo_score_deg = _loo(cal)
        s.status, s.message = "done", f"session complete: {len(result.steps)} bends"
        self._publish()
        d = adapter.diagnose_session([st.sample() for st in result.steps])
        s.diagnosis, s.follow_up = d.sentence, bool(d.follow_up_rows)
        if d.follow_up_rows:
            write_csv_rows(
                self.folder / "follow_up.csv", d.follow_up_rows, ("trial", "commanded_pin_deg")
            )
        score = (
            "no leave-one-out score (too few angles)"
            if s.loo_score_deg is None
            else (f"leave-one-out error {s.loo_score_deg:.3f} deg")
        )
        s.verdict = f"material calibrated: {score}"
        atomic_write_json(
            self.folder / "result.json",
            {"diagnosis": s.diagnosis, "follow_up": s.follow_up, "verdict": s.verdict},
        )
        self._publish()


def _loo(cal: Any) -> float | None:
    """The worst direction's leave-one-angle-out RMSE of the model in use (deg), or None."""
    scores = cal.scores.get(cal.model, {})
    values = [v.get("loao_rmse_deg") for v in scores.values() if isinstance(v, dict)]
    values = [float(v) for v in values if v is not None]
    return max(values) if values else None
