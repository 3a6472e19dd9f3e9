"""Residual plots before and after the diagnosis (PNG bytes, matplotlib without pyplot)."""

from __future__ import annotations

import io

import numpy as np

from cvmeasure.diagnose.core import Diagnosis
from cvmeasure.diagnose.trials import TrialSet

__all__ = ["residual_plot_png"]


def residual_plot_png(diagnosis: Diagnosis, trials: TrialSet, *, dpi: int = 100) -> bytes:
    """A 2 x 2 figure: residuals vs commanded pin angle and vs bend index, before / after.

    Residuals are measured minus predicted (deg) of the full-data fits;
    circles are loaded angles, crosses unloaded; blue counter-clockwise, red
    clockwise.
    """
    from matplotlib.figure import Figure  # no pyplot: no global backend state

    n = len(trials)
    cmd = np.concatenate([trials.commanded_pin_deg, trials.commanded_pin_deg])
    idx = np.concatenate([trials.bend_index, trials.bend_index])
    ccw = np.concatenate([trials.direction, trials.direction]) > 0
    unloaded = np.arange(2 * n) >= n
    fig = Figure(figsize=(10, 6.5), dpi=dpi, layout="constrained")
    axes = fig.subplots(2, 2, sharey="row")
    rows = (
        ("baseline (nuisance only)", diagnosis.baseline_residual_deg, diagnosis.baseline_fit),
        (
            f"extended: {' + '.join(diagnosis.causes) or 'none'}",
            diagnosis.extended_residual_deg,
            diagnosis.extended_fit,
        ),
    )
    for row, (title, res, fit) in enumerate(rows):
        for col, (x, xlabel) in enumerate(((cmd, "commanded pin (deg)"), (idx, "bend index"))):
            ax = axes[row, col]
            for is_ccw, colour in ((True, "tab:blue"), (False, "tab:red")):
                for is_unl, marker in ((False, "o"), (True, "x")):
                    m = (ccw == is_ccw) & (unloaded == is_unl) & np.isfinite(res)
                    label = f"{'ccw' if is_ccw else 'cw'} {'unloaded' if is_unl else 'loaded'}"
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
