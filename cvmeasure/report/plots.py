"""Plots of results as PNG bytes (matplotlib, Agg backend, no display needed).

Each function takes results (records or analysis dataclasses) and returns the
PNG file's bytes, or None when the records hold nothing to plot; the caller
writes them (``--plot out.png``) or embeds them in the HTML report.

matplotlib is imported only when a plot is drawn (half a second or more on import).
"""

from __future__ import annotations

import io
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

__all__ = [
    "bland_altman_png",
    "angles_png",
    "springback_png",
    "residuals_png",
    "part_png",
    "numeric",
]


def _figure(width_in: float = 7.0, height_in: float = 3.6) -> tuple[Any, Any]:
    import matplotlib

    matplotlib.use("Agg", force=True)
    from matplotlib.figure import Figure

    fig = Figure(figsize=(width_in, height_in), dpi=110, layout="constrained")
    return fig, fig.add_subplot(1, 1, 1)


def _png(fig: Any) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", metadata={"Software": None})
    return buf.getvalue()


def _integer_ticks(ax: Any) -> None:
    """Whole-number ticks on the x axis (a photo index has no fractions)."""
    from matplotlib.ticker import MaxNLocator

    ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def numeric(value: Any) -> float | None:
    """``value`` as a finite float, or None."""
    if isinstance(value, bool) or value is None:
        return None
    try:
        out = float(value)
    except (TypeError, ValueError):
        return None
    return out if np.isfinite(out) else None


def bland_altman_png(result: Any) -> bytes:
    """Bland–Altman plot of an :class:`~cvmeasure.agreement.AgreementResult`.

    Per-photo differences (vision - manual mean) against the mean of the two
    methods; bias and limits of agreement with their confidence bands; the
    absolute tolerance as dotted lines.
    """
    ba = result.bland_altman
    avg = np.array([(p["vision_deg"] + p["manual_mean_deg"]) / 2 for p in result.pairs])
    diff = np.array([p["diff_deg"] for p in result.pairs])
    fig, ax = _figure()
    ax.scatter(avg, diff, s=14, color="#1f5f9f", alpha=0.8, label="photos")
    lo_x, hi_x = float(avg.min()), float(avg.max())
    for y, ci, name in (
        (ba.bias_deg, ba.bias_ci_deg, "bias"),
        (ba.loa_low_deg, ba.loa_low_ci_deg, "limits of agreement"),
        (ba.loa_high_deg, ba.loa_high_ci_deg, None),
    ):
        colour = "#222222" if name == "bias" else "#b03020"
        label = None
        if name == "bias":
            label = f"bias {y:+.2f}"
        elif name:
            label = f"{name} {ba.loa_low_deg:+.2f} / {ba.loa_high_deg:+.2f}"
        ax.axhline(y, color=colour, lw=1.2, label=label)
        ax.axhspan(ci[0], ci[1], color=colour, alpha=0.12, lw=0)
    tol = result.tolerance.tolerance.absolute_deg
    ax.axhline(tol, color="#2a8a2a", ls=":", lw=1.2, label=f"tolerance +-{tol:g} deg")
    ax.axhline(-tol, color="#2a8a2a", ls=":", lw=1.2)
    if ba.proportional_bias:
        xs = np.array([lo_x, hi_x])
        intercept = ba.bias_deg - ba.slope * float(avg.mean())
        ax.plot(
            xs, intercept + ba.slope * xs, "--", color="#7a3fa0", lw=1, label="proportional bias"
        )
    ax.set_xlabel("mean of vision and manual (deg)")
    ax.set_ylabel("vision - manual (deg)")
    ax.set_title(f"Bland-Altman, n = {ba.n} photos")
    ax.legend(fontsize=7, loc="best", framealpha=0.85)
    ax.grid(alpha=0.3)
    return _png(fig)


def _machine(records: Sequence[Mapping[str, Any]]) -> list[Mapping[str, Any]]:
    return [
        r for r in records if r.get("ok", True) and numeric(r.get("bend_angle_deg")) is not None
    ]


def angles_png(records: Sequence[Mapping[str, Any]]) -> bytes | None:
    """Bend and pin angles of every machine photo, in file order, with 1-sigma bars."""
    rows = _machine(records)
    if not rows:
        return None
    fig, ax = _figure()
    x = np.arange(len(rows))
    for key, colour in (("bend_angle_deg", "#1f5f9f"), ("pin_angle_deg", "#c07020")):
        y = np.array(
            [numeric(r.get(key)) if numeric(r.get(key)) is not None else np.nan for r in rows]
        )
        if np.all(np.isnan(y)):
            continue
        unc = [
            numeric((r.get("uncertainty_deg") or {}).get(key))
            if isinstance(r.get("uncertainty_deg"), Mapping)
            else None
            for r in rows
        ]
        err = np.array([u if u is not None else 0.0 for u in unc])
        ax.errorbar(x, y, yerr=err, fmt="o", ms=3, lw=1, color=colour, label=key)
    ax.set_xlabel("photo (in results order)")
    _integer_ticks(ax)
    ax.set_ylabel("angle (deg)")
    ax.set_title("Measured angles")
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    return _png(fig)


def springback_png(records: Sequence[Mapping[str, Any]]) -> bytes | None:
    """Springback against the loaded bend angle (trial records with ``springback_deg``)."""
    rows = [
        r
        for r in records
        if numeric(r.get("springback_deg")) is not None
        and numeric(r.get("loaded_bend_deg")) is not None
    ]
    if not rows:
        return None
    fig, ax = _figure()
    loaded = np.array([float(r["loaded_bend_deg"]) for r in rows])
    spring = np.array([float(r["springback_deg"]) for r in rows])
    ax.scatter(loaded, spring, s=16, color="#1f5f9f")
    ax.axhline(0, color="#444444", lw=0.8)
    ax.set_xlabel("loaded bend angle (deg)")
    ax.set_ylabel("springback (deg)")
    ax.set_title(f"Springback, {len(rows)} trials")
    ax.grid(alpha=0.3)
    return _png(fig)


#: Residual / uncertainty groups of :func:`residuals_png`: (title, unit).
_RESIDUAL_GROUPS = (
    ("stated uncertainty, 1 sigma", "deg"),
    ("fit residual RMS", "mm"),
    ("marker centre uncertainty, 1 sigma", "px"),
)


def _residual_series(records: Sequence[Mapping[str, Any]]) -> dict[str, dict[str, list[float]]]:
    """unit -> field -> values, from every measured record."""
    out: dict[str, dict[str, list[float]]] = {unit: {} for _, unit in _RESIDUAL_GROUPS}

    def add(unit: str, name: str, value: Any) -> None:
        if numeric(value) is not None:
            out[unit].setdefault(name, []).append(float(value))

    for r in records:
        if r.get("ok") is False:
            continue
        unc = r.get("uncertainty_deg")
        if isinstance(unc, Mapping):
            for key, value in unc.items():
                add("deg", f"u({key})", value)
        for key, value in r.items():
            if key.startswith("rms_residual_") and key.endswith("_mm"):
                add("mm", key, value)
        for block in ("circle", "polyline"):
            sub = r.get(block)
            if isinstance(sub, Mapping):
                add("mm", f"{block} rms_residual_mm", sub.get("rms_residual_mm"))
        markers = r.get("markers")
        if isinstance(markers, Mapping):
            for role, m in markers.items():
                if isinstance(m, Mapping):
                    add("px", f"{role} sigma_px", m.get("sigma_px"))
    return {unit: series for unit, series in out.items() if series}


def residuals_png(records: Sequence[Mapping[str, Any]]) -> bytes | None:
    """Per-photo fit residuals and stated uncertainties, one panel per unit.

    Stated 1-sigma uncertainties of the angles (deg, ``uncertainty_deg``), RMS
    residuals of the part fits (mm: the circle's and the chord polyline's), and
    the 1-sigma centre uncertainty of every marker (px). Each box spans the
    photos' values (median, quartiles, whiskers at 1.5 IQR, outliers as dots).
    """
    series = _residual_series(records)
    if not series:
        return None
    fig, _ = _figure(width_in=max(4.0, 3.3 * len(series)), height_in=3.6)
    fig.clear()
    axes = fig.subplots(1, len(series), squeeze=False)[0]
    titles = dict((unit, title) for title, unit in _RESIDUAL_GROUPS)
    for ax, (unit, by_name) in zip(axes, series.items(), strict=True):
        names = sorted(by_name)
        ax.boxplot([by_name[n] for n in names], showfliers=True)
        ax.set_xticks(range(1, len(names) + 1), names, rotation=25, fontsize=7, ha="right")
        values = [v for vs in by_name.values() for v in vs]
        ax.set_yscale("log" if min(values) > 0 else "linear")
        ax.set_ylabel(unit)
        ax.set_title(f"{titles[unit]} ({unit})", fontsize=9)
        ax.grid(alpha=0.3)
    fig.suptitle(f"Fit residuals and stated uncertainties over {len(records)} records", fontsize=10)
    return _png(fig)


def part_png(records: Sequence[Mapping[str, Any]]) -> bytes | None:
    """Radius and arc angle of every part photo."""
    rows = [r for r in records if r.get("ok", True) and numeric(r.get("radius_mm")) is not None]
    if not rows:
        return None
    fig, ax = _figure()
    x = np.arange(len(rows))
    ax.plot(x, [float(r["radius_mm"]) for r in rows], "o", color="#1f5f9f", label="radius_mm")
    ax.set_xlabel("photo (in results order)")
    _integer_ticks(ax)
    ax.set_ylabel("radius (mm)")
    arcs = [numeric(r.get("arc_angle_deg")) for r in rows]
    if any(a is not None for a in arcs):
        ax2 = ax.twinx()
        ax2.plot(x, [a if a is not None else np.nan for a in arcs], "s", color="#c07020", ms=4)
        ax2.set_ylabel("arc angle (deg)", color="#c07020")
    ax.set_title("Parts")
    ax.grid(alpha=0.3)
    return _png(fig)
