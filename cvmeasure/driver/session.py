"""The automatic calibration session: bend, photograph, release, photograph, measure.

For each bend of its plan (:func:`SessionConfig.plan`: a mode's angles twice each way in
the order :mod:`cvmeasure.driver.plan` makes for the diagnosis; custom angles once each
way) a session:

1. feeds fresh straight wire (``G91 G1 Y<feed>``),
2. bends: the pin goes to the nominal command for the wanted *loaded* angle
   (the simulation's inverse kinematics; the calibration measures what really
   happened, so the nominal model only has to be close), and waits until the
   move is done,
3. photographs the loaded wire, releases the pin (``G0 X0``), waits,
   photographs the unloaded wire,
4. measures both photos with :func:`cvmeasure.markers.measure_machine_photo`,
5. appends the sample to an append-only session log (JSON Lines, fsync'd).

A session killed at any point resumes from its log: completed angles are never
bent again; an angle that was bent but not completely recorded is bent again
on fresh wire. At the end the samples are fitted
(:func:`~cvmeasure.material.bender_calibration.fit_calibration`).

The machine is anything with ``run(lines)`` (send G-code lines and return once
every move has finished): :class:`StreamedBender` drives a board through the
streamer, a real one or the TinyG double (``sim://``), whose simulated machine
state the photo lab's simulated camera
(:class:`cvmeasure_datasets.simcapture.SimulatedCapture`) renders.

Log records (one JSON object per line): ``{"event": "start", "plan": [...],
"config": {...}}``, ``{"event": "fed", "step": i, "feed_mm": ..., "refeed": ...}``
(fresh wire is out), ``{"event": "bend", "step": i, ...}`` (written before the
bend is sent), ``{"event": "sample", "step": i, ...}`` (a completed angle),
``{"event": "resume", "done": n, "interrupted": [...]}``, ``{"event": "failed",
"step": i, "error": "..."}``. Every ``bend`` follows a ``fed`` of its step: a step
cut after its bend was sent is bent again only on wire fed since.
"""

from __future__ import annotations

import datetime as _dt
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Protocol

from cvmeasure.contracts import MachinePhotoResult, Trial
from cvmeasure.driver.capture import CaptureDevice
from cvmeasure.driver.plan import diagnosis_plan, swept_plan
from cvmeasure.driver.stream import stream_job
from cvmeasure.errors import CvmeasureError, InputError
from cvmeasure.fileio import append_jsonl, read_jsonl
from cvmeasure.kit import default_kit
from cvmeasure.markers.measure import measure_photo_file
from cvmeasure.material.bender_calibration import MODES, BenderCalibration, fit_calibration
from cvmeasure.sim import SimParams
from cvmeasure.sim.kinematics import contact_angle_deg, head_geometry, pin_angle_for_loaded_deg
from cvmeasure.warning import StageWarning

__all__ = [
    "Machine",
    "SessionConfig",
    "SessionStep",
    "SessionResult",
    "SessionInterrupted",
    "StreamedBender",
    "nominal_pin_for_loaded_deg",
    "session_gcode",
    "run_session",
    "read_session_log",
    "session_warnings_json",
]

LOG_NAME = "session.jsonl"


class Machine(Protocol):
    """What a session needs from a bender."""

    def run(self, lines: Sequence[str]) -> None:
        """Send G-code lines; return once every move has finished (machine idle)."""
        ...


@dataclass(frozen=True)
class SessionConfig:
    """What a session bends and how.

    Attributes
    ----------
    mode : str
        ``"quick"``, ``"standard"``, ``"high"`` or ``"custom"`` (then ``angles_deg``
        is used).
    angles_deg : tuple of float
        Calibration angles (wanted loaded bend angles, deg); from the mode
        unless ``mode == "custom"``.
    feed_mm : float
        Fresh wire fed before every bend (mm).
    feed_rate_mm_min, bend_rate_deg_min : float
        F words of the feed and the bend moves.
    duck : bool
        Duck the pin (Z180 / Z0) when the bend direction changes.
    """

    mode: str = "quick"
    angles_deg: tuple[float, ...] = ()
    feed_mm: float = 40.0
    feed_rate_mm_min: float = 3000.0
    bend_rate_deg_min: float = 3000.0
    duck: bool = True

    def plan(self) -> list[tuple[str, float]]:
        """The bends ``(direction, angle_deg)`` in execution order: a mode's angles in the
        diagnosis' order (:func:`~cvmeasure.driver.plan.diagnosis_plan`, each angle twice
        each way), custom angles each once per direction, as listed."""
        if self.mode == "custom":
            return swept_plan(self.angles_deg)
        if self.mode not in MODES:
            raise ValueError(f"unknown mode {self.mode!r}; valid: {', '.join(MODES)}, custom")
        return diagnosis_plan(MODES[self.mode])

    def to_dict(self) -> dict[str, Any]:
        return {
            "mode": self.mode,
            "angles_deg": list(self.angles_deg),
            "feed_mm": self.feed_mm,
            "feed_rate_mm_min": self.feed_rate_mm_min,
            "bend_rate_deg_min": self.bend_rate_deg_min,
            "duck": self.duck,
        }


@dataclass(frozen=True)
class SessionStep:
    """One completed calibration bend, as logged."""

    step: int
    direction: str
    target_deg: float
    commanded_pin_deg: float
    loaded: MachinePhotoResult
    unloaded: MachinePhotoResult
    photo_loaded: str
    photo_unloaded: str
    truth: Mapping[str, Any] | None = None

    @property
    def springback_deg(self) -> float:
        return self.sample().springback_deg

    def sample(self) -> Trial:
        """This bend as a calibration trial (measured on its two photos)."""
        return replace(
            Trial.from_photos(
                self.loaded,
                self.unloaded,
                trial=str(self.step + 1),
                commanded_pin_deg=self.commanded_pin_deg,
                target_deg=self.target_deg,
            ),
            photo_loaded=self.photo_loaded,
            photo_unloaded=self.photo_unloaded,
        )

    def photo_warnings(self) -> list[tuple[str, StageWarning]]:
        """Every warning of this bend's two photos, with the photo it was given on."""
        return [(self.photo_loaded, w) for w in self.loaded.warnings] + [
            (self.photo_unloaded, w) for w in self.unloaded.warnings
        ]

    def to_dict(self) -> dict[str, Any]:
        d = {
            "event": "sample",
            "step": self.step,
            "direction": self.direction,
            "target_deg": self.target_deg,
            "commanded_pin_deg": self.commanded_pin_deg,
            "photo_loaded": self.photo_loaded,
            "photo_unloaded": self.photo_unloaded,
            "loaded": self.loaded.to_dict(),
            "unloaded": self.unloaded.to_dict(),
            "springback_deg": self.springback_deg,
        }
        if self.truth is not None:
            d["truth"] = dict(self.truth)
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> SessionStep:
        return cls(
            step=int(d["step"]),
            direction=str(d["direction"]),
            target_deg=float(d["target_deg"]),
            commanded_pin_deg=float(d["commanded_pin_deg"]),
            loaded=MachinePhotoResult.from_dict(d["loaded"], source="session log"),
            unloaded=MachinePhotoResult.from_dict(d["unloaded"], source="session log"),
            photo_loaded=str(d["photo_loaded"]),
            photo_unloaded=str(d["photo_unloaded"]),
            truth=d.get("truth"),
        )


@dataclass(frozen=True)
class SessionResult:
    """A finished session: its steps in plan order, the fitted calibration, what this run bent."""

    steps: tuple[SessionStep, ...]
    calibration: BenderCalibration
    bent_this_run: tuple[int, ...]
    resumed: bool
    log_path: Path

    def to_dict(self) -> dict[str, Any]:
        return {
            "log": str(self.log_path),
            "resumed": self.resumed,
            "bent_this_run": list(self.bent_this_run),
            "steps": [s.to_dict() for s in self.steps],
            "calibration": self.calibration.to_dict(),
        }


# ----------------------------------------------------------------------------- nominal model


def nominal_pin_for_loaded_deg(loaded_deg: float, direction: str, params: Any = None) -> float:
    """Signed pin command (deg of head rotation from home) that should bend to ``loaded_deg``.

    Uses the tangent-construction kinematics of :mod:`cvmeasure.sim` with the
    given (default) parameters; ``loaded_deg`` is a magnitude, ``direction``
    ``"ccw"`` or ``"cw"``.
    """
    params = params or SimParams()
    sign = -1.0 if direction == "cw" else 1.0
    geom = head_geometry(params, sign)
    phi = float(pin_angle_for_loaded_deg(geom, abs(loaded_deg)))
    return sign * (phi - float(contact_angle_deg(geom)) + params.approach_deg)


def _fmt(value: float) -> str:
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def session_gcode(
    kind: str, config: SessionConfig, *, pin_deg: float = 0.0, previous_direction: str | None = None
) -> list[str]:
    """G-code lines of one session action.

    ``kind``: ``"setup"`` (units, absolute mode, pin home, unducked),
    ``"feed"`` (fresh wire), ``"bend"`` (pin to ``pin_deg``; ducks across
    when the direction changes or the pin's side is unknown, i.e.
    ``previous_direction`` is None), ``"release"`` (pin home).
    Lines are plain ASCII without realtime characters.
    """
    if kind == "setup":
        return ["G21 G90", "G0 Z0", "G0 X0"]
    if kind == "feed":
        return ["G91", f"G1 Y{_fmt(config.feed_mm)} F{_fmt(config.feed_rate_mm_min)}", "G90"]
    if kind == "bend":
        lines = []
        direction = "cw" if pin_deg < 0 else "ccw"
        if config.duck and previous_direction != direction:
            lines += ["G0 Z180", "G0 X0", "G0 Z0"]
        lines.append(f"G1 X{_fmt(pin_deg)} F{_fmt(config.bend_rate_deg_min)}")
        return lines
    if kind == "release":
        return ["G0 X0"]
    raise ValueError(f"unknown G-code kind {kind!r}")


# ----------------------------------------------------------------------------- machines


class StreamedBender:
    """A bender on a serial link, driven one action at a time through the streamer.

    Every :meth:`run` numbers its lines (``N`` words increasing over the whole
    session) and streams them with :func:`cvmeasure.driver.stream.stream_job`,
    which returns once the board has executed them (or raises
    :class:`~cvmeasure.driver.stream.JobStopped` after a safe stop).

    Parameters
    ----------
    link : cvmeasure.driver.transport.Link
        The open link (a real port, or ``sim://`` for the TinyG double).
    config : cvmeasure.driver.stream.StreamConfig, optional
    """

    def __init__(self, link: Any, *, config: Any = None, double: Any = None) -> None:
        self.link = link
        self.config = config
        self.double = double
        self.lines: list[str] = []
        self._number = 0

    def run(self, lines: Sequence[str]) -> None:
        numbered = []
        for line in lines:
            self._number += 1
            numbered.append(f"N{self._number} {line}")
        stream_job(self.link, numbered, config=self.config, source="session")
        self.lines.extend(numbered)

    def close(self) -> None:
        """Close the link (and stop the double this bender owns, if any)."""
        self.link.close()
        if self.double is not None:
            self.double.close()


# ----------------------------------------------------------------------------- the session


def read_session_log(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """The records of a session log (a cut last line from a crash is ignored)."""
    return read_jsonl(path, skip_partial_last=True)


def _photo_name(step: int, direction: str, angle: float, which: str) -> str:
    return f"step{step + 1:02d}_{direction}_{angle:05.1f}_{which}".replace(".", "p")


def run_session(
    machine: Machine,
    camera: CaptureDevice,
    out_dir: str | os.PathLike[str],
    *,
    config: SessionConfig = SessionConfig(),
    kit: Any = None,
    measure_options: Mapping[str, Any] | None = None,
    model: str = "linear",
    params: Any = None,
    name: str = "calibration",
    progress: Callable[[int, int, SessionStep], None] | None = None,
    stop_after: int | None = None,
) -> SessionResult:
    """Run (or resume) a calibration session and fit the calibration.

    Parameters
    ----------
    machine : Machine
        The bender (``run(lines)`` returns once the moves are done).
    camera : CaptureDevice
        Takes the loaded and unloaded photos.
    out_dir : path
        Session folder: ``session.jsonl`` (the log) and ``photos/``. An existing
        log is resumed; it must be of the same plan.
    config : SessionConfig
        Mode, angles, feed.
    kit : MarkerKit, optional
        The marker kit on the machine (default :func:`cvmeasure.kit.default_kit`).
    measure_options : mapping, optional
        Passed on to :func:`cvmeasure.markers.measure_machine_photo` (camera, plane, method...).
    model : str
        Springback model of the calibration.
    params : cvmeasure.sim.SimParams, optional
        Nominal machine model for the pin commands.
    progress : callable(done, total, step), optional
        Called after every completed angle.
    stop_after : int, optional
        Stop (without fitting) after this many angles bent in this run
        (tests and dry runs); raises :class:`SessionInterrupted`.

    Raises
    ------
    InputError
        A photo could not be measured (names the photo and the marker), or the
        log belongs to another plan.
    """
    kit = kit or default_kit()
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    log_path = out / LOG_NAME
    plan = config.plan()
    resumed = log_path.exists()
    done, interrupted = _open_log(log_path, config, plan)
    options = dict(measure_options or {})
    bent: list[int] = []
    previous_direction: str | None = None  # unknown pin side: the first bend ducks across
    machine.run(session_gcode("setup", config))
    for step, (direction, angle) in enumerate(plan):
        if step in done:
            continue
        if stop_after is not None and len(bent) >= stop_after:
            raise SessionInterrupted(f"stopped after {len(bent)} bends as asked")
        pin = round(nominal_pin_for_loaded_deg(angle, direction, params), 3)  # as sent
        bent.append(step)
        try:
            record = _bend_and_measure(
                machine,
                camera,
                out,
                step,
                direction,
                angle,
                pin,
                previous_direction,
                config=config,
                kit=kit,
                options=options,
                log_path=log_path,
                refeed=step in interrupted,
            )
        except CvmeasureError as exc:
            append_jsonl(log_path, {"event": "failed", "step": step, "error": str(exc)})
            raise
        previous_direction = direction
        append_jsonl(log_path, record.to_dict())
        done[step] = record
        if progress is not None:
            progress(len(done), len(plan), record)
    steps = tuple(done[i] for i in sorted(done))
    calibration = _fit_session(steps, config, plan, model, name, log_path)
    return SessionResult(
        steps=steps,
        calibration=calibration,
        bent_this_run=tuple(bent),
        resumed=resumed,
        log_path=log_path,
    )


def _open_log(
    log_path: Path, config: SessionConfig, plan: list[tuple[str, float]]
) -> tuple[dict[int, SessionStep], set[int]]:
    """Resume the log (steps done, steps interrupted mid-bend) or start it with the plan."""
    plan_json = [[d, a] for d, a in plan]
    if log_path.exists():
        return _read_resume(log_path, plan_json)
    append_jsonl(
        log_path,
        {"event": "start", "plan": plan_json, "config": config.to_dict(), "time_utc": _now()},
    )
    return {}, set()


def _fit_session(
    steps: tuple[SessionStep, ...],
    config: SessionConfig,
    plan: list[tuple[str, float]],
    model: str,
    name: str,
    log_path: Path,
) -> BenderCalibration:
    """The calibration fitted to the session's steps, with their photo warnings attached."""
    try:
        calibration = fit_calibration(
            [s.sample() for s in steps],
            model=model,  # type: ignore[arg-type]
            name=name,
            mode=config.mode,
            angles_deg=config.angles_deg or tuple(sorted({a for _, a in plan})),
        )
    except ValueError as exc:
        raise InputError(log_path, f"cannot fit a calibration to this session: {exc}") from None
    return replace(
        calibration,
        provenance={**calibration.provenance, "warnings": session_warnings_json(steps)},
    )


def _read_resume(
    log_path: Path, plan_json: list[list[Any]]
) -> tuple[dict[int, SessionStep], set[int]]:
    """(done steps, steps cut after their bend was sent) of a log being resumed.

    A step whose bend was sent but not recorded may have bent the wire at the pin: it
    is bent again only after fresh wire is fed past that bend. The resume is logged.
    """
    records = read_session_log(log_path)
    start = next((r for r in records if r.get("event") == "start"), None)
    if start is None or start.get("plan") != plan_json:
        raise InputError(
            log_path, "session log belongs to another plan (use a new folder or the same mode)"
        )
    done = {int(r["step"]): SessionStep.from_dict(r) for r in records if r.get("event") == "sample"}
    interrupted = {int(r["step"]) for r in records if r.get("event") == "bend"} - set(done)
    append_jsonl(
        log_path,
        {
            "event": "resume",
            "done": len(done),
            "interrupted": sorted(interrupted),
            "time_utc": _now(),
        },
    )
    return done, interrupted


def session_warnings_json(steps: Sequence[SessionStep]) -> list[dict[str, str]]:
    """Every photo warning of a session for the calibration's ``provenance.warnings``:
    each warning's JSON object (code, message, subject) with the ``photo`` it was given on."""
    return [{**w.to_json(), "photo": photo} for s in steps for photo, w in s.photo_warnings()]


def _bend_and_measure(
    machine: Machine,
    camera: CaptureDevice,
    out: Path,
    step: int,
    direction: str,
    angle: float,
    pin: float,
    previous_direction: str | None,
    *,
    config: SessionConfig,
    kit: Any,
    options: Mapping[str, Any],
    log_path: Path,
    refeed: bool = False,
) -> SessionStep:
    """Feed, bend, photograph loaded, release, photograph unloaded, measure both.

    The log gets ``fed`` once the fresh wire is out (``refeed`` true when the step's
    previous attempt was cut after its bend was sent: that wire may be bent) and
    ``bend`` before the bend is sent, so a resume knows which wire a bend was on.
    """
    machine.run(session_gcode("feed", config))
    append_jsonl(
        log_path,
        {
            "event": "fed",
            "step": step,
            "feed_mm": config.feed_mm,
            "refeed": refeed,
            "time_utc": _now(),
        },
    )
    append_jsonl(
        log_path,
        {
            "event": "bend",
            "step": step,
            "direction": direction,
            "target_deg": angle,
            "commanded_pin_deg": pin,
            "time_utc": _now(),
        },
    )
    machine.run(session_gcode("bend", config, pin_deg=pin, previous_direction=previous_direction))
    shot_loaded = camera.capture(_photo_name(step, direction, angle, "loaded"))
    machine.run(session_gcode("release", config))
    shot_unloaded = camera.capture(_photo_name(step, direction, angle, "unloaded"))
    results = []
    for shot in (shot_loaded, shot_unloaded):
        opts = dict(options)
        if shot.camera is not None and opts.get("plane") is None:
            opts.setdefault("camera", shot.camera)
        results.append(measure_photo_file(shot.path, kit, **opts))
    truth = None
    if shot_loaded.truth is not None and shot_unloaded.truth is not None:
        truth = {
            "loaded_bend_deg": shot_loaded.truth.get("bend_angle_deg"),
            "unloaded_bend_deg": shot_unloaded.truth.get("bend_angle_deg"),
            "pin_angle_deg": shot_loaded.truth.get("pin_angle_deg"),
        }
    record = SessionStep(
        step=step,
        direction=direction,
        target_deg=angle,
        commanded_pin_deg=pin,
        loaded=results[0],
        unloaded=results[1],
        photo_loaded=os.path.relpath(shot_loaded.path, out),
        photo_unloaded=os.path.relpath(shot_unloaded.path, out),
        truth=truth,
    )
    _check_sign(record, shot_loaded.path)
    return record


class SessionInterrupted(CvmeasureError):
    """The session stopped before its plan was complete (resume it from its log)."""


def _check_sign(record: SessionStep, photo: Path) -> None:
    sign = -1.0 if record.direction == "cw" else 1.0
    if sign * record.loaded.bend_angle_deg <= 0:
        raise InputError(
            photo,
            f"measured loaded bend {record.loaded.bend_angle_deg:.2f} deg has the wrong sign "
            f"for a {record.direction} bend (is the kit mirrored or a marker swapped?)",
        )


def _now() -> str:
    return _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
