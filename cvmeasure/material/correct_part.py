"""Correcting the material calibration from a measured finished part (``cvmeasure correct``).

The part's per-vertex bends, compared with its design (:mod:`cvmeasure.part.compare`),
become machine-frame wanted and measured bends in job order; :func:`correct_calibration`
(:mod:`cvmeasure.material.correct`) moves the springback curve and the job's per-vertex
offsets; the next job bends the same polygon with the corrected pins.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cvmeasure.design import bend_angles_deg
from cvmeasure.errors import InputError
from cvmeasure.gcode import (
    MAX_BEND_DEG,
    MIN_SEGMENT_MM,
    GcodeJob,
    bend_list,
    gcode_lines,
    job_header,
)
from cvmeasure.material.bender_calibration import BenderCalibration
from cvmeasure.material.correct import (
    DEFAULT_GAIN,
    Correction,
    correct_calibration,
)
from cvmeasure.warning import StageWarning
from cvmeasure.wireplan import WirePlan

__all__ = [
    "NOT_THE_POLYGON",
    "TURN_RATIO",
    "correct_from_part",
    "machine_bends_from_comparison",
    "orient_to_job",
    "target_bends_deg",
]


#: The part measurement's warnings that say the part is not the polygon compared with: a
#: correction from it would fit the job to another part (:func:`correct_from_part` refuses).
NOT_THE_POLYGON = ("part_chords_longer", "part_chords_shorter")


def machine_bends_from_comparison(comparison: Any) -> tuple[np.ndarray, np.ndarray]:
    """(wanted, measured) machine-frame final bends per vertex from a :class:`BendComparison`.

    The comparison's bends are turns of the design polyline (counter-clockwise
    positive walking from the first, fed-first point); the machine bend is
    minus the turn (:func:`cvmeasure.gcode.bend_list`).
    """
    return -np.asarray(comparison.design_bend_deg, float), -np.asarray(
        comparison.measured_bend_deg, float
    )


def target_bends_deg(chord_vertices_mm: Sequence[Any] | np.ndarray) -> np.ndarray:
    """Machine-frame wanted bends (deg) of a chord polyline, fed from its first point."""

    return -bend_angles_deg(np.asarray(chord_vertices_mm, dtype=np.float64))


#: The other end-to-end orientation is used when its bends' RMS error is below this
#: share of the registered one's.
TURN_RATIO = 0.5


def orient_to_job(
    target_deg: ArrayLike, measured_deg: ArrayLike, sigma_deg: ArrayLike | None
) -> tuple[np.ndarray, np.ndarray | None, bool]:
    """The measured bends in job order, choosing the end the job was fed from.

    The registration of a part onto its design picks the end-to-end orientation by
    shape alone; a part far from its design (the first part on an uncorrected
    machine), of a design nearly symmetric end to end, can fit better reversed.
    Reversed, the bends read ``-measured[::-1]``; the job's wanted bends decide: the
    other orientation is used when its RMS error is below :data:`TURN_RATIO` of the
    registered one's (a symmetric design gives equal errors and keeps the registration).
    Returns (measured, sigma, turned), machine frame, deg.
    """
    t = np.asarray(target_deg, float)
    m = np.asarray(measured_deg, float)
    alt = -m[::-1]
    rms = float(np.sqrt(np.mean((m - t) ** 2)))
    rms_alt = float(np.sqrt(np.mean((alt - t) ** 2)))
    if rms_alt < TURN_RATIO * rms:
        sig = None if sigma_deg is None else np.asarray(sigma_deg, float)[::-1]
        return alt, sig, True
    return m, None if sigma_deg is None else np.asarray(sigma_deg, float), False


def correct_from_part(
    calibration: BenderCalibration,
    measurement: Any,
    *,
    design_name: str = "design",
    gain: float = DEFAULT_GAIN,
    deadband_sigma: float = 2.5,
    min_deadband_deg: float = 0.02,
    min_segment_mm: float = MIN_SEGMENT_MM,
    max_bend_deg: float = MAX_BEND_DEG,
    bend_radius_mm: float = 0.0,
    plan_lines: Sequence[str] | None = None,
    flipped: bool = False,
) -> tuple[BenderCalibration, Correction, Any]:
    """Correct from a measured part; return (calibration, correction, the next job).

    Parameters
    ----------
    measurement : a :class:`~cvmeasure.part.measure.PartMeasurement` measured against
        its design: its ``comparison.bends`` are corrected, and the polygon it was
        compared with (``comparison.polygon_mm``: the polygon bent, the plan's or the
        job's) is bent again by the next job, same feeds, only the pins corrected.
    design_name : the design's name (it keys the job's per-vertex corrections).
    min_segment_mm, max_bend_deg, bend_radius_mm : the rules the next job is fed by, as
        the part's job was (:func:`cvmeasure.gcode.bend_list`; ``cvmeasure gcode``'s
        options): its feeds are then the part's job's.
    plan_lines : the plan's header lines for the next job
        (:meth:`cvmeasure.wireplan.WirePlan.header_lines`); None: the polygon bent's.
    flipped : the part may lie upside down. Without it a part registered to its design
        mirrored is refused: for a design symmetric end to end the mirror image read
        backwards fits as well, so its vertices would be corrected in reverse order.

    Returns
    -------
    (BenderCalibration, Correction, GcodeJob)

    Raises
    ------
    InputError
        The part has no per-vertex bends (no chords found, no design comparison), or its
        chords are not the polygon's (``part_chords_longer``, ``part_chords_shorter``:
        another design's or job's part).
    """

    comp = measurement.comparison
    if comp is None or comp.bends is None:
        raise InputError(
            measurement.source,
            "no per-vertex bends against the design (no chord vertices found in the photo)",
        )
    if comp.registration.mirrored and not flipped:
        raise InputError(
            measurement.source,
            "the part was matched to its design mirrored (upside down): measure it as it "
            "left the machine (PartOptions(allow_mirror=False)), or say it may lie flipped",
        )
    for w in measurement.warnings:
        if w.code in NOT_THE_POLYGON:
            # its bend errors are another part's shape, not this job's springback
            raise InputError(measurement.source, f"not corrected: {w.message}")
    target, measured = machine_bends_from_comparison(comp.bends)
    sigma = measurement.vertex_bend_sigma_deg
    if sigma is not None:
        sigma = np.asarray(sigma, float)[::-1] if comp.registration.reversed else sigma
    measured, sigma, turned = orient_to_job(target, measured, sigma)
    chords = np.asarray(comp.polygon_mm, dtype=np.float64)
    bends = bend_list(
        chords, source=design_name, min_segment_mm=min_segment_mm, max_bend_deg=max_bend_deg,
        bend_radius_mm=bend_radius_mm,
    )  # fmt: skip
    if len(bends.bends_deg) != len(target):
        raise InputError(
            design_name,
            f"{len(target)} vertices measured but the job has {len(bends.bends_deg)} bends "
            "(straight vertices merged)",
        )
    turned_note = (
        "the photo's registration matched the part end to end reversed; its bends fit "
        "the job far better the other way round, which was used",
    )
    # the part's warnings travel with the correction made from it (its record and the
    # calibration's history): a lift or a gap the measurement warned of is what to doubt
    # in the errors corrected
    cal, corr = correct_calibration(
        calibration,
        bends.bends_deg,
        measured,
        sigma_deg=sigma,
        part=measurement.source,
        design=design_name,
        gain=gain,
        deadband_sigma=deadband_sigma,
        min_deadband_deg=min_deadband_deg,
        extra_notes=turned_note if turned else (),
        part_warnings=_warnings_of(measurement, chords),
    )
    lines = gcode_lines(bends, corr.pin_deg, title=design_name.rsplit("/", 1)[-1])
    job = GcodeJob(lines, bends, corr.pin_deg)
    # the next job's file says what it corrects and keeps the polygon it bends, as a job
    # from `cvmeasure gcode` does (so `part --job` compares its part with that polygon)
    if plan_lines is None:
        plan_lines = WirePlan(design_name, "mm", chords).header_lines()
    photo = Path(measurement.source).name if measurement.source else "a part photo"
    title = f"; cvmeasure correct: {design_name} after {photo}, gain {gain:g}"
    return cal, corr, replace(job, header=job_header(title, job, plan_lines=plan_lines))


def _warnings_of(measurement: Any, polygon_mm: np.ndarray) -> tuple[StageWarning, ...]:
    """The measured part's warnings, and ``part_chords_differ`` where the photo shows
    another chord count than the polygon bent (``polygon_mm``, N + 1 vertices)."""
    found = None if measurement.chords_found is None else measurement.chords_found.divisions
    bent = len(polygon_mm) - 1
    differ = ()
    if found is not None and found != bent:
        differ = (
            StageWarning(
                "part_chords_differ",
                f"the photo shows {found} chords, the job bends {bent}; measured with {bent}",
                str(measurement.source),
            ),
        )
    return (*measurement.warnings, *differ)
