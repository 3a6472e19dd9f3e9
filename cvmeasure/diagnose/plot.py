"""Residual plots before and after the diagnosis (PNG bytes, matplotlib without pyplot).

matplotlib is imported only when a plot is drawn (half a second or more on import).
"""

from __future__ import annotations

import io

import numpy as np

from cvmeasure.contracts import BLOCKS, TrialTable
from cvmeasure.diagnose.result import Cause, Diagnosis

__all__ = ["residual_plot_png"]

_MARKERS = (("loaded", "o"), ("unloaded", "x"), ("pin", "^"))


def residual_plot_png(diagnosis: Diagnosis, trials: TrialTable, *, dpi: int = 100) -> bytes:
    """A 2 x 2 figure: residuals vs commanded pin angle and vs bend index, before / after.

    Residuals are measured minus predicted (deg) of the full-data fits;
    circles are loaded angles, crosses unloaded, triangles pin angles; blue
    counter-clockwise, red clockwise.
    """
    from matplotlib.figure import Figure  # no pyplot: no global backend state

    k = len(BLOCKS)
    cmd = np.tile(trials.commanded_pin_deg, k)
    idx = np.tile(trials.bend_index, k)
    ccw = np.tile(trials.direction_sign, k) > 0
    block = np.repeat(np.arange(k), len(trials))
    fig = Figure(figsize=(10, 6.5), dpi=dpi, layout="constrained")
    axes = fig.subplots(2, 2, sharey="row")
    rows = (
        ("baseline (nuisance only)", diagnosis.baseline_residual_deg, diagnosis.baseline_fit),
        (
            f"extended: {Cause.of(diagnosis.causes).label}",
            diagnosis.extended_residual_deg,
            diagnosis.extended_fit,
        ),
    )
    for row, (title, res, fit) in enumerate(rows):
        for col, (x, xlabel) in enumerate(((cmd, "commanded pin (deg)"), (idx, "bend index"))):
            ax = axes[row, col]
            for is_ccw, colour in ((True, "tab:blue"), (False, "tab:red")):
                for b, (what, marker) in enumerate(_MARKERS):
                    m = (ccw == is_ccw) & (block == b) & np.isfinite(res)
                    if not m.any():
                        continue
                    label = f"{'ccw' if is_ccw else 'cw'} {what}"
                    ax.scatter(x[m], res[m], s=14, c=colour, marker=marker, label=label)
            ax.axhline(0.0, color="0.5", lw=0.8)
            ax.set_xlabel(xlabel)
            ax.set_title(f"{title}: rms {fit.rmse_deg:.3f} deg", fontsize=10)
        axes[row, 0].set_ylabel("residual (deg)")
    axes[0, 1].legend(fontsize=8, loc="best")
    fig.suptitle(
        f"held-out RMSE {diagnosis.baseline_rmse_deg:.3f} -> "
        f"{diagnosis.extended_rmse_deg:.3f} deg (gain {100 * diagnosis.gain:.0f} %)"
    )
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
