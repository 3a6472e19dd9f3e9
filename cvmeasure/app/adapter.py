"""The one place where the app calls the cvmeasure library.

Every measuring, fitting and G-code function the app uses is called here, so that when the
library's public API lands the switch is this one file. Functions take and return typed
values (dataclasses of :mod:`cvmeasure.app.state` or library types), never dicts.
"""

from __future__ import annotations

import functools
import os
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.board import CharucoBoardSpec
from cvmeasure.errors import InputError

__all__ = [
    "BOARD",
    "CheckedDesign",
    "LensSolve",
    "PartCheck",
    "check_design",
    "check_points",
    "design_polyline",
    "springback_for",
    "measure_bender_photo",
    "bender_overlay",
    "detect_board_view",
    "coverage_guidance",
    "solve_lens",
    "plane_check",
    "kit_check",
    "measure_finished_part",
    "correct_next_part",
    "run_material_session",
    "diagnose_session",
    "stream_lines",
]

#: The board of the lens calibration, the plane check and the part photos (the spec's example).
BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
#: Views the lens calibration asks for before it solves.
MIN_LENS_VIEWS = 8


@dataclass(frozen=True)
class CheckedDesign:
    """A design that passed the bender's rules: its chords, bends, pin commands and G-code."""

    name: str
    chords_mm: np.ndarray  # (N + 1, 2) design frame
    bends_deg: tuple[float, ...]
    pin_deg: tuple[float, ...]
    gcode: str
    wire_mm: float
    compensation: str


def design_polyline(path: Path) -> Any:
    """The design's single wire (:class:`cvmeasure.design.DesignPath`), or InputError."""
    from cvmeasure.design import load_design

    wire = load_design(path).wire()
    if wire.closed:
        raise InputError(
            path.name, f"closed shape {wire.element or wire.kind}: a wire part needs two free ends"
        )
    return wire


def check_design(path: Path, calibration: Any = None, *, name: str | None = None) -> CheckedDesign:
    """Read a design, check the bender's rules and compensate it (as ``cvmeasure gcode``).

    Raises InputError naming the file when the design breaks a rule.
    """
    from cvmeasure.driver.gcode import wire_polyline

    name = name or path.name
    try:
        wire = design_polyline(path)
        points = wire_polyline(wire.points_mm, arcs=wire.arcs)
    except InputError as exc:
        raise InputError(name, _problem(exc)) from None
    return check_points(points, calibration, name=name)


def check_points(points: Any, calibration: Any = None, *, name: str) -> CheckedDesign:
    """Check and compensate a polyline (mm): rules, bends, pin commands, G-code."""
    from cvmeasure.driver.gcode import SimCompensator, design_job

    try:
        job = design_job(points, source=name, compensation=calibration or SimCompensator())
    except InputError as exc:
        raise InputError(name, _problem(exc)) from None
    return CheckedDesign(
        name=name,
        chords_mm=np.asarray(points, dtype=float),
        bends_deg=tuple(float(b) for b in job.bends.bends_deg),
        pin_deg=tuple(float(p) for p in job.pin_deg),
        gcode=job.text(),
        wire_mm=float(job.bends.total_feed_mm),
        compensation="calibration" if calibration is not None else "simulation model",
    )


def _problem(exc: InputError) -> str:
    """The problem part of an InputError's one line (its source is renamed by the caller)."""
    text = str(exc)
    return text.split(": ", 1)[1] if ": " in text else text


def springback_for(calibration: Any, final_deg: float) -> tuple[float, float]:
    """(pin command deg, springback deg) of a wanted signed final bend angle."""
    pin = float(calibration.compensate(final_deg))
    loaded = float(calibration.compensation.loaded_for(final_deg))
    return pin, abs(loaded) - abs(final_deg)


def measure_bender_photo(path: Path, kit: Any, camera: Any = None) -> Any:
    """The machine photo's signed angles (:class:`cvmeasure.markers.MachinePhotoResult`)."""
    from cvmeasure.markers.measure import measure_photo_file

    options = {"camera": camera} if camera is not None else {}
    return measure_photo_file(path, kit, **options)


def bender_overlay(bgr: np.ndarray, result: Any, kit: Any, max_width_px: int = 1280) -> np.ndarray:
    """The photo with the markers, the machine frame and the angles drawn on it."""
    from cvmeasure.markers.overlay import draw_overlay

    return draw_overlay(bgr, result, kit, max_width_px=max_width_px)


def find_marker_centres(bgr: np.ndarray, kit: Any) -> dict[str, tuple[float, float, float]]:
    """Marker discs found in a live frame: role -> (x px, y px, radius px); fast search only."""
    from cvmeasure.markers.colour import kit_colour_model
    from cvmeasure.markers.detect import find_markers

    search = find_markers(bgr, kit, kit_colour_model(kit))
    out = {}
    for role, c in search.found.items():
        out[role] = (float(c.centre_px[0]), float(c.centre_px[1]), float(c.radius_px))
    return out


def detect_board_view(bgr: np.ndarray, source: str) -> Any:
    """The board's corners in one lens-calibration photo (:class:`BoardDetection`)."""
    from cvmeasure.calibration.detect import detect_board

    return detect_board(bgr, BOARD, source=source)


def coverage_guidance(detections: Sequence[Any], image_size_px: tuple[int, int]) -> str:
    """Where to hold the board next, from the coverage of the views so far (in words)."""
    from cvmeasure.calibration.coverage import RECOMMENDED_VIEWS, image_coverage

    usable = [d for d in detections if len(d.corners_px)]
    if not usable:
        return "hold the board flat in the middle of the view, filling about a third of it"
    cov = image_coverage(usable, image_size_px)
    for warning in cov.warnings:
        if "add photos" in warning and not warning.startswith("only"):
            advice = warning.split(": ", 1)[-1]
            return advice.replace("add photos with the board", "hold the board", 1).replace(
                "add photos", "hold the board", 1
            )
    if len(usable) < RECOMMENDED_VIEWS:
        return (
            f"{len(usable)} of {RECOMMENDED_VIEWS} views: hold the board in another corner of "
            "the view, tilted about 30 deg another way"
        )
    return "coverage is good: solve the calibration"


@dataclass(frozen=True)
class LensSolve:
    """A solved lens: the camera, its RMS, and why it is not yet good (empty when good)."""

    camera: Any
    rms_px: float
    covered_fraction: float
    problems: tuple[str, ...]


def solve_lens(detections: Sequence[Any], image_size_px: tuple[int, int]) -> LensSolve:
    """Calibrate the lens from the views (as ``cvmeasure calibrate``)."""
    from cvmeasure.calibration.pipeline import calibrate_detections

    report = calibrate_detections(list(detections), image_size_px, source="the views taken")
    # dropping a few outlier corners is the solve doing its job, not a reason to redo it
    problems = tuple(str(w) for w in report.warnings if "outlier corner" not in str(w))
    return LensSolve(
        camera=report.camera,
        rms_px=float(report.result.rms_px),
        covered_fraction=float(report.coverage.covered_fraction),
        problems=problems,
    )


def save_camera(path: Path, camera: Any) -> None:
    from cvmeasure.camera import save_camera as _save

    _save(path, camera)


def load_camera(path: Path) -> Any:
    from cvmeasure.camera import load_camera as _load

    return _load(path)


def plane_check(bgr: np.ndarray, camera: Any, source: str) -> Any:
    """The plate's tilt seen by the camera (:class:`cvmeasure.contracts.PlaneModel`)."""
    import cv2

    from cvmeasure.calibration.plane import estimate_plane

    return estimate_plane(cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY), BOARD, camera, source=source)


def kit_check(path: Path, kit: Any, camera: Any = None) -> Any:
    """Measure a photo of the machine at home: which markers are found, how heights were used."""
    return measure_bender_photo(path, kit, camera)


@dataclass(frozen=True)
class PartCheck:
    """A finished part against its design."""

    measurement: Any
    design_bend_deg: tuple[float, ...]
    measured_bend_deg: tuple[float, ...]
    error_deg: tuple[float, ...]
    vertices_px: np.ndarray | None
    vertices_mm: np.ndarray | None
    worst_deg: float


def measure_finished_part(
    bgr: np.ndarray, camera: Any, design: Any, divisions: int, source: str
) -> PartCheck:
    """Measure a part photo against its design, vertex by vertex (as ``cvmeasure part``)."""
    from cvmeasure.part.measure import measure_part

    try:
        m = measure_part(
            bgr,
            BOARD,
            camera,
            divisions=divisions,
            design=design,
            source=source,
            allow_mirror=False,  # the part lies as it left the machine
        )
    except InputError:
        raise
    except ValueError as exc:  # e.g. a design whose vertices fit no circle
        raise InputError(source, f"the part could not be compared with its design: {exc}") from None
    if m.comparison is None or m.comparison.bends is None:
        raise InputError(source, "the part could not be compared with its design")
    b = m.comparison.bends
    return PartCheck(
        measurement=m,
        design_bend_deg=tuple(float(x) for x in b.design_bend_deg),
        measured_bend_deg=tuple(float(x) for x in b.measured_bend_deg),
        error_deg=tuple(float(x) for x in b.error_deg),
        vertices_px=None if m.vertices_px is None else np.asarray(m.vertices_px),
        vertices_mm=None if m.vertices_mm is None else np.asarray(m.vertices_mm),
        worst_deg=float(b.max_abs_error_deg),
    )


def part_overlay(bgr: np.ndarray, check: PartCheck) -> np.ndarray:
    from cvmeasure.part.overlay import draw_overlay

    return draw_overlay(bgr, check.measurement)


def correct_next_part(
    calibration: Any, check: PartCheck, design: Any, design_name: str
) -> tuple[Any, Any, Any]:
    """(corrected calibration, correction, next job) from a measured part (``cvmeasure correct``)."""
    from cvmeasure.material.correct import correct_from_part

    return correct_from_part(calibration, check.measurement, design, design_name=design_name)


@functools.lru_cache(maxsize=1)
def default_calibration() -> Any:
    """The nominal simulated machine's calibration (a start before any material session)."""
    from cvmeasure.contracts import Trial
    from cvmeasure.driver.session import nominal_pin_for_loaded_deg
    from cvmeasure.material.calibration import MODES, fit_calibration
    from cvmeasure.sim import simulate

    angles = MODES["quick"]
    pins = [nominal_pin_for_loaded_deg(a, d) for d in ("ccw", "cw") for a in angles]
    r = simulate(pins)
    samples = [
        Trial(
            trial=str(i),
            commanded_pin_deg=float(p),
            loaded_bend_deg=float(r.loaded_bend_deg[i]),
            unloaded_bend_deg=float(r.unloaded_bend_deg[i]),
            target_deg=float(angles[i % len(angles)]),
        )
        for i, p in enumerate(pins)
    ]
    return fit_calibration(samples, mode="quick", name="nominal machine")


def load_calibration(path: Path) -> Any:
    from cvmeasure.material.calibration import load_calibration as _load

    return _load(path)


def save_calibration(path: Path, calibration: Any) -> None:
    from dataclasses import replace

    from cvmeasure.material.calibration import save_calibration as _save
    from cvmeasure.provenance import provenance

    _save(path, replace(calibration, provenance=calibration.provenance or provenance()))


def session_config(mode: str, angles: Sequence[float]) -> Any:
    from cvmeasure.driver.session import SessionConfig

    return SessionConfig(mode="custom" if angles else mode, angles_deg=tuple(angles))


def session_plan(mode: str, angles: Sequence[float]) -> list[tuple[str, float]]:
    return session_config(mode, angles).plan()


def read_session_log(path: Path) -> list[dict[str, Any]]:
    from cvmeasure.driver.session import read_session_log as _read

    return _read(path)


def session_step_from_record(record: dict[str, Any]) -> Any:
    from cvmeasure.driver.session import SessionStep

    return SessionStep.from_dict(record)


def run_material_session(
    machine: Any,
    camera: Any,
    folder: Path,
    *,
    mode: str,
    angles: Sequence[float],
    progress: Callable[[int, int, Any], None],
    camera_model: Any = None,
) -> Any:
    """Run or resume the automatic calibration session (:func:`run_session`)."""
    from cvmeasure.driver.session import run_session

    options = {"camera": camera_model} if camera_model is not None else {}
    return run_session(
        machine,
        camera,
        folder,
        config=session_config(mode, angles),
        measure_options=options,
        name="material",
        progress=progress,
    )


def streamed_bender(link: Any) -> Any:
    from cvmeasure.driver.session import StreamedBender

    return StreamedBender(link)


def session_interrupted(message: str) -> Exception:
    from cvmeasure.driver.session import SessionInterrupted

    return SessionInterrupted(message)


@dataclass(frozen=True)
class SessionDiagnosis:
    """The diagnosis of a session's trials in one sentence, and its follow-up plan rows."""

    sentence: str
    follow_up_rows: tuple[tuple[str, float], ...]


def diagnose_session(trials: Any) -> SessionDiagnosis:
    """Name the machine effect behind the trials (``cvmeasure diagnose``), in one sentence."""
    from cvmeasure.contracts import TrialTable
    from cvmeasure.diagnose import diagnose
    from cvmeasure.sim import SimParams

    table = trials if isinstance(trials, TrialTable) else TrialTable(tuple(trials))
    try:
        d = diagnose(table, SimParams(), folds=min(5, max(2, len(table.trials) // 2)))
    except ValueError as exc:
        return SessionDiagnosis(f"no diagnosis: {exc}", ())
    gain = 100.0 * d.gain
    if d.cause in ("none", "", None):
        sentence = (
            f"the nominal machine explains the bends (held-out error {d.baseline_rmse_deg:.3f} deg)"
        )
    else:
        sentence = (
            f"most likely {' + '.join(d.causes)}: it cuts the held-out error from "
            f"{d.baseline_rmse_deg:.3f} to {d.extended_rmse_deg:.3f} deg ({gain:.0f} %)"
        )
    rows: tuple[tuple[str, float], ...] = ()
    if d.follow_up is not None:
        rows = tuple((str(r[0]), float(r[1])) for r in d.follow_up.rows())
        sentence += "; a follow-up plan separates the tied explanations"
    return SessionDiagnosis(sentence, rows)


def open_link(url: str, double: Any = None) -> Any:
    from cvmeasure.driver.transport import open_link as _open

    return _open(url, double=double) if double is not None else _open(url)


def stream_control() -> Any:
    from cvmeasure.driver.stream import StreamControl

    return StreamControl()


def stream_lines(
    link: Any,
    text: str,
    *,
    journal: Path,
    resume: bool,
    progress: Callable[[int, int, int | None], None],
    control: Any,
    source: str,
) -> Any:
    """Stream a G-code job, journalled (``cvmeasure bend``); raises JobStopped on a fault."""
    from cvmeasure.driver.stream import prepare_job, stream_job

    job = prepare_job(text.splitlines(), source=source)
    return stream_job(
        link,
        job,
        journal=journal,
        resume=resume,
        progress=progress,
        control=control,
        source=source,
        force=False,
    )


def job_line_numbers(text: str) -> list[tuple[int, bool]]:
    """(N number, is a bend stroke) of every line a job sends, in order."""
    from cvmeasure.driver.stream import prepare_job

    stroke = re.compile(r"G90\s+G1\s+X", re.IGNORECASE)  # as ``cvmeasure correct`` counts
    return [
        (line.number, bool(stroke.search(line.text)))
        for line in prepare_job(text.splitlines(), source="job")
    ]


def default_kit() -> Any:
    from cvmeasure.kit import default_kit as _kit

    return _kit()


def os_fsync_dir(path: Path) -> None:
    """Make a rename in ``path`` durable (best effort)."""
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
