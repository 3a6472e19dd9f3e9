"""Demo step of the diagnosis: a hidden backlash found in simulated trials."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cvmeasure_datasets.demo.report import DemoRow, DemoSection

__all__ = ["demo_step"]

_HIDDEN_BACKLASH_DEG = 1.2
_NOISE_DEG = 0.05


def demo_step(out_dir: Path, *, seed: int) -> DemoSection:
    """Hide a backlash in a simulated plan (both directions), diagnose it, compare with truth.

    Writes ``diagnosis_trials.csv``, ``diagnosis.json``, ``diagnosis_residuals.png``
    and ``diagnosis_extended_params.json`` into ``out_dir``.
    """
    from cvmeasure.diagnose.core import diagnose
    from cvmeasure.diagnose.plot import residual_plot_png
    from cvmeasure.fileio import atomic_write_bytes, atomic_write_json, write_csv_rows
    from cvmeasure.sim import Effect, params_to_json
    from cvmeasure_datasets.trials import measure_trials, random_plan

    rng = np.random.default_rng(seed)
    hidden = Effect("backlash", _HIDDEN_BACKLASH_DEG)
    commands = random_plan(rng, 60)
    trials = measure_trials(commands, (hidden,), _NOISE_DEG, rng)
    result = diagnose(trials)

    out_dir.mkdir(parents=True, exist_ok=True)
    files = [
        write_csv_rows(
            out_dir / "diagnosis_trials.csv",
            trials.rows(),
            ("trial", "commanded_pin_deg", "loaded_bend_deg", "unloaded_bend_deg", "bend_index"),
        ),
        atomic_write_json(out_dir / "diagnosis.json", result.to_dict()),
        atomic_write_bytes(out_dir / "diagnosis_residuals.png", residual_plot_png(result, trials)),
        params_to_json(
            out_dir / "diagnosis_extended_params.json",
            result.extended_params(),
            result.extended_effects(),
        ),
    ]
    fitted = result.params.get("backlash_deg", float("nan"))
    lo, hi = result.intervals.get("backlash_deg", (float("nan"), float("nan")))
    rows = [
        DemoRow(
            "cause named is backlash (1 = yes)",
            float(result.cause.primary == "backlash"),
            1.0,
            "",
            0.0,
        ),
        DemoRow("backlash recovered", fitted, _HIDDEN_BACKLASH_DEG, "deg", 0.05),
        DemoRow("baseline held-out RMSE", result.baseline_rmse_deg, None, "deg"),
        DemoRow(
            "extended held-out RMSE (true: noise)",
            result.extended_rmse_deg,
            _NOISE_DEG,
            "deg",
            0.3 * _NOISE_DEG,
        ),
        DemoRow("held-out RMSE gain", 100.0 * result.gain, None, "%"),
    ]
    notes = [
        f"hidden backlash {_HIDDEN_BACKLASH_DEG} deg, noise {_NOISE_DEG} deg, 60 trials, "
        f"both directions; 95 % interval {lo:.3f} .. {hi:.3f} deg",
        *result.notes,
    ]
    return DemoSection(title="diagnosis", rows=rows, files=[str(f) for f in files], notes=notes)
