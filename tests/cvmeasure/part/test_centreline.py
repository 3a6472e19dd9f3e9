"""Sub-pixel centreline on synthetic images with an exact wire axis (pixels)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from cvmeasure.design import arc_points_mm
from cvmeasure.part.centreline import measure_centreline
from cvmeasure.part.compare import point_to_polyline
from cvmeasure.part.profiles import outer_edges, symmetric_centres

SIZE = (260, 320)  # rows, cols
RADIUS_PX = 4.0  # wire half-width


def _distance_to_axis(axis: np.ndarray, *, flat: bool) -> np.ndarray:
    """Per pixel: distance to the axis polyline; with flat ends, inf beyond the end faces."""
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    pts = np.column_stack((xs.ravel(), ys.ravel()))
    _, dist, along = point_to_polyline(pts, axis)
    dist = np.abs(dist)
    if flat:
        total = float(np.sum(np.hypot(*np.diff(axis, axis=0).T)))
        # beyond either end face (projection outside the axis): not wire
        d0 = (axis[1] - axis[0]) / np.hypot(*(axis[1] - axis[0]))
        d1 = (axis[-1] - axis[-2]) / np.hypot(*(axis[-1] - axis[-2]))
        before = (pts - axis[0]) @ d0 < 0
        after = (pts - axis[-1]) @ d1 > 0
        dist = np.where(before | after | (along > total + 1e-9), np.inf, dist)
    return dist.reshape(SIZE)


def _wire_image(axis, *, sheet="light", shadow=True, flat=False, noise=1.0, seed=0):
    """A round wire: shaded across (dark flanks, bright crest), 1 px anti-aliased edge,
    a shadow band beside one flank, sensor noise."""
    rng = np.random.default_rng(seed)
    d = _distance_to_axis(axis, flat=flat)
    t = np.clip(d / RADIUS_PX, 0.0, 1.0)
    wire = 60.0 + 120.0 * np.sqrt(1.0 - t**2) + 80.0 * np.exp(-((t / 0.25) ** 2))
    alpha = np.clip(RADIUS_PX + 0.5 - d, 0.0, 1.0)
    bg = np.full(SIZE, 210.0 if sheet == "light" else 35.0)
    if shadow:  # the axis moved by 1.5 radii to +x, +y, a soft darker band
        ds = _distance_to_axis(axis + 1.5 * RADIUS_PX, flat=flat)
        bg *= 1.0 - 0.35 * np.clip(RADIUS_PX + 1.0 - ds, 0.0, 1.0)
    img = alpha * wire + (1 - alpha) * bg
    return img + rng.normal(0.0, noise, SIZE)


def _rough_path(axis: np.ndarray, offset_px: float) -> np.ndarray:
    """A skeleton-like guide: the axis shifted sideways and shortened at both ends."""
    dense = np.vstack(
        [np.linspace(a, b, 50, endpoint=False) for a, b in zip(axis[:-1], axis[1:], strict=True)]
    )
    return dense[3:-3] + offset_px


@pytest.mark.parametrize(("sheet", "shadow"), [("light", True), ("dark", True), ("light", False)])
def test_centres_lie_on_the_axis_despite_a_shadow(sheet, shadow):
    axis = arc_points_mm((160.0, 330.0), 200.0, 240.0, 60.0, chords=6)  # y from 130 to 157
    img = _wire_image(axis, sheet=sheet, shadow=shadow)
    cl = measure_centreline(img, _rough_path(axis, 1.5), width_guess_px=2.6 * RADIUS_PX)
    _, dist, _ = point_to_polyline(cl.points_px[1:-1], axis)
    # away from the vertices (the capsule corners are not symmetric)
    verts = axis[1:-1]
    far = np.min(np.hypot(*(cl.points_px[1:-1, None, :] - verts[None]).transpose(2, 0, 1)), axis=1)
    sel = far > 3 * RADIUS_PX
    assert np.sqrt(np.mean(dist[sel] ** 2)) < 0.03
    assert np.abs(np.mean(dist[sel])) < 0.02  # no pull towards the shadow
    assert cl.coverage > 0.9 and cl.asymmetry < 0.05


@pytest.mark.parametrize(("flat", "atol_px"), [(False, 0.25), (True, 0.7)])
def test_end_points_for_round_and_flat_ends(flat, atol_px):
    # the flat end face is drawn without anti-aliasing: +-0.5 px of its own
    axis = np.array([[60.0, 80.0], [160.0, 130.0], [250.0, 120.0]])
    img = _wire_image(axis, flat=flat, shadow=False)
    cl = measure_centreline(
        img,
        _rough_path(axis, 0.8),
        width_guess_px=2.2 * RADIUS_PX,
        end_shape="flat" if flat else "round",
    )
    ends = cl.ends_px
    if np.hypot(*(ends[0] - axis[0])) > np.hypot(*(ends[0] - axis[-1])):
        ends = ends[::-1]
    np.testing.assert_allclose(ends, axis[[0, -1]], atol=atol_px)
    # the ends lie on the axis: across it they are much better than along it
    for end, nxt, true in ((ends[0], axis[1], axis[0]), (ends[1], axis[-2], axis[-1])):
        d = (true - nxt) / np.hypot(*(true - nxt))
        assert abs((end - true) @ np.array([-d[1], d[0]])) < 0.1


def test_symmetric_centres_of_shifted_profiles():
    offsets = np.arange(-200, 201) * 0.05
    true_shift = np.array([-0.8, 0.0, 0.37, 1.2])
    prof = np.exp(-(((offsets[None, :] - true_shift[:, None]) / 2.0) ** 2))
    prof[:, offsets > 4.0] += 0.5  # asymmetric surroundings beyond the window
    shift, cost = symmetric_centres(prof, rho_px=2.5, search_px=1.5)
    np.testing.assert_allclose(shift, true_shift, atol=0.01)
    assert np.all(cost < 1e-3)  # off-grid shifts leave a little
    with pytest.raises(ValueError, match="too short"):
        symmetric_centres(prof, rho_px=9.0, search_px=2.0)
    with pytest.raises(ValueError, match="end_shape"):
        measure_centreline(
            np.zeros((10, 10)), np.zeros((3, 2)), width_guess_px=2, end_shape="pointed"
        )  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("width_px", "blur_px"),
    [(5.85, 0.9), (12.0, 0.6), (19.0, 0.6)],  # the photo lab's wire at 1/4, 1/2 and full size
)
def test_outer_edges_of_a_wire_with_a_broad_flat_crest(width_px, blur_px):
    """A highlight's flat crest is inside the wire, and blurred edges' tails widen the
    stretch by about 2 px whatever the width (the photo lab's 3D wire)."""
    from scipy.ndimage import gaussian_filter1d

    offsets = np.arange(-400, 401) * 0.05
    centre_px = 0.3
    # a disc's shading, saturating to a flat crest over 60 % of the width, on a dark plate
    inside = np.clip(1.0 - ((offsets - centre_px) / (0.5 * width_px)) ** 2, 0.0, None)
    profile = 37.0 + 125.0 * np.clip(1.6 * np.sqrt(inside), 0.0, 1.0)
    profile = gaussian_filter1d(profile, blur_px / 0.05)
    noisy = profile[None, :] + np.random.default_rng(14).normal(0.0, 0.7, (40, len(offsets)))
    left, right = outer_edges(noisy, offsets, width_px)
    assert np.isfinite(left).all() and np.isfinite(right).all()
    # the centre between the edges is the axis (a gradient peak sits inside a blurred
    # disc's edge, alike on both sides: the width reads low, the centre does not move)
    np.testing.assert_allclose(0.5 * (left + right), centre_px, atol=0.05)
    assert np.all(np.abs((right - left) / width_px - 1.0) < 0.1)


def test_polished_wire_whose_limbs_mirror_the_sheet_is_centred_by_symmetry():
    """A polished tube's limbs mirror the dark sheet beside them: only its middle stands
    out, so no edge pair lies the wire's width apart; its symmetric profile centres it."""
    axis = arc_points_mm((160.0, 330.0), 200.0, 240.0, 60.0, chords=6)
    rng = np.random.default_rng(5)
    radius_px = 5.0
    t = _distance_to_axis(axis, flat=False) / radius_px
    img = 35.0 + 150.0 * np.exp(-((t / 0.45) ** 2)) + rng.normal(0.0, 1.0, SIZE)
    cl = measure_centreline(
        img, _rough_path(axis, 1.0), width_guess_px=1.2 * radius_px, wire_width_px=2 * radius_px
    )
    assert cl.centre_from.startswith("symmetry (the edges seen are")
    assert cl.coverage > 0.9
    _, dist, _ = point_to_polyline(cl.points_px[1:-1], axis)
    assert np.sqrt(np.mean(dist**2)) < 0.05


def _mirror_tube_on_light_sheet(axis: np.ndarray, radius_px: float, seed: int) -> np.ndarray:
    """A polished tube on a light sheet, lit from one side: each point across it mirrors
    the direction its normal reflects the view to. The limbs mirror the sheet (light), the
    flanks near 40 deg the dark room's horizon (darker on the side away from the lamp), the
    top the light above, so the darkest band, which a mask holds, is one flank's valley."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    pts = np.column_stack((xs.ravel(), ys.ravel()))
    _, signed, _ = point_to_polyline(pts, axis)
    u = signed.reshape(SIZE) / radius_px  # -1 .. 1 across the tube
    theta = np.degrees(np.arcsin(np.clip(u, -1.0, 1.0)))
    elevation = 90.0 - 2.0 * np.abs(theta)  # of the mirrored ray
    room = np.where(u > 0, 65.0, 75.0)  # the room near the horizon, darker away from the lamp
    sky = 160.0 - 6.0 * u  # the light above, brighter towards the lamp
    tube = np.where(elevation < 0.0, 185.0, np.where(elevation < 30.0, room, sky))
    alpha = np.clip(radius_px + 0.5 - np.abs(u) * radius_px, 0.0, 1.0)
    img = alpha * tube + (1.0 - alpha) * 185.0
    return gaussian_filter(img, 0.8) + rng.normal(0.0, 1.5, SIZE)


def test_mirror_tube_on_a_light_sheet_is_centred_across_both_flanks():
    """The mask of a polished tube on a light sheet holds one dark flank (a valley, itself
    symmetric); with the wire's width known the symmetry window spans both flanks."""
    axis = arc_points_mm((160.0, 330.0), 200.0, 240.0, 60.0, chords=6)
    radius_px = 5.4
    img = _mirror_tube_on_light_sheet(axis, radius_px, seed=3)
    # the mask's path along the darker valley, 0.6 of the half-width off the axis
    path = _rough_path(axis, 0.0)
    normals = np.gradient(path, axis=0)[:, ::-1] * np.array([-1.0, 1.0])
    normals /= np.hypot(*normals.T)[:, None]
    _, side, _ = point_to_polyline(path + normals, axis)
    normals *= np.sign(side)[:, None]
    path = path + 0.6 * radius_px * normals
    cl = measure_centreline(img, path, width_guess_px=4.0, wire_width_px=2.0 * radius_px)
    _, dist, _ = point_to_polyline(cl.points_px[1:-1], axis)
    verts = axis[1:-1]
    far = np.min(np.hypot(*(cl.points_px[1:-1, None, :] - verts[None]).transpose(2, 0, 1)), axis=1)
    sel = far > 3 * radius_px
    # the valley's own centre is 3.3 px off the axis
    assert abs(float(np.mean(dist[sel]))) < 0.3
    assert float(np.sqrt(np.mean(dist[sel] ** 2))) < 0.5


def test_polished_wire_end_found_from_a_short_guide():
    """A polished wire's profiles have a half-contrast flank about its narrow middle only; its
    caps are searched at the wire's own half-width, so a guide path that stops three
    half-widths short of each cap (a skeleton of the bright middle) still reaches them."""
    axis = np.array([[50.0, 70.0], [160.0, 130.0], [265.0, 115.0]])
    rng = np.random.default_rng(5)
    radius_px = 5.0
    t = _distance_to_axis(axis, flat=False) / radius_px
    img = 35.0 + 150.0 * np.exp(-((t / 0.45) ** 2)) + rng.normal(0.0, 1.0, SIZE)
    path = _rough_path(axis, 1.0)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(path, axis=0).T))]
    path = path[(s >= 15.0) & (s <= s[-1] - 15.0)]
    cl = measure_centreline(img, path, width_guess_px=1.2 * radius_px, wire_width_px=2 * radius_px)
    assert cl.centre_from.startswith("symmetry")
    ends = cl.ends_px
    if np.hypot(*(ends[0] - axis[0])) > np.hypot(*(ends[0] - axis[-1])):
        ends = ends[::-1]
    # before the caps were searched at the wire's half-width: 18-27 px short
    np.testing.assert_allclose(ends, axis[[0, -1]], atol=0.25)


def test_midpoints_zigzagging_across_the_wire_are_followed_along_it():
    """Pair midpoints jumping 10 px across a 400 px wire every profile (1 px apart) trace a
    path about 10 times its length: the next pass's path follows the wire's axis, as many points
    as its length in steps, in order along it; a centreline noisy by 0.3 px is kept as it
    lies."""
    from cvmeasure.part.centreline import _next_pass_path
    from cvmeasure.part.profiles import resample_path

    x = np.arange(0.0, 400.0, 1.0)
    zigzag = np.column_stack((x, 100.0 + 5.0 * (-1.0) ** np.arange(len(x))))
    path = _next_pass_path(zigzag, smooth_samples=4.0, step_px=1.0)
    assert abs(len(path) - 400) <= 2  # the old resampling: about 4000
    assert np.all(np.diff(path[:, 0]) > 0)
    # within a pixel of the axis beyond the smoothing's reach of the ends (3 sigma)
    assert np.max(np.abs(path[12:-12, 1] - 100.0)) < 1.0
    rng = np.random.default_rng(3)
    noisy = np.column_stack((x, 100.0 + rng.normal(0.0, 0.3, len(x))))
    np.testing.assert_array_equal(
        _next_pass_path(noisy, smooth_samples=4.0, step_px=1.0), resample_path(noisy, 1.0)
    )


def _measured_past_a_branch(seed: int):
    """The axis and the centreline of a wire whose guide starts 3 half-widths short of its
    head and, before it, turns off the wire: 12 half-widths across it."""
    axis = np.array([[70.0, 90.0], [170.0, 135.0], [280.0, 125.0]])
    img = _wire_image(axis, sheet="light", shadow=False, seed=seed)
    path = _rough_path(axis, 0.5)
    s = np.r_[0.0, np.cumsum(np.hypot(*np.diff(path, axis=0).T))]
    path = path[s >= 3 * RADIUS_PX]
    d = (axis[1] - axis[0]) / np.hypot(*(axis[1] - axis[0]))
    branch = path[0] + np.arange(12 * RADIUS_PX, 0.0, -1.0)[:, None] * np.array([-d[1], d[0]])
    cl = measure_centreline(
        img, np.vstack((branch, path)), width_guess_px=2.2 * RADIUS_PX, wire_width_px=2 * RADIUS_PX
    )
    return axis, cl


@pytest.mark.parametrize("seed", [1, 2])
def test_a_guide_turning_off_the_wire_at_its_end_is_cut_and_the_wire_followed(seed):
    """The mask's skeleton can end in a branch turning off the wire into the sheet (a full-
    size Mitsuba part on cork: 90 deg over its last 40 px), and the centres follow it: the
    end was read 60-72 px off, across the wire. The centres unlike the wire's profile at that
    end are cut, and the wire is followed on by its profile to its cap: within 0.1 px
    (measured), asserted within 0.5 px; the other end as without the branch."""
    axis, cl = _measured_past_a_branch(seed)
    head = min(cl.ends_px, key=lambda e: float(np.hypot(*(e - axis[0]))))
    assert float(np.hypot(*(head - axis[0]))) < 0.5
    tail = min(cl.ends_px, key=lambda e: float(np.hypot(*(e - axis[-1]))))
    assert float(np.hypot(*(tail - axis[-1]))) < 0.5


@pytest.mark.parametrize("seed", [1, 2])
def test_the_wire_followed_past_a_guide_turning_off_it_has_its_centres(seed):
    """Where the guide left the wire before an end (a lifted end's shadow parting from it
    pulled the mask's path off a Mitsuba part on cork: no centre along its last 110 px, the
    end chord's direction unmeasured), the followed stretch is measured along the wire's
    own path: no gap over a wire width from either end point (measured 3.5 px; 28-29 px
    before), every centre within 0.3 px of the axis (measured 0.04; 0.7 before)."""
    axis, cl = _measured_past_a_branch(seed)
    steps = np.hypot(*np.diff(cl.points_px, axis=0).T)
    assert steps.max() < 2 * RADIUS_PX
    _, dist, _ = point_to_polyline(cl.points_px[1:-1], axis)
    assert np.abs(dist).max() < 0.3


def _mirror_tube_beside_its_shadow(axis: np.ndarray, radius_px: float, seed: int) -> np.ndarray:
    """A polished tube on a light sheet with its cast shadow beside it on one side: the limbs
    mirror what lies just beside them (the sheet on one side, the shadow on the other, so no
    step marks either silhouette), the flanks near 40 deg the dark room, the top the light
    above. The shadow band is 0.29 radii wide: its outer edge and the far flank's dark band
    (which starts 0.71 radii out, where the mirrored ray meets the horizon) lie the wire's
    width apart and step opposite ways."""
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    _, signed, _ = point_to_polyline(np.column_stack((xs.ravel(), ys.ravel())), axis)
    u = signed.reshape(SIZE) / radius_px  # -1 .. 1 across the tube
    sheet, shadow = 120.0, 85.0
    beside = np.where((u > 1.0) & (u < 1.29), shadow, sheet)
    theta = np.degrees(np.arcsin(np.clip(u, -1.0, 1.0)))
    elevation = 90.0 - 2.0 * np.abs(theta)  # of the mirrored ray
    limb = np.where(u > 0, shadow, sheet)  # the ground just beside each limb
    # the room's dark horizon below 30 deg, the dim ceiling, the lamp's narrow highlight on top
    tube = np.select(
        (elevation < 0.0, elevation < 30.0, elevation < 70.0), (limb, 40.0, 90.0), 250.0
    )
    alpha = np.clip(radius_px + 0.5 - np.abs(u) * radius_px, 0.0, 1.0)
    img = alpha * tube + (1.0 - alpha) * beside
    return gaussian_filter(img, 0.8) + rng.normal(0.0, 1.5, SIZE)


def test_a_polished_tube_beside_its_shadow_on_a_light_sheet_is_centred_on_its_crest():
    """The strongest edge pair the wire's width apart is the shadow's outer edge and the far
    flank's dark band (measured: their midpoints 1.1 px off a 9 px tube's axis; on
    path-traced parts on white card and cork, 1.4-1.7 px, a radius 0.3-0.5 % low). The
    profiles are a round wire's symmetric ones whose centres lie on the crest: those are the
    centres, and the record says why the edges were not used."""
    axis = arc_points_mm((160.0, 330.0), 200.0, 240.0, 60.0, chords=6)
    radius_px = 4.5
    img = _mirror_tube_beside_its_shadow(axis, radius_px, seed=11)
    cl = measure_centreline(
        img, _rough_path(axis, 1.0), width_guess_px=2.0 * radius_px, wire_width_px=2 * radius_px
    )
    assert cl.centre_from.startswith("symmetry (on a light sheet a polished wire's limbs")
    _, dist, _ = point_to_polyline(cl.points_px[1:-1], axis)
    assert abs(float(np.median(dist))) < 0.15
    assert float(np.sqrt(np.mean(dist**2))) < 0.3


#: Grey levels across a path-traced 2 mm polished wire (18.7 px) on black card under a low
#: lamp, every px from -20 to 20 px about its axis: the saturated crest, and 5 px beside it
#: a band the far flank mirrors, 0.45 of the crest's height over the card.
_CREST_AND_BAND = np.array(
    [27, 27, 25, 27, 33, 35, 33, 29, 22, 22, 19, 23, 36, 61, 103, 109, 87, 117, 204, 254, 253,
     246, 212, 145, 80, 37, 24, 19, 20, 21, 22, 25, 30, 35, 35, 32, 31, 32, 30, 29, 31],
    dtype=float,
)  # fmt: skip


@pytest.mark.parametrize("seed", [0, 1])
def test_a_dim_band_beside_a_saturated_crest_is_not_taken_for_the_wire(seed):
    """A polished wire on a dark sheet whose limbs mirror the sheet (its edges lost) and
    whose mask's path runs along the dim band beside its crest: a window sized to the
    narrow crest finds the band symmetric too, and the flat, saturated crest, of little
    variance, lost to it by the asymmetry relative to the variance (measured: the centres
    5.1 px off the axis along the whole wire; on the render, along 2.4 chords, two vertex
    bends 4.6 deg off at 3.4 stated sigma). The passes look across the stated half-width
    and bar levels under most of the crest's height: on the axis within 0.1 px."""
    axis = arc_points_mm((160.0, 330.0), 200.0, 240.0, 60.0, chords=6)
    rng = np.random.default_rng(seed)
    ys, xs = np.mgrid[0 : SIZE[0], 0 : SIZE[1]].astype(np.float64)
    _, signed, _ = point_to_polyline(np.column_stack((xs.ravel(), ys.ravel())), axis)
    img = np.interp(signed.reshape(SIZE), np.arange(-20, 21), _CREST_AND_BAND)
    img += rng.normal(0.0, 2.0, SIZE)
    path = _rough_path(axis, 0.0)
    normals = np.gradient(path, axis=0)[:, ::-1] * np.array([-1.0, 1.0])
    normals /= np.hypot(*normals.T)[:, None]
    _, side, _ = point_to_polyline(path + normals, axis)
    normals *= np.sign(side)[:, None]
    cl = measure_centreline(img, path - 5.0 * normals, width_guess_px=5.0, wire_width_px=12.0)
    assert cl.centre_from.startswith("symmetry")
    _, dist, _ = point_to_polyline(cl.points_px[1:-1], axis)
    assert float(np.max(np.abs(dist))) < 0.5
    assert abs(float(np.mean(dist))) < 0.1


@pytest.mark.parametrize(
    ("offset_radii", "search_px", "taken"), [(0.0, 0.5, True), (0.6, 0.5, False), (0.6, 3.5, True)]
)
def test_symmetric_centres_in_a_flanks_valley_are_not_taken_on_a_light_sheet(
    offset_radii, search_px, taken
):
    """One flank's dark valley is symmetric too (asymmetry measured 0.09 in a window of 0.3
    radii about it, under the round wire's 0.12): symmetric centres that lie in it (3 px off
    a 10.8 px tube's axis) are not taken over the silhouette edges, those on the crest are.
    With the crest just within the search (3.24 px away), the valley-barred search reaches
    it along 70 % of the wire, 7 % of the centres in short runs between, off the crest: those
    are dropped and the rest taken, every one within 0.5 px of the axis (measured 0.23; the
    tube's centres from its axis: 0.47), the valley 3 px away."""
    from cvmeasure.part.centreline import _final_symmetric, _symmetric_on_crest
    from cvmeasure.part.profiles import (
        PROFILE_STEP_PX,
        path_normals,
        resample_path,
        sample_across,
        smooth_path,
    )

    axis = arc_points_mm((160.0, 330.0), 200.0, 240.0, 60.0, chords=6)
    radius_px = 5.4
    img = _mirror_tube_on_light_sheet(axis, radius_px, seed=3).astype(np.float32)
    reach = round(4.0 * radius_px / PROFILE_STEP_PX)
    offsets = np.arange(-reach, reach + 1) * PROFILE_STEP_PX
    path = resample_path(axis, 1.0)
    normals = path_normals(smooth_path(path, 4.0))
    centres = path + offset_radii * radius_px * normals

    def profiles_at(c: np.ndarray, n: np.ndarray) -> np.ndarray:
        return sample_across(img, c, n, offsets)

    last = (centres, normals, profiles_at(centres, normals), 0.3 * radius_px, search_px)
    centres_, normals_, prof, rho, search = last
    found = _final_symmetric(prof, centres_, normals_, rho, search, 1.0, 30, trim_share=0.4)
    _, dist, _ = point_to_polyline(found[0], axis)
    assert found[4] < 0.12  # symmetric either way
    assert abs(float(np.median(dist))) == pytest.approx(offset_radii * radius_px, abs=0.5)
    got = _symmetric_on_crest(img, last, 1.0, 30, path, 2.0 * radius_px)
    assert (got is not None) == taken
    if taken:
        _, dist, _ = point_to_polyline(got[0], axis)
        assert abs(float(np.median(dist))) < 0.2
        assert float(np.max(np.abs(dist))) < 0.5


def test_stray_runs_are_marked_between_the_crests_long_runs_only():
    """Centres every pixel: a long run, 4 stray runs of 3 centres 15 px aside, a long run,
    and short runs past either long one (at the caps, left to the ends' rules): the 12
    stray centres are marked, no other."""
    from cvmeasure.part.centreline import _short_runs

    def run(x0, n, y=0.0):
        return np.column_stack((x0 + np.arange(n, dtype=float), np.full(n, y)))

    strays = [run(110.0 + 10.0 * k, 3, 15.0) for k in range(4)]
    cap_runs = [run(-20.0, 2, 5.0), run(-12.0, 3), run(260.0, 4, -8.0)]
    centres = np.vstack(
        [cap_runs[0], cap_runs[1], run(0.0, 100), *strays, run(150.0, 100), cap_runs[2]]
    )
    stray = _short_runs(centres, 1.0, 9.0)
    assert stray.sum() == 12
    np.testing.assert_array_equal(centres[stray], np.vstack(strays))
    assert not _short_runs(np.vstack([run(0.0, 100), run(150.0, 100)]), 1.0, 9.0).any()
