"""``cvmeasure correct``'s summary line: the worst error it quotes is one the photo resolves."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from cvmeasure.cli import main
from cvmeasure.contracts import Trial
from cvmeasure.design import bend_angles_deg
from cvmeasure.driver.session import nominal_pin_for_loaded_deg
from cvmeasure.material.bender_calibration import MODES, fit_calibration, save_calibration
from cvmeasure.sim import simulate
from cvmeasure.warning import StageWarning


def _calibration():
    """The nominal simulated bender's calibration (quick mode, no noise)."""
    pins = [nominal_pin_for_loaded_deg(a, d) for d in ("ccw", "cw") for a in MODES["quick"]]
    r = simulate(pins)
    samples = [
        Trial(str(i), float(p), float(r.loaded_bend_deg[i]), float(r.unloaded_bend_deg[i]))
        for i, p in enumerate(pins)
    ]
    return fit_calibration(samples, model="linear")


#: Machine-frame bend errors (deg) and their stated sigmas of a part whose chord between
#: vertices 3 and 4 the photo did not show: those two bends' sigmas widened to 21 and 18 deg.
ERRORS = np.array([0.3, -0.412, 0.05, 9.887, -4.2, -0.1, 0.2, -0.15, 0.12])
SIGMAS = np.array([0.02, 0.02, 0.02, 21.0, 18.0, 0.05, 0.02, 0.02, 0.02])


def _measured_part(bgr, board, camera, *, design, design_source, source, options, reference_mm):
    """What ``measure_part`` gives for that photo (the polygon it was compared with, its
    bends read ``ERRORS`` off: machine bends are minus the design's turns)."""
    turns = bend_angles_deg(np.asarray(reference_mm, float))
    bends = SimpleNamespace(design_bend_deg=turns, measured_bend_deg=turns - ERRORS)
    registration = SimpleNamespace(mirrored=False, reversed=False)
    gap = StageWarning("part_centreline_gap", "the centreline was lost along chord(s) 4", source)
    return SimpleNamespace(
        comparison=SimpleNamespace(bends=bends, registration=registration, polygon_mm=reference_mm),
        vertex_bend_sigma_deg=SIGMAS,
        warnings=(gap,),
        chords_found=None,
        source=source,
    )


def test_the_summary_names_the_readings_within_their_uncertainty(
    tmp_path, monkeypatch, capsys, arc_svg
):
    """The part's worst error is 9.887 deg at sigma 21 deg, which the correction leaves
    alone within its dead band: the line quotes the worst error beyond its band (0.412
    deg) and names the two wide readings apart, the larger with its vertex and sigma."""
    monkeypatch.setattr("cvmeasure.imageio.read_photo", lambda path: SimpleNamespace(bgr=None))
    monkeypatch.setattr("cvmeasure.board.load_board", lambda path: None)
    monkeypatch.setattr("cvmeasure.camera_model.load_camera", lambda path: None)
    monkeypatch.setattr("cvmeasure.part.measure.measure_part", _measured_part)
    save_calibration(tmp_path / "cal.json", _calibration())
    design = arc_svg(tmp_path / "arc.svg", 55.0, 15.0, 165.0)  # 10 chords, 9 bends of 15 deg
    out, gcode = tmp_path / "cal2.json", tmp_path / "job2.gcode"
    args = ["correct", str(tmp_path / "part.jpg"), "--design", str(design), "--divisions", "10"]
    args += ["--material", str(tmp_path / "cal.json"), "--board", "b.json", "--camera", "c.json"]
    assert main([*args, "-o", str(out), "--gcode", str(gcode)]) == 0
    printed = capsys.readouterr()
    assert printed.out.splitlines() == [
        "9 vertices, worst error 0.412 deg (2 more within their stated uncertainty, up to "
        "9.887 deg at vertex 3, sigma 21.000 deg); 0 curve knot(s) moved; "
        f"wrote {out} and {gcode}"
    ]
    assert "part_centreline_gap" in printed.err
