"""Demo step of the calibration session: the double with backlash, rendered photos, seed parts."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cvmeasure_datasets.demo.report import DemoRow, DemoSection

__all__ = ["demo_step"]

#: Calibration angles of the demo (wanted loaded angles, deg), both directions.
_ANGLES_DEG = (2.5, 10.0, 45.0)
_BACKLASH_DEG = 0.5
#: The seed paper's parts: (segment bend angle in deg, segments).
_PARTS = {"half circle": (9.0, 20), "saddle": (3.48, 13)}


def demo_step(out_dir: Path, *, seed: int) -> DemoSection:
    """Run a 6-bend session on the TinyG double (0.5 deg backlash) and bend the seed's parts.

    Writes ``session_calibration.json``, ``session_report.html`` and the session
    folder ``session/`` (log, photos, trials CSV) into ``out_dir``.
    """
    from cvmeasure.driver.session import (
        SessionConfig,
        run_session,
    )
    from cvmeasure.driver.session_report import write_session_report
    from cvmeasure.material.bender_calibration import save_calibration
    from cvmeasure.sim import Effect, pin_command_for_angle, simulate
    from cvmeasure.testing.bender import simulated_bender
    from cvmeasure_datasets.simcapture import SimulatedCapture, double_photo_state

    effects = (Effect("backlash", _BACKLASH_DEG),)
    session_dir = Path(out_dir) / "session"
    bender = simulated_bender(effects=effects, speedup=500.0)
    camera = SimulatedCapture(
        session_dir / "photos", lambda: double_photo_state(bender.double), scale=0.2, seed=seed
    )
    try:
        result = run_session(
            bender,
            camera,
            session_dir,
            config=SessionConfig(mode="custom", angles_deg=_ANGLES_DEG),
            name="demo",
        )
    finally:
        bender.close()
    cal = result.calibration
    files = [
        save_calibration(Path(out_dir) / "session_calibration.json", cal),
        write_session_report(
            Path(out_dir) / "session_report.html", cal, result.steps, session_dir=session_dir
        ),
    ]
    pins = [s.commanded_pin_deg for s in cal.samples]
    truth = simulate(pins, effects=effects).springback_deg
    measured = np.array([s.springback_deg for s in cal.samples])
    worst = int(np.argmax(np.abs(measured - truth)))
    rows = [DemoRow("springback, worst of 6 bends", measured[worst], truth[worst], "deg", 0.05)]
    notes = []
    for part, (target, segments) in _PARTS.items():
        final = simulate(np.full(segments, cal.compensate(target)), effects=effects)
        rows.append(
            DemoRow(
                f"{part}: bend of each of {segments}",
                final.unloaded_bend_deg[0],
                target,
                "deg",
                0.1,
            )
        )
        uncalibrated = simulate([pin_command_for_angle(target)], effects=effects)
        notes.append(
            f"seed {part}: without the calibration the nominal model bends "
            f"{uncalibrated.unloaded_bend_deg[0]:.3f} deg (the machine's backlash)"
        )
    notes.insert(
        0,
        f"TinyG double on a pty with {_BACKLASH_DEG} deg backlash, angles "
        f"{', '.join(f'{a:g}' for a in _ANGLES_DEG)} deg both directions, photos rendered at "
        "scale 0.2 and measured; compensation model linear",
    )
    return DemoSection(
        title="calibration session", rows=rows, files=[str(f) for f in files], notes=notes
    )
