"""The typed result of a part measurement and its pieces.

:class:`PartMeasurement` is what :func:`cvmeasure.part.measure.measure_part` returns and
``cvmeasure part --json`` prints (``to_dict``); :class:`ArcResult` is one method's arc,
:class:`DesignComparison` the part against its design.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from enum import StrEnum
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from cvmeasure.geometry import CircleFit
from cvmeasure.method_names import PART_METHODS
from cvmeasure.part.arc_uncertainty import ArcUncertainty
from cvmeasure.part.compare import (
    BendComparison,
    Deviation,
    Registration,
)
from cvmeasure.part.fit import (
    ChordCount,
)
from cvmeasure.part.seed_methods import SeedArc
from cvmeasure.warning import StageWarning

if TYPE_CHECKING:
    from cvmeasure.contracts import PlaneModel

__all__ = [
    "Method",
    "METHODS",
    "ArcResult",
    "DesignComparison",
    "DivisionsSource",
    "PlaneSummary",
    "PartWire",
    "LiftUse",
    "LiftSource",
    "PartLift",
    "PartMeasurement",
]


Method = Literal["centreline_fit", "seed_ellipse", "seed_sagitta"]

METHODS: tuple[str, ...] = PART_METHODS


@dataclass(frozen=True)
class ArcResult:
    """The spec's part quantities from one method.

    ``segment_bend_deg`` is ``arc_angle_deg / divisions`` (None without divisions).
    """

    method: str
    radius_mm: float
    chord_width_mm: float
    height_mm: float
    arc_angle_deg: float
    divisions: int | None

    @property
    def segment_bend_deg(self) -> float | None:
        return None if not self.divisions else self.arc_angle_deg / self.divisions

    def to_dict(self) -> dict[str, Any]:
        return {
            "method": self.method,
            "radius_mm": self.radius_mm,
            "chord_width_mm": self.chord_width_mm,
            "height_mm": self.height_mm,
            "arc_angle_deg": self.arc_angle_deg,
            "segment_bend_deg": self.segment_bend_deg,
        }


@dataclass(frozen=True)
class DesignComparison:
    """The part registered to its design and how far it deviates.

    ``bends`` only with divisions: per-vertex bends (design order and sense)
    and the seed's absolute / relative errors of the bend per chord. ``polygon_mm``:
    what the part was compared with (design frame, mm; ndarray (N+1, 2)): the polygon
    bent, or the design's curve without a chord count; ``correct`` bends it again.
    """

    source: str
    registration: Registration
    deviation: Deviation
    design_arc: ArcResult
    bends: BendComparison | None
    polygon_mm: np.ndarray

    def to_dict(self) -> dict[str, Any]:
        return {
            "design": self.source,
            "registration": self.registration.to_dict(),
            "deviation": self.deviation.to_dict(),
            "design_arc": self.design_arc.to_dict(),
            "bends": None if self.bends is None else self.bends.to_dict(),
        }


class DivisionsSource(StrEnum):
    """Where a part's chord count came from.

    ``GIVEN``: the caller's ``divisions`` (``--divisions``); ``PLAN``: the polygon bent
    (the design's or the job's); ``PHOTO``: vertices found on the centreline. The value
    is what ``to_dict`` writes; a smooth curve has no chord count (None).
    """

    GIVEN = "given"
    PLAN = "plan"
    PHOTO = "photo"


@dataclass(frozen=True)
class PlaneSummary:
    """The board plane a part was measured on.

    Attributes
    ----------
    tilt_deg : the plane's tilt from facing the camera, degrees.
    mm_per_px : the plane's scale at the part, mm per pixel.
    rms_px : the board corners' reprojection RMS, pixels.
    corner_count : board corners the plane was fitted to.
    """

    tilt_deg: float
    mm_per_px: float
    rms_px: float
    corner_count: int

    @classmethod
    def of(cls, plane: PlaneModel) -> PlaneSummary:
        """The summary of a :class:`~cvmeasure.plane_model.PlaneModel`."""
        return cls(plane.tilt_deg, plane.mm_per_px, plane.rms_px, plane.corner_count)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class PartWire:
    """How the wire was found: its segmentation and its centreline (pixels).

    Attributes
    ----------
    sheet : ``"dark"`` or ``"light"``: the sheet is darker or lighter than the wire.
    background_level : median grey level around the wire (0-255).
    contrast : median absolute wire - background difference inside the mask.
    threshold : the difference level the mask was cut at.
    width_px : rough wire width (mask area / path length), pixels.
    length_px : the mask's path length, pixels.
    area_px : the mask's area, pixels.
    centre_from : how the centres were placed (``"symmetry"``, ``"silhouette"``, ...).
    edge_width_px : median distance between the silhouette edges, pixels; else None.
    points : centreline points.
    half_width_px : apparent half-width (flank at half contrast), pixels.
    rho_px : the half-window of the symmetric centres, pixels.
    ends_px : the two end points (x, y), pixels.
    rejected : profiles dropped in the last pass.
    coverage : share of profiles with a symmetric centre.
    asymmetry : median remaining profile asymmetry (0 symmetric, about 1 none).
    end_uncertainty_px : how far inside each end a weaker step could be the cap, pixels.

    See :class:`cvmeasure.part.segment.WireMask` and
    :class:`cvmeasure.part.centreline.Centreline`, which this summarises without their
    arrays.
    """

    sheet: str
    background_level: float
    contrast: float
    threshold: float
    width_px: float
    length_px: float
    area_px: int
    centre_from: str
    edge_width_px: float | None
    points: int
    half_width_px: float
    rho_px: float
    ends_px: list[list[float]]
    rejected: int
    coverage: float
    asymmetry: float
    end_uncertainty_px: list[float]

    @classmethod
    def of(cls, mask_summary: dict[str, Any], centreline_summary: dict[str, Any]) -> PartWire:
        """From ``WireMask.to_dict()`` and ``Centreline.to_dict()``."""
        return cls(**mask_summary, **centreline_summary)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class LiftUse(StrEnum):
    """How a part's lift off the plate was used: ``BOUND`` (its effect in the sigmas and
    the ``part_lifted`` warning) or ``CORRECTION`` (the part refitted at the lift read)."""

    BOUND = "bound"
    CORRECTION = "correction"


class LiftSource(StrEnum):
    """Where the lift used came from: the wire's apparent ``WIDTH`` (the bound), its cast
    ``SHADOW`` or a ``MOVED_PHOTO`` of the part slid on the plate (corrections)."""

    WIDTH = "width"
    SHADOW = "shadow"
    MOVED_PHOTO = "moved_photo"


@dataclass(frozen=True)
class PartLift:
    """A part's lift off the plate and what it may change (:mod:`cvmeasure.part.lift_use`).

    Attributes
    ----------
    used : bounded or corrected (:class:`LiftUse`).
    source : where the lift came from (:class:`LiftSource`).
    lift_mm : bounded: the width's estimate (None without one); corrected: the lift
        corrected with (the reading, or the bound it was read above), mm.
    lift_sigma_mm : the estimate's or the reading's standard uncertainty, mm; else None.
    bound_mm : the lift whose worst effect is reported below, mm.
    effect_radius_pct : the bound's worst change of the radius, percent.
    effect_segment_bend_deg : the bound's worst change of the bend per chord, degrees.
    effect_bend_deg : the bound's worst change of a vertex bend, degrees.
    read_lift_mm : corrected: the shadow's or the two photos' own reading, mm; else None.
    details : the reading's own diagnostics as written to JSON (slopes, samples, lamp
        direction, registration residuals; see ``docs/part-measurement.md``).
    moved, shadow : bounded: a second photo's or the shadow's reading that was not used
        (JSON diagnostics, with ``message`` saying why); else None.
    """

    used: LiftUse
    source: LiftSource
    lift_mm: float | None
    lift_sigma_mm: float | None
    bound_mm: float
    effect_radius_pct: float
    effect_segment_bend_deg: float
    effect_bend_deg: float
    read_lift_mm: float | None = None
    details: dict[str, Any] = field(default_factory=dict)
    moved: dict[str, Any] | None = None
    shadow: dict[str, Any] | None = None

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            **self.details,
            "lift_mm": self.lift_mm,
            "lift_sigma_mm": self.lift_sigma_mm,
            "used": self.used.value,
            "source": self.source.value,
            "bound_mm": self.bound_mm,
            "effect_radius_pct": self.effect_radius_pct,
            "effect_segment_bend_deg": self.effect_segment_bend_deg,
            "effect_bend_deg": self.effect_bend_deg,
        }
        if self.read_lift_mm is not None:
            out["read_lift_mm"] = self.read_lift_mm
        if self.moved is not None:
            out["moved"] = self.moved
        if self.shadow is not None:
            out["shadow"] = self.shadow
        return out


@dataclass(frozen=True)
class PartMeasurement:
    """Everything measured on one part photo.

    Attributes
    ----------
    source : the photo.
    result : the headline :class:`ArcResult` (from ``method``).
    methods : the result of every method, by name.
    vertex_bend_deg : ndarray (N-1,) signed bends at the fitted vertices (ours,
        with divisions), counter-clockwise positive in the board frame; else None.
    vertex_bend_sigma_deg : their standard uncertainties (sampling only), degrees.
    vertices_mm : ndarray (N+1, 2) fitted chord vertices, board mm; else None.
    vertices_px : the same vertices in photo pixels.
    centreline_mm : ndarray (M, 2) the wire's centreline, board mm, end to end.
    centreline_px : ndarray (M, 2) the same in photo pixels.
    wire_width_mm : apparent wire width (flanks at half contrast), mm.
    circle : the circle fit behind ``ours``.
    plane : the board plane (:class:`PlaneSummary`).
    wire : how the wire was found (:class:`PartWire`).
    comparison : against the design, when one was given.
    warnings : things a user should know (e.g. arcs too short for a stable radius).
    shape : ``"arc"`` (bends of one sign) or ``"s-curve"`` (a saddle: the bends change
        sign, so radius and arc angle describe no real arc).
    divisions_from : where the chord count came from (:class:`DivisionsSource`), or None
        (none: a smooth curve).
    chords_found : what the vertex search on the centreline found.
    lift : with a wire diameter, the part's lift off the plate and its effect
        (:class:`PartLift`); else None.
    uncertainty : the headline radius' and bend per chord's standard uncertainties with
        what moves every vertex alike (:class:`~cvmeasure.part.arc_uncertainty.ArcUncertainty`:
        the circle's sampling, the plane's scale, the centreline's offset across the wire,
        the end points along it, a corrected lift, the vertices' spacing where
        ``part_chord_spacing`` warns; not a lift only bounded); None for a seed method's
        headline or a straight part.
    downsample : the wire was measured on the photo averaged over blocks of this many
        pixels a side (:attr:`~cvmeasure.part.options.PartOptions.downsample`; 1: the
        photo's own pixels). The pixel figures above are the photo's either way.
    """

    source: str
    result: ArcResult
    methods: dict[str, ArcResult]
    vertex_bend_deg: np.ndarray | None
    vertex_bend_sigma_deg: np.ndarray | None
    vertices_mm: np.ndarray | None
    vertices_px: np.ndarray | None
    centreline_mm: np.ndarray
    centreline_px: np.ndarray
    wire_width_mm: float
    circle: CircleFit
    plane: PlaneSummary
    wire: PartWire
    seed_arcs: dict[str, SeedArc] = field(default_factory=dict)
    comparison: DesignComparison | None = None
    warnings: tuple[StageWarning, ...] = ()
    shape: str = "arc"
    divisions_from: DivisionsSource | None = None
    chords_found: ChordCount | None = None
    lift: PartLift | None = None
    uncertainty: ArcUncertainty | None = None
    downsample: int = 1

    @property
    def radius_sigma_mm(self) -> float | None:
        """One standard uncertainty of the headline radius, mm (see ``uncertainty``)."""
        return None if self.uncertainty is None else self.uncertainty.radius_sigma_mm

    @property
    def segment_bend_sigma_deg(self) -> float | None:
        """One standard uncertainty of the bend per chord, degrees (see ``uncertainty``)."""
        return None if self.uncertainty is None else self.uncertainty.segment_bend_sigma_deg

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"photo": self.source, **self.result.to_dict()}
        out["radius_sigma_mm"] = self.radius_sigma_mm
        out["arc_angle_sigma_deg"] = (
            None if self.uncertainty is None else self.uncertainty.arc_angle_sigma_deg
        )
        out["segment_bend_sigma_deg"] = self.segment_bend_sigma_deg
        out["uncertainty"] = None if self.uncertainty is None else self.uncertainty.to_dict()
        out["divisions"] = self.result.divisions
        out["divisions_from"] = None if self.divisions_from is None else self.divisions_from.value
        out["shape"] = self.shape
        out["chords_found"] = None if self.chords_found is None else self.chords_found.to_dict()
        out["vertex_bend_deg"] = (
            None if self.vertex_bend_deg is None else self.vertex_bend_deg.tolist()
        )
        out["vertex_bend_sigma_deg"] = (
            None if self.vertex_bend_sigma_deg is None else self.vertex_bend_sigma_deg.tolist()
        )
        out["bend_sense"] = "counter-clockwise positive in the board frame (x, y)"
        out["vertices_mm"] = None if self.vertices_mm is None else self.vertices_mm.tolist()
        out["wire_width_mm"] = self.wire_width_mm
        out["circle"] = self.circle.to_dict("mm")
        out["methods"] = {k: v.to_dict() for k, v in self.methods.items()}
        out["seed_arcs"] = {k: v.to_dict() for k, v in self.seed_arcs.items()}
        out["plane"] = self.plane.to_dict()
        out["downsample"] = self.downsample
        out["wire"] = self.wire.to_dict()
        out["centreline_mm"] = self.centreline_mm.tolist()
        # for overlays: the centreline in photo pixels, at most 400 points
        step = max(1, len(self.centreline_px) // 400)
        line_px = np.vstack((self.centreline_px[::step], self.centreline_px[-1:]))
        out["centreline_px"] = np.round(line_px, 2).tolist()
        out["vertices_px"] = (
            None if self.vertices_px is None else np.round(self.vertices_px, 2).tolist()
        )
        out["comparison"] = None if self.comparison is None else self.comparison.to_dict()
        out["lift"] = None if self.lift is None else self.lift.to_dict()
        out["warnings"] = [w.to_json() for w in self.warnings]
        return out
