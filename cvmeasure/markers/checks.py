"""The checks of a marker measurement and the typed warnings they give.

Per disc (:func:`marker_warnings`): hidden, overexposed, unevenly lit, faint or
off-colour. On a plane pose (:func:`plane_warnings`): the discs' sizes on the plane
against the kit's diameters say whether the plane is this photo's and whether the
kit's heights are the markers' (:func:`implied_heights_mm`). Every warning is a
:class:`cvmeasure.warning.StageWarning`; the codes are listed in docs/conventions.md.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from cvmeasure.geometry import CircleFit
from cvmeasure.kit import ROLES, MarkerKit, default_kit
from cvmeasure.markers.colour import WhiteEstimate, bgr8_to_space, kit_colour_model
from cvmeasure.markers.refine import UNEVEN_RING_SPREAD
from cvmeasure.warning import StageWarning

__all__ = [
    "PlaneDisc",
    "anisotropy",
    "colour_delta_e",
    "implied_heights_mm",
    "lateral_ca_estimate",
    "marker_warnings",
    "plane_warnings",
]

#: Warning thresholds of one disc.
HIDDEN_COVERAGE = 0.9
OVEREXPOSED_FRACTION = 0.5
FAR_DELTA_E = 25.0
LOW_CONTRAST = 25.0
#: A ring median channel at or above this (8-bit) counts as clipped: no white to balance on.
RING_CLIPPED_LEVEL = 250.0
#: Markers measured on a plane whose size differs from the kit's by more than this
#: (median over the discs) mean the plane is from another camera pose or distance.
PLANE_SCALE_TOLERANCE = 0.02
#: Discs that come out elliptic on the plane by more than this, all in one direction,
#: mean the plane's tilt is not the photo's. A coarse check: JPEG edges already make
#: round discs read ~0.2 % elliptic, and a plane tilted 3 deg off (0.04 deg of angle
#: error) reads only ~0.3 % (benchmarks: the scale check catches another distance).
PLANE_SHAPE_TOLERANCE = 0.005
#: The discs' heights implied by their sizes differing from the kit's, relative to one
#: another (RMS about their median offset), by more than this (mm) mean the kit's
#: heights are not the markers' (flat stickers measured with a 3D kit, or the reverse),
#: when the other story fits them better by :data:`STORY_MARGIN_MM`; by more than
#: :data:`HEIGHT_OFF_TOLERANCE_MM`, whatever the other story. (The two stories differ by
#: 3.5 mm RMS for the built-in heights; a disc's implied height reads its radius to
#: ``Z / r``: 0.3 % of an 11 px radius is 2.5 mm at 850 mm.)
HEIGHT_SPREAD_TOLERANCE_MM = 2.0
STORY_MARGIN_MM = 1.0
HEIGHT_OFF_TOLERANCE_MM = 5.0


def colour_delta_e(
    kit: MarkerKit, edges: Mapping[str, Any], search_white: Any = None
) -> dict[str, float]:
    """CIE76 difference between each disc's colour, balanced on the rings' white, and the kit's.

    Where the rings are clipped their median is no white (it loses the cast), so
    the white the marker search used (``search_white``) is taken instead.
    """
    rings = np.array([e.ring_bgr for e in edges.values()], dtype=np.float64)
    if not len(rings) or rings.max() <= 0:
        return {}
    b, g, r = np.median(rings, axis=0)
    white = WhiteEstimate((float(r), float(g), float(b)), len(rings), 0.0)
    if search_white is not None and max(r, g, b) >= RING_CLIPPED_LEVEL:
        white = search_white
    discs = np.clip(np.array([e.disc_bgr for e in edges.values()], dtype=np.float64), 0, 255)
    lab = bgr8_to_space(discs, "lab", white)
    model = kit_colour_model(kit, "lab")  # cached: the kit's CIELAB colours
    return {
        role: float(np.linalg.norm(lab[i] - model.means[model.roles.index(role)]))
        for i, role in enumerate(edges)
    }


def lateral_ca_estimate(
    shifts: Mapping[str, Mapping[str, tuple[float, float]]],
    centres_px: Mapping[str, tuple[float, float]],
    shape: tuple[int, ...],
) -> float | None:
    """Lateral chromatic aberration ``k`` from the discs' red and blue edge shifts.

    Red magnified by ``1 + k`` and blue by ``1 - k`` about the image centre shift a
    disc at offset ``v`` (px) from the centre by ``+k v`` in red and ``-k v`` in blue;
    ``k`` is their least-squares fit over all discs (dimensionless; None without data).
    """
    h, w = shape[:2]
    centre = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    num = den = 0.0
    for role, by_channel in shifts.items():
        v = np.asarray(centres_px[role], dtype=np.float64) - centre
        for name, sign in (("red", 1.0), ("blue", -1.0)):
            if name in by_channel:
                num += sign * float(np.dot(by_channel[name], v))
                den += float(v @ v)
    return num / den if den > 0 else None


def anisotropy(offsets: np.ndarray) -> np.ndarray:
    """(cos 2t, sin 2t) components of a closed outline's ellipticity, from its radii.

    The radius about the centre fitted as ``r0 (1 + a cos 2t + b sin 2t)``; returns
    ``2 (a, b)``: 0 for a circle, about (e, 0) for an ellipse with axes a (1 + e) along
    x and a along y. Unlike second moments of the points, it does not read the points'
    uneven spacing round the outline (rays even in the image are uneven on a tilted
    plane: 1 % at 8 deg of tilt) as a shape.
    """
    r = np.hypot(offsets[:, 0], offsets[:, 1])
    t = np.arctan2(offsets[:, 1], offsets[:, 0])
    basis = np.column_stack((np.ones_like(t), np.cos(2 * t), np.sin(2 * t)))
    if len(r) < 3:
        return np.zeros(2)
    sol = np.linalg.lstsq(basis, r, rcond=None)[0]
    return 2.0 * sol[1:] / (sol[0] or 1.0)


def marker_warnings(
    role: str, fit: CircleFit, edges: Any, delta_e: float | None
) -> list[StageWarning]:
    """What is in doubt about one disc's edge: hidden, clipped, shadowed, faint, off-colour."""
    out = []
    if fit.coverage < HIDDEN_COVERAGE:
        out.append(
            StageWarning(
                "marker_hidden",
                f"marker {role!r} partly hidden ({100 * fit.coverage:.0f} % of its edge visible)",
                role,
            )
        )
    if edges.clipped_fraction > OVEREXPOSED_FRACTION:
        out.append(
            StageWarning(
                "marker_overexposed",
                f"marker {role!r} overexposed ({100 * edges.clipped_fraction:.0f} % of its "
                "ring clipped)",
                role,
            )
        )
    if edges.ring_spread >= UNEVEN_RING_SPREAD:
        out.append(
            StageWarning(
                "marker_uneven_light",
                f"marker {role!r} unevenly lit (its ring's level varies by "
                f"{100 * edges.ring_spread:.0f} % of the disc-to-ring step: a shadow or an "
                "object across it?); edges taken against each ray's own levels",
                role,
            )
        )
    if edges.contrast < LOW_CONTRAST:
        out.append(
            StageWarning(
                "marker_low_contrast",
                f"marker {role!r} has low contrast ({edges.contrast:.0f}/255)",
                role,
            )
        )
    if delta_e is not None and delta_e > FAR_DELTA_E:
        out.append(
            StageWarning(
                "marker_colour_far",
                f"marker {role!r} colour far from the kit (Delta E {delta_e:.0f} after white "
                "balance)",
                role,
            )
        )
    return out


@dataclass(frozen=True)
class PlaneDisc:
    """One disc's circle fitted on the plane at its kit height.

    ``radius_mm`` is the fitted radius there, mm; ``shape`` its :func:`anisotropy`
    (None when its edge is partly hidden: a shape would read the cover); ``whole``
    False when its edge is partly hidden or shadowed (its size then reads the cover,
    so the size checks leave it out).
    """

    role: str
    radius_mm: float
    shape: np.ndarray | None = None
    whole: bool = True


def implied_heights_mm(
    discs: Sequence[PlaneDisc], kit: MarkerKit, camera_height_mm: float
) -> dict[str, float]:
    """Each disc's height above the plate (mm) implied by its size on the plane.

    Mapping a disc's edge to the plane at height ``h`` sizes it by ``(Z - h) / (Z - t)``
    for a disc truly at height ``t`` (``Z`` the camera's height above the plate, mm):
    along each pixel's ray, planes at two heights are a homothety about the camera's
    foot point. A disc of the kit's diameter measured ``s`` times that size at the kit's
    height ``h`` therefore stands at ``Z - (Z - h) / s``. The figure holds to the print's
    size tolerance (1 % of a disc's diameter is ~1 % of ``Z``, 8 mm at 850 mm): a check
    of which story the kit tells, not a measurement of the heights.
    """
    z = float(camera_height_mm)
    out = {}
    for d in discs:
        ratio = d.radius_mm / (0.5 * kit.by_role(d.role).diameter_mm)
        out[d.role] = z - (z - kit.height_mm(d.role)) / ratio
    return out


def plane_warnings(
    discs: Sequence[PlaneDisc], kit: MarkerKit, camera_height_mm: float
) -> list[StageWarning]:
    """The plane pose's checks: the kit's heights, the plane's scale and tilt.

    The discs' implied heights (:func:`implied_heights_mm`) differing from the kit's
    *relative to one another* mean the kit's heights are not the markers' (flat
    stickers measured with a 3D kit, caps with a flat kit, caps off their heights);
    all of them off by one amount, i.e. every disc the same size off, mean the
    plane is from another camera distance. Discs all elliptic alike mean another tilt.
    """
    out: list[StageWarning] = []
    sized = [d for d in discs if d.whole]
    if not sized:
        return out
    implied = implied_heights_mm(sized, kit, camera_height_mm)
    offsets = np.array([implied[r] - kit.height_mm(r) for r in implied])
    common = float(np.median(offsets))
    spread = _spread_mm(implied, {r: kit.height_mm(r) for r in implied})
    # the other story (flat stickers for a 3D kit, the built-in heights for a flat one)
    other = _spread_mm(implied, _other_story_mm(kit))
    ratio = float(np.median([d.radius_mm / (0.5 * kit.by_role(d.role).diameter_mm) for d in sized]))
    wrong_story = spread > HEIGHT_SPREAD_TOLERANCE_MM and other < spread - STORY_MARGIN_MM
    # discs tens of mm off the plate (beyond three times any story's tallest cap) are no
    # kit's story, whatever their spread: the plane is from another pose
    tallest = max([kit.height_mm(r) for r in implied] + list(_other_story_mm(kit).values()))
    no_kit_story = abs(common) > HEIGHT_OFF_TOLERANCE_MM + 3.0 * tallest
    kit_off = wrong_story or spread > HEIGHT_OFF_TOLERANCE_MM
    if len(sized) >= 3 and kit_off and not no_kit_story:
        out.append(_kit_heights_warning(implied, kit, other_story=wrong_story))
    elif no_kit_story or abs(ratio - 1.0) > PLANE_SCALE_TOLERANCE:
        out.append(
            StageWarning(
                "plane_scale",
                f"the markers measure {100 * (ratio - 1):+.1f} % in size on the plane against "
                "the kit's diameters: the plane is probably from another camera pose or "
                "distance (measure the plane again from this pose), or every marker stands "
                f"{common:+.0f} mm off the kit's heights ({kit.heights_text()})",
                "plane",
            )
        )
    shapes = [d.shape for d in discs if d.shape is not None]
    if len(shapes) >= 3:
        shape = np.asarray(shapes)
        mean = shape.mean(axis=0)
        se = shape.std(axis=0, ddof=1) / math.sqrt(len(shape))
        size = float(np.hypot(*mean))
        if size > PLANE_SHAPE_TOLERANCE and size > 3.0 * float(np.hypot(*se)):
            out.append(
                StageWarning(
                    "plane_tilt",
                    f"the discs come out {100 * size:.1f} % elliptic on the plane, all alike: "
                    "the plane's tilt is not this photo's (measure the plane again from this "
                    "pose)",
                    "plane",
                )
            )
    return out


def _spread_mm(implied: Mapping[str, float], heights: Mapping[str, float]) -> float:
    """RMS of the implied heights' offsets from ``heights`` about their median, mm: how
    far they are from that story, whatever the common offset (the plane's scale)."""
    off = np.array([implied[r] - heights[r] for r in implied])
    return float(np.sqrt(np.mean((off - np.median(off)) ** 2)))


def _other_story_mm(kit: MarkerKit) -> dict[str, float]:
    """The heights of the other story: flat stickers for a kit with heights, the built-in
    kit's heights for a flat one."""
    if kit.has_heights:
        return {r: 0.0 for r in ROLES}
    built_in = default_kit()
    return {r: built_in.height_mm(r) for r in ROLES}


def _kit_heights_warning(
    implied: Mapping[str, float], kit: MarkerKit, *, other_story: bool
) -> StageWarning:
    """The wrong-kit warning: the heights the discs' sizes imply against the kit's."""
    seen = ", ".join(f"{r} {h:.0f}" for r, h in implied.items())
    if kit.has_heights and other_story:
        hint = (
            "they look like flat stickers on the plate: measure with a flat kit "
            "(--flat-kit, or a kit JSON without height_mm)"
        )
    elif not kit.has_heights and other_story:
        hint = (
            "they stand at heights: use a kit giving each marker's height_mm (the built-in "
            "kit, or measure them with `cvmeasure markers heights`)"
        )
    else:
        hint = (
            "measure the markers' heights (`cvmeasure markers heights`) or correct height_mm "
            "in the kit JSON; a plane from another camera pose can also cause this"
        )
    return StageWarning(
        "kit_heights_mismatch",
        f"the discs' sizes on the plane put them at {seen} mm above the plate but the kit's "
        f"heights are {kit.heights_text()}: the kit does not describe these markers, so the "
        f"angles are off; {hint}",
        "kit",
    )
