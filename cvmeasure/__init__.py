"""cvmeasure: computer-vision metrology and calibration for CNC wire bending.

The library is organised by pipeline stage (see the README's layout section);
the ``cvmeasure`` command is a thin CLI over it.
"""

__version__ = "0.1.0"

__all__ = ["__version__"]
