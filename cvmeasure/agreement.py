"""Agreement of vision with manual readings: Bland–Altman, gauge R&R, tolerance verdict.

Differences are ``vision - manual`` in degrees. With one manual reading per
photo this is the classic Bland–Altman analysis; with several readings of a
photo (``reader`` and/or ``repeat`` columns) the differences of single readings
are analysed with the replicate correction of Bland & Altman (2007): the
variance of a single difference is the variance of the per-photo mean
differences plus ``(1 - 1/m_h)`` times the pooled within-photo variance of the
manual readings (``m_h`` the harmonic mean of readings per photo).
The manual readings also give a crossed gauge R&R split (ANOVA method):
repeatability (same reader, same photo) and reproducibility (between readers).
Photos that show the same bend (optional ``bend`` column) give the vision
repeatability.

The seed paper's accepted tolerance is 10 % relative and 1 degree absolute;
:class:`Tolerance` makes both configurable.

References
----------
Bland JM, Altman DG (1986) Statistical methods for assessing agreement between two
methods of clinical measurement. Lancet 327:307-310. doi:10.1016/S0140-6736(86)90837-8
Bland JM, Altman DG (2007) Agreement between methods of measurement with multiple
observations per individual. J Biopharm Stat 17:571-582. doi:10.1080/10543400701329422
AIAG (2010) Measurement Systems Analysis, 4th ed. (ANOVA gauge R&R).

``scipy.stats`` is imported in the functions that use it (half a second or more on
import), so the modules that only write agreement tables start fast.
"""

from __future__ import annotations

import math
import os
from collections import defaultdict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.errors import InputError
from cvmeasure.fileio import read_csv_rows
from cvmeasure.warning import StageWarning

__all__ = [
    "ManualReading",
    "Tolerance",
    "BlandAltman",
    "GaugeRR",
    "ToleranceVerdict",
    "AgreementResult",
    "load_manual",
    "vision_angles",
    "bland_altman",
    "gauge_rr",
    "agreement",
]


@dataclass(frozen=True)
class ManualReading:
    """One manual reading of one photo's bend angle (degrees)."""

    photo: str
    bend_angle_deg: float
    reader: str = ""
    repeat: str = ""
    bend: str = ""


@dataclass(frozen=True)
class Tolerance:
    """Accepted error: ``|d| <= absolute_deg`` and ``|d| <= relative * |manual|``.

    ``relative`` None (or 0) checks the absolute limit only. The seed's defaults:
    10 % relative, 1 degree absolute.
    """

    relative: float | None = 0.10
    absolute_deg: float = 1.0

    def within(self, diff_deg: np.ndarray, manual_deg: np.ndarray) -> np.ndarray:
        ok = np.abs(diff_deg) <= self.absolute_deg
        if self.relative:
            ok &= np.abs(diff_deg) <= self.relative * np.abs(manual_deg)
        return ok

    def to_dict(self) -> dict[str, Any]:
        return {"relative": self.relative, "absolute_deg": self.absolute_deg}


@dataclass(frozen=True)
class BlandAltman:
    """Bias and 95 % limits of agreement of ``vision - manual``, with confidence intervals.

    ``n`` counts photos; ``sd_deg`` is the standard deviation of the difference of
    one vision reading and one manual reading. CIs are the approximate ones of
    Bland & Altman (1986): SE(bias) = s/sqrt(n), SE(limit) = s*sqrt(3/n), t with
    n-1 degrees of freedom. Proportional bias: least-squares slope of the
    per-photo differences on the per-photo means of the two methods.
    """

    n: int
    n_readings: int
    bias_deg: float
    sd_deg: float
    loa_low_deg: float
    loa_high_deg: float
    bias_ci_deg: tuple[float, float]
    loa_low_ci_deg: tuple[float, float]
    loa_high_ci_deg: tuple[float, float]
    slope: float
    slope_ci: tuple[float, float]
    slope_p: float
    proportional_bias: bool
    manual_within_sd_deg: float
    readings_per_photo_harmonic: float
    confidence: float = 0.95

    def to_dict(self) -> dict[str, Any]:
        return {
            "n": self.n,
            "n_readings": self.n_readings,
            "bias_deg": self.bias_deg,
            "sd_deg": self.sd_deg,
            "loa_low_deg": self.loa_low_deg,
            "loa_high_deg": self.loa_high_deg,
            "bias_ci_deg": list(self.bias_ci_deg),
            "loa_low_ci_deg": list(self.loa_low_ci_deg),
            "loa_high_ci_deg": list(self.loa_high_ci_deg),
            "proportional_bias": {
                "slope": self.slope,
                "slope_ci": list(self.slope_ci),
                "p_value": self.slope_p,
                "significant": self.proportional_bias,
            },
            "manual_within_sd_deg": self.manual_within_sd_deg,
            "readings_per_photo_harmonic": self.readings_per_photo_harmonic,
            "confidence": self.confidence,
        }


@dataclass(frozen=True)
class GaugeRR:
    """Variance split of repeated readings (ANOVA gauge R&R), as standard deviations in degrees.

    ``grr_percent`` is the gauge's share of the total standard deviation
    (%GRR of total variation, < 10 % good, > 30 % unacceptable by AIAG);
    ``ndc`` the number of distinct categories, 1.41 * part / gauge.
    """

    parts: int
    readers: int
    repeats: int
    repeatability_sd_deg: float
    reproducibility_sd_deg: float
    reader_sd_deg: float
    interaction_sd_deg: float
    grr_sd_deg: float
    part_sd_deg: float
    total_sd_deg: float
    grr_percent: float
    ndc: float
    notes: tuple[str, ...] = ()

    def to_dict(self) -> dict[str, Any]:
        return {
            "parts": self.parts,
            "readers": self.readers,
            "repeats": self.repeats,
            "repeatability_sd_deg": self.repeatability_sd_deg,
            "reproducibility_sd_deg": self.reproducibility_sd_deg,
            "reader_sd_deg": self.reader_sd_deg,
            "interaction_sd_deg": self.interaction_sd_deg,
            "grr_sd_deg": self.grr_sd_deg,
            "part_sd_deg": self.part_sd_deg,
            "total_sd_deg": self.total_sd_deg,
            "grr_percent": self.grr_percent,
            "ndc": self.ndc,
            "notes": list(self.notes),
        }


@dataclass(frozen=True)
class ToleranceVerdict:
    """How the differences compare with the accepted tolerance."""

    tolerance: Tolerance
    n_within: int
    n_pairs: int
    worst_abs_diff_deg: float
    loa_within_absolute: bool

    @property
    def share_within(self) -> float:
        return self.n_within / self.n_pairs if self.n_pairs else float("nan")

    @property
    def verdict(self) -> str:
        ok = self.loa_within_absolute and self.n_within == self.n_pairs
        return "within tolerance" if ok else "outside tolerance"

    @property
    def reason(self) -> str:
        """Why the verdict is what it is, in words (readings failing, limits outside)."""
        failing = self.n_pairs - self.n_within
        parts = []
        if failing:
            parts.append(f"{failing} of {self.n_pairs} readings fail the tolerance")
        if not self.loa_within_absolute:
            parts.append("the 95 % limits of agreement exceed the absolute tolerance")
        return "; ".join(parts) or f"all {self.n_pairs} readings and the limits of agreement pass"

    def to_dict(self) -> dict[str, Any]:
        return {
            **self.tolerance.to_dict(),
            "n_within": self.n_within,
            "n_pairs": self.n_pairs,
            "share_within": self.share_within,
            "worst_abs_diff_deg": self.worst_abs_diff_deg,
            "loa_within_absolute": self.loa_within_absolute,
            "verdict": self.verdict,
            "reason": self.reason,
        }


@dataclass(frozen=True)
class AgreementResult:
    """Everything the agreement analysis found; ``to_dict`` puts the headline numbers on top."""

    bland_altman: BlandAltman
    tolerance: ToleranceVerdict
    manual_rr: GaugeRR | None
    vision_repeatability_sd_deg: float | None
    pairs: tuple[dict[str, Any], ...]
    unmatched_manual: tuple[str, ...] = ()
    warnings: tuple[StageWarning, ...] = field(default=())

    def to_dict(self) -> dict[str, Any]:
        ba = self.bland_altman
        return {
            "n": ba.n,
            "bias_deg": ba.bias_deg,
            "loa_low_deg": ba.loa_low_deg,
            "loa_high_deg": ba.loa_high_deg,
            "difference": "vision - manual",
            "bland_altman": ba.to_dict(),
            "tolerance": self.tolerance.to_dict(),
            "manual_rr": None if self.manual_rr is None else self.manual_rr.to_dict(),
            "vision_repeatability_sd_deg": self.vision_repeatability_sd_deg,
            "pairs": list(self.pairs),
            "unmatched_manual": list(self.unmatched_manual),
            "warnings": [w.to_json() for w in self.warnings],
        }


# --------------------------------------------------------------------------- inputs


def load_manual(path: str | os.PathLike[str]) -> list[ManualReading]:
    """Read MANUAL.csv: ``photo, bend_angle_deg`` and optional ``reader``, ``repeat``, ``bend``."""

    rows = read_csv_rows(path, required=("photo", "bend_angle_deg"))
    readings = []
    for line, row in enumerate(rows, start=2):
        try:
            value = float(row["bend_angle_deg"])
        except ValueError:
            raise InputError(
                path, f"line {line}: bend_angle_deg {row['bend_angle_deg']!r} is not a number"
            ) from None
        if not math.isfinite(value) or not row["photo"]:
            raise InputError(path, f"line {line}: needs a photo name and a finite bend_angle_deg")
        readings.append(
            ManualReading(
                photo=Path(row["photo"]).name,
                bend_angle_deg=value,
                reader=row.get("reader", ""),
                repeat=row.get("repeat", ""),
                bend=row.get("bend", ""),
            )
        )
    if not readings:
        raise InputError(path, "no readings (only a header)")
    return readings


def vision_angles(
    records: Iterable[Mapping[str, Any]], *, source: str = "results", key: str = "bend_angle_deg"
) -> dict[str, float]:
    """Vision bend angles by photo file name from per-photo result records.

    Records without the angle (failed photos, part photos) are skipped; the same
    file name with two different angles raises InputError (ambiguous match).
    """
    out: dict[str, float] = {}
    for rec in records:
        photo = rec.get("photo") or rec.get("file_name")
        value = rec.get(key)
        if not photo or value is None or rec.get("ok") is False:
            continue
        name = Path(str(photo)).name
        if name in out and not math.isclose(out[name], float(value), abs_tol=1e-9):
            raise InputError(source, f"photo name {name} appears twice with different angles")
        out[name] = float(value)
    return out


# --------------------------------------------------------------------------- statistics


def _t(confidence: float, dof: int) -> float:
    from scipy import stats

    return float(stats.t.ppf(0.5 + confidence / 2, max(dof, 1)))


def bland_altman(
    vision_deg: Sequence[float],
    manual_readings_deg: Sequence[Sequence[float]],
    *,
    confidence: float = 0.95,
    alpha: float = 0.05,
) -> BlandAltman:
    """Bland–Altman analysis of one vision value and one or more manual readings per photo.

    Parameters
    ----------
    vision_deg : sequence of float, shape (n,)
        Vision bend angle of each photo, degrees.
    manual_readings_deg : sequence of sequences of float
        The manual readings of each photo (one or more), degrees.
    confidence : float
        Confidence level of the intervals (default 0.95).
    alpha : float
        Significance level of the proportional-bias test (default 0.05).
    """
    from scipy import stats

    v = np.asarray(vision_deg, dtype=float)
    groups = [np.asarray(g, dtype=float) for g in manual_readings_deg]
    n = len(v)
    if n != len(groups) or n < 3 or any(len(g) == 0 for g in groups):
        raise ValueError("need at least 3 photos, each with a vision value and a manual reading")
    m_mean = np.array([g.mean() for g in groups])
    counts = np.array([len(g) for g in groups], dtype=float)
    d_mean = v - m_mean
    ss_within = sum(float(((g - g.mean()) ** 2).sum()) for g in groups)
    dof_within = int(counts.sum() - n)
    s2_within = ss_within / dof_within if dof_within > 0 else 0.0
    m_h = n / float(np.sum(1.0 / counts))
    s2_d = float(np.var(d_mean, ddof=1)) + (1.0 - 1.0 / m_h) * s2_within
    sd = math.sqrt(s2_d)
    bias = float(d_mean.mean())
    z = float(stats.norm.ppf(0.5 + confidence / 2))
    t = _t(confidence, n - 1)
    lo, hi = bias - z * sd, bias + z * sd
    se_bias = math.sqrt(float(np.var(d_mean, ddof=1)) / n)
    se_loa = sd * math.sqrt(3.0 / n)
    avg = (v + m_mean) / 2
    fit = stats.linregress(avg, d_mean)
    t_slope = _t(confidence, n - 2)
    return BlandAltman(
        n=n,
        n_readings=int(counts.sum()),
        bias_deg=bias,
        sd_deg=sd,
        loa_low_deg=lo,
        loa_high_deg=hi,
        bias_ci_deg=(bias - t * se_bias, bias + t * se_bias),
        loa_low_ci_deg=(lo - t * se_loa, lo + t * se_loa),
        loa_high_ci_deg=(hi - t * se_loa, hi + t * se_loa),
        slope=float(fit.slope),
        slope_ci=(
            float(fit.slope - t_slope * fit.stderr),
            float(fit.slope + t_slope * fit.stderr),
        ),
        slope_p=float(fit.pvalue),
        proportional_bias=bool(fit.pvalue < alpha),
        manual_within_sd_deg=math.sqrt(s2_within),
        readings_per_photo_harmonic=float(m_h),
        confidence=confidence,
    )


def gauge_rr(values_deg: Sequence[float], parts: Sequence[Any], readers: Sequence[Any]) -> GaugeRR:
    """Crossed gauge R&R by two-way ANOVA (parts x readers, with repeats).

    Parameters
    ----------
    values_deg : sequence of float
        Every reading, degrees.
    parts, readers : sequences
        The part (photo or bend) and the reader of each reading. The design must
        be balanced: every reader reads every part the same number of times.

    Notes
    -----
    Variance components from the mean squares (negative estimates set to 0):
    repeatability = MS_error; interaction = (MS_pr - MS_error)/r;
    reader = (MS_reader - MS_pr)/(p r); part = (MS_part - MS_pr)/(o r).
    With one reading per cell the interaction cannot be told from
    repeatability (it is pooled into it); with one reader reproducibility is 0.
    """
    y = np.asarray(values_deg, dtype=float)
    part_ids = {k: i for i, k in enumerate(dict.fromkeys(parts))}
    reader_ids = {k: i for i, k in enumerate(dict.fromkeys(readers))}
    p, o = len(part_ids), len(reader_ids)
    cells: dict[tuple[int, int], list[float]] = defaultdict(list)
    for value, part, reader in zip(y, parts, readers, strict=True):
        cells[(part_ids[part], reader_ids[reader])].append(float(value))
    sizes = {len(c) for c in cells.values()}
    if len(cells) != p * o or len(sizes) != 1:
        raise ValueError(
            "gauge R&R needs a balanced design: every reader reads every part equally often"
        )
    r = sizes.pop()
    if p < 2:
        raise ValueError("gauge R&R needs at least two parts")
    if o == 1 and r == 1:
        raise ValueError("gauge R&R needs repeated readings (more readers or repeats)")
    cube = np.empty((p, o, r))
    for (i, j), vals in cells.items():
        cube[i, j, :] = vals
    grand = cube.mean()
    part_m = cube.mean(axis=(1, 2))
    reader_m = cube.mean(axis=(0, 2))
    cell_m = cube.mean(axis=2)
    ss_part = o * r * float(((part_m - grand) ** 2).sum())
    ss_reader = p * r * float(((reader_m - grand) ** 2).sum())
    ss_int = r * float(((cell_m - part_m[:, None] - reader_m[None, :] + grand) ** 2).sum())
    ss_err = float(((cube - cell_m[:, :, None]) ** 2).sum())
    notes: list[str] = []
    ms_part = ss_part / (p - 1)
    ms_reader = ss_reader / (o - 1) if o > 1 else 0.0
    dof_int = (p - 1) * (o - 1)
    ms_int = ss_int / dof_int if dof_int > 0 else 0.0
    if r > 1:
        ms_err = ss_err / (p * o * (r - 1))
        var_int = max(0.0, (ms_int - ms_err) / r) if o > 1 else 0.0
    else:
        ms_err = ms_int  # interaction and repeatability are confounded
        var_int = 0.0
        notes.append("one reading per part and reader: interaction pooled into repeatability")
    var_rep = ms_err
    base = ms_int if (o > 1 and r > 1) else ms_err
    var_reader = max(0.0, (ms_reader - base) / (p * r)) if o > 1 else 0.0
    if o == 1:
        notes.append("one reader: reproducibility cannot be estimated (0)")
    var_part = max(0.0, (ms_part - base) / (o * r))
    var_grr = var_rep + var_reader + var_int
    total = var_grr + var_part
    grr_sd, part_sd = math.sqrt(var_grr), math.sqrt(var_part)
    return GaugeRR(
        parts=p,
        readers=o,
        repeats=r,
        repeatability_sd_deg=math.sqrt(var_rep),
        reproducibility_sd_deg=math.sqrt(var_reader + var_int),
        reader_sd_deg=math.sqrt(var_reader),
        interaction_sd_deg=math.sqrt(var_int),
        grr_sd_deg=grr_sd,
        part_sd_deg=part_sd,
        total_sd_deg=math.sqrt(total),
        grr_percent=100.0 * grr_sd / math.sqrt(total) if total > 0 else float("nan"),
        ndc=1.41 * part_sd / grr_sd if grr_sd > 0 else float("inf"),
        notes=tuple(notes),
    )


def _vision_repeatability(by_bend: Mapping[str, list[float]]) -> float | None:
    """Pooled within-bend SD of vision angles over bends photographed more than once."""
    groups = [np.asarray(v) for v in by_bend.values() if len(v) > 1]
    dof = sum(len(g) - 1 for g in groups)
    if dof == 0:
        return None
    return math.sqrt(sum(float(((g - g.mean()) ** 2).sum()) for g in groups) / dof)


def agreement(
    manual: Sequence[ManualReading],
    vision_by_name: Mapping[str, float],
    *,
    tolerance: Tolerance | None = None,
    confidence: float = 0.95,
) -> AgreementResult:
    """Compare vision angles with manual readings, photos matched by file name.

    Raises InputError (source ``manual``) when fewer than 3 photos match.
    """
    tolerance = tolerance or Tolerance()
    by_photo: dict[str, list[ManualReading]] = defaultdict(list)
    for reading in manual:
        by_photo[reading.photo].append(reading)
    matched = [name for name in by_photo if name in vision_by_name]
    unmatched = tuple(name for name in by_photo if name not in vision_by_name)
    if len(matched) < 3:
        raise InputError(
            "manual",
            f"only {len(matched)} photo(s) match a vision result by file name; need at least 3",
        )
    vision = [vision_by_name[name] for name in matched]
    groups = [[r.bend_angle_deg for r in by_photo[name]] for name in matched]
    ba = bland_altman(vision, groups, confidence=confidence)

    single_diffs = np.array([v - m for v, g in zip(vision, groups, strict=True) for m in g])
    single_manual = np.array([m for g in groups for m in g])
    within = tolerance.within(single_diffs, single_manual)
    verdict = ToleranceVerdict(
        tolerance=tolerance,
        n_within=int(within.sum()),
        n_pairs=len(single_diffs),
        worst_abs_diff_deg=float(np.abs(single_diffs).max()),
        loa_within_absolute=bool(
            max(abs(ba.loa_low_deg), abs(ba.loa_high_deg)) <= tolerance.absolute_deg
        ),
    )

    warnings: list[StageWarning] = []
    rr = None
    readings = [r for name in matched for r in by_photo[name]]
    if any(len(g) > 1 for g in groups):
        part_of = [r.bend or r.photo for r in readings]
        try:
            rr = gauge_rr(
                [r.bend_angle_deg for r in readings], part_of, [r.reader for r in readings]
            )
        except ValueError as exc:
            warnings.append(StageWarning("agreement_no_gauge_rr", f"no manual gauge R&R: {exc}"))
    bends: dict[str, list[float]] = defaultdict(list)
    for name in matched:
        bend = by_photo[name][0].bend
        if bend:
            bends[bend].append(vision_by_name[name])
    if unmatched:
        warnings.append(
            StageWarning(
                "agreement_unmatched",
                f"{len(unmatched)} manual photo(s) without a vision result",
                ", ".join(unmatched[:5]) + (", ..." if len(unmatched) > 5 else ""),
            )
        )

    pairs = tuple(
        {
            "photo": name,
            "vision_deg": v,
            "manual_mean_deg": float(np.mean(g)),
            "manual_readings": len(g),
            "diff_deg": v - float(np.mean(g)),
        }
        for name, v, g in zip(matched, vision, groups, strict=True)
    )
    return AgreementResult(
        bland_altman=ba,
        tolerance=verdict,
        manual_rr=rr,
        vision_repeatability_sd_deg=_vision_repeatability(bends),
        pairs=pairs,
        unmatched_manual=unmatched,
        warnings=tuple(warnings),
    )
