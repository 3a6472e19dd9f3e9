"""The wire's resolution in the photo: pixels per wire radius, warned about or refused.

A part photo resolves the wire's cross-section in a few pixels. Below about 3 px per wire
radius the centreline can follow one flank, or the cast shadow on a light sheet, along a
stretch of the wire: a systematic shift the fit's scatter does not see, so the vertex
bends' sigmas stop covering their errors (rendered arcs on a light sheet at 2.3 px per
radius: vertex bends 1.3 deg off, 3-5 sigma). That is warned about
(``part_low_resolution``); below :data:`MIN_PX_PER_RADIUS` the wire is too narrow for a
centreline and the photo is refused.

The figure is the wire's radius over the plane's scale: the stated radius when the wire's
diameter is given, else the apparent half-width the centreline measured (its flank at half
contrast) read as a radius. On a dark sheet that half-width is about 0.8 of the radius (the
round wire's shading puts half contrast inside its silhouette); on a light sheet the
shadow joins the wire and it is about the radius or more, so it is taken as it is.
``docs/design/part-measurement.md`` gives the measurement the thresholds come from.
"""

from __future__ import annotations

from dataclasses import dataclass

from cvmeasure.errors import InputError
from cvmeasure.warning import StageWarning

__all__ = [
    "WARN_PX_PER_RADIUS",
    "MIN_PX_PER_RADIUS",
    "HALF_WIDTH_PER_RADIUS",
    "WireResolution",
    "wire_resolution",
    "resolution_warning",
    "resolution_warnings",
    "coarse_line_hint",
]

#: Below this many pixels per wire radius the part is warned about (``part_low_resolution``).
WARN_PX_PER_RADIUS = 3.0

#: Below this the photo is refused: the wire is under two pixels wide.
MIN_PX_PER_RADIUS = 1.0

#: The apparent half-width (half contrast) over the wire's radius, by sheet, where no
#: diameter is given: 0.78-0.79 measured on dark sheets at 0.26-0.64 mm/px; on a light
#: sheet the shadow widens it (1.0-1.05 at 0.26-0.37 mm/px), so it is not scaled up there.
HALF_WIDTH_PER_RADIUS = {"dark": 0.8, "light": 1.0}


@dataclass(frozen=True)
class WireResolution:
    """How finely a photo resolves the wire.

    Attributes
    ----------
    px_per_radius : the wire's radius in the photo, pixels.
    mm_per_px : the plane's scale at the part, mm per pixel.
    stated : True when the radius is the stated wire diameter's half, False when it is
        the measured half-width's (see the module notes).
    """

    px_per_radius: float
    mm_per_px: float
    stated: bool

    def describe(self) -> str:
        """'1.9 px per wire radius (0.43 mm per px, from ...)'."""
        whence = "the wire's stated diameter" if self.stated else "the wire's measured width"
        return (
            f"{self.px_per_radius:.2f} px per wire radius "
            f"({self.mm_per_px:.3f} mm per px, from {whence})"
        )


def wire_resolution(
    half_width_px: float, mm_per_px: float, wire_diameter_mm: float | None, sheet: str
) -> WireResolution:
    """The wire's pixels per radius (see the module notes).

    ``half_width_px``: the centreline's apparent half-width (pixels); ``mm_per_px``: the
    plane's scale; ``wire_diameter_mm``: the stated diameter or None; ``sheet``:
    ``"dark"`` or ``"light"``.
    """
    if wire_diameter_mm is not None and mm_per_px > 0.0:
        return WireResolution(0.5 * float(wire_diameter_mm) / mm_per_px, float(mm_per_px), True)
    per_radius = HALF_WIDTH_PER_RADIUS.get(sheet, 1.0)
    return WireResolution(float(half_width_px) / per_radius, float(mm_per_px), False)


def resolution_warning(resolution: WireResolution, source: str) -> StageWarning | None:
    """The ``part_low_resolution`` warning (or None); raises InputError below the floor.

    ``source`` names the photo (the refusal's file, the warning's subject).
    """
    px = resolution.px_per_radius
    # the scale that would give the threshold for this wire
    needed_mm_per_px = px * resolution.mm_per_px / WARN_PX_PER_RADIUS
    closer = (
        "move the camera closer to the part or photograph it at a higher resolution "
        f"(at least {WARN_PX_PER_RADIUS:g} px per wire radius: about {needed_mm_per_px:.2f} "
        "mm per px or finer)"
    )
    if not px >= MIN_PX_PER_RADIUS:  # NaN refused too
        raise InputError(
            source,
            f"the wire is resolved at only {resolution.describe()}, under the "
            f"{MIN_PX_PER_RADIUS:g} px a centreline needs: {closer}",
        )
    if px >= WARN_PX_PER_RADIUS:
        return None
    return StageWarning(
        "part_low_resolution",
        f"the wire is resolved at only {resolution.describe()}: the centreline can follow "
        "one flank or the shadow along a stretch, so the vertex bends (by a degree or more, "
        "beyond their sigmas), the bend per chord, arc angle and radius may be off; " + closer,
        source,
    )


def resolution_warnings(
    half_width_px: float,
    mm_per_px: float,
    wire_diameter_mm: float | None,
    sheet: str,
    source: str,
) -> list[StageWarning]:
    """:func:`resolution_warning` of :func:`wire_resolution`, as a list (empty or one)."""
    resolution = wire_resolution(half_width_px, mm_per_px, wire_diameter_mm, sheet)
    warning = resolution_warning(resolution, source)
    return [warning] if warning else []


def coarse_line_hint(
    half_width_px: float, mm_per_px: float, sheet: str, wire_diameter_mm: float | None = None
) -> str:
    """A clause for a refused line resolved under the threshold ('' otherwise).

    A coarse photo can lose the wire to its shadow or a flank, so "no wire found" there may
    mean "too few pixels": the clause says so and what to do. With the wire's stated
    diameter its pixels per radius are the diameter's over the plane's scale, not the
    refused line's half-width (a line thinner than the wire is not the wire, whatever the
    photo's resolution).
    """
    resolution = wire_resolution(half_width_px, mm_per_px, wire_diameter_mm, sheet)
    if not resolution.px_per_radius < WARN_PX_PER_RADIUS:
        return ""
    return (
        f"; the line is {resolution.px_per_radius:.1f} px per radius across at "
        f"{mm_per_px:.3f} mm per px: if it is the wire, the photo is too coarse for it (move "
        f"the camera closer or use a higher resolution, {WARN_PX_PER_RADIUS:g} px per wire "
        "radius or more)"
    )
