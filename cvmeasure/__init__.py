"""cvmeasure: computer-vision metrology and calibration for CNC wire bending.

A camera replaces the protractor: calibrate the lens, measure the plate's plane,
measure pin and bend angles on bender photos and finished parts against their
design, fit the wire's springback, diagnose what the machine model gets wrong,
and write compensated G-code. One verb per job; each takes file paths or
objects already loaded and returns a typed result that :func:`save` writes.

Example
-------
.. code-block:: python

    import cvmeasure

    cal = cvmeasure.calibrate_camera(["view01.jpg", "view02.jpg", ...], "board.json")
    cvmeasure.save("camera.json", cal)
    part = cvmeasure.measure_part(
        "part.jpg", board="board.json", camera="camera.json", design="half-circle.svg",
        options=cvmeasure.PartOptions(wire=cvmeasure.WireOptions(diameter_mm=2.0)),
    )
    print(part.result.radius_mm, part.vertex_bend_deg, part.warnings)
    job = cvmeasure.gcode_for("half-circle.svg", "material.json")
    cvmeasure.save("job.gcode", job)

``docs/examples/`` holds runnable scripts (the tests run them). The jobs:

==========================  ====================================================
``calibrate_camera``        lens from board photos -> :class:`CameraCalibration`
``measure_plane``           the plate's plane from a board photo -> ``PlaneModel``
``measure_bender_photo``    pin and bend angles of a bender photo
``measure_springback``      a loaded/unloaded pair -> a ``Trial``
``measure_part``            a finished part (and against its design); how:
                            ``PartOptions`` (``WireOptions``, ``LiftOptions``)
``fit_material``            trials -> springback compensation (material calibration)
``diagnose_trials``         what the simulation gets wrong on measured trials
``gcode_for``               a design -> compensated G-code job
``correct``                 a measured part corrects the material and the job
``load_*`` / ``save``       every file type (photo, board, camera, plane, kit,
                            design, material, trials, params)
==========================  ====================================================

The names load on first use (PEP 562): the command line imports this package for
``--version``/``--help`` and must not pay for OpenCV, SciPy and every stage then.
"""

from __future__ import annotations

from cvmeasure._lazy import lazy_names

__version__ = "0.1.0"

#: The public API, all defined in :mod:`cvmeasure.api`.
_API = (
    "Cause",
    "CameraCalibration",
    "CorrectedJob",
    "PartOptions",
    "WireOptions",
    "LiftOptions",
    "calibrate_camera",
    "measure_plane",
    "measure_bender_photo",
    "measure_springback",
    "measure_part",
    "fit_material",
    "diagnose_trials",
    "gcode_for",
    "correct",
    "load_photo",
    "load_board",
    "load_camera",
    "load_plane",
    "load_kit",
    "load_design",
    "load_material",
    "load_trials",
    "load_params",
    "save",
)

__all__ = ["__version__", *_API]


__getattr__, __dir__ = lazy_names(__name__, globals(), dict.fromkeys(_API, "cvmeasure.api"))
