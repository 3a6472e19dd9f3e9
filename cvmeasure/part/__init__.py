"""Finished wire parts measured from a photo and compared with their design (issue 5).

Stages, each a module with pure functions and frozen result types:

* :mod:`~cvmeasure.part.segment` -- the wire's mask on a dark or light sheet;
* :mod:`~cvmeasure.part.centreline` -- its sub-pixel centreline, in board mm;
* :mod:`~cvmeasure.part.fit` -- robust circle and polyline fits (our method);
* :mod:`~cvmeasure.part.seed_methods` -- the seed paper's ellipse and sagitta methods
  and its Source code 1;
* :mod:`~cvmeasure.part.compare` -- registration to the design, deviation profile;
* :mod:`~cvmeasure.part.options` -- how a part is measured (:class:`PartOptions`);
* :mod:`~cvmeasure.part.measure` -- all of it for one photo;
* :mod:`~cvmeasure.part.overlay` -- the pictures.
"""

from __future__ import annotations

from cvmeasure.part.compare import deviation_profile, register_to_design
from cvmeasure.part.fit import fit_polyline
from cvmeasure.part.measure import ArcResult, PartMeasurement, measure_part
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
from cvmeasure.part.result import DivisionsSource, PartWire, PlaneSummary
from cvmeasure.part.seed_methods import (
    circle_ellipse_intersections,
    ellipse_method,
    sagitta_method,
    seed_bending_angle,
)

__all__ = [
    "ArcResult",
    "PartMeasurement",
    "PlaneSummary",
    "PartWire",
    "DivisionsSource",
    "measure_part",
    "PartOptions",
    "WireOptions",
    "LiftOptions",
    "fit_polyline",
    "register_to_design",
    "deviation_profile",
    "seed_bending_angle",
    "circle_ellipse_intersections",
    "ellipse_method",
    "sagitta_method",
]
