"""A round wire's end point from its cap's silhouette (pixels, exact synthetic axis)."""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.part.compare import point_to_polyline
from cvmeasure.part.ends import end_point
from cvmeasure.part.profiles import PROFILE_STEP_PX, sample_across

SIZE = (260, 320)  # rows, cols
RADIUS_PX = 4.0  # wire half-width


def _distance_to_axis(axis: np.ndarray) -> np.ndarray:
    """Per pixel: distance to the axis polyline (round caps at its ends)."""
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    _, dist, _ = point_to_polyline(np.column_stack((xs.ravel(), ys.ravel())), axis)
    return np.abs(dist).reshape(SIZE)


def _dim_wire_on_a_light_plate(axis: np.ndarray, glint_px: np.ndarray) -> np.ndarray:
    """A wire darker than its plate (dark limbs, a dim crest), round caps, anti-aliased
    edges, a sharp specular glint on its axis at ``glint_px``, sensor noise."""
    rng = np.random.default_rng(3)
    d = _distance_to_axis(axis)
    t = np.clip(d / RADIUS_PX, 0.0, 1.0)
    wire = 0.5 * (60.0 + 120.0 * np.sqrt(1.0 - t**2) + 80.0 * np.exp(-((t / 0.25) ** 2)))
    alpha = np.clip(RADIUS_PX + 0.5 - d, 0.0, 1.0)
    img = alpha * wire + (1.0 - alpha) * 150.0 + rng.normal(0.0, 1.0, SIZE)
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]]
    r2 = (xs - glint_px[0]) ** 2 + (ys - glint_px[1]) ** 2
    return np.minimum(img + 600.0 * np.exp(-r2 / (2 * 0.6**2)), 255.0).astype(np.float32)


@pytest.mark.parametrize("glint_in_px", [5.0, 8.0])
def test_a_glint_inside_the_wire_is_not_its_cap(glint_in_px):
    """A specular glint rising out of the dim crest steps as strongly as the cap's outline
    against the plate; inside the centres between silhouette edges it is the wire's own
    shading, and the end is its cap's (before: read 10-13 px inside)."""
    axis = np.array([[60.0, 80.0], [160.0, 130.0], [250.0, 120.0]])
    d = (axis[1] - axis[0]) / np.hypot(*(axis[1] - axis[0]))
    img = _dim_wire_on_a_light_plate(axis, axis[0] + glint_in_px * d)
    # centres between the silhouette edges reaching 3 px short of the cap's centre
    centres = axis[0] + np.arange(3.0, 60.0, 1.0)[:, None] * d
    normals = np.tile([-d[1], d[0]], (len(centres), 1))
    reach = round(9.0 / PROFILE_STEP_PX)
    offsets = np.arange(-reach, reach + 1) * PROFILE_STEP_PX
    profiles = sample_across(img, centres, normals, offsets)
    end, spread = end_point(
        img, centres, profiles, offsets, 2.0, RADIUS_PX, head=True, silhouette=True
    )
    assert abs(float((end - axis[0]) @ d)) < 0.1  # along the axis
    assert abs(float((end - axis[0]) @ np.array([-d[1], d[0]]))) < 0.1
    assert spread == 0.0


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_a_flank_at_the_plates_level_does_not_match_the_bare_plate(seed):
    """A wire whose flank (0.35-0.9 half-widths) is at the plate's level -- a narrow bright
    crest, a thin dark limb -- matches the bare plate beyond its cap as well as its cap;
    the axis' level on the wire before the cap tells them apart (before: 5-7 px beyond)."""
    axis = np.array([[60.0, 80.0], [160.0, 130.0], [250.0, 120.0]])
    half_width = 5.0
    rng = np.random.default_rng(seed)
    t = _distance_to_axis(axis) / half_width
    wire = 70.0 * np.exp(-((t / 0.15) ** 2)) - 20.0 * np.exp(-(((t - 1.0) / 0.06) ** 2))
    img = (150.0 + np.where(t < 1.2, wire, 0.0) + rng.normal(0.0, 2.0, SIZE)).astype(np.float32)
    d = (axis[1] - axis[0]) / np.hypot(*(axis[1] - axis[0]))
    centres = axis[0] + np.arange(12.0, 60.0, 1.0)[:, None] * d  # stopping 12 px short
    normals = np.tile([-d[1], d[0]], (len(centres), 1))
    reach = round(12.0 / PROFILE_STEP_PX)
    offsets = np.arange(-reach, reach + 1) * PROFILE_STEP_PX
    profiles = sample_across(img, centres, normals, offsets)
    end, _ = end_point(img, centres, profiles, offsets, 2.0, half_width, head=True, axis_level=True)
    # the synthetic cap's narrow crest and limb do not repeat the flank exactly: 0.4 px
    assert abs(float((end - axis[0]) @ d)) < 0.6


@pytest.mark.parametrize("lit_px", [12.0, 16.0])
def test_a_lit_last_stretch_is_wire_not_plate(lit_px):
    """A low lamp facing an end on a light plate lights the wire's last millimetres to a
    crest brighter than the plate, while the profiles before hold its dark flanks: the
    strongest step along the axis is where that crest begins, inside the wire. Beyond it
    the axis is brighter than the plate (no cast shadow is), so the cap lies farther out
    (before: read ``lit_px`` inside)."""
    axis = np.array([[60.0, 80.0], [160.0, 130.0], [250.0, 120.0]])
    d = (axis[1] - axis[0]) / np.hypot(*(axis[1] - axis[0]))
    img = _dim_wire_on_a_light_plate(axis, np.array([-50.0, -50.0]))
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    rel = np.stack((xs - axis[0][0], ys - axis[0][1]), axis=-1)
    along, across = rel @ d, rel @ np.array([-d[1], d[0]])
    # the crest (the middle 60 % across) lit to above the plate's 150 over the last
    # ``lit_px`` and on the cap, its dark limbs kept
    inside = np.hypot(np.minimum(along, 0.0), across) < 0.6 * RADIUS_PX
    crest = inside & (along < lit_px)
    img = np.where(crest, 250.0, img).astype(np.float32)
    # centres between the silhouette edges only before the lit stretch
    centres = axis[0] + np.arange(lit_px + 2.0, 80.0, 1.0)[:, None] * d
    normals = np.tile([-d[1], d[0]], (len(centres), 1))
    reach = round(9.0 / PROFILE_STEP_PX)
    offsets = np.arange(-reach, reach + 1) * PROFILE_STEP_PX
    profiles = sample_across(img, centres, normals, offsets)
    end, _ = end_point(img, centres, profiles, offsets, 2.0, RADIUS_PX, head=True, silhouette=True)
    assert abs(float((end - axis[0]) @ d)) < 0.5  # along the axis


@pytest.mark.parametrize("dim_side", [True, False])
def test_the_unlit_side_of_a_cap_on_a_dark_plate_is_wire(dim_side):
    """A lamp lights a bright wire's cap up to a terminator; beyond it the cap, lit by the
    room only, is dimmer than the wire and still brighter than the dark plate, up to its
    outline. The strongest step along the axis is the terminator; the end is the outline's
    (at 0.11 mm/px a 3 mm wire's ends were read 0.5-1 mm short). Without a dim side, the
    blurred outline's glow beyond it does not move the end out. (Levels as on a Mitsuba
    render: wire 200, its dim side 85, a black card 31.)"""
    from scipy.ndimage import gaussian_filter

    radius_px = 12.0  # a 3 mm wire at 0.11 mm/px has a 13.6 px half-width
    axis = np.array([[60.0, 80.0], [160.0, 130.0], [250.0, 120.0]])
    d = (axis[1] - axis[0]) / np.hypot(*(axis[1] - axis[0]))
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    along = np.stack((xs - axis[0][0], ys - axis[0][1]), axis=-1) @ d
    wire = np.where(dim_side & (along < -0.45 * radius_px), 85.0, 200.0)
    alpha = np.clip(radius_px + 0.5 - _distance_to_axis(axis), 0.0, 1.0)
    rng = np.random.default_rng(5)
    img = gaussian_filter(alpha * wire + (1.0 - alpha) * 31.0, 1.0)
    img = (img + rng.normal(0.0, 2.0, SIZE)).astype(np.float32)
    centres = axis[0] + np.arange(3.0, 90.0, 1.0)[:, None] * d
    normals = np.tile([-d[1], d[0]], (len(centres), 1))
    reach = round(2.5 * radius_px / PROFILE_STEP_PX)
    offsets = np.arange(-reach, reach + 1) * PROFILE_STEP_PX
    profiles = sample_across(img, centres, normals, offsets)
    end, _ = end_point(img, centres, profiles, offsets, 2.0, radius_px, head=True, silhouette=True)
    assert abs(float((end - axis[0]) @ d)) < 1.0  # along the axis (dim side: was 6.5 px in)


def _bright_wire_with_a_cap_glint(axis, half_width, glint_share, seed):
    """A polished wire brighter than a dark plate (narrow bright crest, dark limbs), round
    caps, and the glint a low lamp beyond the first end lights on that cap's flank:
    ``glint_share`` half-widths out from the cap's centre along the axis."""
    rng = np.random.default_rng(seed)
    t = _distance_to_axis(axis) / half_width
    wire = 40.0 + 210.0 * np.exp(-((t / 0.3) ** 2))
    alpha = np.clip(half_width + 0.5 - t * half_width, 0.0, 1.0)
    d = (axis[0] - axis[1]) / np.hypot(*(axis[1] - axis[0]))  # outward at the first end
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]]
    spot = axis[0] + glint_share * half_width * d
    r2 = (xs - spot[0]) ** 2 + (ys - spot[1]) ** 2
    wire = wire + 120.0 * np.exp(-r2 / (2 * (0.12 * half_width) ** 2))
    img = alpha * wire + (1.0 - alpha) * 30.0 + rng.normal(0.0, 3.0, SIZE)
    return np.clip(img, 0.0, 255.0).astype(np.float32)


@pytest.mark.parametrize(("glint_share", "seed"), [(0.6, 1), (0.66, 2), (0.72, 3)])
def test_a_low_lamps_glint_on_the_cap_does_not_lengthen_the_wire(glint_share, seed, monkeypatch):
    """A lamp 8 deg up beyond a wire's end lights a glint on the cap's flank facing it,
    about 0.66 half-widths out (where the normal bisects lamp and camera), which the cylinder's cross profile never shows: matched
    with that profile the end lies 2-4 px beyond the cap's centre (3 full-size Mitsuba
    parts 3.2-4.8 px, the bend per chord 0.03-0.05 deg off); read from the crest's first
    fall along the axis it lies on it."""
    import cvmeasure.part.ends as ends

    axis = np.array([[60.0, 80.0], [160.0, 130.0], [250.0, 120.0]])
    half_width = 12.0
    img = _bright_wire_with_a_cap_glint(axis, half_width, glint_share, seed)
    d = (axis[1] - axis[0]) / np.hypot(*(axis[1] - axis[0]))
    centres = axis[0] + np.arange(6.0, 90.0, 1.0)[:, None] * d
    normals = np.tile([-d[1], d[0]], (len(centres), 1))
    reach = round(24.0 / PROFILE_STEP_PX)
    offsets = np.arange(-reach, reach + 1) * PROFILE_STEP_PX
    profiles = sample_across(img, centres, normals, offsets)

    def along_px() -> float:
        end, _ = end_point(
            img, centres, profiles, offsets, 3.0, half_width, head=True, axis_level=True
        )
        return float((end - axis[0]) @ -d)  # + beyond the cap's centre

    assert abs(along_px()) < 0.5
    monkeypatch.setattr(ends, "GLINT_REACH", 0.0)  # the profile's match alone
    assert along_px() > 1.5


#: Grey levels along the axis of a path-traced 3 mm polished wire (28 px wide) on white
#: paper under a low lamp, every 0.4 px from 12 px past the line's start: the crest, its
#: fall into the cap's dark limb (to 86), the rise to the paper at the outline (37.8 px
#: from the scene's truth), then the paper's grain, a dip to 146 that falls more steeply
#: than the limb did.
_AXIS_PAST_A_CAP = np.array(
    [150, 148, 150, 156, 156, 150, 143, 137, 136, 136, 135, 135, 136, 139, 143, 146, 151, 159,
     167, 175, 175, 173, 175, 174, 173, 166, 161, 158, 157, 158, 159, 160, 157, 151, 144, 136,
     126, 120, 121, 125, 127, 127, 128, 126, 122, 119, 115, 112, 106, 101, 97, 92, 88, 86, 89,
     92, 95, 99, 103, 109, 114, 120, 123, 121, 122, 126, 134, 147, 162, 175, 184, 188, 189,
     185, 183, 178, 167, 156, 146, 149, 156, 162, 164, 166, 168, 171, 174, 176, 170, 163, 158,
     159, 170, 179, 184, 183, 180, 181, 183, 187, 190, 187, 187, 188, 189, 186, 186, 181, 175,
     170, 166, 167, 171, 173, 172, 170, 170, 172, 173, 178, 183],
    dtype=float,
)  # fmt: skip


def test_the_papers_grain_just_past_a_dark_limbed_cap_is_not_its_outline():
    """The outline of a cap ringed by its dark limb is the rise out of the limb. The fall
    into it was looked for as the strongest fall beyond the wire's reach; here the paper's
    grain 3.5 px past the outline falls more steeply (22 against 19 grey levels per px) and
    its rise out of the dip was taken (the outline 11.1 px out, the wire's end with it, the
    bend per chord 0.05 deg off). Of the falls at least half the strongest's, the innermost
    that makes an outline is taken: within 1.5 px of the truth (measured 1.2 px out)."""
    from cvmeasure.part.ends import _dark_limb_outline

    t = np.arange(0, round(117.0 / PROFILE_STEP_PX) + 1) * PROFILE_STEP_PX
    sampled_at = 12.0 + 0.4 * np.arange(len(_AXIS_PAST_A_CAP))
    axial = np.interp(t, sampled_at, _AXIS_PAST_A_CAP)
    axial[t > sampled_at[-1]] = 175.0  # the paper's level
    outline = _dark_limb_outline(axial, t, 14.11, 175.3, 10.64, 18.2, lambda _: False)
    assert outline is not None
    assert abs(outline - 37.8) < 1.5


#: Grey levels along the end's line of a path-traced 3 mm polished wire (27.5 px wide),
#: darker than the white card it lies on, every 0.4 px from 12 px past the line's start: the
#: dim crest with its ripples (dips to 148-149), its fall into the cap's dark limb (to 91),
#: the rise to the card at the outline (48.5 px from the scene's truth), the card's grain.
_AXIS_OF_A_DIM_WIRE = np.array(
    [176, 177, 177, 178, 180, 184, 182, 183, 185, 184, 178, 170, 160, 157, 157, 161, 160, 163,
     170, 181, 176, 169, 167, 160, 149, 148, 157, 165, 165, 164, 160, 161, 161, 160, 158, 154,
     147, 148, 154, 165, 171, 176, 180, 184, 180, 177, 169, 165, 166, 170, 174, 176, 178, 177,
     171, 165, 159, 160, 160, 157, 151, 145, 140, 137, 136, 136, 136, 133, 124, 119, 119, 117,
     112, 108, 105, 104, 101, 95, 96, 97, 96, 93, 91, 91, 93, 100, 103, 103, 103, 107, 113,
     122, 135, 151, 164, 172, 177, 177, 175, 173, 175, 179, 182, 182, 178, 176, 176, 177, 184,
     190, 196, 201, 204, 205, 204, 200, 196, 196, 199, 201, 201, 200, 197, 191, 187, 185, 184,
     185, 185, 189, 195],
    dtype=float,
)  # fmt: skip


def test_a_dim_wires_cap_is_where_its_limb_dips_as_dark_as_its_sides():
    """A wire darker than its plate: its crest's ripples dip below the card by more than the
    card's spread, as the cap's limb does, and the rise out of the first ripple was taken for
    the outline (20.9 px short). The cap's limb dips as dark as the wire's sides' limb (the
    wire's darkest, 106 here); a dip that stays a quarter of the way up to the card is not it:
    the outline within 0.6 px of the truth (measured 0.5 px out)."""
    from cvmeasure.part.ends import LIMB_LEVEL_SHARE, _dark_limb_outline

    t = np.arange(0, round(64.0 / PROFILE_STEP_PX) + 1) * PROFILE_STEP_PX
    sampled_at = 12.0 + 0.4 * np.arange(len(_AXIS_OF_A_DIM_WIRE))
    axial = np.interp(t, sampled_at, _AXIS_OF_A_DIM_WIRE)
    card, spread, darkest = 183.7, 10.2, 106.3

    def outline(level):
        return _dark_limb_outline(axial, t, 13.75, card, spread, 18.45, lambda _: False, level)

    assert outline(None) < 30.0  # a ripple's rise
    found = outline(darkest + LIMB_LEVEL_SHARE * (card - darkest))
    assert found is not None
    assert abs(found - 48.47) < 0.6
