"""Production tracking: control charts, capability and a drift alarm per vertex.

A run of parts bent from one design, each measured against it
(:func:`cvmeasure.part.measure.measure_part` with the design), gives at every
vertex a series of bends, one per part in bending order. For each vertex:

* an **individuals / moving-range chart** (Montgomery, *Introduction to
  Statistical Quality Control*, ch. 6.4): centre line the mean of the first
  ``baseline_parts`` parts (the reference a drift is judged against), the within
  sigma ``MR-bar / 1.128`` (d2 of n = 2; moving ranges hardly see a slow
  drift), individuals limits ``centre +- 3 sigma``, moving-range upper limit
  ``3.267 MR-bar`` (D4);
* **capability** against the design tolerance, the seed paper's ``|error| <=
  1 deg`` and ``<= 10 %`` of the design bend (both must hold, as in
  :class:`cvmeasure.agreement.Tolerance`, so the half-width is ``min(1 deg, 0.1
  |design|)``): ``Cp = 2 tol / 6 sigma``, ``Cpk = (tol - |mean - design|) / 3 sigma``;
* a **drift alarm**: the Western Electric rules on the individuals chart
  (1: a point beyond 3 sigma; 2: 2 of 3 beyond 2 sigma on one side; 3: 4 of 5
  beyond 1 sigma on one side; 4: 8 in a row on one side) and a tabular CUSUM
  (``k = 0.5 sigma``, ``h = 5 sigma``) around the centre line. The alarm names
  the first part and the rule.

With fewer than 3 parts nothing can be charted (ValueError).

matplotlib is imported only when a track plot is drawn (half a second or more on import).
"""

from __future__ import annotations

import io
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from cvmeasure.agreement import Tolerance

__all__ = [
    "D2",
    "D4",
    "VertexChart",
    "TrackResult",
    "track_bends",
    "bends_from_records",
    "tracking_png",
]

#: d2 of moving ranges of 2 (sigma = MR-bar / d2).
D2 = 1.128
#: D4 of moving ranges of 2 (MR upper limit = D4 MR-bar).
D4 = 3.267


def _finite_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


@dataclass(frozen=True)
class VertexChart:
    """One vertex's individuals / moving-range chart, capability and alarms (deg)."""

    vertex: int
    design_deg: float
    values_deg: tuple[float, ...]
    mean_deg: float
    sigma_deg: float
    centre_deg: float
    ucl_deg: float
    lcl_deg: float
    mr_bar_deg: float
    mr_ucl_deg: float
    tolerance_deg: float
    cp: float | None
    cpk: float | None
    alarms: tuple[Mapping[str, Any], ...]

    @property
    def first_alarm_part(self) -> int | None:
        return min((int(a["part"]) for a in self.alarms), default=None)

    def to_dict(self) -> dict[str, Any]:
        return {
            "vertex": self.vertex,
            "design_deg": self.design_deg,
            "values_deg": list(self.values_deg),
            "mean_deg": self.mean_deg,
            "bias_deg": self.mean_deg - self.design_deg,
            "sigma_deg": self.sigma_deg,
            "centre_deg": self.centre_deg,
            "ucl_deg": self.ucl_deg,
            "lcl_deg": self.lcl_deg,
            "mr_bar_deg": self.mr_bar_deg,
            "mr_ucl_deg": self.mr_ucl_deg,
            "tolerance_deg": self.tolerance_deg,
            "cp": self.cp,
            "cpk": self.cpk,
            "alarms": [dict(a) for a in self.alarms],
            "first_alarm_part": self.first_alarm_part,
        }


@dataclass(frozen=True)
class TrackResult:
    """Control charts of every vertex of a run of parts."""

    parts: tuple[str, ...]
    charts: tuple[VertexChart, ...]
    tolerance: Tolerance
    baseline_parts: int

    @property
    def alarm(self) -> bool:
        return any(c.alarms for c in self.charts)

    @property
    def worst_cpk(self) -> float | None:
        values = [c.cpk for c in self.charts if c.cpk is not None]
        return min(values) if values else None

    def to_dict(self) -> dict[str, Any]:
        alarmed = [c for c in self.charts if c.alarms]
        return {
            "parts": list(self.parts),
            "vertices": len(self.charts),
            "tolerance": self.tolerance.to_dict(),
            "baseline_parts": self.baseline_parts,
            "alarm": self.alarm,
            "alarmed_vertices": [c.vertex for c in alarmed],
            "first_alarm_part": min((c.first_alarm_part for c in alarmed), default=None),
            "worst_cpk": self.worst_cpk,
            "charts": [c.to_dict() for c in self.charts],
        }


def _western_electric(z: np.ndarray) -> list[dict[str, Any]]:
    """Western Electric rule violations of standardised points ``z`` (first per rule)."""
    found: list[dict[str, Any]] = []
    rules = (
        ("WE1: beyond 3 sigma", 1, 1, 3.0),
        ("WE2: 2 of 3 beyond 2 sigma", 3, 2, 2.0),
        ("WE3: 4 of 5 beyond 1 sigma", 5, 4, 1.0),
        ("WE4: 8 in a row on one side", 8, 8, 0.0),
    )
    for name, window, need, level in rules:
        for i in range(window - 1, len(z)):
            w = z[i - window + 1 : i + 1]
            for side in (1.0, -1.0):
                if np.sum(side * w > level) >= need and side * z[i] > level:
                    found.append({"part": i, "rule": name, "side": "high" if side > 0 else "low"})
                    break
            else:
                continue
            break
    return found


def _cusum(x: np.ndarray, centre: float, sigma: float) -> dict[str, Any] | None:
    """First tabular-CUSUM alarm (k = 0.5 sigma, h = 5 sigma), or None."""
    hi = lo = 0.0
    for i, v in enumerate(x):
        hi = max(0.0, hi + (v - centre) - 0.5 * sigma)
        lo = max(0.0, lo - (v - centre) - 0.5 * sigma)
        if hi > 5.0 * sigma or lo > 5.0 * sigma:
            return {"part": i, "rule": "CUSUM", "side": "high" if hi > lo else "low"}
    return None


def track_bends(
    measured_deg: ArrayLike,
    design_deg: ArrayLike,
    *,
    parts: Sequence[str] | None = None,
    tolerance: Tolerance | None = None,
    baseline_parts: int = 10,
    min_sigma_deg: float = 1e-6,
) -> TrackResult:
    """Charts of every vertex from bends of a run of parts.

    Parameters
    ----------
    measured_deg : ndarray (parts, N), measured bend per part (bending order) and vertex.
    design_deg : ndarray (N,), the design's bend per vertex (same sense).
    parts : names of the parts (default ``part 0`` ...).
    tolerance : the accepted error (default the seed's 1 deg and 10 %).
    baseline_parts : parts whose mean is the centre line (all when fewer).
    min_sigma_deg : floor of the within sigma (a run of identical values).

    Raises
    ------
    ValueError
        Fewer than 3 parts or mismatched shapes.
    """
    x = np.asarray(measured_deg, dtype=np.float64)
    d = np.asarray(design_deg, dtype=np.float64).ravel()
    if x.ndim != 2 or x.shape[1] != d.size:
        raise ValueError(f"measured bends of shape {x.shape} do not fit {d.size} design vertices")
    if x.shape[0] < 3:
        raise ValueError(f"a control chart needs at least 3 parts, got {x.shape[0]}")
    tol = tolerance or Tolerance()
    names = tuple(parts) if parts is not None else tuple(f"part {i}" for i in range(x.shape[0]))
    base = max(2, min(baseline_parts, x.shape[0]))
    charts = []
    for j in range(d.size):
        v = x[:, j]
        mean = float(np.mean(v))
        mr_bar = float(np.mean(np.abs(np.diff(v))))
        sigma = max(mr_bar / D2, min_sigma_deg)
        half = tol.absolute_deg
        if tol.relative:
            half = min(half, tol.relative * abs(d[j]))
        centre = float(np.mean(v[:base]))
        alarms = _western_electric((v - centre) / sigma)
        cusum = _cusum(v, centre, sigma)
        if cusum is not None:
            alarms.append(cusum)
        charts.append(
            VertexChart(
                vertex=j,
                design_deg=float(d[j]),
                values_deg=tuple(float(a) for a in v),
                mean_deg=mean,
                sigma_deg=sigma,
                centre_deg=centre,
                ucl_deg=centre + 3.0 * sigma,
                lcl_deg=centre - 3.0 * sigma,
                mr_bar_deg=mr_bar,
                mr_ucl_deg=D4 * mr_bar,
                tolerance_deg=half,
                cp=_finite_or_none(2.0 * half / (6.0 * sigma)),
                cpk=_finite_or_none((half - abs(mean - d[j])) / (3.0 * sigma)),
                alarms=tuple(sorted(alarms, key=lambda a: a["part"])),
            )
        )
    return TrackResult(names, tuple(charts), tol, base)


def bends_from_records(
    records: Sequence[Mapping[str, Any]],
) -> tuple[list[str], np.ndarray, np.ndarray]:
    """(part names, design bends (N,), measured bends (parts, N)) from part result records.

    Uses each record's ``comparison.bends`` (``cvmeasure part --design`` /
    :meth:`PartMeasurement.to_dict`); records without it, or of another vertex count
    than the first, are skipped. Order: as given (bending order).

    Raises
    ------
    ValueError
        No record carries per-vertex bends against a design.
    """
    names: list[str] = []
    rows: list[list[float]] = []
    design: np.ndarray | None = None
    for rec in records:
        bends = (rec.get("comparison") or {}).get("bends") or {}
        meas = bends.get("measured_bend_deg")
        if not meas:
            continue
        d = np.asarray(bends["design_bend_deg"], dtype=np.float64)
        if design is None:
            design = d
        if d.shape != design.shape or not np.allclose(d, design, atol=1e-6):
            continue
        names.append(str(rec.get("photo") or rec.get("file_name") or f"part {len(names)}"))
        rows.append([float(v) for v in meas])
    if design is None:
        raise ValueError("no record carries per-vertex bends against a design")
    return names, design, np.asarray(rows)


def tracking_png(result: TrackResult, *, max_vertices: int = 6) -> bytes:
    """Individuals and moving-range charts of the vertices with alarms (else the worst Cpk)."""
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    charts = sorted(
        result.charts,
        key=lambda c: (not c.alarms, c.cpk if c.cpk is not None else math.inf),
    )[:max_vertices]
    fig = Figure(figsize=(7.0, 2.2 * len(charts)), dpi=110, layout="constrained")
    axes = fig.subplots(len(charts), 2, squeeze=False)
    for row, c in zip(axes, charts, strict=True):
        idx = np.arange(len(c.values_deg))
        ax = row[0]
        ax.plot(idx, c.values_deg, "o-", ms=3, lw=1)
        for y, style in ((c.centre_deg, "-"), (c.ucl_deg, "--"), (c.lcl_deg, "--")):
            ax.axhline(y, color="grey", ls=style, lw=0.8)
        ax.axhline(c.design_deg + c.tolerance_deg, color="red", lw=0.8, ls=":")
        ax.axhline(c.design_deg - c.tolerance_deg, color="red", lw=0.8, ls=":")
        for a in c.alarms:
            ax.plot(a["part"], c.values_deg[a["part"]], "rx", ms=8)
        cpk = "-" if c.cpk is None else f"{c.cpk:.2f}"
        ax.set_title(f"vertex {c.vertex}: bend (deg), Cpk {cpk}", fontsize=8)
        mr = np.abs(np.diff(c.values_deg))
        row[1].plot(idx[1:], mr, "o-", ms=3, lw=1)
        row[1].axhline(c.mr_bar_deg, color="grey", lw=0.8)
        row[1].axhline(c.mr_ucl_deg, color="grey", ls="--", lw=0.8)
        row[1].set_title("moving range (deg)", fontsize=8)
        for a in row:
            a.tick_params(labelsize=7)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    return buf.getvalue()
