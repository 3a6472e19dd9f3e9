"""The project's exception and warning hierarchy.

``CvmeasureError`` is the base of everything the library raises on purpose.
``InputError`` means bad input from the user (unreadable file, schema error,
markers not found): the CLI maps it to exit code 2 and prints its one-line
message, which always names the file and the problem.
``DeviceError`` covers the bender and camera; ``DeviceTimeoutError`` is a
deadline that passed (it does not shadow the builtin ``TimeoutError``).
"""

from __future__ import annotations

from os import PathLike

__all__ = [
    "CvmeasureError",
    "InputError",
    "DeviceError",
    "DeviceTimeoutError",
    "CvmeasureWarning",
    "CompensationRangeWarning",
]


class CvmeasureError(Exception):
    """Base class of every error cvmeasure raises on purpose."""


class InputError(CvmeasureError, ValueError):
    """Bad user input. ``str(err)`` is one line: ``<source>: <problem>``.

    Parameters
    ----------
    source : str or path-like
        The file (or other input) that is wrong, e.g. ``photos/img_03.jpg``.
    problem : str
        What is wrong with it, in words a user understands.
    """

    def __init__(self, source: str | PathLike[str], problem: str) -> None:
        self.source = str(source)
        self.problem = " ".join(str(problem).split())
        super().__init__(f"{self.source}: {self.problem}")


class DeviceError(CvmeasureError):
    """The bender or the camera failed (port gone, malformed reply, alarm)."""


class DeviceTimeoutError(DeviceError):
    """A device did not answer before its deadline."""


class CvmeasureWarning(UserWarning):
    """Base class of the warnings cvmeasure emits."""


class CompensationRangeWarning(CvmeasureWarning):
    """A springback curve was evaluated outside its calibrated range (extrapolated or clamped).

    Defined here, below both :mod:`cvmeasure.material.compensation` (which warns it) and
    :mod:`cvmeasure.gcode` (which turns it into a job's typed warning), so neither
    imports the other.
    """
