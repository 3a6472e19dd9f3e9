"""Bend and Inspect: designs, the queue with quantities, the job with progress, the part check.

Files on disk are the truth: ``designs/`` (uploaded designs and the corrected G-code of the
next part), ``queue.json``, ``jobs/<item>/part<k>.gcode`` with its streamer journal, and
``jobs.jsonl`` (one line per finished part: bends and seconds, from which the time left is
learned) and ``parts.jsonl`` (one line per inspected part: the control chart).
"""

from __future__ import annotations

import statistics
import time
import uuid
from dataclasses import asdict
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from cvmeasure.app import adapter
from cvmeasure.app.state import Busy, DesignFile, InspectState, JobState, QueueItem, VertexDeviation
from cvmeasure.errors import CvmeasureError, DeviceError, InputError
from cvmeasure.fileio import (
    append_jsonl,
    atomic_write_bytes,
    atomic_write_json,
    read_json,
    read_jsonl,
)

if TYPE_CHECKING:
    from cvmeasure.app.operator import Operator

__all__ = ["Bending", "DESIGN_SUFFIXES"]

DESIGN_SUFFIXES = (".svg", ".dxf")
#: A part passes when every vertex bend is within this of its design (deg).
DEFAULT_TOLERANCE_DEG = 0.5


class Bending:
    def __init__(self, op: Operator) -> None:
        self.op = op
        self.designs = op.folder / "designs"
        self.jobs = op.folder / "jobs"
        self._control: Any = None
        self._last_part: tuple[str, str, int] | None = None  # (item id, design, part)
        self._check: Any = None
        self.last_check: Any = None  # the last measured part (adapter.PartCheck), for Hops

    @property
    def job(self) -> JobState:
        return self.op.state.job

    # ------------------------------------------------------------------ restore

    def restore(self) -> None:
        st = self.op.state
        if self.designs.is_dir():
            for path in sorted(self.designs.iterdir()):
                if path.suffix.lower() in DESIGN_SUFFIXES:
                    try:
                        st.files.append(self._checked(path))
                    except InputError:
                        continue
        qpath = self.op.folder / "queue.json"
        if qpath.is_file():
            st.queue = [QueueItem(**q) for q in read_json(qpath)]
        for item in st.queue:  # the journals and the finished-part log are the truth
            item.done = sum(1 for r in self._history() if r.get("item") == item.id)
        self._restore_job()
        history = self._history()
        if history:
            last = history[-1]
            self._last_part = (str(last["item"]), str(last["design"]), int(last["part"]))
        parts = self.op.folder / "parts.jsonl"
        if parts.is_file():
            st.inspect.history = read_jsonl(parts, skip_partial_last=True)[-200:]

    def _restore_job(self) -> None:
        """A part whose journal has no finished record was cut off by a restart."""
        finished = {(r.get("item"), r.get("part")) for r in self._history()}
        for item in self.op.state.queue:
            for k in range(1, item.quantity + 1):
                journal = self.jobs / item.id / f"part{k}.journal.jsonl"
                if journal.is_file() and (item.id, k) not in finished:
                    j = self.job
                    j.status, j.item, j.design, j.part = "interrupted", item.id, item.design, k
                    j.quantity = item.quantity
                    j.message = (
                        f"part {k} of {item.design} was cut off by a restart: take the wire "
                        "out, then bend the part again"
                    )
                    return

    def _history(self) -> list[dict[str, Any]]:
        path = self.op.folder / "jobs.jsonl"
        if not path.is_file():
            return []

        return read_jsonl(path, skip_partial_last=True)

    # ------------------------------------------------------------------ files and queue

    def _checked(self, path: Path) -> DesignFile:
        d = adapter.check_design(path, self.op.calibration(), name=path.name)
        return DesignFile(
            name=d.name,
            bends=len(d.bends_deg),
            bends_deg=[round(b, 3) for b in d.bends_deg],
            pin_deg=[round(p, 3) for p in d.pin_deg],
            chords_mm=np.round(d.chords_mm, 3).tolist(),
            wire_mm=round(d.wire_mm, 1),
            compensation=d.compensation,
        )

    def upload(self, name: str, data: bytes) -> DesignFile:
        """Check a dropped file; a wrong one is refused with a message naming it."""
        name = Path(name or "unnamed").name
        if Path(name).suffix.lower() not in DESIGN_SUFFIXES:
            raise InputError(name, "not a design drawing: drop an .svg or .dxf file")
        tmp = self.designs / f".upload-{uuid.uuid4().hex}{Path(name).suffix.lower()}"
        atomic_write_bytes(tmp, data)
        try:
            design = self._checked(tmp)
        except InputError as exc:
            raise InputError(name, str(exc).split(": ", 1)[-1]) from None
        finally:
            pass
        tmp.replace(self.designs / name)
        design.name = name
        self.op.state.files = [f for f in self.op.state.files if f.name != name] + [design]
        (self.designs / f"{name}.next.gcode").unlink(missing_ok=True)
        self.op.publish("files")
        return design

    def _save_queue(self) -> None:
        atomic_write_json(self.op.folder / "queue.json", [asdict(q) for q in self.op.state.queue])
        self.op.publish("queue")

    def add(self, design: str, quantity: int) -> QueueItem:
        if not any(f.name == design for f in self.op.state.files):
            raise InputError(design, "no such design: upload it first")
        if not 1 <= quantity <= 10000:
            raise InputError("quantity", "must be between 1 and 10000")
        item = QueueItem(uuid.uuid4().hex[:8], design, quantity)
        self.op.state.queue.append(item)
        self._save_queue()
        return item

    def remove(self, item_id: str) -> None:
        if self.job.status in ("bending", "paused") and self.job.item == item_id:
            raise InputError(item_id, "this item is bending now")
        self.op.state.queue = [q for q in self.op.state.queue if q.id != item_id]
        self._save_queue()

    # ------------------------------------------------------------------ the job

    def _next_item(self) -> QueueItem | None:
        return next((q for q in self.op.state.queue if q.done < q.quantity), None)

    def _seconds_per_bend(self) -> tuple[float | None, str]:
        rates = [r["seconds"] / r["bends"] for r in self._history()[-50:] if r.get("bends")]
        if not rates:
            return None, "no earlier part yet: learning"
        return statistics.median(rates), f"learned from {len(rates)} earlier part(s)"

    def start(self) -> None:
        """Bend the next part of the first unfinished queue item."""
        if self.job.status in ("bending", "paused"):
            raise InputError("job", "a part is bending already")
        if self.job.status in ("lost",):
            raise InputError("job", "the last part stopped: continue it first")
        item = self._next_item()
        if item is None:
            raise InputError("queue", "nothing left to bend: add a design to the queue")
        self.op.ensure_connected()
        rig = self.op.need_rig()
        part = item.done + 1
        if self.job.status == "interrupted" and self.job.item == item.id:
            part = self.job.part  # bent again from the start, on a fresh journal
            old = self.jobs / item.id / f"part{part}.journal.jsonl"
            old.replace(old.with_name(f"part{part}.cut-{int(time.time())}.jsonl"))
        text = self._job_text(item.design)
        gcode = self.jobs / item.id / f"part{part}.gcode"
        atomic_write_bytes(gcode, text.encode("ascii"))
        self._launch(rig, item, part, text, resume=False, fresh=True)

    def _job_text(self, design: str) -> str:
        corrected = self.designs / f"{design}.next.gcode"
        if corrected.is_file():
            return corrected.read_text(encoding="ascii")
        return adapter.check_design(self.designs / design, self.op.calibration()).gcode

    def continue_part(self) -> None:
        """After a serial loss: reconnect, then continue the part from its journal."""
        j = self.job
        if j.status != "lost":
            raise InputError("job", "no stopped part to continue")
        self.op.ensure_connected()
        rig = self.op.need_rig()
        item = next(q for q in self.op.state.queue if q.id == j.item)
        text = (self.jobs / item.id / f"part{j.part}.gcode").read_text(encoding="ascii")
        # no journal: the link went before the first line of the part was sent
        journal = self.jobs / item.id / f"part{j.part}.journal.jsonl"
        self._launch(rig, item, j.part, text, resume=journal.is_file(), fresh=False)

    def _launch(
        self, rig: Any, item: QueueItem, part: int, text: str, *, resume: bool, fresh: bool
    ) -> None:
        if self.op.machine_busy():
            raise Busy("the machine is busy; wait for it or stop what it is doing")
        lines = adapter.job_line_numbers(text)
        strokes = [n for n, is_bend in lines if is_bend]
        j = self.job
        j.status, j.item, j.design, j.part, j.quantity = (
            "bending",
            item.id,
            item.design,
            part,
            item.quantity,
        )
        j.bends_total = len(strokes)
        if fresh:
            j.bends_done, j.elapsed_s = 0, 0.0
            rig.mark_part()
        j.message = f"bending part {part} of {item.quantity}: {item.design}"
        self._control = adapter.stream_control()
        self.op.publish("job")
        journal = self.jobs / item.id / f"part{part}.journal.jsonl"
        self.op.background(
            "job", lambda: self._work(rig, item, part, text, journal, strokes, resume)
        )

    def _work(self, rig, item, part, text, journal, strokes, resume) -> None:
        j = self.job
        t0 = time.perf_counter() - j.elapsed_s
        last = [0.0]

        def progress(sent: int, total: int, executed: int | None) -> None:
            if executed is not None:
                j.bends_done = sum(1 for n in strokes if n < executed)
            j.elapsed_s = time.perf_counter() - t0
            rate, why = self._seconds_per_bend()
            if rate is None and j.bends_done:
                rate, why = j.elapsed_s / j.bends_done, "from this part so far"
            j.time_left_s = None if rate is None else rate * (j.bends_total - j.bends_done)
            j.time_left_from = why
            if time.perf_counter() - last[0] > 0.25:
                last[0] = time.perf_counter()
                self.op.publish("job")

        try:
            adapter.stream_lines(
                rig.link, text, journal=journal, resume=resume, progress=progress,
                control=self._control, source=f"{item.design} part {part}",
            )  # fmt: skip
        except DeviceError as exc:
            reason = getattr(getattr(exc, "stop", None), "reason", "")
            if reason == "aborted":
                j.status, j.message = "cancelled", f"part {part} cancelled: take the wire out"
            else:
                j.status = "lost"
                j.message = (
                    f"the link was lost at bend {j.bends_done + 1} of {j.bends_total} "
                    f"({reason or 'port gone'}). Reconnect, then continue part {part} from "
                    f"bend {j.bends_done + 1}"
                )
                self.op.link_lost(f"during part {part} of {item.design}")
            self.op.publish("job")
            return
        except CvmeasureError as exc:
            j.status, j.message = "failed", str(exc)
            self.op.publish("job")
            return
        j.elapsed_s = time.perf_counter() - t0
        j.bends_done, j.time_left_s = j.bends_total, 0.0
        append_jsonl(
            self.op.folder / "jobs.jsonl",
            {"item": item.id, "design": item.design, "part": part, "bends": j.bends_total,
             "seconds": j.elapsed_s, "time_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())},
        )  # fmt: skip
        item.done = max(item.done, part)
        self._last_part = (item.id, item.design, part)
        j.status, j.message = "done", f"part {part} of {item.quantity} done: inspect it"
        self._save_queue()
        self.op.publish("job")

    def pause(self) -> None:
        if self.job.status == "bending" and self._control is not None:
            self._control.hold()
            self.job.status, self.job.message = "paused", "paused (feedhold)"
            self.op.publish("job")

    def resume(self) -> None:
        if self.job.status == "paused" and self._control is not None:
            self._control.resume()
            self.job.status, self.job.message = "bending", "bending"
            self.op.publish("job")

    def cancel(self) -> None:
        if self.job.status in ("bending", "paused") and self._control is not None:
            self._control.abort()

    # ------------------------------------------------------------------ inspect

    def inspect(self, tolerance_deg: float = DEFAULT_TOLERANCE_DEG) -> None:
        rig = self.op.need_rig()
        if self.op.camera_model is None:
            raise InputError("camera", "calibrate the camera first (Set up)")
        if self._last_part is None:
            raise InputError("part", "bend a part first")
        item_id, design_name, part = self._last_part
        ins = self.op.state.inspect
        ins.busy, ins.message = True, "measuring the part"
        self.op.publish("inspect")

        def work() -> None:
            try:
                self._measure(rig, item_id, design_name, part, tolerance_deg)
            except CvmeasureError as exc:
                ins.message, ins.verdict, ins.passed = str(exc), "", None
            finally:
                ins.busy = False
                self.op.publish("inspect")

        self.op.background("inspect", work, machine=False)

    def _measure(self, rig, item_id: str, design_name: str, part: int, tol: float) -> None:
        path = rig.capture(
            "part", f"{Path(design_name).stem}-part{part}", self.op.folder / "inspect", part
        )
        cpu0 = time.thread_time()  # the verdict's own work, from the photo on disk
        bgr = cv2.imread(str(path))
        design = self.designs / design_name
        check = adapter.measure_finished_part(bgr, self.op.camera_model, design, path.name)
        self._check = (check, design, design_name)
        self.last_check = check
        ok, jpg = cv2.imencode(".jpg", adapter.part_overlay(bgr, check))
        if ok:
            atomic_write_bytes(self.op.folder / "inspect" / "overlay.jpg", jpg.tobytes())
        passed = check.worst_deg <= tol
        ins = self.op.state.inspect
        ins.design, ins.part, ins.tolerance_deg, ins.worst_deg = (
            design_name,
            part,
            tol,
            check.worst_deg,
        )
        ins.passed, ins.corrected = passed, False
        ins.verdict = ("PASS" if passed else "FAIL") + (
            f": worst vertex {check.worst_deg:.2f} deg (tolerance {tol:g} deg)"
        )
        if check.warnings:  # a verdict the measurement doubts says so where it is read
            n = len(check.warnings)
            ins.verdict += f", {n} warning{'s' if n > 1 else ''}: read below before trusting it"
        ins.warnings = list(check.warnings)
        ins.vertices = [
            VertexDeviation(i + 1, d, m, e, abs(e) <= tol)
            for i, (d, m, e) in enumerate(
                zip(check.design_bend_deg, check.measured_bend_deg, check.error_deg, strict=True)
            )
        ]
        ins.message = f"{design_name} part {part} measured"
        ins.measure_cpu_s = time.thread_time() - cpu0
        record = {"design": design_name, "part": part, "worst_deg": check.worst_deg,
                  "passed": passed, "errors_deg": list(check.error_deg),
                  "warnings": [w.to_json() for w in check.warnings]}  # fmt: skip
        append_jsonl(self.op.folder / "parts.jsonl", record)
        ins.history = (ins.history + [record])[-200:]

    def correct(self) -> None:
        """Correct the calibration and the next part of the inspected design (the closed loop)."""
        if self._check is None:
            raise InputError("part", "inspect a part first")
        check, design, name = self._check
        cal, corr, job = adapter.correct_next_part(self.op.calibration(), check, design)
        adapter.save_calibration(self.op.calibration_path, cal)
        header = f"; cvmeasure ui: {name} corrected after part {self.op.state.inspect.part}\n"
        atomic_write_bytes(
            self.designs / f"{name}.next.gcode", (header + job.text()).encode("ascii")
        )
        ins = self.op.state.inspect
        ins.corrected = True
        # the worst error quoted is one the measurement resolves, readings within their
        # uncertainty apart (vertex numbers left out: the job's, not the table's above)
        ins.message = (
            f"the next part of {name} is corrected from the part's errors: "
            f"{corr.error_summary(2, name_vertex=False)}; bend it from the Bend page"
        )
        if corr.warnings:  # kept with the correction in the calibration's history too
            codes = ", ".join(dict.fromkeys(w.code for w in corr.warnings))
            ins.message += f" (the part measured with warnings: {codes})"
        self._check = None
        self.op.publish("inspect")

    def fresh_inspect(self) -> None:
        self.op.state.inspect = InspectState(history=self.op.state.inspect.history)
