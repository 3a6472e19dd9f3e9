"""Closed loop: a finished part's per-vertex bend errors correct the compensation.

A part bent from a design is photographed and measured
(:func:`cvmeasure.part.measure.measure_part` with the design gives the bend at
every vertex, in the design's order). Its errors flow back in two layers, both
in *aim* space (the final angle the compensation is asked for; the pin command
is ``compensate(aim)``):

1. **per direction and angle, through the compensation curve**: the vertices
   of one direction are grouped by wanted final angle (groups closer than
   :data:`GROUP_GAP_DEG`); a group whose mean error ``e`` exceeds its noise
   dead band moves the springback curve the part was bent with so that the
   wanted angle ``T`` is reached with the loaded angle that used to give
   ``T - step * e``: a knot replaces the knots within the gap of ``T`` (linear
   and PCHIP curves; any job bending ``T`` afterwards benefits);
2. **per vertex, for a repeated job**: each vertex's next pin is the pin it was
   bent with, moved by the damped error this correction removes (its group's
   mean, plus its own rest beyond its band: drift along the job, backlash after
   a change of side), through the slope of the uncorrected compensation. The
   per-vertex pin offsets (kept in the calibration's history for that design and
   bend count) are what makes the moved curve give those pins, so the curve's
   interpolation between moved knots never corrects a vertex twice.

A vertex not bent at all (its measured bend in the wanted direction below
:data:`UNBENT_SIGMA` sigmas: the pin stopped short of the wire, a dead zone of
backlash, home offset and lost steps) is censored: its shortfall is taken as the
larger of the wanted bend and the median shortfall of its direction's bent
vertices, and it moves no knot and is left out of the response estimate.

The correction is damped (``gain`` < 1, default 0.95): with the true
response slope ``s = d final / d aim`` near 1, each error is multiplied by
``1 - gain * s``, which converges without sign changes for ``0 < gain * s < 1``
and converges for ``gain * s < 2`` (a slope 10 % over the model's overshoots by
4.5 % of the error, within the noise for a first part's errors). A heavier damping
leaves a tenth of a first part's error, at the noise of one reading, for the
settled job's pooled corrections to find later, moving vertices part after part. From the
second part of a job on, the machine's response is measured (the pooled ratio
of bend change to pin change between its last two parts, over the model's) and
the step becomes ``informed_gain / ratio`` (default 0.95). The dead band: an error
seen once is corrected only beyond ``first_look_sigma`` (4) measurement sigmas;
while a vertex's pin stays within :data:`STILL_PIN_DEG` its errors are pooled over
the job's parts (each brought to the current pin by the response to the small pin
moves) and the mean of ``k`` is corrected beyond ``deadband_sigma`` (2.5) sigmas
over ``sqrt(k)``, so a converged job is not kicked about by measurement noise (one
photo's outlier weighs ``1/k`` in the mean instead of starting a correction). The
sigmas are the part's stated ones scaled by :func:`noise_factor` (the job's own
part-to-part scatter, once it repeats). A pooled error past its band is corrected less
:data:`SHRINK_SIGMA` sigmas of its estimate (a soft threshold), and a group's mean is
given only to members whose own readings agree with it: a reading just past the band,
which may be noise, moves a vertex by little, never by the whole band.

The calibration keeps every correction in ``provenance["corrections"]`` (a list,
oldest first; :meth:`Correction.to_dict`): which part photo, which design,
the errors, the curve knots moved and the per-vertex offsets. A correction
edits the fitted curve, not the raw samples: :meth:`BenderCalibration.refit` starts
again from the samples (and so drops the corrections' knots).
"""

from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cvmeasure.material.bender_calibration import BenderCalibration
from cvmeasure.material.compensation import (
    Compensation,
    CompensationRangeWarning,
    SpringbackCurve,
    direction_of,
    fit_compensation,
)
from cvmeasure.warning import StageWarning

__all__ = [
    "GROUP_GAP_DEG",
    "DEFAULT_GAIN",
    "DEFAULT_INFORMED_GAIN",
    "Correction",
    "correct_calibration",
    "job_vertex_offsets",
    "corrected_pin_commands",
    "corrections_of",
    "noise_factor",
    "UNBENT_SIGMA",
]

#: Wanted final angles closer than this (deg) share one curve correction.
GROUP_GAP_DEG = 0.5
#: Default damping gain of a correction.
DEFAULT_GAIN = 0.95
#: Damping gain once the machine's response has been measured (see :func:`correct_calibration`).
DEFAULT_INFORMED_GAIN = 0.95
_CURVE_MODELS = ("linear", "pchip")
#: Pins that moved less than this (deg) between two parts of a job count as the same
#: pin: their errors are pooled (brought to the new pin by the response) and their
#: differences measure the noise (:func:`noise_factor`).
STILL_PIN_DEG = 0.1
#: At most this many parts of a job are pooled per vertex (a slow drift of the
#: process is still followed).
POOL_PARTS = 10
#: This part's error differing from the job's pooled earlier parts (same pin) by more
#: than this many combined sigmas is a suspect jump (see :func:`_pooled_errors`).
JUMP_SIGMA = 6.0
#: A significant error is corrected less this many sigmas of its estimate (see
#: :func:`_move_knots`).
SHRINK_SIGMA = 1.0
#: A vertex whose measured bend (in the wanted direction) is below this many sigmas was
#: not bent at all (see :func:`correct_calibration`).
UNBENT_SIGMA = 3.0


@dataclass(frozen=True)
class Correction:
    """One correction from one measured part (all angles machine frame, signed, deg).

    Attributes
    ----------
    part : the part photo's name.
    design : the design's name; ``bends`` its bend count (the job's key).
    gain, deadband_sigma, min_deadband_deg : the damping used.
    target_deg, measured_deg : wanted and measured final bend per vertex (job order).
    error_deg : measured - wanted.
    curve_updates : per moved knot: direction, final_deg (magnitude), error_deg
        (group mean, magnitude sense), aim_shift_deg, loaded_before_deg, loaded_after_deg,
        vertices (job indices, from 0).
    vertex_offset_deg : the per-vertex pin offsets after this correction (cumulative).
    pin_deg : the pin commands of the corrected job.
    bent_pin_deg : the pin commands the measured part was bent with.
    model_final_per_pin : d final / d pin per vertex of the uncorrected compensation.
    response_ratio : the machine's observed d final / d pin over the model's, from
        this part and the job's previous one (None: first part, or too little change);
        the step is ``informed_gain / response_ratio``.
    unbent : per vertex, whether it was not bent at all (measured bend in the wanted
        direction below :data:`UNBENT_SIGMA` sigmas: the pin stopped short of the wire).
    sigma_deg : the measured bends' stated standard uncertainties.
    noise_factor : how much larger the job's observed part-to-part scatter is than
        the stated sigmas (>= 1; see :func:`noise_factor`); the dead band uses
        ``sigma_deg * noise_factor``.
    suspect : per vertex, whether this part's error was a jump from the earlier parts
        bent with the same pin, left out of the pool (a measurement outlier, or a
        process jump confirmed by the next part).
    band_deg : per vertex, the dead band (deg) its error had to exceed to be corrected on
        its own: ``first_look_sigma`` sigmas on a first look, ``deadband_sigma`` sigmas of
        the pooled mean of the job's parts at this pin otherwise (the sigmas as in
        ``noise_factor``); 0 for a vertex not bent at all.
    within_band : per vertex, whether its error lay within ``band_deg``, so that the
        correction did not act on it on its own (the error weighed is this part's on a
        first look, the pooled mean otherwise): the measurement cannot tell it from 0.
    notes : what was not corrected and why.
    warnings : what to doubt in the errors corrected: the measured part's warnings (a
        lift, a gap in the centreline, a chord count the photo does not show) and this
        correction's own (``part_chords_differ``), as the part measurement gave them.
    """

    part: str
    design: str
    bends: int
    gain: float
    deadband_sigma: float
    first_look_sigma: float
    min_deadband_deg: float
    target_deg: tuple[float, ...]
    measured_deg: tuple[float, ...]
    error_deg: tuple[float, ...]
    curve_updates: tuple[Mapping[str, Any], ...]
    vertex_offset_deg: tuple[float, ...]
    pin_deg: tuple[float, ...]
    bent_pin_deg: tuple[float, ...] = ()
    model_final_per_pin: tuple[float, ...] = ()
    response_ratio: float | None = None
    unbent: tuple[bool, ...] = ()
    sigma_deg: tuple[float, ...] = ()
    noise_factor: float = 1.0
    suspect: tuple[bool, ...] = ()
    notes: tuple[str, ...] = ()
    warnings: tuple[StageWarning, ...] = ()
    band_deg: tuple[float, ...] = ()
    within_band: tuple[bool, ...] = ()

    @property
    def max_abs_error_deg(self) -> float:
        """The worst |error| (deg) over every vertex, measured well or not."""
        return float(np.max(np.abs(self.error_deg))) if self.error_deg else 0.0

    @property
    def resolved_max_abs_error_deg(self) -> float | None:
        """The worst |error| (deg) among the vertices whose error lies beyond its dead band.

        Those are the errors the measurement resolves and the correction acts on. A
        vertex whose error lies within its band (``within_band``; e.g. a bend at a
        chord the photo did not show, its sigma widened to many degrees) is left out,
        however large its reading: the measurement cannot tell it from 0. The test is
        the correction's own (on a vertex pooled over the job's parts, the pooled mean's
        against the pool's band); the error quoted is this part's reading. None when
        every error lies within its band; without bands (``within_band`` empty) every
        vertex counts, as in :attr:`max_abs_error_deg`.
        """
        within = self.within_band or (False,) * len(self.error_deg)
        beyond = [abs(e) for e, w in zip(self.error_deg, within, strict=True) if not w]
        return max(beyond) if beyond else None

    @property
    def unresolved_vertices(self) -> tuple[int, ...]:
        """The vertices (job indices, from 0) within their dead band whose |error| exceeds
        :attr:`resolved_max_abs_error_deg` (all within their band when that is None),
        largest |error| first: the readings a worst error over all vertices would quote,
        which the measurement cannot tell from 0."""
        worst = self.resolved_max_abs_error_deg
        out = [
            i
            for i, (e, w) in enumerate(zip(self.error_deg, self.within_band, strict=False))
            if w and (worst is None or abs(e) > worst)
        ]
        return tuple(sorted(out, key=lambda i: -abs(self.error_deg[i])))

    def error_summary(self, decimals: int = 3, *, name_vertex: bool = True) -> str:
        """This part's errors in words, e.g. 'worst error 0.412 deg (3 more within their
        stated uncertainty, up to 9.887 deg at vertex 4, sigma 21.000 deg)'.

        The worst is :attr:`resolved_max_abs_error_deg`; the readings within their dead
        band that exceed it (:attr:`unresolved_vertices`) are counted apart, with the
        largest and its stated sigma (deg; vertices by job index, from 0, unless
        ``name_vertex`` is False).
        """
        worst = self.resolved_max_abs_error_deg
        hidden = self.unresolved_vertices
        if not hidden:
            return f"worst error {worst or 0.0:.{decimals}f} deg"
        top = hidden[0]
        at = f"vertex {top}, " if name_vertex else ""
        sigma = self.sigma_deg[top] if self.sigma_deg else 0.0
        largest = (
            f"up to {abs(self.error_deg[top]):.{decimals}f} deg at {at}sigma "
            f"{sigma:.{decimals}f} deg"
        )
        if worst is None:
            return f"every error within its stated uncertainty ({largest})"
        return (
            f"worst error {worst:.{decimals}f} deg ({len(hidden)} more within their stated "
            f"uncertainty, {largest})"
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "part": self.part,
            "design": self.design,
            "bends": self.bends,
            "gain": self.gain,
            "deadband_sigma": self.deadband_sigma,
            "first_look_sigma": self.first_look_sigma,
            "min_deadband_deg": self.min_deadband_deg,
            "target_deg": list(self.target_deg),
            "measured_deg": list(self.measured_deg),
            "error_deg": list(self.error_deg),
            "measured_error_deg": list(self.error_deg),
            "max_abs_error_deg": self.max_abs_error_deg,
            "curve_updates": [dict(u) for u in self.curve_updates],
            "vertex_offset_deg": list(self.vertex_offset_deg),
            "pin_deg": list(self.pin_deg),
            "bent_pin_deg": list(self.bent_pin_deg),
            "model_final_per_pin": list(self.model_final_per_pin),
            "response_ratio": self.response_ratio,
            "unbent": list(self.unbent),
            "sigma_deg": list(self.sigma_deg),
            "noise_factor": self.noise_factor,
            "suspect": list(self.suspect),
            "band_deg": list(self.band_deg),
            "within_band": list(self.within_band),
            "notes": list(self.notes),
            "warnings": [w.to_json() for w in self.warnings],
        }


def corrections_of(calibration: BenderCalibration) -> list[dict[str, Any]]:
    """The calibration's correction history (oldest first; empty when none)."""
    return list(calibration.provenance.get("corrections", []))


def _last_of_job(calibration: BenderCalibration, design: str, bends: int) -> dict[str, Any] | None:
    for c in reversed(corrections_of(calibration)):
        if c.get("design") == design and int(c.get("bends", -1)) == bends:
            return c
    return None


def job_vertex_offsets(calibration: BenderCalibration, design: str, bends: int) -> np.ndarray:
    """The latest per-vertex pin offsets (deg) for this design and bend count, else zeros."""
    last = _last_of_job(calibration, design, bends)
    return np.zeros(bends) if last is None else np.asarray(last["vertex_offset_deg"], float)


#: The observed response may differ from the model's by this factor at most.
RESPONSE_RATIO_RANGE = (0.5, 2.0)


def _response_ratio(
    prev: Mapping[str, Any] | None,
    bent_pin: np.ndarray,
    measured: np.ndarray,
    noise_deg: float,
    unbent: np.ndarray,
) -> float | None:
    """Observed d final / d pin over the model's, pooled over the job's vertices.

    From the last two parts of the job (their pins and measured bends); None when
    the pins moved too little to tell the slope from the noise. Vertices not bent
    in either part (``unbent`` now, ``unbent`` in the previous record) have no slope.
    """
    if prev is None or "bent_pin_deg" not in prev or "model_final_per_pin" not in prev:
        return None
    used = ~unbent & ~np.asarray(prev.get("unbent", np.zeros(unbent.size, bool)), bool)
    if not used.any():
        return None
    dp = (bent_pin - np.asarray(prev["bent_pin_deg"], float))[used]
    dm = (measured - np.asarray(prev["measured_deg"], float))[used]
    model = np.asarray(prev["model_final_per_pin"], float)[used]
    if np.sqrt(np.mean(dp**2)) < 10.0 * max(noise_deg, 0.005):
        return None
    observed = float(np.sum(dp * dm) / np.sum(dp * dp))
    expected = float(np.sum(dp * dp * model) / np.sum(dp * dp))
    return float(np.clip(observed / expected, *RESPONSE_RATIO_RANGE))


def corrected_pin_commands(
    calibration: BenderCalibration,
    target_deg: ArrayLike,
    vertex_offset_deg: ArrayLike | None = None,
) -> tuple[float, ...]:
    """Pin commands (deg): the calibration's for the wanted bends plus per-vertex pin offsets.

    A wanted bend a little outside the calibrated range is extrapolated.
    """
    t = np.asarray(target_deg, dtype=np.float64)
    off = np.zeros_like(t) if vertex_offset_deg is None else np.asarray(vertex_offset_deg, float)
    out = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CompensationRangeWarning)
        for target, o in zip(t, off, strict=True):
            out.append(0.0 if target == 0 else calibration.compensate(target, outside="warn") + o)
    return tuple(float(p) for p in out)


def _base_compensation(calibration: BenderCalibration) -> Compensation:
    """The compensation fitted to the raw samples alone (no correction knots): its slopes."""
    pin = [s.commanded_pin_deg for s in calibration.samples]
    loaded = [s.loaded_bend_deg for s in calibration.samples]
    unloaded = [s.unloaded_bend_deg for s in calibration.samples]
    return fit_compensation(pin, loaded, unloaded, model=calibration.model)  # type: ignore[arg-type]


def _slope(fn: Any, x: float, h: float = 0.5) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CompensationRangeWarning)
        return float((fn(x + h) - fn(x - h)) / (2.0 * h))


@dataclass(frozen=True)
class _Pool:
    """Per vertex: parts pooled (k), their weighted mean error brought to this part's pin,
    its standard uncertainty, and whether this part's error is a suspect jump."""

    k: np.ndarray
    mean_deg: np.ndarray
    sigma_deg: np.ndarray
    suspect: np.ndarray


def _pooled_errors(
    calibration: BenderCalibration,
    design: str,
    bent_pin: np.ndarray,
    error: np.ndarray,
    sigma: np.ndarray,
    floor_deg: float,
    factor: float,
    response_ratio: float,
) -> _Pool:
    """Pool this part's errors with the job's latest parts bent with (nearly) this pin.

    A part bent with a pin within :data:`STILL_PIN_DEG` of this part's counts, its error
    moved by the response to the pin change (the model's slope times ``response_ratio``:
    a few hundredths of a degree of pin, known to a few per cent); the pool stops at the
    first part outside it, or not bent at that vertex, and holds at most
    :data:`POOL_PARTS` parts. The mean is weighted by the inverse variances (each part's
    stated sigma times ``factor``, at least ``floor_deg``): a vertex its photo measured
    badly weighs little. This part's error is a suspect jump when it differs from the
    earlier parts' mean by more than :data:`JUMP_SIGMA` combined sigmas: it is not
    pooled, unless the job's previous part showed the same jump (then the process
    moved: the pool restarts from those two parts).
    """
    w_now = 1.0 / np.maximum(sigma * factor, floor_deg) ** 2
    w_sum = np.zeros(error.size)
    we_sum = np.zeros(error.size)
    k_prev = np.zeros(error.size)
    open_ = np.ones(error.size, bool)
    last: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None  # previous part's (e, w, suspect)
    for c in reversed(corrections_of(calibration)):
        if c.get("design") != design or int(c.get("bends", -1)) != error.size:
            continue
        pins = np.asarray(c.get("bent_pin_deg", ()), float)
        if pins.shape != bent_pin.shape or "model_final_per_pin" not in c:
            break
        unbent = np.asarray(c.get("unbent", np.zeros(error.size, bool)), bool)
        open_ &= (np.abs(pins - bent_pin) < STILL_PIN_DEG) & ~unbent & (k_prev < POOL_PARTS - 1)
        if not open_.any():
            break
        model = np.asarray(c["model_final_per_pin"], float)
        moved = np.asarray(c["measured_error_deg"], float) + response_ratio * model * (
            bent_pin - pins
        )
        s = np.asarray(c.get("sigma_deg", sigma), float)
        w = 1.0 / np.maximum(s * factor, floor_deg) ** 2
        was_suspect = np.asarray(c.get("suspect", np.zeros(error.size, bool)), bool)
        if last is None:
            last = (moved, w, was_suspect & open_)
        use = open_ & ~was_suspect
        w_sum += np.where(use, w, 0.0)
        we_sum += np.where(use, w * moved, 0.0)
        k_prev += use
    with np.errstate(invalid="ignore", divide="ignore"):
        mean_prev = np.where(k_prev > 0, we_sum / w_sum, 0.0)
        gap_sigma = np.sqrt(1.0 / w_now + np.where(k_prev > 0, 1.0 / w_sum, 0.0))
    suspect = (k_prev > 0) & (np.abs(error - mean_prev) > JUMP_SIGMA * gap_sigma)
    k = k_prev + 1
    mean = (we_sum + w_now * error) / (w_sum + w_now)
    sig_pool = 1.0 / np.sqrt(w_sum + w_now)
    if last is not None:
        e_l, w_l, s_l = last
        again = suspect & s_l & (np.abs(error - e_l) <= JUMP_SIGMA * np.sqrt(1 / w_now + 1 / w_l))
        # the same jump twice running: the process moved; pool those two parts only
        mean = np.where(again, (w_l * e_l + w_now * error) / (w_l + w_now), mean)
        sig_pool = np.where(again, 1.0 / np.sqrt(w_l + w_now), sig_pool)
        k = np.where(again, 2.0, k)
        suspect &= ~again
    # a suspect jump is not pooled: the earlier parts' mean stands
    mean = np.where(suspect, mean_prev, mean)
    sig_pool = np.where(suspect, 1.0 / np.sqrt(np.maximum(w_sum, 1e-30)), sig_pool)
    k = np.where(suspect, k_prev, k)
    return _Pool(k, mean, sig_pool, suspect)


#: At least this many repeat differences before the stated sigmas are scaled.
MIN_REPEATS = 6
#: The stated sigmas are scaled by at most this.
MAX_NOISE_FACTOR = 5.0


def noise_factor(
    calibration: BenderCalibration,
    design: str,
    bent_pin: np.ndarray,
    measured: np.ndarray,
    sigma: np.ndarray,
) -> float:
    """Observed over stated measurement noise of this job (>= 1; 1 until enough repeats).

    The stated per-vertex sigmas of a part photo count sampling only; whether they
    hold is seen when the job repeats. Between consecutive parts of the job (its
    history, then this part), a vertex whose pin moved less than :data:`STILL_PIN_DEG`
    should change its bend by the model's response to that move, within
    ``sqrt(s1^2 + s2^2)``; the robust SD (1.4826 times the median absolute value) of
    those normalised differences (at least :data:`MIN_REPEATS` of them, vertices bent
    in both parts) scales the stated sigmas.
    """
    runs = [
        c
        for c in corrections_of(calibration)
        if c.get("design") == design
        and int(c.get("bends", -1)) == bent_pin.size
        and len(c.get("sigma_deg", ())) == bent_pin.size
    ]
    now = {
        "bent_pin_deg": bent_pin,
        "measured_deg": measured,
        "sigma_deg": sigma,
        "unbent": np.zeros(bent_pin.size, bool),
        "model_final_per_pin": runs[-1]["model_final_per_pin"] if runs else np.ones(bent_pin.size),
    }
    z: list[np.ndarray] = []
    seq = [*runs, now]
    for a, b in zip(seq[:-1], seq[1:], strict=False):
        dp = np.asarray(b["bent_pin_deg"], float) - np.asarray(a["bent_pin_deg"], float)
        dm = np.asarray(b["measured_deg"], float) - np.asarray(a["measured_deg"], float)
        s2 = np.asarray(a["sigma_deg"], float) ** 2 + np.asarray(b["sigma_deg"], float) ** 2
        ok = (
            (np.abs(dp) < STILL_PIN_DEG)
            & (s2 > 0)
            & ~np.asarray(a.get("unbent", np.zeros(dp.size, bool)), bool)
            & ~np.asarray(b.get("unbent", np.zeros(dp.size, bool)), bool)
        )
        model = np.asarray(a["model_final_per_pin"], float)
        z.append(((dm - model * dp)[ok]) / np.sqrt(s2[ok]))
    zz = np.concatenate(z) if z else np.zeros(0)
    if zz.size < MIN_REPEATS:
        return 1.0
    # a robust scale (1.4826 MAD, the SD of a normal): one photo's outlier must not
    # widen the band for the whole job (outliers are the jump test's business)
    return float(np.clip(1.4826 * np.median(np.abs(zz)), 1.0, MAX_NOISE_FACTOR))


def _groups(magnitudes: np.ndarray) -> list[np.ndarray]:
    order = np.argsort(magnitudes, kind="stable")
    groups: list[list[int]] = []
    for i in order:
        if groups and magnitudes[i] - magnitudes[groups[-1][-1]] <= GROUP_GAP_DEG:
            groups[-1].append(int(i))
        else:
            groups.append([int(i)])
    return [np.asarray(g) for g in groups]


def _loaded_at(curve: SpringbackCurve, final_deg: float) -> float:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CompensationRangeWarning)
        return float(curve.loaded_for_final_deg(final_deg, outside="warn"))


def _with_knot(curve: SpringbackCurve, final_deg: float, loaded_deg: float) -> SpringbackCurve:
    f = np.asarray(curve.final_deg)
    ld = np.asarray(curve.loaded_deg)
    keep = np.abs(f - final_deg) > GROUP_GAP_DEG
    f = np.append(f[keep], final_deg)
    ld = np.append(ld[keep], loaded_deg)
    order = np.argsort(f)
    f, ld = f[order], ld[order]
    lo, hi = min(curve.domain_deg[0], float(f[0])), max(curve.domain_deg[1], float(f[-1]))
    return replace(
        curve,
        final_deg=tuple(float(v) for v in f),
        loaded_deg=tuple(float(v) for v in ld),
        domain_deg=(lo, hi),
    )


def correct_calibration(
    calibration: BenderCalibration,
    target_deg: ArrayLike,
    measured_deg: ArrayLike,
    *,
    sigma_deg: ArrayLike | None = None,
    part: str = "part",
    design: str = "design",
    gain: float = DEFAULT_GAIN,
    deadband_sigma: float = 2.5,
    first_look_sigma: float = 4.0,
    min_deadband_deg: float = 0.02,
    informed_gain: float = DEFAULT_INFORMED_GAIN,
    vertex_offset_deg: ArrayLike | None = None,
    shrink_sigma: float = SHRINK_SIGMA,
    extra_notes: tuple[str, ...] = (),
    part_warnings: tuple[StageWarning, ...] = (),
) -> tuple[BenderCalibration, Correction]:
    """Correct a calibration from one part's per-vertex final bends (see the module notes).

    Parameters
    ----------
    calibration : the calibration the part was bent with.
    target_deg, measured_deg : ndarray (N,), wanted and measured final bends per
        vertex in job order, machine frame, signed, deg.
    sigma_deg : standard uncertainty of each measured bend (deg); None = 0 (only
        ``min_deadband_deg`` then).
    part, design : names for the history; ``design`` with N keys the per-vertex offsets.
    gain, informed_gain : damping in (0, 1] while the machine's response is the model's,
        and once measured from two parts of the job; the larger of the two is used.
    deadband_sigma, first_look_sigma, min_deadband_deg : the dead band: an error
        seen once is corrected beyond ``first_look_sigma`` sigmas; the mean of k
        parts bent with the same pin beyond ``deadband_sigma * sigma / sqrt(k)``;
        sigma is at least ``min_deadband_deg / deadband_sigma``.
    vertex_offset_deg : the offsets the part was bent with; None = the latest in
        the calibration's history for this design and N.
    shrink_sigma : a significant error pooled over two or more parts is corrected less
        this many sigmas of its estimate (see :func:`_band_and_spread`).
    extra_notes, part_warnings : notes on how the bends were read and the measured
        part's warnings, kept with the correction (its record and the history).

    Returns
    -------
    (BenderCalibration, Correction)
        The corrected calibration (history appended) and the correction.

    Raises
    ------
    ValueError
        Mismatched lengths, a gain outside (0, 1], or a curve model the
        correction cannot move (cubic / physical: refit as linear first).
    """
    if not 0.0 < gain <= 1.0:
        raise ValueError(f"gain must be in (0, 1], got {gain}")
    t, m, sig, offsets = _checked_inputs(
        calibration, design, target_deg, measured_deg, sigma_deg, vertex_offset_deg
    )
    bent_pin = np.asarray(corrected_pin_commands(calibration, t, offsets))
    base = _base_compensation(calibration)
    pin_per_final = _pin_per_final(base, t)
    # the stated sigmas, scaled by the job's own part-to-part scatter once it repeats
    factor = noise_factor(calibration, design, bent_pin, m, sig)
    floor = min_deadband_deg / max(deadband_sigma, 1e-9)
    unbent = _unbent(t, m, np.maximum(sig * factor, floor))
    prev = _last_of_job(calibration, design, t.size)
    ratio = _response_ratio(prev, bent_pin, m, float(np.median(sig)), unbent)
    # with the machine's response measured (ratio) the damping can be lighter, still < 1
    step = max(gain, informed_gain) / ratio if ratio else gain
    # evidence accumulates while a vertex's pin stays the same (k parts, sigma / sqrt(k))
    pool = _pooled_errors(calibration, design, bent_pin, m - t, sig, floor, factor, ratio or 1.0)
    band, spread = _band_and_spread(pool, unbent, (first_look_sigma, deadband_sigma, shrink_sigma))
    error = pool.mean_deg
    notes = _suspect_notes(pool.suspect) + _dead_zone_shortfalls(t, error, band, unbent)
    curves, updates, corrected = _move_knots(
        calibration, base, t, error, (band, spread), unbent, step, notes
    )
    comp = replace(calibration.compensation, springback=curves)
    new_cal = replace(calibration, compensation=comp)
    offsets, pins = _next_pins(new_cal, t, bent_pin - step * corrected * pin_per_final)
    correction = Correction(
        part=part,
        design=design,
        bends=int(t.size),
        gain=float(gain),
        deadband_sigma=float(deadband_sigma),
        first_look_sigma=float(first_look_sigma),
        min_deadband_deg=float(min_deadband_deg),
        target_deg=tuple(float(v) for v in t),
        measured_deg=tuple(float(v) for v in m),
        error_deg=tuple(float(v) for v in m - t),
        curve_updates=tuple(updates),
        vertex_offset_deg=tuple(float(v) for v in offsets),
        pin_deg=pins,
        bent_pin_deg=tuple(float(v) for v in bent_pin),
        model_final_per_pin=tuple(float(1.0 / v) for v in pin_per_final),
        response_ratio=ratio,
        unbent=tuple(bool(v) for v in unbent),
        sigma_deg=tuple(float(v) for v in sig),
        noise_factor=factor,
        suspect=tuple(bool(v) for v in pool.suspect),
        notes=(*notes, *extra_notes),
        warnings=tuple(part_warnings),
        band_deg=tuple(float(v) for v in band),
        within_band=tuple(bool(v) for v in ~_beyond_band(error, band)),
    )
    history = {"corrections": [*corrections_of(calibration), correction.to_dict()]}
    return replace(new_cal, provenance={**calibration.provenance, **history}), correction


def _band_and_spread(
    pool: _Pool, unbent: np.ndarray, sigmas: tuple[float, float, float]
) -> tuple[np.ndarray, np.ndarray]:
    """Per vertex (deg): the dead band its error must exceed, and what a significant error
    is shrunk by. ``sigmas`` = (first_look_sigma, deadband_sigma, shrink_sigma).

    A pooled error (a job settling: a low band that noise crosses now and then) moves a
    vertex only by what it shows beyond its uncertainty (a soft threshold), so a mean just
    past the band moves it by a little, not by the whole band; a first look past
    ``first_look_sigma`` is no noise and is corrected whole, as is a dead-zone shortfall.
    """
    first_look, deadband, shrink = sigmas
    band = np.where(pool.k == 1, first_look, deadband) * pool.sigma_deg
    spread = np.where(unbent | (pool.k <= 1), 0.0, shrink * pool.sigma_deg)
    return band, spread


def _beyond_band(error: np.ndarray, band: np.ndarray) -> np.ndarray:
    """Per vertex, whether its error (deg) lies beyond its dead band (deg): corrected on its own."""
    return np.abs(error) > band


def _checked_inputs(
    calibration: BenderCalibration,
    design: str,
    target_deg: ArrayLike,
    measured_deg: ArrayLike,
    sigma_deg: ArrayLike | None,
    vertex_offset_deg: ArrayLike | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Wanted and measured bends, their sigmas and the offsets bent with, checked (deg)."""
    t = np.asarray(target_deg, dtype=np.float64).ravel()
    m = np.asarray(measured_deg, dtype=np.float64).ravel()
    if t.shape != m.shape or t.size == 0:
        raise ValueError(f"{t.size} wanted bends but {m.size} measured")
    sig = np.zeros_like(t) if sigma_deg is None else np.asarray(sigma_deg, float).ravel()
    if sig.shape != t.shape:
        raise ValueError("sigma_deg must have one value per vertex")
    if calibration.model not in _CURVE_MODELS:
        raise ValueError(
            f"a {calibration.model} springback curve cannot be corrected knot by knot; "
            "refit the calibration as linear or pchip first"
        )
    offsets = (
        job_vertex_offsets(calibration, design, t.size)
        if vertex_offset_deg is None
        else np.asarray(vertex_offset_deg, dtype=np.float64).copy()
    )
    if offsets.shape != t.shape:
        raise ValueError("vertex_offset_deg must have one value per vertex")
    return t, m, sig, offsets


def _pin_per_final(base: Any, t: np.ndarray) -> np.ndarray:
    """d pin / d final bend of the model at each wanted bend (1 where nothing is wanted)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", CompensationRangeWarning)
        return np.array(
            [
                _slope(lambda x: base.compensate(x, outside="warn"), float(tt)) if tt else 1.0
                for tt in t
            ]
        )


def _unbent(t: np.ndarray, m: np.ndarray, sig_eff: np.ndarray) -> np.ndarray:
    """Vertices not bent at all: bent less than their noise, or the wrong way.

    The pin stopped short of the wire (a dead zone: backlash, home offset and lost steps
    together exceed the wanted bend). Such a vertex's error says only that the shortfall
    is at least the wanted bend; it is read from the same direction's bent vertices.
    """
    sign = np.where(t < 0, -1.0, 1.0)
    return (sign * m < UNBENT_SIGMA * sig_eff) & (np.abs(t) > 2.0 * UNBENT_SIGMA * sig_eff)


def _next_pins(
    new_cal: BenderCalibration, t: np.ndarray, wanted_pin: np.ndarray
) -> tuple[np.ndarray, Any]:
    """Per-vertex offsets (deg) and pins that bend ``wanted_pin`` under ``new_cal``.

    The job's next pins are set per vertex: the pin the part was bent with, moved by the
    damped error this correction removes. The curve's knots serve later jobs; whatever
    they (and their interpolation between knots) do to this job's vertices, the offsets
    take back, so no vertex is corrected twice and an untouched vertex keeps its pin.
    """
    offsets = wanted_pin - np.asarray(corrected_pin_commands(new_cal, t))
    return offsets, corrected_pin_commands(new_cal, t, offsets)


def _suspect_notes(suspect: np.ndarray) -> list[str]:
    """A note naming the vertices whose error is unlike their earlier parts' (not pooled)."""
    if not suspect.any():
        return []
    return [
        f"vertices {', '.join(str(int(i)) for i in np.flatnonzero(suspect))}: "
        "error unlike the earlier parts bent with this pin (a measurement outlier or a "
        "jump of the process); not pooled until the next part shows it again"
    ]


def _dead_zone_shortfalls(
    t: np.ndarray,
    error: np.ndarray,
    band: np.ndarray,
    unbent: np.ndarray,
) -> list[str]:
    """Set each unbent vertex's error from its direction's bent ones (in place); notes."""
    sign = np.where(t < 0, -1.0, 1.0)
    notes = []
    for direction in ("ccw", "cw"):
        d_idx = np.array([tt != 0 and direction_of(tt) == direction for tt in t])
        stuck = d_idx & unbent
        if not stuck.any():
            continue
        bent_ok = d_idx & ~unbent
        short = float(np.median(-sign[bent_ok] * error[bent_ok])) if bent_ok.any() else 0.0
        error[stuck] = -sign[stuck] * np.maximum(np.abs(t[stuck]), short)
        band[stuck] = 0.0
        notes.append(
            f"{direction}: {int(stuck.sum())} vertices not bent at all (dead zone); their "
            f"shortfall is taken as max(wanted bend, the direction's median {short:.2f} deg)"
        )
    return notes


def _soft(error: Any, spread: Any) -> np.ndarray:
    """``error`` moved towards 0 by ``spread`` (deg), never past it (a soft threshold)."""
    e = np.asarray(error, float)
    return np.sign(e) * np.maximum(np.abs(e) - np.asarray(spread, float), 0.0)


def _move_knots(
    calibration: BenderCalibration,
    base: Any,
    t: np.ndarray,
    error: np.ndarray,
    band_spread: tuple[np.ndarray, np.ndarray],
    unbent: np.ndarray,
    step: float,
    notes: list[str],
) -> tuple[dict[str, Any], list[dict[str, Any]], np.ndarray]:
    """Move each direction's curve knot by its group's significant mean error.

    ``band_spread`` is, per vertex, (the dead band an error must exceed, the amount a
    significant error is shrunk by: ``shrink_sigma`` sigmas of its estimate). A vertex
    whose own error is significant is corrected by it, shrunk; one whose own is not
    takes its group's shrunk mean only when its own reading agrees with that mean within
    its band (a group mean is not forced on a member whose reading says otherwise).
    Returns the moved curves, the updates made and, per vertex, the error (aim deg) this
    correction removes; notes are appended to ``notes``.
    """
    band, spread = band_spread
    sign = np.where(t < 0, -1.0, 1.0)
    curves = dict(calibration.compensation.springback)
    bent_curves = dict(calibration.compensation.springback)
    updates: list[dict[str, Any]] = []
    corrected = np.zeros(t.size)
    for direction in ("ccw", "cw"):
        idx = np.flatnonzero([(tt != 0 and direction_of(tt) == direction) for tt in t])
        if idx.size == 0:
            continue
        if direction not in curves:
            notes.append(f"no {direction} curve: {idx.size} vertices left uncorrected")
            continue
        mags = np.abs(t[idx])
        for group in _groups(mags):
            members = idx[group]
            own = _beyond_band(error[members], band[members])
            corrected[members] = np.where(own, _soft(error[members], spread[members]), 0.0)
            live = members[~unbent[members]]  # a dead-zone vertex says nothing of the curve
            if live.size == 0:
                continue
            e_mag = float(np.mean(sign[live] * error[live]))
            group_band = float(np.sqrt(np.mean(band[live] ** 2)) / np.sqrt(live.size))
            if abs(e_mag) <= group_band:
                continue
            e_use = float(_soft(e_mag, np.sqrt(np.mean(spread[live] ** 2) / live.size)))
            # the group's mean is significant: a member without its own significant error
            # takes it when its reading agrees with it within its band
            agrees = np.abs(error[live] - sign[live] * e_mag) <= band[live]
            group_share = np.where(agrees, sign[live] * e_use, 0.0)
            corrected[live] = np.where(own[~unbent[members]], corrected[live], group_share)
            final = float(np.mean(np.abs(t[live])))
            shift = -step * e_use
            # the knot moves from where the part was bent (the calibration it was bent
            # with), not from a curve already moved by a neighbouring group
            before = _loaded_at(bent_curves[direction], final)
            slope = _slope(lambda x, c=base.springback[direction]: _loaded_at(c, x), final)
            after = before + shift * slope
            moved = _with_knot(curves[direction], final, after)
            if np.any(np.diff(moved.loaded_deg) <= 0):
                notes.append(
                    f"{direction} {final:.2f} deg: moving the knot would make the curve "
                    "non-monotone; corrected per vertex only"
                )
                continue
            curves[direction] = moved
            updates.append(
                {
                    "direction": direction,
                    "final_deg": final,
                    "error_deg": e_mag,
                    "aim_shift_deg": shift,
                    "loaded_before_deg": before,
                    "loaded_after_deg": after,
                    "vertices": [int(i) for i in live],
                }
            )
    return curves, updates, corrected
