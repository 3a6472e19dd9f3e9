"""The app's server-side state: typed dataclasses, the event bus, who controls the machine.

The state lives on the server (never in a browser), so a page that reconnects, or a second
browser, sees the same thing. After a restart the state is rebuilt from the files on disk
(the session log, the job journals, the queue file): they are the truth.
"""

from __future__ import annotations

import threading
import time
import uuid
from collections import deque
from dataclasses import asdict, dataclass, field
from typing import Any

from cvmeasure.errors import CvmeasureError
from cvmeasure.fileio import to_jsonable
from cvmeasure.warning import StageWarning

__all__ = [
    "Busy",
    "Connection",
    "LensView",
    "LensState",
    "PlaneCheck",
    "MarkerCheck",
    "KitCheck",
    "MaterialStep",
    "MaterialState",
    "DesignFile",
    "QueueItem",
    "JobState",
    "VertexDeviation",
    "InspectState",
    "AppState",
    "Event",
    "EventBus",
    "Control",
]


class Busy(CvmeasureError):
    """The machine or the camera is doing something else (HTTP 409)."""


@dataclass
class Connection:
    """The bender and the camera: ``state`` is closed, operational or lost."""

    state: str = "closed"
    port: str = ""
    camera: str = ""
    simulated: bool = False
    message: str = "not connected"


@dataclass
class LensView:
    index: int
    corners: int
    usable: bool
    note: str


@dataclass
class LensState:
    """The lens calibration: views taken, where to hold the board next, the verdict."""

    views: list[LensView] = field(default_factory=list)
    guidance: str = "connect the camera first"
    verdict: str = "camera calibrated: not yet, because no photos of the board were taken"
    good: bool = False
    rms_px: float | None = None
    busy: bool = False


@dataclass
class PlaneCheck:
    done: bool = False
    tilt_deg: float | None = None
    verdict: str = "plane check: not done yet"
    good: bool = False


@dataclass
class MarkerCheck:
    role: str
    found: bool
    detail: str


@dataclass
class KitCheck:
    done: bool = False
    markers: list[MarkerCheck] = field(default_factory=list)
    verdict: str = "kit check: not done yet"
    good: bool = False
    warnings: list[StageWarning] = field(default_factory=list)  # the measurement's, e.g. heights


@dataclass
class MaterialStep:
    """One calibration bend as measured: loaded and released angles (deg, signed)."""

    step: int
    direction: str
    target_deg: float
    loaded_deg: float
    unloaded_deg: float
    springback_deg: float


@dataclass
class MaterialState:
    """The automatic material session.

    ``status``: idle, running, pausing, paused, stopped, lost (serial link lost), interrupted
    (found unfinished in its log at start-up), done, failed. ``next_bend`` is 1-based: the
    bend a continue starts with.
    """

    status: str = "idle"
    mode: str = "quick"
    angles_deg: list[float] = field(default_factory=list)
    plan: list[tuple[str, float]] = field(default_factory=list)
    steps: list[MaterialStep] = field(default_factory=list)
    next_bend: int = 1
    message: str = "no session yet"
    last_photo: str = ""
    last_photo_angle_deg: float | None = None
    last_photo_warnings: list[StageWarning] = field(default_factory=list)
    calibration: str = ""
    loo_score_deg: float | None = None
    diagnosis: str = ""
    follow_up: bool = False
    verdict: str = ""


@dataclass
class DesignFile:
    """An uploaded design that passed the rules: bends and compensated pin angles."""

    name: str
    bends: int
    bends_deg: list[float]
    pin_deg: list[float]
    chords_mm: list[list[float]]
    wire_mm: float
    compensation: str


@dataclass
class QueueItem:
    id: str
    design: str
    quantity: int
    done: int = 0


@dataclass
class JobState:
    """The running bend job. ``status``: idle, bending, paused, lost, interrupted, done, cancelled."""

    status: str = "idle"
    item: str = ""
    design: str = ""
    part: int = 0
    quantity: int = 0
    bends_done: int = 0
    bends_total: int = 0
    elapsed_s: float = 0.0
    time_left_s: float | None = None
    time_left_from: str = ""
    message: str = "nothing bending"


@dataclass
class VertexDeviation:
    vertex: int
    design_deg: float
    measured_deg: float
    error_deg: float
    ok: bool


@dataclass
class InspectState:
    """The last inspected part: per-vertex deviations, PASS/FAIL, and the correction."""

    design: str = ""
    part: int = 0
    verdict: str = ""
    passed: bool | None = None
    tolerance_deg: float = 0.5
    worst_deg: float | None = None
    vertices: list[VertexDeviation] = field(default_factory=list)
    # what the part measurement doubts (a low resolution, a gap in the centreline, ...):
    # shown beside the verdict, which a warning does not change but may not hold
    warnings: list[StageWarning] = field(default_factory=list)
    corrected: bool = False
    message: str = "no part inspected yet"
    busy: bool = False
    measure_cpu_s: float | None = None  # CPU time of the last verdict (photo read to verdict)
    history: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class AppState:
    connection: Connection = field(default_factory=Connection)
    lens: LensState = field(default_factory=LensState)
    plane: PlaneCheck = field(default_factory=PlaneCheck)
    kit: KitCheck = field(default_factory=KitCheck)
    material: MaterialState = field(default_factory=MaterialState)
    files: list[DesignFile] = field(default_factory=list)
    queue: list[QueueItem] = field(default_factory=list)
    job: JobState = field(default_factory=JobState)
    inspect: InspectState = field(default_factory=InspectState)

    def section(self, name: str) -> Any:
        """One section as JSON-able data (``files`` and ``queue`` are lists)."""
        value = getattr(self, name)
        if isinstance(value, list):
            return to_jsonable([asdict(v) for v in value])
        return to_jsonable(asdict(value))


#: Sections of the state, each sent as one SSE event type.
SECTIONS = ("connection", "lens", "plane", "kit", "material", "files", "queue", "job", "inspect")


@dataclass(frozen=True)
class Event:
    id: str
    kind: str
    data: Any


class EventBus:
    """Events for Server-Sent Events: numbered, kept for a while so a reconnect can catch up.

    Ids are ``<boot>-<n>``: after a server restart a browser's ``Last-Event-ID`` names an
    old boot, and it gets the whole state again.
    """

    def __init__(self, keep: int = 500) -> None:
        self.boot = uuid.uuid4().hex[:8]
        self._events: deque[tuple[int, Event]] = deque(maxlen=keep)
        self._n = 0
        self._cond = threading.Condition()

    def publish(self, kind: str, data: Any) -> Event:
        with self._cond:
            self._n += 1
            ev = Event(f"{self.boot}-{self._n}", kind, data)
            self._events.append((self._n, ev))
            self._cond.notify_all()
            return ev

    def last_number(self) -> int:
        with self._cond:
            return self._n

    def since(self, number: int) -> list[tuple[int, Event]]:
        """Events after ``number`` (this boot's count)."""
        with self._cond:
            return [(n, e) for n, e in self._events if n > number]

    def parse_last_id(self, last_id: str | None) -> int | None:
        """The count in a ``Last-Event-ID`` of this boot, else None (send everything)."""
        if not last_id or "-" not in last_id:
            return None
        boot, _, n = last_id.partition("-")
        if boot != self.boot or not n.isdigit():
            return None
        oldest = self._events[0][0] if self._events else self._n + 1
        number = int(n)
        return number if number >= oldest - 1 else None


class Control:
    """Which browser controls the machine; the others watch.

    The first client that acts takes control while nobody holds it; another client must
    take it over explicitly (a button), never by accident.
    """

    def __init__(self) -> None:
        self.holder: str | None = None
        self.since = 0.0
        self._lock = threading.Lock()

    def allows(self, client: str | None) -> bool:
        with self._lock:
            if not client:
                return False
            if self.holder is None:
                self.holder, self.since = client, time.time()
            return self.holder == client

    def take(self, client: str) -> None:
        with self._lock:
            self.holder, self.since = client, time.time()
