"""How a part photo is measured: the options of :func:`cvmeasure.part.measure.measure_part`.

Frozen dataclasses, grouped by what they describe: the wire stock
(:class:`WireOptions`), how its lift off the plate is read (:class:`LiftOptions`),
and the part and the method (:class:`PartOptions`, which holds the other two).
The defaults are ``cvmeasure part``'s: a flat part on the plate, its chord count
found in the photo, the headline values from ``centreline_fit``.

Example
-------
>>> from cvmeasure.part.options import PartOptions, WireOptions
>>> opts = PartOptions(divisions=8, wire=WireOptions(diameter_mm=2.0))
>>> opts.method, opts.lift.shadow, opts.lift.max_lift_mm
('centreline_fit', True, 3.0)
"""

from __future__ import annotations

from dataclasses import dataclass, field

from cvmeasure.method_names import part_method
from cvmeasure.part.ends import EndShape
from cvmeasure.part.lift import MAX_LIFT_MM
from cvmeasure.part.result import METHODS, Method

__all__ = ["LiftOptions", "PartOptions", "WireOptions"]


@dataclass(frozen=True)
class WireOptions:
    """The wire stock as it lies on the plate.

    Attributes
    ----------
    diameter_mm : the wire's diameter (mm). Given, the centreline lies between the
        wire's two silhouette edges (not on a side-lit highlight) and the part's lift
        off the plate is measured or bounded (:class:`LiftOptions`); None: the
        centreline is the wire's centre of symmetry and the lift is not read.
    end_shape : ``"round"`` or ``"flat"`` (cut) wire ends.
    axis_height_mm : the wire axis' height above the board's plane (mm, towards the
        camera); None: the wire's radius with ``diameter_mm``, else 0.
    """

    diameter_mm: float | None = None
    end_shape: EndShape = "round"
    axis_height_mm: float | None = None


@dataclass(frozen=True)
class LiftOptions:
    """How the part's lift off the plate is read (with :attr:`WireOptions.diameter_mm`).

    Attributes
    ----------
    shadow : read the lift from the wire's cast shadow (one photo) and correct the
        part for it when it agrees with the wire width's bound; False: only bound it.
        A second photo of the part slid on the plate, when given, is used instead.
    max_lift_mm : the largest lift a part is taken to rock to (mm) when the lift is
        bounded rather than measured.
    """

    shadow: bool = True
    max_lift_mm: float = MAX_LIFT_MM


@dataclass(frozen=True)
class PartOptions:
    """How a finished part is measured.

    Attributes
    ----------
    divisions : the chord count N the part was bent in; None finds the vertices in the
        photo. Given, a warning says when the photo shows another count.
    method : which method gives the headline values (``result``): ``"centreline_fit"``,
        ``"seed_ellipse"`` or ``"seed_sagitta"`` (all are reported under ``methods``);
        the older names ``"ours"``, ``"ellipse"``, ``"sagitta"`` are read too.
    allow_mirror : a design may be matched mirrored (the part photographed upside
        down); False matches it as it left the machine.
    wire : the wire stock (:class:`WireOptions`).
    lift : the lift off the plate (:class:`LiftOptions`).
    downsample : measure the wire on the photo averaged over blocks of this many pixels
        a side (1, the default: on the photo's own pixels); None: the block that brings a
        wire of known diameter nearest 12 px wide
        (:func:`~cvmeasure.part.downsample.auto_downsample`; 1 without a diameter). For a
        wire many pixels wide: at 0.11 mm/px a 2-3 mm wire spans 18-28 px, and on the
        held-out renderer's photos its polished surface's reflections and its shadow's
        grain gave edges a wire's width apart that are not its silhouette; over 2 x 2
        blocks (9-14 px) the edges are those at the wire's own scale
        (:mod:`cvmeasure.part.downsample`, which says what it costs). The board plane is
        found on the photo itself.

    Raises ValueError on an unknown ``method``, ``divisions < 1`` or ``downsample < 1``.
    """

    divisions: int | None = None
    method: Method = "centreline_fit"
    allow_mirror: bool = True
    wire: WireOptions = field(default_factory=WireOptions)
    lift: LiftOptions = field(default_factory=LiftOptions)
    downsample: int | None = 1

    def __post_init__(self) -> None:
        method = part_method(self.method)
        if method not in METHODS:
            raise ValueError(f"method must be one of {', '.join(METHODS)}; got {self.method!r}")
        if self.divisions is not None and self.divisions < 1:
            raise ValueError(f"divisions must be >= 1, got {self.divisions}")
        ds = self.downsample
        if ds is not None and (int(ds) != ds or ds < 1):
            raise ValueError(f"downsample must be a whole number >= 1, got {self.downsample}")
        object.__setattr__(self, "method", method)  # an older name read as the current one
