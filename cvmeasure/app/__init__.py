"""The operator's web app (``cvmeasure ui``): pages, an HTTP API, Server-Sent Events, Hops.

Modules: :mod:`.state` (typed server state, events, who controls the machine),
:mod:`.adapter` (every call into the library), :mod:`.rig` (the bench: a port and a camera;
the simulated bench lives in the photo lab, ``cvmeasure_datasets.simrig``), :mod:`.operator`
(connection and set-up checks), :mod:`.material` (the calibration session), :mod:`.bending`
(designs, queue, jobs, inspection), :mod:`.charts`, :mod:`.hops` and :mod:`.server`.
Needs the ``[app]`` extra (FastAPI, uvicorn, Jinja2, python-multipart).
"""
