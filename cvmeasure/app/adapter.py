"""The one place where the app calls the cvmeasure library.

Measuring, fitting, G-code and the closed loop go through the public API (``import
cvmeasure``: :mod:`cvmeasure.api`). What the public API does not offer is called here from
its module, and only here: the automatic session and the streamer (:mod:`cvmeasure.driver`),
the coverage advice and the per-view board detection of the lens calibration, the fast
marker search of the live view, the photo overlays, and the nominal simulation the app starts
from before any material session. Functions return typed values, never dicts.

The driver's session log and serial transport are imported when the operator first
reads a session or opens a link, so the app's pages come up without them.
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

import cvmeasure
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.contracts import Trial
from cvmeasure.design import DesignPath
from cvmeasure.diagnose.result import CauseKind
from cvmeasure.driver.session import (
    SessionConfig,
    SessionInterrupted,
    SessionStep,
    StreamedBender,
    nominal_pin_for_loaded_deg,
    run_session,
)
from cvmeasure.driver.stream import StreamControl, prepare_job, stream_job
from cvmeasure.errors import InputError
from cvmeasure.lens.coverage import RECOMMENDED_VIEWS, image_coverage
from cvmeasure.lens.detect import detect_board
from cvmeasure.markers.colour import kit_colour_model
from cvmeasure.markers.detect import find_markers
from cvmeasure.markers.overlay import draw_overlay as draw_marker_overlay
from cvmeasure.material.bender_calibration import MODES
from cvmeasure.part.overlay import draw_overlay as draw_part_overlay
from cvmeasure.sim import simulate
from cvmeasure.warning import StageWarning

__all__ = [
    "BOARD",
    "CheckedDesign",
    "LensSolve",
    "PartCheck",
    "check_design",
    "check_points",
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


def check_design(path: Path, calibration: Any = None, *, name: str | None = None) -> CheckedDesign:
    """Read a design, check the bender's rules and compensate it (``cvmeasure.gcode_for``).

    Raises InputError naming the file (as ``name``) when the design breaks a rule.
    """
    name = name or path.name
    try:
        wire = cvmeasure.load_design(path).wire()
        job = cvmeasure.gcode_for(path, calibration)
    except InputError as exc:
        raise InputError(name, _problem(exc)) from None
    return _checked(name, wire.points_mm, job, calibration)


def check_points(points: Any, calibration: Any = None, *, name: str) -> CheckedDesign:
    """Check and compensate a polyline (mm): rules, bends, pin commands, G-code."""

    wire = DesignPath(np.asarray(points, dtype=float), closed=False, kind="polyline", element=name)
    try:
        job = cvmeasure.gcode_for(wire, calibration)
    except InputError as exc:
        raise InputError(name, _problem(exc)) from None
    return _checked(name, wire.points_mm, job, calibration)


def _checked(name: str, points: Any, job: Any, calibration: Any) -> CheckedDesign:
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
    return cvmeasure.measure_bender_photo(path, kit, camera=camera)


def bender_overlay(bgr: np.ndarray, result: Any, kit: Any, max_width_px: int = 1280) -> np.ndarray:
    """The photo with the markers, the machine frame and the angles drawn on it."""

    return draw_marker_overlay(bgr, result, kit, max_width_px=max_width_px)


def find_marker_centres(bgr: np.ndarray, kit: Any) -> dict[str, tuple[float, float, float]]:
    """Marker discs found in a live frame: role -> (x px, y px, radius px); fast search only."""

    search = find_markers(bgr, kit, kit_colour_model(kit))
    out = {}
    for role, c in search.found.items():
        out[role] = (float(c.centre_px[0]), float(c.centre_px[1]), float(c.radius_px))
    return out


def detect_board_view(bgr: np.ndarray, source: str) -> Any:
    """The board's corners in one lens-calibration photo (:class:`BoardDetection`)."""

    return detect_board(bgr, BOARD, source=source)


def coverage_guidance(detections: Sequence[Any], image_size_px: tuple[int, int]) -> str:
    """Where to hold the board next, from the coverage of the views so far (in words)."""

    usable = [d for d in detections if len(d.corners_px)]
    if not usable:
        return "hold the board flat in the middle of the view, filling about a third of it"
    cov = image_coverage(usable, image_size_px)
    for warning in cov.warnings:
        if warning.code != "calib_few_views" and "add photos" in warning.message:
            advice = warning.message.split(": ", 1)[-1]
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


def solve_lens(photos: Sequence[Path]) -> LensSolve:
    """Calibrate the lens from the views' photos (``cvmeasure.calibrate_camera``)."""
    cal = cvmeasure.calibrate_camera(list(photos), BOARD, model="5")
    report = cal.report
    # dropping a few outlier corners is the solve doing its job, not a reason to redo it
    problems = tuple(str(w) for w in report.warnings if w.code != "calib_corners_dropped")
    return LensSolve(
        camera=cal.camera,
        rms_px=float(report.result.rms_px),
        covered_fraction=float(report.coverage.covered_fraction),
        problems=problems,
    )


def save_camera(path: Path, camera: Any) -> None:
    cvmeasure.save(path, camera)


def load_camera(path: Path) -> Any:
    return cvmeasure.load_camera(path)


def plane_check(bgr: np.ndarray, camera: Any, source: str) -> Any:
    """The plate's tilt seen by the camera (``cvmeasure.measure_plane``)."""
    return cvmeasure.measure_plane(bgr, BOARD, camera)


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
    warnings: tuple[StageWarning, ...] = ()


def measure_finished_part(bgr: np.ndarray, camera: Any, design: Path, source: str) -> PartCheck:
    """Measure a part photo against its design, vertex by vertex (``cvmeasure.measure_part``).

    The part is compared with the polygon the app bends the design as (planned by
    ``cvmeasure.gcode_for``'s rules, as :func:`check_design` plans it), in its chord count.
    """
    try:
        m = cvmeasure.measure_part(
            bgr,
            board=BOARD,
            camera=camera,
            design=design,
            # the part lies as it left the machine: never matched mirrored
            options=cvmeasure.PartOptions(allow_mirror=False),
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
        warnings=tuple(m.warnings),
    )


def part_overlay(bgr: np.ndarray, check: PartCheck) -> np.ndarray:
    return draw_part_overlay(bgr, check.measurement)


def correct_next_part(calibration: Any, check: PartCheck, design: Path) -> tuple[Any, Any, Any]:
    """(corrected calibration, correction, next job) from a measured part (``cvmeasure.correct``).

    The design is given by its path: its file name keys the job's per-vertex corrections.
    """
    out = cvmeasure.correct(check.measurement, design, calibration)
    return out.material, out.correction, out.job


@functools.lru_cache(maxsize=1)
def default_calibration() -> Any:
    """The nominal simulated machine's calibration (a start before any material session)."""

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
    return cvmeasure.fit_material(samples, name="nominal machine")


def load_calibration(path: Path) -> Any:
    return cvmeasure.load_material(path)


def save_calibration(path: Path, calibration: Any) -> None:
    cvmeasure.save(path, calibration)


def session_config(mode: str, angles: Sequence[float]) -> Any:
    return SessionConfig(mode="custom" if angles else mode, angles_deg=tuple(angles))


def session_plan(mode: str, angles: Sequence[float]) -> list[tuple[str, float]]:
    return session_config(mode, angles).plan()


def read_session_log(path: Path) -> list[dict[str, Any]]:
    from cvmeasure.driver.session import read_session_log as _read

    return _read(path)


def session_step_from_record(record: dict[str, Any]) -> Any:
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
    return StreamedBender(link)


def session_interrupted(message: str) -> Exception:
    return SessionInterrupted(message)


@dataclass(frozen=True)
class SessionDiagnosis:
    """The diagnosis of a session's trials in one sentence, and its follow-up plan rows."""

    sentence: str
    follow_up_rows: tuple[tuple[str, float], ...]


def diagnose_session(trials: Any) -> SessionDiagnosis:
    """Name the machine effect behind the trials (``cvmeasure diagnose``), in one sentence."""
    try:
        d = cvmeasure.diagnose_trials(list(trials))
    except ValueError as exc:
        return SessionDiagnosis(f"no diagnosis: {exc}", ())
    gain = 100.0 * d.gain
    if d.cause.kind is CauseKind.NONE:
        sentence = (
            f"the nominal machine explains the bends (held-out error {d.baseline_rmse_deg:.3f} deg)"
        )
    elif d.cause.kind is CauseKind.UNEXPLAINED:
        sentence = (
            "no known machine effect explains the bends (held-out error "
            f"{d.baseline_rmse_deg:.3f} deg): look at the machine before bending parts"
        )
    else:
        sentence = (
            f"most likely {d.cause.label}: it cuts the held-out error from "
            f"{d.baseline_rmse_deg:.3f} to {d.extended_rmse_deg:.3f} deg ({gain:.0f} %)"
        )
    rows: tuple[tuple[str, float], ...] = ()
    if d.follow_up is not None:
        rows = tuple((str(r["trial"]), float(r["commanded_pin_deg"])) for r in d.follow_up.rows())
        sentence += "; a follow-up plan separates the tied explanations"
    return SessionDiagnosis(sentence, rows)


def open_link(url: str, double: Any = None) -> Any:
    from cvmeasure.driver.transport import open_link as _open

    return _open(url, double=double) if double is not None else _open(url)


def stream_control() -> Any:
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

    stroke = re.compile(r"G90\s+G1\s+X", re.IGNORECASE)  # as ``cvmeasure correct`` counts
    return [
        (line.number, bool(stroke.search(line.text)))
        for line in prepare_job(text.splitlines(), source="job")
    ]


def default_kit() -> Any:
    return cvmeasure.load_kit()


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
