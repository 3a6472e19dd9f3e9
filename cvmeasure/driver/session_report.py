"""Plots and the HTML report of a calibration: data, every model's fit, residuals, overlays.

:func:`plot_calibration` draws, per direction, the measured springback over the
final angle with the curve of every springback model, and below it each
model's leave-one-angle-out errors. :func:`write_session_report` writes one
self-contained HTML file (images embedded) with that plot, the table of model
scores, the samples, and overlays of the measured markers on the photos.
Matplotlib is imported only here.
"""

from __future__ import annotations

import html
import io
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.fileio import atomic_write_bytes, atomic_write_text
from cvmeasure.material.bender_calibration import BenderCalibration
from cvmeasure.material.compensation import DIRECTIONS, SPRINGBACK_MODELS, fit_springback
from cvmeasure.warning import StageWarning

__all__ = ["calibration_figure_png", "plot_calibration", "write_session_report"]

_COLOURS = {
    "linear": "tab:blue",
    "cubic": "tab:red",
    "pchip": "tab:green",
    "physical": "tab:purple",
}


def calibration_figure_png(calibration: BenderCalibration) -> bytes:
    """PNG bytes of the calibration's data, fitted curves and residuals per direction."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    directions = [d for d in DIRECTIONS if calibration.samples_of(d)]
    fig, axes = plt.subplots(
        2, len(directions), figsize=(6 * len(directions), 7), squeeze=False, sharex="col"
    )
    for col, direction in enumerate(directions):
        samples = calibration.samples_of(direction)
        sign = -1.0 if direction == "cw" else 1.0
        final = np.array([sign * s.unloaded_bend_deg for s in samples])
        loaded = np.array([sign * s.loaded_bend_deg for s in samples])
        unc = np.array([s.uncertainty_deg.get("springback_deg", 0.0) for s in samples])
        top, bottom = axes[0, col], axes[1, col]
        top.errorbar(final, loaded - final, yerr=unc, fmt="ko", ms=4, label="measured", zorder=5)
        for model in SPRINGBACK_MODELS:
            try:
                curve = fit_springback(final, loaded, model=model, direction=direction)  # type: ignore[arg-type]
            except ValueError:
                continue
            score = curve.loao_rmse_deg
            label = f"{model} (LOAO RMS {score:.3f} deg)" if score is not None else model
            # over the curve's own domain: repeated bends are averaged into one angle, so
            # the lowest single bend can lie just below it
            grid = np.linspace(*curve.domain_deg, 300)
            top.plot(grid, curve.springback_deg(grid), color=_COLOURS[model], label=label)
            if curve.loao_errors_deg:
                bottom.plot(
                    np.array(curve.final_deg[1:-1]),
                    curve.loao_errors_deg,
                    "o-",
                    color=_COLOURS[model],
                    label=model,
                )
        used = calibration.model
        top.set_title(f"{direction} bends (compensation uses {used})")
        top.set_ylabel("springback (deg)")
        top.legend(fontsize=8)
        top.grid(alpha=0.3)
        bottom.axhline(0, color="k", lw=0.8)
        bottom.set_xlabel("final (unloaded) bend angle (deg)")
        bottom.set_ylabel("leave-one-angle-out error (deg)")
        bottom.grid(alpha=0.3)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90)
    plt.close(fig)
    return buf.getvalue()


def plot_calibration(calibration: BenderCalibration, path: str | os.PathLike[str]) -> Path:
    """Write the data / fits / residuals plot of a calibration as PNG (atomically)."""
    return atomic_write_bytes(path, calibration_figure_png(calibration))


def write_session_report(
    path: str | os.PathLike[str],
    calibration: BenderCalibration,
    steps: Sequence[Any] = (),
    *,
    session_dir: str | os.PathLike[str] | None = None,
    max_overlays: int = 4,
) -> Path:
    """Write the calibration's HTML report (one file, images embedded), atomically.

    Parameters
    ----------
    path : path
        The HTML file.
    calibration : BenderCalibration
    steps : sequence of SessionStep
        The session's steps (for the overlays and the photo names).
    session_dir : path, optional
        Folder the steps' photo paths are relative to.
    max_overlays : int
        How many steps get loaded/unloaded overlays (spread over the plan).
    """
    from cvmeasure.report.html import html_img, html_page
    from cvmeasure.report.thumbnails import overlay_thumbnail

    e = html.escape
    parts = [
        f"<p class=meta>mode {e(calibration.mode)}, angles "
        f"{e(', '.join(f'{a:g}' for a in calibration.angles_deg))} deg, "
        f"{len(calibration.samples)} bends; compensation model <b>{e(calibration.model)}</b>; "
        f"created {e(calibration.created_utc)}.</p>",
        "<h2>Springback curves and residuals</h2>",
        html_img(calibration_figure_png(calibration), "springback curves", css_class="figure"),
        "<h2>Model scores (leave-one-angle-out, deg)</h2><table><tr><th>model</th>",
    ]
    directions = [d for d in DIRECTIONS if calibration.samples_of(d)]
    parts += [f"<th>{d} RMS</th><th>{d} max</th>" for d in directions] + ["</tr>"]
    for model, by_dir in calibration.scores.items():
        cells = []
        for d in directions:
            s = by_dir.get(d, {}) if isinstance(by_dir, dict) else {}
            for key in ("loao_rmse_deg", "loao_max_deg"):
                v = s.get(key) if isinstance(s, dict) else None
                cells.append(f"<td class=num>{'-' if v is None else f'{v:.4f}'}</td>")
        parts.append(f"<tr><th>{e(model)}</th>{''.join(cells)}</tr>")
    parts.append(
        "</table><h2>Calibration bends (deg)</h2><table><tr><th>trial</th><th>direction</th>"
        "<th>target</th><th>pin command</th><th>loaded bend</th><th>unloaded bend</th>"
        "<th>springback</th><th>u(springback), 1 sigma</th></tr>"
    )
    for s in calibration.samples:
        u = s.uncertainty_deg.get("springback_deg")
        parts.append(
            f"<tr><td>{e(s.trial)}</td><td>{s.direction}</td>"
            f"<td class=num>{'' if s.target_deg is None else f'{s.target_deg:g}'}</td>"
            f"<td class=num>{s.commanded_pin_deg:.3f}</td>"
            f"<td class=num>{s.loaded_bend_deg:.3f}</td>"
            f"<td class=num>{s.unloaded_bend_deg:.3f}</td><td class=num>{s.springback_deg:.4f}</td>"
            f"<td class=num>{'' if u is None else f'{u:.4f}'}</td></tr>"
        )
    parts.append("</table>")
    parts += _warnings_section(calibration)
    if steps and session_dir is not None:
        parts.append("<h2>Overlays (measured markers)</h2>")
        picks = sorted(
            set(np.linspace(0, len(steps) - 1, min(max_overlays, len(steps))).astype(int))
        )
        for i in picks:
            step = steps[i]
            parts.append(
                f"<h3>step {step.step + 1}: {step.direction} {step.target_deg:g} deg</h3><p>"
            )
            for which, rel, rec in (
                ("loaded", step.photo_loaded, step.loaded),
                ("unloaded", step.photo_unloaded, step.unloaded),
            ):
                photo_path = Path(session_dir) / rel
                if photo_path.exists():
                    jpeg = overlay_thumbnail(rec.to_dict(), photo_path, width_px=480)
                    parts.append(
                        html_img(jpeg, f"{which} {rel}", mime="image/jpeg", css_class="overlay")
                    )
                    parts.append(f" {which}: bend {rec.bend_angle_deg:.3f} deg ")
            parts.append("</p>")
    return atomic_write_text(path, html_page(f"Calibration {calibration.name}", parts))


def _warnings_section(calibration: BenderCalibration) -> list[str]:
    """The session's photo warnings (``provenance.warnings``), one row per photo and code."""
    e = html.escape
    rows = calibration.provenance.get("warnings") or []
    if not rows:
        return ["<h2>Warnings</h2><p>No warnings on any photo.</p>"]
    out = [
        f"<h2>Warnings</h2><p>{len(rows)} warning(s) on "
        f"{len({r.get('photo') for r in rows})} photo(s).</p>",
        "<table><tr><th>photo</th><th>code</th><th>subject</th><th>message</th></tr>",
    ]
    for r in rows:
        w = StageWarning.from_json(r)
        out.append(
            f"<tr><td>{e(str(r.get('photo', '')))}</td><td>{e(w.code)}</td>"
            f"<td>{e(w.subject)}</td><td>{e(w.message)}</td></tr>"
        )
    out.append("</table>")
    return out
