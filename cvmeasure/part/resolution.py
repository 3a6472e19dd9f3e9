"""The wire's resolution in the photo: pixels per wire radius, warned about or refused.

A part photo resolves the wire's cross-section in a few pixels. Below about 2.5 px per
wire radius (apparent, measured) the centreline can lock onto one flank or onto the cast
shadow along a stretch of the wire: a systematic shift the fit's scatter does not see, so
the vertex bends' sigmas no longer cover their errors (on a light sheet, 1.3 deg off at 5
sigma at 1.9 px per radius). That is warned about (``part_low_resolution``); below
:data:`MIN_PX_PER_RADIUS` the wire is too narrow for a centreline at all and the photo is
refused. The figure is the wire's apparent half-width (its flank at half contrast, as the
centreline measured it) over the plane's scale, so it needs no wire diameter; a stated
diameter is named beside it. ``docs/design/part-measurement.md`` gives the measurement the
thresholds come from.
"""

from __future__ import annotations

from dataclasses import dataclass

from cvmeasure.errors import InputError
from cvmeasure.warning import StageWarning

__all__ = [
    "WARN_PX_PER_RADIUS",
    "MIN_PX_PER_RADIUS",
    "WireResolution",
    "wire_resolution",
    "resolution_warning",
    "resolution_warnings",
]

#: Below this many pixels per wire radius (apparent half-width) the part is warned about
#: (``part_low_resolution``).
WARN_PX_PER_RADIUS = 2.5

#: Below this the photo is refused: the wire is under two pixels wide.
MIN_PX_PER_RADIUS = 1.0


@dataclass(frozen=True)
class WireResolution:
    """How finely a photo resolves the wire.

    Attributes
    ----------
    px_per_radius : the wire's apparent half-width in the photo, pixels.
    mm_per_px : the plane's scale at the part, mm per pixel.
    wire_diameter_mm : the wire's stated diameter (None when not given).
    """

    px_per_radius: float
    mm_per_px: float
    wire_diameter_mm: float | None = None

    @property
    def stated_px_per_radius(self) -> float | None:
        """The stated wire radius over the plane's scale, pixels (None without a diameter)."""
        if self.wire_diameter_mm is None or self.mm_per_px <= 0.0:
            return None
        return 0.5 * self.wire_diameter_mm / self.mm_per_px

    def describe(self) -> str:
        """'1.9 px per wire radius (0.43 mm per px)', with the stated wire's figure if given."""
        text = f"{self.px_per_radius:.1f} px per wire radius ({self.mm_per_px:.3f} mm per px"
        stated = self.stated_px_per_radius
        if stated is not None:
            text += f"; {stated:.1f} px per radius of the {self.wire_diameter_mm:g} mm wire stated"
        return text + ")"


def wire_resolution(
    half_width_px: float, mm_per_px: float, wire_diameter_mm: float | None = None
) -> WireResolution:
    """The wire's resolution from its measured half-width (pixels) and the plane's scale."""
    return WireResolution(float(half_width_px), float(mm_per_px), wire_diameter_mm)


def resolution_warning(resolution: WireResolution, source: str) -> StageWarning | None:
    """The ``part_low_resolution`` warning (or None); raises InputError below the floor.

    ``source`` names the photo in the refusal.
    """
    px = resolution.px_per_radius
    closer = (
        "move the camera closer to the part or photograph it at a higher resolution "
        f"(at least {WARN_PX_PER_RADIUS:g} px per wire radius)"
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
        "one flank or the shadow along a stretch, so the vertex bends (by up to about 1 deg, "
        "beyond their sigmas), bend per chord, arc angle and radius may be off; " + closer,
        source,
    )


def resolution_warnings(
    half_width_px: float, mm_per_px: float, wire_diameter_mm: float | None, source: str
) -> list[StageWarning]:
    """:func:`resolution_warning` of the measured half-width, as a list (empty or one)."""
    warning = resolution_warning(
        wire_resolution(half_width_px, mm_per_px, wire_diameter_mm), source
    )
    return [warning] if warning else []
