"""The end points of a wire's centreline: where each cap's outline lies on the axis.

A wire's end is taken as a hemispherical cap (a cut end rounded by handling), so the
brightness beyond the end along the axis repeats the half-profile across the wire; a
round wire measured between silhouette edges ends at its cap's silhouette less the
half-width. An end facing its cast shadow on a light plate states how far inside the
taken outline the true one could lie. Away from silhouette edges the matched cap is read
again from the crest's first fall along the axis, which a low lamp's glint on the cap's
flank does not move; a wire darker than its plate, whose crest has no such fall, from the
rise out of its cap's dark limb.

Where the centres were cut back at an end (their guide, the mask's skeleton, ended in a
branch turning off the wire into the sheet), the wire is followed on from the last centre
kept by its own cross profile (:func:`_follow_end`): the end's line is the followed axis',
and the cap is looked for at the followed reach.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

import numpy as np
from scipy.ndimage import gaussian_filter1d

from cvmeasure.geometry import arclength_mm
from cvmeasure.part.fit import fit_line
from cvmeasure.part.profiles import PROFILE_STEP_PX, sample_image, zero_mean_correlation

__all__ = [
    "INTO_SHADOW_COS",
    "LIMB_DEPTH_SHARE",
    "LIMB_LEVEL_SHARE",
    "LIMB_REACH",
    "SHADOW_STEP_SHARE",
    "SHADOW_DARKER",
    "EndShape",
    "end_point",
]


#: An end whose outward axis is within 60 deg of the shadow's direction faces away from
#: the light (:func:`end_point`).
INTO_SHADOW_COS = 0.5

#: Least strength of a step inside the taken cap edge (share of the strongest) that can be
#: the cap's silhouette where a cast shadow reaches past the cap (:func:`_cap_edge`).
SHADOW_STEP_SHARE = 0.25

#: A stretch along the axis whose darkening below the plate exceeds this many times the
#: wire body's is cast shadow (measured: shadows 1.9-2.4, caps' own stretches <= 0.9).
SHADOW_DARKER = 1.25

#: A cap's dark limb is taken where the axis beyond the crest's fall dips below the plate by
#: more than this share of the crest's height over it (:func:`_dark_limb_outline`; Mitsuba's
#: polished 2 mm caps on cork: 0.3-0.4; the photo lab's caps on the dark sheet: 0.01).
LIMB_DEPTH_SHARE = 0.15

#: On a wire darker than its plate, a cap's dark limb is the rim's: it dips at least as far
#: as this share of the way from the wire's own darkest (its sides' limb) up to the plate
#: (:func:`_limb_outline_on_light_plate`). On a full-size Mitsuba part (3 mm steel on white
#: card) the crest's own ripples dipped to 0.41-0.54 of the way, the paper's grain to 0.71,
#: the caps' limbs to the wire's darkest or below it.
LIMB_LEVEL_SHARE = 0.25

#: A dim wire's end placed by its cap's dark limb replaces the matched one within this many
#: half-widths of it: the flank's match ended a 3 mm wire on white card 0.15 half-widths
#: short (the side lamp shades the cap's flank along the axis unlike the cylinder's across
#: it, while the rim's limb is the same), farther off the dip is another's.
LIMB_REACH = 0.6

#: Least correlation of the photo's cross profile with the wire's own for a followed end
#: to go on (:func:`_follow_profile`): the wire's own profiles correlate 0.85-0.98 with
#: their neighbours' on full-size Mitsuba parts, the sheet's grain and a skeleton's branch
#: crossing the wire -0.7 to 0.5.
FOLLOW_MIN_CORRELATION = 0.6

#: Half-widths either side of the axis compared while following the wire: the wire and its
#: silhouette, little of what lies beside it.
FOLLOW_SPAN = 1.1

#: Half-widths either way across which each step's best match is looked for.
FOLLOW_SHIFT = 0.3

#: Farthest the wire is followed, in half-widths from the end's line's start.
FOLLOW_MAX = 30.0

#: Half-widths the followed axis may drift across the centres' line before its own line is
#: the end's (:func:`_follow_end`).
FOLLOW_DRIFT = 0.5

#: The followed profile runs on past the cylinder into the cap (by up to a half-width): the
#: steps more than this many half-widths inside its reach are the wire's own shading.
FOLLOW_INSIDE = 1.0

#: The cap's outline is looked for up to this many half-widths beyond the followed reach: a
#: low lamp can light the last few millimetres so that the profile there is no longer the
#: wire's (a lit crest 3-4 half-widths long), while the sheet's grain farther out can step
#: like an outline (a full-size Mitsuba part's end 54-72 px out without the bound).
FOLLOW_BEYOND = 5.0

#: A round end read from the crest's first fall (:func:`_crest_fall`) replaces the matched
#: one within this many half-widths of it: the low lamp's glint on the cap pulled the
#: match 0.24-0.38 half-widths out on full-size Mitsuba parts; farther off, the axis fell
#: early (a gap in the crest, a followed end's stray stretch: 1.8-12 half-widths).
GLINT_REACH = 0.6

#: Least height of the crest over the plate, in the noise of the axis' own level, for the
#: crest's fall to place a round end (:func:`_crest_fall`).
CREST_FALL_CONTRAST = 5.0

#: Both profiles are smoothed by this (px, Gaussian sigma) before their fall is read.
FALL_SMOOTH_PX = 1.0

EndShape = Literal["round", "flat"]


def end_point(
    gray: np.ndarray,
    centres: np.ndarray,
    profiles: np.ndarray,
    offsets: np.ndarray,
    rho: float,
    half_width: float,
    *,
    head: bool,
    shape: EndShape = "round",
    silhouette: bool = False,
    shadow: np.ndarray | None = None,
    axis_level: bool = False,
    follow: bool = False,
) -> tuple[np.ndarray, float]:
    """The end point of the wire's axis at one end, pixels, and its uncertainty (px).

    Round ends: the centre of the hemispherical cap. Flat ends: the end face,
    where the brightness along the axis crosses half-way from the crest (the
    median on the axis inside the wire) to the background beyond.

    With ``silhouette`` (centres between the silhouette edges, ``half_width`` half
    the edges' distance), a round end is the cap's silhouette on the axis
    (:func:`_cap_edge`) moved back by the half-width: the cap's outline is the
    same limb as the wire's sides, so the edges' shading bias cancels. The
    brightness along the axis of a side-lit cap (a specular spot, a lit or a
    dark face) does not repeat the profile across the wire, which the match
    below assumes (it stopped 30 px short on the photo lab's 23 px wire).

    ``shadow``: the image direction in which the wire's shadow lies, when seen. An end
    whose axis points into it (within 60 deg) faces away from the light and the shadow of
    a lifted end can reach beyond its cap: the returned uncertainty says how far inside
    the cap's silhouette could lie (:func:`_cap_edge`; 0 elsewhere).

    ``axis_level``: a round end away from silhouette edges is matched on the axis' level
    on the wire before the cap as well as on the flank beyond it (for a polished wire
    measured at its own half-width, whose flank can lie at the plate's level).

    The axis near the end is a robust line through the centres 1.5 to 4.5
    half-widths from the last one (the last centres can be pulled by the
    cap's shadow); the cap is searched along that line.

    ``follow``: the centres at this end were cut back (they ran off the wire); the wire
    is followed on by its profile (:func:`_follow_end`), the end's line moved onto the
    followed axis, and a round cap looked for from ``FOLLOW_INSIDE`` half-widths inside
    the followed reach (not where the end faces its cast shadow, which the profile can
    follow too) up to ``FOLLOW_BEYOND`` half-widths beyond it.
    """
    pts = centres if head else centres[::-1]
    prof = profiles if head else profiles[::-1]
    s = arclength_mm(pts)
    sel = (s >= 1.5 * half_width) & (s <= 4.5 * half_width + 1.0)
    if sel.sum() < 5:
        sel = np.zeros(len(pts), dtype=bool)
        sel[: min(len(pts), 10)] = True
    p0, d, _ = fit_line(pts[sel])
    if d @ (pts[0] - pts[sel][-1]) < 0:
        d = -d  # outward
    first = pts[sel][0]
    start = p0 + ((first - p0) @ d) * d
    # mean cross half-profile in the window, symmetrised, on the flank
    # u in [0.35, 0.9] half-widths: inside the wire (no shadow), away from the
    # narrow specular crest (whose sampled height differs between a ridge and a cap)
    mid = len(offsets) // 2
    k0 = int(round(0.35 * half_width / PROFILE_STEP_PX))
    k1 = max(k0 + 2, int(round(max(rho, 0.9 * half_width) / PROFILE_STEP_PX)))
    block = prof[sel]
    template = _symmetric_half(block, k0, k1)
    if shape == "flat":
        return _flat_end(gray, start, d, block, half_width), 0.0
    normal = np.array([-d[1], d[0]])
    followed = _follow_end(gray, start, d, block, offsets, half_width) if follow else None
    across = 0.0
    reached_centres = float((pts[0] - start) @ d)
    if followed is not None:
        if followed.moved:
            # the end's line is the followed axis': the centres stop short of it
            start, d = followed.start, followed.direction
            normal = np.array([-d[1], d[0]])
            reached_centres = 0.0
        across = followed.across_px
    if silhouette:
        into_shadow = shadow is not None and float(d @ shadow) >= INTO_SHADOW_COS
        # the centres between the silhouette edges reach the last one: the cap lies beyond
        reached, limit = reached_centres, None
        if followed is not None:
            # the followed profile can run on over a cast shadow beyond the cap: not
            # taken as the wire's reach where the end faces its shadow
            if not into_shadow:
                reached = max(reached, followed.reach_px - FOLLOW_INSIDE * half_width)
            if followed.reach_px >= reached_centres:
                limit = followed.reach_px + FOLLOW_BEYOND * half_width + 2.0
        found = _cap_edge(
            gray, start, d, block, half_width, facing_shadow=into_shadow, reached_px=reached,
            limit_px=limit,
        )  # fmt: skip
        if found is not None:
            edge, spread = found
            return start + (edge - half_width) * d + across * normal, spread
    far = 8.0 * half_width + 4.0
    if followed is not None:
        far = max(far, followed.reach_px + 2.0 * half_width + 2.0)
    search = np.arange(
        -round((1.0 * half_width) / PROFILE_STEP_PX), round(far / PROFILE_STEP_PX) + 1
    )
    search = search * PROFILE_STEP_PX
    # with axis_level also the axis' own level on the wire before the cap's centre: a flank
    # near the plate's level matches the bare plate too (a dim wire's cap was read 23 px out
    # on a light plate), the plate never matches the wire behind the cap
    u = np.arange(k0, k1 + 1) * PROFILE_STEP_PX
    if axis_level:
        u = np.concatenate((-u[::-1], u))
        inside = np.full(k1 - k0 + 1, float(np.median(block[:, mid])))
        template = np.concatenate((inside, template))
    samples = sample_image(
        gray, start[None, None, :] + (search[:, None, None] + u[None, :, None]) * d
    )
    costs = np.mean((samples - template[None, :]) ** 2, axis=1)
    k = int(np.argmin(costs))
    if 0 < k < len(costs) - 1:
        c0, c1, c2 = costs[k - 1], costs[k], costs[k + 1]
        den = c0 - 2 * c1 + c2
        frac = 0.5 * (c0 - c2) / den if den > 0 else 0.0
        best = float(search[k] + np.clip(frac, -1, 1) * PROFILE_STEP_PX)
    else:
        best = float(search[k])
    fall = _crest_fall(gray, start, d, block, offsets, half_width, far)
    if fall is not None and abs(fall - best) <= GLINT_REACH * half_width:
        best = fall
    reached = reached_centres
    if followed is not None:
        reached = max(reached, followed.reach_px - FOLLOW_INSIDE * half_width)
    rim = _limb_outline_on_light_plate(gray, start, d, block, half_width, far, reached)
    if rim is not None and abs(rim - half_width - best) <= LIMB_REACH * half_width:
        best = rim - half_width
    return start + best * d + across * normal, 0.0


def _limb_outline_on_light_plate(
    gray: np.ndarray,
    start: np.ndarray,
    d: np.ndarray,
    block: np.ndarray,
    half_width: float,
    far: float,
    reached_px: float,
) -> float | None:
    """Where a wire darker than its plate has its cap's outline along ``start + t d`` (t,
    px), read from the rise out of the cap's dark limb (:func:`_dark_limb_outline`); None
    where the wire is not darker than the plate along its axis, or no limb is seen.

    The crest of such a wire does not stand clear of the plate, so its fall along the axis
    places no end (:func:`_crest_fall`), and the flank's match leans on shading that a side
    lamp gives the cap's flank differently along the axis than the cylinder's across it.
    The rim's limb is the same limb as the sides' (the room mirrored at grazing angles): it
    dips as dark, to within :data:`LIMB_LEVEL_SHARE` of the way from the wire's darkest
    (``block``'s profiles within 1.2 half-widths of the axis) to the plate, which tells it
    from the crest's own ripples and the plate's grain.
    """
    mid = block.shape[1] // 2
    background, plate_spread = _plate(block)
    reach = min(mid, block.shape[1] - 1 - mid, int(round(1.2 * half_width / PROFILE_STEP_PX)))
    darkest = float(_symmetric_half(block, 0, reach).min())
    crest = float(np.median(block[:, mid]))
    if crest >= background - 2.0 * plate_spread or background <= darkest + 4.0 * plate_spread:
        return None
    t = np.arange(0, round(far / PROFILE_STEP_PX) + 1) * PROFILE_STEP_PX
    axial = sample_image(gray, start[None, :] + t[:, None] * d[None, :])

    def plate_inside(t_px: float) -> bool:
        return _plate_inside(gray, start, d, t_px, half_width, background, plate_spread)

    level = darkest + LIMB_LEVEL_SHARE * (background - darkest)
    return _dark_limb_outline(
        axial, t, half_width, background, plate_spread, reached_px, plate_inside, level
    )


def _crest_fall(
    gray: np.ndarray,
    start: np.ndarray,
    d: np.ndarray,
    block: np.ndarray,
    offsets: np.ndarray,
    half_width: float,
    far: float,
) -> float | None:
    """Where the cap's centre lies along ``start + t d`` (t, px) from the crest's fall alone.

    A wire brighter than the plate falls along its axis, past the cap's centre, as it
    falls across from its axis: the cap centre lies where the axis first falls to the
    level half-way between crest and plate, less the distance at which the cross profile
    falls to that level (the median symmetrised profile of ``block``, sampled at
    ``offsets``). Only the crest's first fall is read: a low lamp lights a glint on the
    cap's flank facing it (where its normal bisects lamp and camera, about 0.66 of a
    half-width out for a lamp 8 deg up), which the cylinder's cross profile never shows.
    None where the crest does not stand clear of the plate (a dark or a dim wire) or the
    axis does not fall to that level.
    """
    mid = len(offsets) // 2
    reach = min(mid, len(offsets) - 1 - mid, int(round(1.6 * half_width / PROFILE_STEP_PX)))
    u = np.arange(reach + 1) * PROFILE_STEP_PX
    outer = u >= 1.2 * half_width
    if not outer.any():
        return None
    half = _symmetric_half(block, 0, reach)
    on_axis = block[:, mid]
    crest, plate = float(np.median(on_axis)), float(np.median(half[outer]))
    noise = 1.4826 * float(np.median(np.abs(on_axis - crest)))
    if crest - plate < max(CREST_FALL_CONTRAST * noise, 1.0):
        return None
    level = 0.5 * (crest + plate)
    # both profiles smoothed alike (1 px): the axis' noise, without moving one crossing
    # against the other on a narrow crest
    whole = gaussian_filter1d(np.concatenate((half[:0:-1], half)), FALL_SMOOTH_PX / PROFILE_STEP_PX)
    across = _first_fall(u, whole[reach:], level)
    step = 10 * PROFILE_STEP_PX
    t = np.arange(0.0, far + step, step)
    axial = sample_image(gray, start[None, None, :] + t[:, None, None] * d)[:, 0]
    along = _first_fall(t, gaussian_filter1d(axial, FALL_SMOOTH_PX / step), level)
    return None if across is None or along is None else along - across


def _symmetric_half(block: np.ndarray, k0: int, k1: int) -> np.ndarray:
    """The median over ``block``'s profiles of their half-profile symmetrised about the
    middle sample, from ``k0`` to ``k1`` samples out (both sides' mean)."""
    mid = block.shape[1] // 2
    right = block[:, mid + k0 : mid + k1 + 1]
    left = block[:, mid - k1 : mid - k0 + 1][:, ::-1]
    return np.median(0.5 * (right + left), axis=0)


def _first_fall(t: np.ndarray, values: np.ndarray, level: float) -> float | None:
    """Where ``values`` (sampled at ``t``) first fall below ``level`` (interpolated); None
    when they start below it or never fall below it."""
    below = np.flatnonzero(values < level)
    if not len(below) or below[0] == 0:
        return None
    j = int(below[0])
    return float(
        t[j - 1] + (values[j - 1] - level) / (values[j - 1] - values[j]) * (t[j] - t[j - 1])
    )


@dataclass(frozen=True)
class _Followed:
    """The wire followed on from an end's last centre kept (:func:`_follow_end`).

    ``start + t direction`` is the end's line (px); the wire's profile is seen up to
    ``reach_px`` along it, its axis ``across_px`` to the left of the line there (px,
    along ``(-direction[1], direction[0])``). ``moved``: the line is the followed axis',
    not the centres'.
    """

    start: np.ndarray
    direction: np.ndarray
    reach_px: float
    across_px: float
    moved: bool


def _follow_end(
    gray: np.ndarray,
    start: np.ndarray,
    d: np.ndarray,
    block: np.ndarray,
    offsets: np.ndarray,
    half_width: float,
) -> _Followed | None:
    """The wire followed on from ``start`` along ``d`` by its own cross profile, None when
    not seen there.

    For an end whose centres were cut back (their skeleton's branch turned into the sheet:
    :func:`cvmeasure.part.centreline.measure_centreline`), the wire goes on where its
    profile does. Where the followed axis drifts off the centres' line by over
    ``FOLLOW_DRIFT`` half-widths (at least 2 px; a last chord past a vertex the centres
    did not reach), the line through the followed axis is the end's, followed again.
    """
    found = _follow_profile(gray, start, d, block, offsets, half_width)
    if found is None:
        return None
    moved = False
    for _ in range(3):
        t, lateral = found
        near = t >= t[-1] - 4.0 * half_width
        if near.sum() < 5 or np.abs(lateral[near]).max() <= max(FOLLOW_DRIFT * half_width, 2.0):
            break
        normal = np.array([-d[1], d[0]])
        axis = start + t[near, None] * d + lateral[near, None] * normal
        p0, d1, _ = fit_line(axis)
        d = d1 if d1 @ d >= 0 else -d1
        start = p0 + ((axis[0] - p0) @ d) * d
        moved = True
        again = _follow_profile(gray, start, d, block, offsets, half_width)
        if again is None:
            found = (np.array([float((axis[-1] - start) @ d)]), np.zeros(1))
            break
        found = again
    t, lateral = found
    last = t >= t[-1] - 2.0 * half_width
    return _Followed(start, d, float(t[-1]), float(np.median(lateral[last])), moved)


def _follow_profile(
    gray: np.ndarray,
    start: np.ndarray,
    d: np.ndarray,
    block: np.ndarray,
    offsets: np.ndarray,
    half_width: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """Where along ``start + t d`` the photo shows the wire's cross profile: the steps
    ``t`` (px, every half pixel, ascending) and the axis' offset across the line at each
    (px); None where it is not seen at all.

    The wire's profile is the median of ``block`` (the profiles across the wire near the
    end, at ``offsets``) within ``FOLLOW_SPAN`` half-widths of the axis. At each step the
    photo's profile, averaged over half a half-width along, is matched by correlation
    across ``FOLLOW_SHIFT`` half-widths either way; it is the wire's where the best
    correlation is at least ``FOLLOW_MIN_CORRELATION`` and its contrast within a factor
    of 2 of the wire's (the bare sheet's grain correlates by chance, at a fraction of the
    contrast). The axis moves by at most 0.25 px a step towards the best match. Followed
    until more than a quarter half-width of steps in a row are not the wire's, or to the
    photo's edge.
    """
    span = np.abs(offsets) <= FOLLOW_SPAN * half_width
    every = max(1, int(round(0.25 / PROFILE_STEP_PX)))
    u = offsets[span][::every]
    du = float(u[1] - u[0])
    wire = np.median(block[:, span], axis=0)[::every]
    wire = wire - wire.mean()
    wire_norm = float(np.sqrt(wire @ wire))
    if wire_norm <= 0:
        return None
    reach_k = max(1, int(round(FOLLOW_SHIFT * half_width / du)))
    u_wide = u[0] + du * np.arange(-reach_k, len(u) + reach_k)
    normal = np.array([-d[1], d[0]])
    along = np.linspace(-0.25 * half_width, 0.25 * half_width, 5)
    step = 0.5
    gap = max(1, int(round(0.25 * half_width / step)))
    h, w = gray.shape[:2]
    lateral, misses = 0.0, 0
    seen: list[tuple[float, float]] = []
    for t in np.arange(0.0, FOLLOW_MAX * half_width + 4.0 + step, step):
        pts = start + (t + along)[:, None, None] * d + (lateral + u_wide)[None, :, None] * normal
        if (pts < 0.0).any() or (pts[..., 0] > w - 1.0).any() or (pts[..., 1] > h - 1.0).any():
            break  # the photo's edge: the wire is not seen beyond it
        prof = sample_image(gray, pts).mean(axis=0)
        windows = np.lib.stride_tricks.sliding_window_view(prof, len(u))
        corr, norms = zero_mean_correlation(windows, wire)
        k = int(np.argmax(corr))
        if corr[k] >= FOLLOW_MIN_CORRELATION and 0.5 <= norms[k] / wire_norm <= 2.0:
            seen.append((float(t), lateral))
            lateral += float(np.clip((k - reach_k) * du, -0.25, 0.25))
            misses = 0
        else:
            misses += 1
            if misses > gap:
                break
    if not seen:
        return None
    t_px, lateral_px = np.array(seen).T
    return t_px, lateral_px


def _plate(block: np.ndarray) -> tuple[float, float]:
    """The plate's grey level beside the wire and its own spread (texture and noise, a
    robust sd), from the outer tenths of the profiles across the wire near an end."""
    outer = max(2, block.shape[1] // 10)
    plate = np.concatenate((block[:, :outer], block[:, -outer:]), axis=1).ravel()
    level = float(np.median(plate))
    return level, 1.4826 * float(np.median(np.abs(plate - level)))


def _cap_edge(
    gray: np.ndarray,
    start: np.ndarray,
    d: np.ndarray,
    block: np.ndarray,
    half_width: float,
    *,
    facing_shadow: bool = False,
    reached_px: float = -np.inf,
    limit_px: float | None = None,
) -> tuple[float, float] | None:
    """Distance (px) from ``start`` along ``d`` to a round end's silhouette, None if none,
    and how far inside it a weaker step could be the silhouette instead (px, else 0).

    The silhouette is where the brightness along the axis steps from the wire's towards
    the background's (the profiles' ``block`` across the wire near the end give both
    levels): a peak of that signed gradient (over 0.5 px, refined by a parabola). Of the
    peaks at least half as strong as the strongest, the outermost within two
    half-widths beyond the strongest: a specular spot on the cap has edges of its own
    inside the cap, a shadow's penumbra beyond it is soft, and another object farther
    away is not taken. At an end facing away from the light (``facing_shadow``) on a
    plate brighter than the wire, the shadow's far edge steps like the silhouette and as
    strongly, and may be the outermost peak (13.5 px beyond the cap at a 1.5 mm lift):
    there the uncertainty is how far inside the taken peak the innermost one at least a
    quarter as strong lies (within two half-widths), else 0. Taking the innermost strong
    peak instead was measured wrong as often (a lab render's cap: 0.10 deg per chord).

    ``reached_px``: how far along ``d`` the wire is known to reach (its last centre between
    silhouette edges). Steps inside it are the wire's own shading -- a low lamp's highlight
    rising out of a dark flank on a light plate steps as strongly as the cap's outline
    (a 2 mm wire's end read 5 mm short) -- and are not taken while a step lies beyond it.
    ``limit_px``: the farthest along ``d`` the outline is looked for (px; None: eight
    half-widths and 4 px, the reach before an end was followed, :func:`end_point`).
    """
    mid = block.shape[1] // 2
    k_in = max(1, int(round(0.8 * half_width / PROFILE_STEP_PX)))
    wire = float(np.median(block[:, mid - k_in : mid + k_in + 1]))
    background, plate_spread = _plate(block)
    sign = 1.0 if wire > background else -1.0
    far = 8.0 * half_width + 4.0 if limit_px is None else max(limit_px, 4.0 * PROFILE_STEP_PX)
    t = np.arange(0, round(far / PROFILE_STEP_PX) + 1) * PROFILE_STEP_PX
    axial = sample_image(gray, start[None, :] + t[:, None] * d[None, :])
    grad = -sign * gaussian_filter1d(axial, 0.5 / PROFILE_STEP_PX, order=1)
    inner = grad[1:-1]
    peaks = np.nonzero((inner >= grad[:-2]) & (inner > grad[2:]) & (inner > 0))[0] + 1
    if len(peaks) == 0:
        return None

    def plate_inside(t_px: float) -> bool:
        return _plate_inside(gray, start, d, t_px, half_width, background, plate_spread)

    if not facing_shadow:
        limb = _dark_limb_outline(
            axial, t, half_width, background, plate_spread, reached_px, plate_inside
        )
        if limb is not None:
            return limb, 0.0
    every = peaks  # the walk over a cast shadow below may go back inside
    if np.any(t[peaks] > reached_px):
        peaks = peaks[t[peaks] > reached_px]
    strong = peaks[grad[peaks] >= 0.5 * grad[peaks].max()]
    first = strong[np.argmax(grad[strong])]
    k = int(strong[t[strong] <= t[first] + 2.0 * half_width].max())
    if not facing_shadow:
        k = _inside_off_plate(strong, t, k, first, plate_inside)
    if not facing_shadow and sign < 0:
        # a light plate only: on a dark one the cap's own glow and blur beyond the
        # silhouette are brighter than the plate too (a black card's cap moved 1-2 px out)
        k = _past_lit_wire(axial, t, grad, peaks, k, half_width, background, plate_spread)
    if sign > 0:
        k = _past_dim_limb(axial, t, grad, peaks, k, half_width, background, plate_spread)
    spread = 0.0
    # the shadow's far edge steps like the silhouette, and as strongly, only where the plate
    # is brighter than the wire (a light sheet); on a dark one it is faint beside the wire's
    if facing_shadow and sign < 0:
        weak = every[grad[every] >= SHADOW_STEP_SHARE * grad[peaks].max()]
        # walk in over cast shadow: a stretch inside the taken step darker than the wire's
        # body is plate lit by the ambient light only, not the lamp-lit wire or its cap
        while True:
            inside = weak[(t[weak] < t[k]) & (t[weak] >= t[k] - 2.0 * half_width)]
            if len(inside) == 0:
                break
            j = int(inside.max())
            level = _stretch_level(gray, start, d, t[j], t[k], half_width)
            if background - level <= SHADOW_DARKER * (background - wire):
                break
            k = j
        near = weak[(t[weak] <= t[k]) & (t[weak] >= t[k] - 2.0 * half_width)]
        spread = float(t[k] - t[near].min())
        # the cap's own outline against the shadow may give no rising step at all (its dark
        # limb meets the shadow at about the shadow's level): a stretch inside the taken
        # step as dark as cast shadow and longer than a half-width (a cap's own dark limb
        # lies within one half-width of its outline) has the silhouette somewhere in it
        dark = axial < background - SHADOW_DARKER * (background - wire)
        j = k - 1
        while j >= 0 and dark[j]:
            j -= 1
        run = float(t[k] - t[j + 1]) if j + 1 < k else 0.0
        if run > half_width:
            spread = max(spread, run)
    g0, g1, g2 = grad[k - 1], grad[k], grad[k + 1]
    den = g0 - 2 * g1 + g2
    frac = 0.5 * (g0 - g2) / den if den < 0 else 0.0
    return float(t[k] + np.clip(frac, -0.5, 0.5) * PROFILE_STEP_PX), spread


def _dark_limb_outline(
    axial: np.ndarray,
    t: np.ndarray,
    half_width: float,
    background: float,
    plate_spread: float,
    reached_px: float,
    plate_inside: Callable[[float], bool],
    limb_level: float | None = None,
) -> float | None:
    """The outline of a polished cap ringed by its own dark limb (px along ``t``), else None.

    A polished round end under a lamp is bright at its crest and dark at its rim, where it
    mirrors the dim room at grazing angles: along the axis the brightness falls from the
    crest into a narrow stretch darker than the plate and rises back to the plate at the
    outline. The fall is the strongest step but lies inside the cap (by the limb's width,
    up to a half-width) and the plate's texture beyond can step as strongly as the rise
    (a Mitsuba part's 2 mm caps on cork were read 2.9 px short and 4.2 px long). The same
    limb bounds the wire's sides, whose silhouette edges are taken at the last step before
    the plate (:func:`cvmeasure.part.profiles.outer_edges`); here too: the outline is the
    rise out of a stretch darker than the plate (by more than twice the plate's spread and
    :data:`LIMB_DEPTH_SHARE` of the crest's height over the plate) that starts at a strong
    fall (at least half the strongest's, the innermost that makes one) and ends within a
    half-width of it; with ``limb_level`` (grey), only a stretch dipping to that level.
    None where the axis beyond those falls does not go below the plate
    (a dark plate, a dim cap), or stays dark past a half-width (cast shadow). Not used at an
    end facing its cast shadow, which is dark beyond the cap too (:func:`_cap_edge`).
    """
    step = float(t[1] - t[0])
    g = gaussian_filter1d(axial, 0.5 / step, order=1) / step  # grey per px, outward
    beyond = t > reached_px
    if not beyond.any():
        return None
    # the falls outward with the wire inside them (a fleck or the grain of a light plate
    # beyond the cap falls into a dark stretch and rises out of it too: a lab cap with a dark
    # fleck 1.2 half-widths beyond it was read 12.9 px out), of those at least half as
    # strong as the strongest the innermost that makes an outline: the grain just beyond a
    # cap can fall more steeply than the limb (white paper under a low lamp, 3.5 px past a
    # 3 mm cap: 22 against the limb's 19 grey levels per px; taken, the end read 11 px out)
    strongest = int(np.argmin(np.where(beyond, g, np.inf)))
    mid = g[1:-1]
    falls = np.nonzero((mid <= g[:-2]) & (mid < g[2:]) & (mid < 0) & beyond[1:-1])[0] + 1
    falls = np.array([i for i in falls if not plate_inside(float(t[i]))] or [strongest])
    strong = falls[g[falls] <= 0.5 * g[falls].min()]
    for k in sorted(strong.tolist(), key=lambda i: t[i]):
        outline = _rise_out_of_limb(
            axial, g, t, k, half_width, background, plate_spread, limb_level
        )
        if outline is not None:
            return outline
    return None


def _rise_out_of_limb(
    axial: np.ndarray,
    g: np.ndarray,
    t: np.ndarray,
    k: int,
    half_width: float,
    background: float,
    plate_spread: float,
    limb_level: float | None = None,
) -> float | None:
    """The rise out of the dark limb that the fall at index ``k`` into ``axial`` (grey
    levels at ``t``, px; ``g`` their gradient, grey per px) enters, px along ``t``, else
    None (:func:`_dark_limb_outline`); with ``limb_level``, only a limb dipping to it."""
    step = float(t[1] - t[0])
    win = (t > t[k]) & (t <= t[k] + half_width)
    if g[k] >= 0 or not win.any():
        return None
    m = int(np.nonzero(win)[0][np.argmin(axial[win])])
    depth = background - float(axial[m])
    # the crest the fall starts from, over the plate
    crest = float(axial[(t >= t[k] - half_width) & (t <= t[k])].max()) - background
    if depth <= max(2.0 * plate_spread, LIMB_DEPTH_SHARE * crest):
        return None
    if limb_level is not None and float(axial[m]) > limb_level:
        return None
    rise = (t > t[m]) & (t <= t[k] + half_width)
    if not rise.any():
        return None
    j = int(np.nonzero(rise)[0][np.argmax(g[rise])])
    if g[j] <= 0 or j + 1 >= len(t):
        return None
    # back out of the dark stretch: at least half-way up to the plate within a pixel past it
    after = (t > t[j]) & (t <= t[j] + 1.0)
    if not after.any() or float(axial[after].max()) < float(axial[m]) + 0.5 * depth:
        return None
    g0, g1, g2 = g[j - 1], g[j], g[j + 1]
    den = g0 - 2 * g1 + g2
    frac = 0.5 * (g0 - g2) / den if den < 0 else 0.0
    return float(t[j] + np.clip(frac, -0.5, 0.5) * step)


def _past_lit_wire(
    axial: np.ndarray,
    t: np.ndarray,
    grad: np.ndarray,
    peaks: np.ndarray,
    k: int,
    half_width: float,
    background: float,
    plate_spread: float,
) -> int:
    """The step taken for the cap's silhouette (index ``k`` into ``t``), moved out past lit
    wire: where the axis beyond the taken step is brighter than the plate, that is the wire
    lit by the lamp (a cast shadow is never brighter than the plate it falls on), so the
    silhouette lies farther out, at the next step beyond which the axis is at the plate's
    level. A low lamp facing an end on a light plate lights its last few millimetres to a
    crest brighter than the plate, while the profiles before the end hold the dark flanks
    too: the strongest step was inside that crest and a Mitsuba part's end was read 14 px
    (4 mm) short. Elsewhere (the plate beyond the taken step, as on every photo-lab cap)
    the step is kept. For a plate brighter than the wire's band (``background``), whose
    own spread is ``plate_spread`` (:func:`_plate`).
    """
    span = max(half_width, 1.0)

    def lit_beyond(j: int) -> bool:
        sel = (t > t[j] + 1.0) & (t <= t[j] + 1.0 + span)
        return _above_plate(axial[sel], background, plate_spread)

    if not lit_beyond(k):
        return k
    beyond = peaks[(t[peaks] > t[k]) & (grad[peaks] >= SHADOW_STEP_SHARE * grad[k])]
    for j in beyond:
        if not lit_beyond(int(j)):
            return int(j)
    return k


def _past_dim_limb(
    axial: np.ndarray,
    t: np.ndarray,
    grad: np.ndarray,
    peaks: np.ndarray,
    k: int,
    half_width: float,
    background: float,
    plate_spread: float,
) -> int:
    """The step taken for the cap's silhouette (index ``k`` into ``t``) on a plate darker
    than the wire, moved out past the cap's unlit side: the lamp lights the cap up to a
    terminator, beyond which the cap, lit by the room only, is dimmer than the wire and
    still brighter than the plate, up to its outline. The strongest step is the
    terminator; the outline is the next step out (within a half-width, at least
    ``SHADOW_STEP_SHARE`` as strong) with the axis between them above the plate's level
    (by twice its spread). At 0.11 mm/px a 3 mm wire's dim side spans 5-10 px and its
    ends were read 0.5-1 mm short; a blurred step's glow has no second step beyond it. A
    dim side whose step to the plate is under a quarter of the terminator's is not
    followed (it is not told from the plate's grain).
    """
    reference = grad[k]
    while True:
        beyond = peaks[
            (t[peaks] > t[k])
            & (t[peaks] <= t[k] + half_width)
            & (grad[peaks] >= SHADOW_STEP_SHARE * reference)
        ]
        for j in beyond:
            if _above_plate(axial[(t > t[k] + 1.0) & (t < t[j] - 1.0)], background, plate_spread):
                k = int(j)
                break
        else:
            return k


def _above_plate(stretch: np.ndarray, background: float, plate_spread: float) -> bool:
    """Whether a stretch of the axis' samples (not empty) is brighter than the plate: its
    median above the plate's level ``background`` by twice the plate's own spread."""
    return len(stretch) > 0 and float(np.median(stretch)) > background + 2.0 * plate_spread


def _plate_inside(
    gray: np.ndarray,
    start: np.ndarray,
    d: np.ndarray,
    t_px: float,
    half_width: float,
    background: float,
    plate_spread: float,
) -> bool:
    """Whether the image just inside a step on the axis ``start + t d`` at ``t_px`` is bare
    plate: over a half-width inside it (1 px clear of the step, a blurred step's own foot),
    both the axis' median and the median distance from the plate's level across a half-width
    either side of the axis are within twice the plate's spread. A cap's outline, its dark
    limb and its fall from the crest have the wire inside them; a step with bare plate
    inside is the plate's own grain, a fleck or texture beyond the cap, however strong."""
    span = max(half_width, 1.0)
    ts = np.arange(t_px - 1.0 - span, t_px - 1.0, 0.5)
    if len(ts) == 0:
        return False
    us = np.arange(-span, span + 1e-9, 0.5)
    normal = np.array([-d[1], d[0]])
    pts = start[None, None, :] + ts[:, None, None] * d + us[None, :, None] * normal
    patch = sample_image(gray, pts)
    near = 2.0 * plate_spread
    on_axis = float(np.median(patch[:, len(us) // 2]))
    return (
        abs(on_axis - background) <= near and float(np.median(np.abs(patch - background))) <= near
    )


def _inside_off_plate(
    strong: np.ndarray, t: np.ndarray, k: int, first: int, plate_inside: Callable[[float], bool]
) -> int:
    """The step taken for the cap's silhouette (index ``k`` into ``t``), moved in past steps
    with bare plate inside them (``plate_inside``, :func:`_plate_inside`): a grainy light
    sheet's steps along one line reach half the cap's (a Mitsuba part's end on white paper
    was read 10.6 px, 3 mm, out on such a step). Taken instead: the outermost of the
    ``strong`` steps between the strongest (``first``) and ``k`` with wire inside it; ``k``
    where every one of them has plate inside (no rule can tell then).
    """
    if not plate_inside(float(t[k])):
        return k
    inner = strong[(t[strong] >= t[first]) & (t[strong] < t[k])]
    for j in sorted(inner.tolist(), key=lambda i: -t[i]):
        if not plate_inside(float(t[j])):
            return int(j)
    return k


def _stretch_level(
    gray: np.ndarray, start: np.ndarray, d: np.ndarray, t0: float, t1: float, half_width: float
) -> float:
    """Mean grey level of the stretch of the axis ``start + t d`` between two steps at ``t0``
    and ``t1`` (px; 1.5 px kept clear of each), within a quarter half-width across it."""
    lo, hi = t0 + 1.5, t1 - 1.5
    ts = np.arange(lo, hi + 1e-9, 0.5) if hi > lo else np.array([0.5 * (t0 + t1)])
    us = np.arange(-0.25 * half_width, 0.25 * half_width + 1e-9, 0.5)
    normal = np.array([-d[1], d[0]])
    pts = start[None, None, :] + ts[:, None, None] * d + us[None, :, None] * normal
    return float(np.mean(sample_image(gray, pts)))


def _flat_end(
    gray: np.ndarray, start: np.ndarray, d: np.ndarray, block: np.ndarray, half_width: float
) -> np.ndarray:
    """The end face of a square-cut wire along the axis ``start + t d``, pixels."""
    mid = block.shape[1] // 2
    crest = float(np.median(block[:, mid]))
    background, _ = _plate(block)
    level = 0.5 * (crest + background)
    t = np.arange(
        -round(half_width / PROFILE_STEP_PX), round((8.0 * half_width + 4.0) / PROFILE_STEP_PX) + 1
    )
    t = t * PROFILE_STEP_PX
    axial = sample_image(gray, start[None, :] + t[:, None] * d[None, :])
    sign = 1.0 if crest > background else -1.0
    inside = (axial - level) * sign > 0
    k0 = int(np.argmax(inside))  # first sample inside the wire
    beyond = np.nonzero(~inside[k0:])[0]
    if not inside.any() or len(beyond) == 0:
        return start
    k = k0 + int(beyond[0])  # first sample past the end face
    a, b = axial[k - 1], axial[k]
    frac = (level - a) / (b - a) if b != a else 0.5
    return start + (t[k - 1] + frac * (t[k] - t[k - 1])) * d
