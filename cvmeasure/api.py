"""The public API: one verb per job, each taking paths or loaded objects.

``import cvmeasure`` exposes these names (see :mod:`cvmeasure`). Every verb
accepts a file path wherever it takes a board, camera, plane, kit, design,
material calibration, trials table or photo, or the object already loaded
(``load_*``), and returns a typed result that :func:`save` writes.

Bad input raises :class:`cvmeasure.errors.InputError` naming the file or
option and the problem (what the CLI prints as one line, exit 2).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure import __version__
from cvmeasure.board import BoardSpec
from cvmeasure.board import load_board as _read_board
from cvmeasure.camera_model import CameraModel, save_camera
from cvmeasure.camera_model import load_camera as _read_camera
from cvmeasure.contracts import MachinePhotoResult, PlaneModel, Trial, TrialTable
from cvmeasure.design import Design, DesignPath
from cvmeasure.design import load_design as _read_design
from cvmeasure.diagnose import Cause, Diagnosis
from cvmeasure.diagnose import diagnose as _diagnose
from cvmeasure.errors import InputError
from cvmeasure.fileio import atomic_write_json, atomic_write_text, to_jsonable
from cvmeasure.gcode import GcodeJob, SimCompensator, design_job, job_header
from cvmeasure.imageio import Photo, read_photo
from cvmeasure.kit import MarkerKit, default_kit
from cvmeasure.kit import load_kit as _read_kit
from cvmeasure.lens.pipeline import CalibrationReport, calibrate_detections, detect_photos
from cvmeasure.lens.plane import DEFAULT_TOLERANCE_DEG, estimate_plane
from cvmeasure.markers.measure import measure_photo_file, measure_trial
from cvmeasure.material.bender_calibration import (
    BenderCalibration,
    fit_calibration,
    save_calibration,
)
from cvmeasure.material.bender_calibration import load_calibration as _read_material
from cvmeasure.material.correct import Correction
from cvmeasure.material.correct_part import correct_from_part
from cvmeasure.part.measure import PartMeasurement
from cvmeasure.part.measure import measure_part as _measure_part
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
from cvmeasure.sim import SimParams, params_from_json, params_to_json
from cvmeasure.warning import StageWarning
from cvmeasure.wireplan import plan_design, plan_for_part

__all__ = [
    "Cause",
    "CameraCalibration",
    "CorrectedJob",
    "PartOptions",
    "WireOptions",
    "LiftOptions",
    "calibrate_camera",
    "measure_plane",
    "measure_bender_photo",
    "measure_springback",
    "measure_part",
    "fit_material",
    "diagnose_trials",
    "gcode_for",
    "correct",
    "load_photo",
    "load_board",
    "load_camera",
    "load_plane",
    "load_kit",
    "load_design",
    "load_material",
    "load_trials",
    "load_params",
    "save",
]

PathLike = str | os.PathLike[str]


@dataclass(frozen=True)
class CameraCalibration:
    """A solved lens: the camera to save and the report to judge it by.

    ``camera`` carries its calibration record (board, views, uncertainty); save it with
    :func:`save`. ``report`` holds the cross-validation diff (read it first: it shows
    model error the RMS hides), the projection-uncertainty map, coverage and warnings.
    """

    camera: CameraModel
    report: CalibrationReport

    @property
    def warnings(self) -> tuple[StageWarning, ...]:
        return self.report.warnings


@dataclass(frozen=True)
class CorrectedJob:
    """The closed loop's output: the corrected material calibration, what changed, the next job."""

    material: BenderCalibration
    correction: Correction
    job: GcodeJob


# --- loading ----------------------------------------------------------------------------


def load_photo(path: PathLike) -> Photo:
    """Decode a photo file (JPEG, PNG, TIFF or camera RAW)."""
    return read_photo(path)


def load_board(path: PathLike) -> BoardSpec:
    """Read a board JSON (ChArUco or chessboard; ``cvmeasure targets`` writes one)."""
    return _read_board(path)


def load_camera(path: PathLike) -> CameraModel:
    """Read a camera JSON (``cvmeasure calibrate`` or :func:`calibrate_camera` wrote it)."""
    return _read_camera(path)


def load_plane(path: PathLike, camera: CameraModel | PathLike | None = None) -> PlaneModel:
    """Read a plane JSON; it carries its camera (``camera``, if given, must be that one)."""
    return PlaneModel.load(path, camera=_camera(camera))


def load_kit(path: PathLike | None = None) -> MarkerKit:
    """Read a marker-kit JSON; without a path, the built-in kit."""
    return default_kit() if path is None else _read_kit(path)


def load_design(path: PathLike) -> Design:
    """Read an SVG or DXF wire design; ``.wire()`` gives the one wire path."""
    return _read_design(path)


def load_material(path: PathLike) -> BenderCalibration:
    """Read a material calibration (``diwire-material/1`` JSON)."""
    return _read_material(path)


def load_trials(path: PathLike) -> TrialTable:
    """Read a trials CSV (loaded/unloaded bends per trial, docs/conventions.md)."""
    return TrialTable.read_csv(path, source=str(path))


def load_params(path: PathLike) -> tuple[SimParams, tuple[Any, ...]]:
    """Read a simulation params JSON: ``(params, effects)``."""
    return params_from_json(path)


def save(path: PathLike, result: Any) -> Path:
    """Write any result or loaded object to ``path`` (atomically); return the path.

    A camera or :class:`CameraCalibration` -> camera JSON; a plane -> plane JSON; a
    material calibration -> its JSON; a trials table -> trials CSV; a G-code job -> the
    G-code text; ``(SimParams, effects)`` -> params JSON; a :class:`CorrectedJob` -> the
    material JSON (save ``.job`` separately); anything with ``to_dict()`` (a photo or part
    measurement, a diagnosis, a correction) -> its JSON.
    """
    if isinstance(result, CameraCalibration):
        result = result.camera
    if isinstance(result, CorrectedJob):
        result = result.material
    if isinstance(result, CameraModel):
        return save_camera(path, result)
    if isinstance(result, PlaneModel):
        return result.save(path)
    if isinstance(result, BenderCalibration):
        return save_calibration(path, result)
    if isinstance(result, TrialTable):
        return result.write_csv(path)
    if isinstance(result, GcodeJob):
        return atomic_write_text(path, result.text())
    if isinstance(result, SimParams):
        return params_to_json(path, result)
    if isinstance(result, tuple) and len(result) == 2 and isinstance(result[0], SimParams):
        return params_to_json(path, result[0], tuple(result[1]))
    if hasattr(result, "to_dict"):
        return atomic_write_json(path, to_jsonable(result.to_dict()))
    raise TypeError(f"save: no file format for a {type(result).__name__}")


# --- arguments: a path or the object ------------------------------------------------------


def _board(board: BoardSpec | PathLike | None) -> BoardSpec | None:
    return load_board(board) if isinstance(board, str | os.PathLike) else board


def _camera(camera: CameraModel | PathLike | None) -> CameraModel | None:
    return load_camera(camera) if isinstance(camera, str | os.PathLike) else camera


def _plane(plane: PlaneModel | PathLike | None, camera: CameraModel | None) -> PlaneModel | None:
    return load_plane(plane, camera) if isinstance(plane, str | os.PathLike) else plane


def _kit(kit: MarkerKit | PathLike | None) -> MarkerKit:
    return load_kit(kit) if kit is None or isinstance(kit, str | os.PathLike) else kit


def _design(design: Design | DesignPath | PathLike) -> Design:
    if isinstance(design, str | os.PathLike):
        design = load_design(design)
    return Design("design", (design,)) if isinstance(design, DesignPath) else design


def _photo(photo: Photo | PathLike | np.ndarray, source: str) -> Photo:
    if isinstance(photo, Photo):
        return photo
    if isinstance(photo, np.ndarray):
        return Photo(source, photo, False)
    return read_photo(photo)


def _material(material: BenderCalibration | PathLike) -> BenderCalibration:
    return load_material(material) if isinstance(material, str | os.PathLike) else material


def _trials(trials: TrialTable | Sequence[Trial] | PathLike) -> TrialTable:
    if isinstance(trials, str | os.PathLike):
        return load_trials(trials)
    return trials if isinstance(trials, TrialTable) else TrialTable(tuple(trials))


# --- the verbs ----------------------------------------------------------------------------


def calibrate_camera(
    photos: Sequence[PathLike],
    board: BoardSpec | PathLike,
    *,
    model: str = "auto",
    board_warp: str = "auto",
    reject_outliers: bool = True,
    progress: Callable[[str], None] | None = None,
) -> CameraCalibration:
    """Calibrate the lens from photos of a board (what ``cvmeasure calibrate`` runs).

    Parameters
    ----------
    photos : paths of the board photos (JPEG, PNG, TIFF, RAW), 15 or more views.
    board : the board (or its JSON).
    model : distortion model, ``"auto"`` (chosen by held-out error), ``"1"``, ``"2"``,
        ``"5"``, ``"8"``, ``"rational"`` or ``"thin-prism"``.
    board_warp : the board's bow solved with the lens: ``"auto"``, ``"on"`` or ``"off"``.
    reject_outliers : drop outlier corners and views before the final solve.
    progress : called with one line per photo read.

    Raises
    ------
    InputError
        No photo shows a usable board, or too few views remain.
    """
    spec = _board(board)
    detections = detect_photos(photos, spec, progress=progress)
    if not detections:
        raise InputError("photos", "no photos given")
    sizes = [d.image_size_px for d in detections]
    size = max(set(sizes), key=sizes.count)
    source = f"{len(photos)} photo(s) ({photos[0]}{', ...' if len(photos) > 1 else ''})"
    if not any(d.ok for d in detections):
        first = detections[0]
        raise InputError(
            first.source if len(detections) == 1 else source,
            f"no usable board in any photo ({first.source}: {first.reason})",
        )
    report = calibrate_detections(
        detections,
        size,
        model=model,
        reject_outliers=reject_outliers,
        source=source,
        board_warp=board_warp,
    )
    return CameraCalibration(report.camera_model(spec), report)


def measure_plane(
    photo: Photo | PathLike | np.ndarray,
    board: BoardSpec | PathLike,
    camera: CameraModel | PathLike,
    *,
    tolerance_deg: float = DEFAULT_TOLERANCE_DEG,
) -> PlaneModel:
    """Measure the plate's plane from a photo of the board lying on it (``cvmeasure plane``).

    The result maps undistorted photo pixels to board millimetres and says whether
    ignoring the camera's tilt keeps angle errors within ``tolerance_deg`` (deg).
    """
    p = _photo(photo, "photo")
    return estimate_plane(
        p.gray8(), _board(board), _camera(camera), tolerance_deg=tolerance_deg, source=p.path
    )


def measure_bender_photo(
    photo: Photo | PathLike,
    kit: MarkerKit | PathLike | None = None,
    *,
    camera: CameraModel | PathLike | None = None,
    plane: PlaneModel | PathLike | None = None,
    board: BoardSpec | PathLike | None = None,
    method: str = "edge_fit",
    space: str = "lab",
    edge: str | None = None,
    heights: str = "none",
) -> MachinePhotoResult:
    """Signed pin and bend angles (deg, machine frame) of one bender photo (``cvmeasure measure``).

    Parameters
    ----------
    photo : the photo's path (a JPEG is read by its fastest path) or a loaded photo.
    kit : the marker kit (or its JSON); the built-in kit when None.
    camera : the calibrated camera; without it angles are measured in image pixels.
    plane : the plate's plane (``measure_plane``); markers are then measured at their
        kit heights. Or ``board``: find that board in this photo (needs ``camera``).
    method : ``"edge_fit"`` or ``"seed_hough"`` (the seed paper's baseline, image pixels
        only); the older ``"ours"`` / ``"seed"`` are read too.
    space : colour space of the segmentation, ``"lab"`` or ``"rgb"``.
    edge : image the disc edges are found in, ``"luma"``, ``"green"``, ``"colour"``,
        ``"shade"``, or None (by the photo's type and the kit's ``step_mm``).
    heights : without a plane, ``"none"`` (bound the heights' effect) or ``"parallel"``.

    Raises
    ------
    InputError
        The photo is unreadable, or a marker is missing or ambiguous (named with why).
    """
    cam = _camera(camera)
    return measure_photo_file(
        photo if isinstance(photo, Photo) else Path(photo),
        _kit(kit),
        camera=cam,
        plane=_plane(plane, cam),
        board=_board(board),
        method=method,
        space=space,
        edge=edge,
        heights=heights,
    )


def measure_springback(
    loaded: MachinePhotoResult | Photo | PathLike,
    unloaded: MachinePhotoResult | Photo | PathLike,
    *,
    kit: MarkerKit | PathLike | None = None,
    camera: CameraModel | PathLike | None = None,
    plane: PlaneModel | PathLike | None = None,
    trial: str | None = None,
    commanded_pin_deg: float = math.nan,
) -> Trial:
    """One trial from a loaded and an unloaded photo of a bend: its springback (deg)."""
    cam = _camera(camera)
    pl, k = _plane(plane, cam), _kit(kit)

    def measured(x: MachinePhotoResult | Photo | PathLike) -> MachinePhotoResult:
        if isinstance(x, MachinePhotoResult):
            return x
        return measure_bender_photo(x, k, camera=cam, plane=pl)

    return measure_trial(
        measured(loaded), measured(unloaded), trial, commanded_pin_deg=commanded_pin_deg
    )


def measure_part(
    photo: Photo | PathLike | np.ndarray,
    *,
    board: BoardSpec | PathLike | None = None,
    camera: CameraModel | PathLike | None = None,
    plane: PlaneModel | PathLike | None = None,
    design: Design | DesignPath | PathLike | None = None,
    job: GcodeJob | PathLike | None = None,
    min_segment_mm: float = 12.0,
    max_bend_deg: float = 135.0,
    moved_photo: Photo | PathLike | np.ndarray | None = None,
    options: PartOptions | None = None,
    **deprecated: Any,
) -> PartMeasurement:
    """Measure a finished part lying beside the board (``cvmeasure part``).

    Parameters
    ----------
    photo : the part's photo (path, loaded photo, or BGR array at the camera's size).
    board, camera : the board in the photo and the calibrated camera; or ``plane``, a
        plane measured before (``measure_plane``), which carries its camera.
    design : the SVG/DXF design (or loaded); then the result carries the best rigid fit,
        the deviation profile and each vertex's bend error against the polygon bent:
        the design planned as :func:`gcode_for` plans it (``min_segment_mm``,
        ``max_bend_deg``, and ``options.divisions`` as its chords per curve), whose
        chord count the part is then measured in.
    job : the job the part was bent with (:func:`gcode_for`'s, or its file): the part is
        compared with the polygon in its header (``cvmeasure part --job``).
    moved_photo : a second photo of the part slid on the plate: the lift is then
        measured from the two views (needs ``board`` and the wire's diameter).
    options : how to measure (:class:`PartOptions`; None: the defaults): the chord count
        bent (``divisions``; None finds it), the headline ``method``, ``allow_mirror``,
        the wire (:class:`WireOptions`: with ``diameter_mm`` the centreline lies between
        the wire's silhouette edges and the lift off the plate is measured or bounded,
        and warned about) and the lift (:class:`LiftOptions`).

    The keywords ``wire_diameter_mm``, ``divisions``, ``shadow_lift``, ``method`` and
    ``allow_mirror`` of earlier versions are still read, with a DeprecationWarning:
    they set the same fields of ``options``.

    Returns
    -------
    PartMeasurement
        ``result.radius_mm``, ``vertex_bend_deg`` and their sigmas, ``comparison``
        against the design, ``warnings``.
    """
    opts = _part_options(options, deprecated)
    if board is None and plane is None:
        raise InputError("measure_part", "give the board and camera, or a plane")
    if board is not None and plane is None and camera is None:
        raise InputError("board", "finding the board's plane needs the camera")
    if job is not None and design is None:
        raise InputError("job", "comparing with the job's polygon needs the design")
    plan = None
    if design is not None:
        # the polygon bent, planned as gcode_for / `cvmeasure gcode` plan it (or the job's)
        plan = plan_for_part(
            _design(design), job=job, min_segment_mm=min_segment_mm,
            max_bend_deg=max_bend_deg, divisions=opts.divisions,
        )  # fmt: skip
        opts = replace(opts, divisions=None)
    cam = _camera(camera)
    p = _photo(photo, "photo")
    moved = None if moved_photo is None else _photo(moved_photo, "moved photo").bgr
    return _measure_part(
        p.bgr,
        _board(board),
        cam,
        options=opts,
        plane=_plane(plane, cam),
        design=None if plan is None else plan.as_path(),
        design_source=str(design) if isinstance(design, str | os.PathLike) else "design",
        reference_mm=None if plan is None else plan.vertices_mm,
        moved_image=moved,
        source=p.path,
    )


#: measure_part's keywords of earlier versions -> the PartOptions field each sets.
_OLD_PART_KEYWORDS = {
    "wire_diameter_mm": "wire=WireOptions(diameter_mm=...)",
    "divisions": "divisions=...",
    "shadow_lift": "lift=LiftOptions(shadow=...)",
    "method": "method=...",
    "allow_mirror": "allow_mirror=...",
}


def _part_options(options: PartOptions | None, old: dict[str, Any]) -> PartOptions:
    """``options`` with the earlier keywords folded in (one warning naming them all)."""
    opts = PartOptions() if options is None else options
    unknown = sorted(set(old) - set(_OLD_PART_KEYWORDS))
    if unknown:
        raise TypeError(f"measure_part() got an unexpected keyword argument {unknown[0]!r}")
    if old:
        warnings.warn(
            f"measure_part({', '.join(f'{n}=...' for n in old)}) is deprecated: pass "
            f"options=PartOptions({', '.join(_OLD_PART_KEYWORDS[n] for n in old)})",
            DeprecationWarning,
            stacklevel=3,
        )
    for name, value in old.items():
        if name == "wire_diameter_mm":
            opts = replace(opts, wire=replace(opts.wire, diameter_mm=value))
        elif name == "shadow_lift":
            opts = replace(opts, lift=replace(opts.lift, shadow=value))
        else:
            opts = replace(opts, **{name: value})
    return opts


def fit_material(
    trials: TrialTable | Sequence[Trial] | PathLike,
    *,
    model: str = "linear",
    motion_model: str = "pchip",
    name: str | None = None,
) -> BenderCalibration:
    """Fit the springback compensation to measured trials (``cvmeasure fit``).

    ``model``: ``"linear"``, ``"cubic"``, ``"pchip"`` or ``"physical"``; every model is
    scored leave-one-angle-out in the result. Refuses to extrapolate.
    """
    table = _trials(trials)
    if name is None:
        name = Path(trials).stem if isinstance(trials, str | os.PathLike) else "calibration"
    try:
        return fit_calibration(table, model=model, motion_model=motion_model, name=name)
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(
            str(trials) if isinstance(trials, str | os.PathLike) else "trials", str(exc)
        ) from None


def diagnose_trials(
    trials: TrialTable | Sequence[Trial] | PathLike,
    params: SimParams | PathLike | None = None,
    *,
    max_causes: int = 2,
    follow_up: bool = True,
) -> Diagnosis:
    """What the simulation gets wrong on measured trials (``cvmeasure diagnose``).

    ``params``: the nominal simulation parameters (or a params JSON, whose effects are
    kept as part of the model). The result names the cause(s) with a 95 % interval, or
    says none explains the data, with terms discovered beyond the catalogue. Its
    ``cause`` is a :class:`Cause`: compare it with ``Cause.of(("backlash",))``, read its
    ``effects``, or print its ``label``.
    (Named ``diagnose_trials`` because ``cvmeasure.diagnose`` is the subpackage.)
    """
    table = _trials(trials)
    effects: tuple[Any, ...] = ()
    if isinstance(params, str | os.PathLike):
        params, effects = load_params(params)
    try:
        return _diagnose(
            table,
            params or SimParams(),
            base_effects=effects,
            max_causes=max_causes,
            follow_up=follow_up,
        )
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(
            str(trials) if isinstance(trials, str | os.PathLike) else "trials", str(exc)
        ) from None


def gcode_for(
    design: Design | DesignPath | PathLike,
    material: BenderCalibration | PathLike | None = None,
    *,
    divisions: int | None = None,
    min_segment_mm: float = 12.0,
    max_bend_deg: float = 135.0,
    bend_radius_mm: float = 0.0,
) -> GcodeJob:
    """A design -> compensated TinyG G-code (``cvmeasure gcode``; ``save`` writes it).

    ``material``: the material calibration whose springback compensation sets each pin
    command; without it, the simulation's nominal model. ``divisions`` bends a curve in
    that many equal chords.
    """

    design = _design(design)
    # the same planner and rules as `cvmeasure gcode` (refusals name element and number)
    plan = plan_design(
        design, min_segment_mm=min_segment_mm, max_bend_deg=max_bend_deg, divisions=divisions
    )
    compensation = SimCompensator() if material is None else _material(material)
    job = design_job(
        plan.vertices_mm,
        source=design.source,
        compensation=compensation,
        min_segment_mm=min_segment_mm,
        max_bend_deg=max_bend_deg,
        bend_radius_mm=bend_radius_mm,
    )
    # the file `cvmeasure gcode` writes: its header keeps the polygon bent for part/correct
    title = f"; cvmeasure {__version__} gcode from {Path(design.source).name}"
    model = "simulation model" if material is None else "calibration"
    return replace(job, header=job_header(title, job, model=model, plan_lines=plan.header_lines()))


def correct(
    part: PartMeasurement,
    design: Design | DesignPath | PathLike,
    material: BenderCalibration | PathLike,
    *,
    gain: float = 0.9,
    deadband_sigma: float = 2.5,
    min_segment_mm: float = 12.0,
    max_bend_deg: float = 135.0,
    bend_radius_mm: float = 0.0,
    flipped: bool = False,
) -> CorrectedJob:
    """The closed loop (``cvmeasure correct``): a finished part corrects material and job.

    ``part`` must be measured with ``design`` (:func:`measure_part`), so its per-vertex
    bend errors are known. Returns the corrected material calibration, what changed and
    the next G-code job: it bends the polygon the part was compared with again (the
    design's plan or the job's, ``part.comparison.polygon_mm``), fed by the rules the
    part's job was (``min_segment_mm``, ``max_bend_deg``, ``bend_radius_mm`` as for
    :func:`gcode_for`); its header keeps that polygon, as ``cvmeasure correct``'s does.
    A part registered mirrored is refused unless ``flipped`` (it may lie upside down):
    measure it as it left the machine, ``PartOptions(allow_mirror=False)``, as
    ``cvmeasure correct`` does.
    """
    if not 0 < gain <= 1:
        raise InputError("gain", f"must be in (0, 1], got {gain}")
    name = Path(design).name if isinstance(design, str | os.PathLike) else "design"
    cal = _material(material)
    try:
        cal2, corr, job = correct_from_part(
            cal, part, design_name=name, gain=gain,
            deadband_sigma=deadband_sigma, min_segment_mm=min_segment_mm,
            max_bend_deg=max_bend_deg, bend_radius_mm=bend_radius_mm, flipped=flipped,
        )  # fmt: skip
    except ValueError as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(str(material), str(exc)) from None
    return CorrectedJob(cal2, corr, job)
