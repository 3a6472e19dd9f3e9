"""Finished wire parts measured from a photo and compared with their design (issue 5).

Stages, each a module with pure functions and frozen result types:

* :mod:`~cvmeasure.part.segment` -- the wire's mask on a dark or light sheet;
* :mod:`~cvmeasure.part.centreline` -- its sub-pixel centreline, in board mm;
* :mod:`~cvmeasure.part.fit` -- robust circle and polyline fits (our method);
* :mod:`~cvmeasure.part.seed_methods` -- the seed paper's ellipse and sagitta methods
  and its Source code 1;
* :mod:`~cvmeasure.part.compare` -- registration to the design, deviation profile;
* :mod:`~cvmeasure.part.measure` -- all of it for one photo;
* :mod:`~cvmeasure.part.overlay` -- the pictures.
"""

from __future__ import annotations

__all__: list[str] = []
