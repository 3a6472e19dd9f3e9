"""Marker measurement: bender photos -> signed pin, bend and springback angles (issue 4).

Stages, one module each: :mod:`.colour` (white balance, chromatic adaptation,
colour models), :mod:`.detect` (search on a reduced copy), :mod:`.refine`
(sub-pixel edge points, robust circle fit), :mod:`.angles` (machine frame,
signed angles, uncertainty), :mod:`.measure` (the per-photo pipeline),
:mod:`.seed_baseline` (the seed paper's method), :mod:`.overlay` (a picture).
"""

from __future__ import annotations

from cvmeasure.markers.angles import (
    MachineAngles,
    machine_angles,
    springback_deg,
    springback_sigma_deg,
    to_machine_frame,
)
from cvmeasure.markers.measure import (
    METHODS,
    MachinePhotoResult,
    MarkerMeasurement,
    MarkerNotFoundError,
    measure_machine_photo,
    measure_photo_file,
    measure_trial,
)

__all__ = [
    "MachineAngles",
    "machine_angles",
    "springback_deg",
    "springback_sigma_deg",
    "to_machine_frame",
    "METHODS",
    "MachinePhotoResult",
    "MarkerMeasurement",
    "MarkerNotFoundError",
    "measure_machine_photo",
    "measure_photo_file",
    "measure_trial",
]
