"""The wire's sub-pixel centreline: symmetric-profile centres across the wire.

A round wire's brightness across it is symmetric about its axis (shading,
specular crest and dark flanks alike), while what lies *beside* it is not: a
cast shadow darkens one side only, which is why a threshold or edge midpoint
is pulled towards the shadow on a light sheet. So each centre is the point
about which the profile across the wire, *within* the wire, is most symmetric:
the shift ``c`` minimising ``sum_u (I(c + u) - I(c - u))^2`` over
``|u| <= rho``, ``rho`` a little less than the wire's half-width, on
profiles sampled every 0.05 px along the normals (bilinear), refined by a
parabola through the cost minimum. Four passes: normals from the skeleton
with a window of most of the wire's rough width (a small window finds false
centres in each dark flank: a local valley is symmetric too), then normals from
the centres found with the window set from the half-width measured about
them; centres that jump from the running median along the wire are dropped. Beside a wire
brighter than its sheet, the last pass looks for the centres only where the profile stands
out above the sheet (a lifted end's shadow parts from the wire as a dark valley, symmetric
too: :func:`_sheet_floor`), and so does every pass where the symmetric centres are the
measurement (no stated width, or its silhouette edges not used), the first across the
whole mask (which holds the shadow too); those passes bar a dimmer band beside the crest as
well (a polished flank mirroring the room: :func:`_crest_level`).
With the wire's expected width known and the wire's band not clearly brighter than the
sheet (white, printed cork), the window is set from that width instead: a polished tube's
limbs mirror the light sheet, so the mask and the half-width measured about it hold only one
flank's dark valley, whose own centre lies off the axis.

Each end of the wire is found the same way along the axis: the wire's end is
taken as a hemispherical cap (as a cut end rounded by handling, and as the
renderer draws it), so the brightness beyond the end point along the axis
repeats the half-profile across the wire; the end point is where the axial
profile best matches the mean cross half-profile.

With the wire's expected width in pixels (from its diameter through the
calibrated plane, :func:`cvmeasure.part.locate.measure_centreline_mm`), the
centres are instead taken between the wire's two **silhouette edges**
(:func:`cvmeasure.part.profiles.silhouette_edges`): the symmetry above holds only for light from
straight above; a light from one side puts the specular highlight on the lit
flank and the symmetric centre follows it (1.4-2.9 px off the axis on a
ray-traced 19 px wire lit from 50 deg elevation). A silhouette edge is a peak of
the profile's gradient; per profile, the pair of peaks whose distance is within
8 % of the expected width, that step one up and one down, with no highlight
beyond either, and whose summed strength is largest is the wire (the highlight's
own edges are closer together, the shadow's outer edge farther out). The stated width is a
prior the photo must agree with: where the profiles are a round wire's symmetric ones, the
first pass looks for each pair near the symmetric centre (``SYMMETRIC_REACH``), about the
width the edges show there (a narrow highlight's far edge and a hard cast shadow's outer
edge are a width apart too, step opposite ways and can outscore the wire's own edges on a
light sheet). But a polished tube's limbs mirror the sheet just beside them (a
ray grazing the limb goes on to the sheet), so on a dark sheet only the lit flank and the
highlight stand out and edges the wire's width apart are found along a minority of it
(the edges found typically 30-40 % narrower on Mitsuba renders of a 3 mm tube, 11 px):
then, where the profiles are a round wire's symmetric ones, their centres are kept
(``centre_from`` says why). On a light sheet the same mirroring hides the silhouette where
the limb meets its own cast shadow, and a pair the width apart forms from the shadow's
outer edge and the far flank's dark band (path-traced 2 mm steel on white card and cork:
1.4-1.7 px towards the shadow along the whole wire, the radius 0.3-0.5 % low): there too,
where the profiles are a round wire's symmetric ones and their centres lie on its crest
along most of it (valleys barred from the search: :func:`_symmetric_on_crest`), those are
the centres. Where the profiles are not symmetric (a lamp a few degrees above the plate
lights one flank only) and single profiles show the pair along too little of the wire (a
grainy sheet), the pairs are looked for again on profiles averaged along a wire width
(``EDGE_AVERAGE_WIDTHS``). The end
points are the caps' silhouettes on the axis less the half-width. Before they are looked
for, an end whose first centres' profiles are not like the wire's nearby (a guide whose
skeleton ends in a branch into the sheet: the centres run off the wire) is cut back to the
first stretch that is, and the wire followed on from there (:mod:`cvmeasure.part.ends`); where
that leaves over two widths of wire without centres (a lifted end's shadow parting from it
led the mask's path away), the centres are measured again along the wire's own path, end to
end. The edges' distance is the wire's apparent width, which
:mod:`cvmeasure.part.lift` reads as the wire's distance from the camera.

The steps live in their own modules: profile sampling and analysis in
:mod:`cvmeasure.part.profiles`, the end points in :mod:`cvmeasure.part.ends`, each chord's
whole cross-profile in :mod:`cvmeasure.part.chord_profiles`; this module runs them.

Frames: input and output in image pixels (OpenCV: x right, y down, pixel
centres at integers). :mod:`cvmeasure.part.measure` maps them to board mm.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.ndimage import gaussian_filter1d, uniform_filter1d
from scipy.spatial import cKDTree

from cvmeasure.part.ends import EndShape, end_point
from cvmeasure.part.profiles import (
    PROFILE_STEP_PX,
    asymmetry_ratio,
    despike,
    edge_gradient,
    half_width_px,
    long_runs,
    majority_filter,
    outer_edges,
    path_length,
    path_normals,
    resample_path,
    sample_across,
    side_levels,
    silhouette_edges,
    smooth_path,
    symmetric_centres,
    zero_mean_correlation,
)

__all__ = ["Centreline", "measure_centreline"]

#: Least correlation of a centre's profile with the wire's nearby for it to be the wire's
#: near an end (:func:`_end_stretches_like`).
LIKE_MIN = 0.6
#: Share of the centres along a wire width from an end's first kept one that must be like
#: the wire's.
LIKE_RUN_SHARE = 0.7
#: Half-widths either side of a centre compared (:func:`_like_the_wire`).
LIKE_SPAN = 1.3
#: Wire widths either side of a centre whose profiles' median is the wire's profile there.
LIKE_WINDOW_WIDTHS = 3.0
#: Wire widths from each end within which centres unlike the wire are dropped.
LIKE_END_WIDTHS = 3.0
#: An end followed on past where the guide left the wire, farther than this many wire widths
#: from the centres kept, is measured again along the followed stretch (:func:`measure_centreline`).
REMEASURE_GAP_WIDTHS = 2.0

#: A pass's edge midpoints tracing a path this many times longer than their smoothed
#: path zigzag across the wire; the next pass follows the smoothed one
#: (:func:`_silhouette_centres`). A centreline that follows the wire, noisy by a pixel
#: every few pixels, is within a few per cent of its smoothed length.
ZIGZAG_LENGTH_RATIO = 1.5

#: How far the first pass of the pair search looks from the mask's path for the pair's
#: midpoint, in wire widths (:func:`_silhouette_centres`).
FIRST_PASS_REACH = 1.0

#: How far the first pass looks for the pair's midpoint from the symmetric centre, in wire
#: widths, where the profiles are a round wire's symmetric ones (:func:`_symmetric_prior`):
#: the photo's own say where the wire lies, which a stated width must agree with. A side
#: light moves the symmetric centre off the axis (0.07-0.15 widths on the photo lab's
#: sheets, more under a lamp a few degrees above the plate, which lights one flank only);
#: a pair of the highlight's far edge and the cast shadow's outer edge lies about 0.65
#: widths off. The reach lies between the two.
SYMMETRIC_REACH = 0.4

#: Least share of the first pass's profiles with a pair about the symmetric centre within
#: twice the tolerance of the stated width for their median width to be the one the pairs
#: are taken about (:func:`_silhouette_centres`): 0.99-1.0 on the photo lab's light sheet
#: (6-11 % wide), 0.68 on a polished tube on a dark sheet (10 % narrow).
WIDTH_SEEN_SHARE = 0.9

#: Smallest half-window of the symmetry test (px): below it a dark flank's own
#: valley is symmetric enough to pass for a centre.
_MIN_RHO_PX = 1.5

#: Least length of the silhouette centreline, as a share of the symmetric one's.
SILHOUETTE_MIN_SHARE = 0.95

#: Remaining asymmetry (see :attr:`Centreline.asymmetry`) above which the symmetric
#: centres are not a wire's (rendered wires lit from above give 0.001-0.08).
SYMMETRIC_WIRE_MAX = 0.12

#: Least length of the silhouette centreline, as a share of the mask path's, when the
#: symmetric centres are not a wire's (the path runs on a little into a joined shadow).
SILHOUETTE_MIN_SHARE_OF_PATH = 0.85

#: Least share of the profiles with a centre between silhouette edges (or from one edge)
#: for those to be used; below it the symmetric centres are, where they are a wire's.
SILHOUETTE_MIN_COVERAGE = 0.5

#: Largest ratio of the wire band's mean level to the sheet's at which the sheet counts as
#: light (:func:`_dark_on_sheet`): path-traced steel gives 0.6-0.95 on white and printed cork,
#: 1.8-3.3 on dark grey and black card.
LIGHT_SHEET_BAND_MAX = 1.25

#: On a light sheet with the wire's width known, the first symmetric pass's half-window
#: in half-widths: both silhouette steps to the sheet inside it (:func:`_symmetric_passes`).
KNOWN_WIDTH_FIRST_RHO = 1.2

#: The later passes' search either way about the first pass's centres, in half-widths:
#: within the axis' basin, short of a flank's valley (about 0.75 half-widths off).
KNOWN_WIDTH_REFINE = 0.3

#: Share of the symmetry window's offsets left out of the final centres' cost, those of
#: largest asymmetry, where a round wire's silhouette edges were not found (a polished
#: wire whose limbs mirror the sheet): a narrow feature on one flank only (a lamp's second
#: glint on its lit flank) then no longer pulls the centre, which the crest and the other
#: flank fix. Only there: where the edges are found they place the centres, and without
#: the wire's width the symmetric centres stay the whole window's.
HIGHLIGHT_TRIM_SHARE = 0.4

#: Length of wire (in wire widths) over which neighbouring cross-profiles are averaged
#: before the silhouette edges are looked for again, where neither the symmetry test nor
#: single profiles' edges say wire (:func:`_silhouette_if_whole`): the wire's edges run on
#: along it, a sheet's grain does not. Path-traced renders under a lamp 8 deg above a white
#: sheet are grainy enough (a tenth of the sheet's level, pixel to pixel) that single
#: profiles had the wire's pair a width apart along under half of a 3 mm wire, and the
#: first pass's wide reach took grain pairs up to a width off the axis (its 84 % of pairs
#: spread +-0.9 widths), from which the later passes' narrow reach lost the wire. A width
#: is well short of a chord (>= 10 mm); on every profile it moved results on photos whose
#: single profiles were enough, so it is only the fallback.
EDGE_AVERAGE_WIDTHS = 1.0

#: Why the silhouette edges found were not used for a polished wire on a light sheet
#: (:attr:`Centreline.edges_refused`).
EDGES_ON_LIGHT_SHEET = (
    "on a light sheet a polished wire's limbs mirror the sheet, so the edges found need not "
    "be its silhouette; its profiles are a round wire's symmetric ones, centred on its crest"
)
#: Widths either side of a symmetric centre whose mean level it must not lie below (a
#: flank's dark valley, not the wire's crest; :func:`_symmetric_on_crest`).
VALLEY_REACH_WIDTHS = 0.25
#: Least share of the profiles with a centre on the crest for those to be taken on a light
#: sheet over the silhouette edges. Path-traced parts on white card and cork: 0.78-0.99; a
#: photo-lab wire lifted 1.5 mm over a light sheet, its crest in reach along a sixth of it:
#: 0.16 (the few centres left were symmetric to 0.002 and passed every other test).
CREST_MIN_COVERAGE = 0.5
#: Shortest run of the crest's centres that follows the crest, in wire widths. Where the
#: crest is out of reach the valley-barred search leaves the profiles without a centre but
#: a few find a symmetric point beside the wire, in runs of 1-5 centres: path-traced steel
#: on white card, 5 % of a wire's centres 8-19 px off along a sixth of it (its edges there
#: 4-6 px off too, 1.6 px towards the shadow along the whole wire), a vertex bend beside them
#: 1.1 deg off at 5 stated sigma, which the closed loop took for the machine's; under 1.3 %
#: between the caps on the light-sheet photos whose crest was followed (up to 3 % counting
#: the caps, where the ends' rules cut them). Those stray centres are dropped: the stretch
#: is left without centres, its chords' directions unmeasured and said so
#: (``part_centreline_gap``), the rest on the crest (that wire's radius 0.05 % off, where the
#: edges' centres put it 0.55 % off).
CREST_RUN_MIN_WIDTHS = 0.5
#: Largest share of the crest's centres in runs shorter than ``CREST_RUN_MIN_WIDTHS``
#: between longer ones (:func:`_short_runs`) for the rest to be taken: more, and the crest is
#: not what the search follows.
STRAY_SHARE_MAX = 0.1
#: Largest share of the symmetric centres in a valley for them to be taken on a light sheet
#: over the silhouette edges. On the path-traced parts on white card and cork at 0.11 mm/px:
#: 0-1.3 % where they followed the axis, 5-12 % where a stretch ran into one flank's valley.
VALLEY_SHARE_MAX = 0.03

#: Least height of a bright wire's symmetric centre over the sheet, as a share of the
#: brightest's within reach (:func:`_crest_level`). Path-traced polished steel on dark and
#: black card: 99 % of each photo's centres at 0.71 or more (most at 0.95-1); a flank's
#: mirrored band beside a saturated crest at 0.45-0.5.
CREST_LEVEL_SHARE = 0.65

#: Relative range of the silhouette edges' distance about the expected width.
PAIR_TOLERANCE = 0.08

#: Share of profiles with a clean edge pair from which the gaps are left open.
PAIRS_ONLY_SHARE = 0.6

#: A gap in the clean pairs at least this many wire widths long is filled by one edge
#: even where pairs cover most of the wire (a chord without a centre has no line).
LONG_GAP_WIDTHS = 3.0


@dataclass(frozen=True)
class Centreline:
    """A wire centreline in image pixels.

    Attributes
    ----------
    points_px : ndarray (M, 2); ordered centres from one end point to the
        other, both end points included (x, y), pixels.
    half_width_px : the wire's apparent half-width (flank at half contrast), pixels.
    rho_px : the half-window the symmetric centres used, pixels.
    ends_px : ndarray (2, 2); the two end points (also ``points_px[0]``, ``[-1]``).
    rejected : profiles dropped in the last pass (no symmetric centre near the guess).
    coverage : the share of the last pass's profiles that had a symmetric
        centre: near 1 along a wire, lower along other thin structures.
    asymmetry : median over the profiles of the remaining asymmetry at the centre
        relative to the profile's own variance in the window (0 perfectly
        symmetric, about 1 for no symmetry at all).
    between_edges : whether the centres lie between the wire's two silhouette edges
        (else at the profiles' centre of symmetry).
    edges_refused : why the silhouette edges, asked for, were not used (None: used, or
        not asked for).
    edge_width_px : with silhouette edges, ndarray (M,): the distance between the
        two edges at each point (NaN at the end points), pixels; else None.
    lit_points_px : with silhouette edges and the shadow's side seen, ndarray (M, 2): the
        same centres with each pair's midpoint replaced by the lit side's edge moved by
        half the wire's width (:func:`_silhouette_centres`); for the bend at each vertex,
        which the shadow side's edge bends on a lifted part. Else None.
    end_uncertainty_px : (2,) how far inside each end point a weaker step could be the
        cap's silhouette instead (pixels, along the axis; 0 where none): at an end facing
        away from the light on a light sheet, where the shadow's far edge and the cap's
        silhouette both step the same way (:func:`_cap_edge`).
    """

    points_px: np.ndarray
    half_width_px: float
    rho_px: float
    ends_px: np.ndarray
    rejected: int
    coverage: float = 1.0
    asymmetry: float = 0.0
    between_edges: bool = False
    edge_width_px: np.ndarray | None = None
    end_uncertainty_px: np.ndarray = field(default_factory=lambda: np.zeros(2))
    lit_points_px: np.ndarray | None = None
    edges_refused: str | None = None

    @property
    def round_profile(self) -> bool:
        """Whether the profiles are a round wire's: between its silhouette edges, or symmetric
        within ``SYMMETRIC_WIRE_MAX`` (a side-lit round wire is not symmetric across; between
        the edges a wire wide along most of its length is the test instead)."""
        return self.between_edges or self.asymmetry <= SYMMETRIC_WIRE_MAX

    @property
    def centre_from(self) -> str:
        """How the centres were placed, as the record says it: ``"silhouette"`` (between the
        two silhouette edges), ``"symmetry"``, or ``"symmetry (...)"`` with why the
        silhouette edges, asked for, were not used."""
        if self.between_edges:
            return "silhouette"
        return "symmetry" if self.edges_refused is None else f"symmetry ({self.edges_refused})"

    def to_dict(self) -> dict[str, Any]:
        widths = self.edge_width_px
        return {
            "centre_from": self.centre_from,
            "edge_width_px": (
                None
                if widths is None or not np.isfinite(widths).any()
                else float(np.nanmedian(widths))
            ),
            "points": len(self.points_px),
            "half_width_px": self.half_width_px,
            "rho_px": self.rho_px,
            "ends_px": self.ends_px.tolist(),
            "rejected": self.rejected,
            "coverage": self.coverage,
            "asymmetry": self.asymmetry,
            "end_uncertainty_px": [float(v) for v in self.end_uncertainty_px],
        }


def measure_centreline(
    gray: np.ndarray,
    path_px: np.ndarray,
    *,
    width_guess_px: float,
    step_px: float = 1.0,
    end_shape: EndShape = "round",
    wire_width_px: float | None = None,
) -> Centreline:
    """Sub-pixel centreline of the wire along a rough path.

    Parameters
    ----------
    gray : ndarray (H, W), float; the photo's grey levels.
    path_px : ndarray (M, 2); an ordered rough centre path (the mask's
        skeleton), end to end, pixels.
    width_guess_px : the wire's rough width (from the mask), pixels.
    step_px : spacing of the centres along the wire, pixels.
    end_shape : ``"round"`` (hemispherical caps, matched to the cross profile)
        or ``"flat"`` (square-cut: the end face is where the brightness along
        the axis falls half-way from the wire's crest to the background).
    wire_width_px : the wire's expected apparent width (its diameter seen from the
        camera), pixels. With it the centres lie between the two silhouette edges
        (see the module notes); without it, at the profiles' centre of symmetry.

    Raises
    ------
    ValueError
        When too few profiles give a centre (no wire along the path).
    """
    if end_shape not in ("round", "flat"):
        raise ValueError(f"end_shape must be 'round' or 'flat', got {end_shape!r}")
    g = np.asarray(gray, dtype=np.float32)
    centre, followed = _centreline_along(
        g, path_px, width_guess_px, step_px, end_shape, wire_width_px
    )
    reach_px = REMEASURE_GAP_WIDTHS * 2.0 * centre.half_width_px
    gapped = [f and gap > reach_px for f, gap in zip(followed, _end_gaps_px(centre), strict=True)]
    if centre.round_profile and any(gapped):
        # the mask's path left the wire before this end (a lifted end's shadow parting from
        # it: the last 110 px of a Mitsuba part on cork had no centre, its chord's direction
        # was not measured): the wire's own path, end to end, guides the centres this time.
        # Only a round wire's: along its own centres a line that is none (a strip between
        # two surfaces, its profile a step) can look symmetric
        try:
            again, _ = _centreline_along(
                g, centre.points_px, width_guess_px, step_px, end_shape, wire_width_px
            )
        except ValueError:  # no wire along it after all: the first pass stands
            return centre
        # kept where it measured the stretch (its profiles there like the wire's)
        filled = all(
            not was or gap <= reach_px for was, gap in zip(gapped, _end_gaps_px(again), strict=True)
        )
        centre = again if again.round_profile and filled else centre
    return centre


def _end_gaps_px(centre: Centreline) -> list[float]:
    """How far each end point lies from the centre next to it, pixels."""
    inner = centre.points_px[1:-1]
    if len(inner) == 0:
        return [0.0, 0.0]
    return [
        float(np.hypot(*(centre.ends_px[0] - inner[0]))),
        float(np.hypot(*(centre.ends_px[1] - inner[-1]))),
    ]


def _centreline_along(
    g: np.ndarray,
    path_px: np.ndarray,
    width_guess_px: float,
    step_px: float,
    end_shape: EndShape,
    wire_width_px: float | None,
) -> tuple[Centreline, tuple[bool, bool]]:
    """:func:`measure_centreline` along one guide path (``g``: the photo's grey levels as
    float32), and whether each end (head, tail) was followed on past where the centres were
    cut back (:func:`_end_stretches_like`)."""
    hw0 = max(1.0, 0.5 * width_guess_px)
    path = resample_path(np.asarray(path_px, dtype=np.float64), step_px)
    path = smooth_path(path, max(2.0, 2.0 * hw0) / step_px)
    reach = 3.0 * hw0 + 4.0
    if wire_width_px is not None:
        reach = max(reach, 1.25 * wire_width_px + 5.0)
    offsets = (
        np.arange(-round(reach / PROFILE_STEP_PX), round(reach / PROFILE_STEP_PX) + 1)
        * PROFILE_STEP_PX
    )

    def profiles_at(centres: np.ndarray, normals: np.ndarray) -> np.ndarray:
        return sample_across(g, centres, normals, offsets)

    window = int(round(6.0 * hw0 / step_px))
    known_hw = None if wire_width_px is None else 0.5 * float(wire_width_px)
    # without the wire's width the symmetric centres are the measurement: their passes keep
    # above a dark sheet's level from the first (:func:`_sheet_floor`). With it they seed
    # the silhouette edges' search, measured from passes as before; where the edges are not
    # used, the passes are run again with the floor for the symmetric centres below
    centres, normals, prof, rough, rho, search = _symmetric_passes(
        profiles_at, path, offsets, hw0, reach, step_px, window, known_hw=known_hw,
        above_sheet=wire_width_px is None,
    )  # fmt: skip
    half_width = rough
    centres0 = centres
    centres, prof_ok, rejected, coverage, symmetry = _final_symmetric(
        prof, centres0, normals, rho, search, step_px, window
    )
    at_edges = False
    widths = shadow = lit = refused = None
    if wire_width_px is not None:
        found = _silhouette_if_whole(
            profiles_at, path, centres, offsets, float(wire_width_px), step_px, rough, window,
            symmetry,
        )  # fmt: skip
        if not isinstance(found, _EdgesRefused):
            centres, prof_ok, widths, coverage, shadow, lit = found
            at_edges = True
            if np.isfinite(widths).any():
                half_width = 0.5 * float(np.nanmedian(widths))
            crest = None
            if symmetry <= SYMMETRIC_WIRE_MAX and _dark_on_sheet(prof, offsets, max(rho, 1.0)):
                crest = _symmetric_on_crest(
                    g, (centres0, normals, prof, rho, search), step_px, window, centres,
                    float(wire_width_px),
                )  # fmt: skip
            if crest is not None:
                # a polished wire on a light sheet, its profiles a round wire's symmetric
                # ones: the edges found need not be its silhouette (the module notes)
                centres, prof_ok, rejected, coverage, symmetry = crest
                at_edges, half_width, refused = False, rough, EDGES_ON_LIGHT_SHEET
                widths = shadow = lit = None
        else:
            refused = found.reason
            centres0, normals, prof, rough, rho, search = _symmetric_passes(
                profiles_at, path, offsets, hw0, reach, step_px, window, known_hw=known_hw,
                above_sheet=True,
            )  # fmt: skip
            half_width = rough
            # the trimmed symmetry places the centres of a wire whose edges were lost; it
            # does not make a wire of a line whose profiles are not symmetric and whose
            # edges are both seen closer together than the wire (a strip 7 px across beside
            # a 9.5 px wire: 0.15 untrimmed, 0.12 trimmed): its untrimmed asymmetry stands
            centres, prof_ok, rejected, coverage, symmetry = _final_symmetric(
                prof, centres0, normals, rho, search, step_px, window,
                trim_share=0.0 if found.no_wire_across else HIGHLIGHT_TRIM_SHARE,
            )  # fmt: skip
    # between silhouette edges the end is found from the cap's silhouette too
    # a polished wire's profiles may have a half-contrast flank about its narrow crest only:
    # its cap is searched at the wire's own half-width where that is known
    cap_half_width = half_width
    known_width = not at_edges and wire_width_px is not None
    keep_like, cut = _end_stretches_like(prof_ok, offsets, half_width, step_px)
    centres, prof_ok = centres[keep_like], prof_ok[keep_like]
    widths = None if widths is None else widths[keep_like]
    lit = None if lit is None else lit[keep_like]
    if known_width:
        cap_half_width = max(half_width, 0.5 * float(wire_width_px))
    found_ends = [
        end_point(
            g, centres, prof_ok, offsets, rho, cap_half_width,
            head=head, shape=end_shape, silhouette=at_edges, shadow=shadow,
            axis_level=known_width, follow=cut[0 if head else 1],
        )
        for head in (True, False)
    ]  # fmt: skip
    ends = np.vstack([e[0] for e in found_ends])
    end_uncertainty = np.array([e[1] for e in found_ends])
    keep = _inside_ends(centres, ends, half_width, step_px)
    lit_points = None if lit is None else np.vstack((ends[:1], lit[keep], ends[1:]))
    edge_width = None if widths is None else np.concatenate(([np.nan], widths[keep], [np.nan]))
    return Centreline(
        points_px=np.vstack((ends[:1], centres[keep], ends[1:])),
        half_width_px=half_width,
        rho_px=rho,
        ends_px=ends,
        rejected=rejected,
        coverage=coverage,
        asymmetry=symmetry,
        between_edges=at_edges,
        edge_width_px=edge_width,
        end_uncertainty_px=end_uncertainty,
        lit_points_px=lit_points,
        edges_refused=refused,
    ), cut


def _final_symmetric(
    prof: np.ndarray,
    centres: np.ndarray,
    normals: np.ndarray,
    rho: float,
    search: float,
    step_px: float,
    window: int,
    trim_share: float = 0.0,
    valley_reach_px: float | None = None,
) -> tuple[np.ndarray, np.ndarray, int, float, float]:
    """The last pass of symmetric centres: the centres and their profiles, the profiles
    rejected, the share kept and the remaining asymmetry (:attr:`Centreline.asymmetry`).

    ``trim_share`` > 0: each centre is the trimmed symmetry's (that share of the most
    asymmetric offsets left out) where that lies within half the window of the whole
    window's, else the whole window's. ``valley_reach_px``: no centre in a valley that
    deep either side (:func:`symmetric_centres`).
    """
    slope = 0.4 * step_px
    floor = _sheet_floor(prof, rho)
    shift, asym = symmetric_centres(
        prof, rho_px=rho, search_px=search, max_slope_px=slope, min_level=floor,
        valley_reach_px=valley_reach_px,
    )  # fmt: skip
    if trim_share > 0.0:
        trimmed, _ = symmetric_centres(
            prof, rho_px=rho, search_px=search, max_slope_px=slope, trim_share=trim_share,
            min_level=floor, valley_reach_px=valley_reach_px,
        )  # fmt: skip
        near = np.isfinite(trimmed) & (np.abs(trimmed - shift) <= 0.5 * rho)
        shift = np.where(near, trimmed, shift)
    shift = despike(shift, window)
    ok = np.isfinite(shift) & ~_darker_than_sheet(prof, shift, floor)
    rejected = int((~ok).sum())
    coverage = float(ok.mean())
    symmetry = asymmetry_ratio(prof[ok], shift[ok], asym[ok], rho)
    centres = (centres + shift[:, None] * normals)[ok]
    if len(centres) < 5:
        raise ValueError("no symmetric wire profile along the path")
    return centres, prof[ok], rejected, coverage, symmetry


def _darker_than_sheet(prof: np.ndarray, shift: np.ndarray, sheet: np.ndarray | None) -> np.ndarray:
    """True (P,) at the symmetric centres that lie below the sheet's floor ``sheet`` (P,)
    beside them (:func:`_sheet_floor`; None, a wire not brighter than its sheet: nothing
    flagged).

    ``prof`` are sampled every ``PROFILE_STEP_PX`` about the guesses, ``shift`` (P,) the
    centres' offsets (NaN: none).
    """
    n = prof.shape[1]
    out = np.zeros(len(prof), dtype=bool)
    if sheet is None:
        return out
    ok = np.isfinite(shift)
    at = np.clip(np.rint(shift[ok] / PROFILE_STEP_PX).astype(int) + n // 2, 0, n - 1)
    out[ok] = prof[np.nonzero(ok)[0], at] < sheet[ok]
    return out


def _sheet_floor(prof: np.ndarray, rho: float) -> np.ndarray | None:
    """The sheet's level (P,) below which no centre of a bright wire lies, or None where the
    wire does not stand out brighter than its sheet (:func:`_dark_on_sheet` true).

    A bright wire's centre of symmetry is on its crest or a lit flank, well above the sheet
    (path-traced steel on dark and black card: 2-7 times the sheet's level at every
    centre); a lifted end's cast shadow parts from the wire as a dark valley a width beside
    it, symmetric too, which the centres followed for a chord's length and more (at a
    part's lifted end on dark card: 5-6 px off an 11 px wire, a sixth of the wire; on the
    photo lab's 19 px wire lifted 3 mm, 26 px off along a sixth of it and lost along
    another), and the gap between them, at the sheet's level, took the last centres at the
    end. Such a centre lies on no wire: the passes look for the centres where the profile
    stands out above the sheet by the ratio that tells a bright wire's band from its sheet
    (``LIGHT_SHEET_BAND_MAX``; :func:`symmetric_centres`' ``min_level``), so they stay on
    the wire beside the shadow. ``prof`` are sampled every ``PROFILE_STEP_PX`` about the
    guesses; the sheet's level is the brighter side's outer tenth (the other may be in the
    shadow).
    """
    if len(prof) == 0:
        return None
    n = prof.shape[1]
    offsets = (np.arange(n) - n // 2) * PROFILE_STEP_PX
    if _dark_on_sheet(prof, offsets, max(rho, 1.0)):
        return None
    return LIGHT_SHEET_BAND_MAX * np.maximum(*side_levels(prof))


def _silhouette_if_whole(
    profiles_at: Any,
    path: np.ndarray,
    centres: np.ndarray,
    offsets: np.ndarray,
    width_px: float,
    step_px: float,
    rough: float,
    window: int,
    symmetry: float,
) -> tuple | _EdgesRefused:
    """:func:`_silhouette_centres` when they follow the wire far enough and stand for its
    silhouette, else why not (the symmetric centres are then used).

    ``centres`` are the symmetric ones, ``symmetry`` their remaining asymmetry.
    """
    # from the mask's path, not the symmetric centres: those may have lost a
    # stretch of the wire (a clipped highlight), which could not come back
    # where the profiles are a round wire's symmetric ones, the pairs are looked for about
    # their centres: on a light sheet the highlight's far edge and a hard cast shadow's
    # outer edge can be a width apart, step opposite ways and outscore the wire's own edges
    # (the limb beside the shadow steps little), a pair within reach of a mask's path that
    # holds the shadow too
    prior = centres if symmetry <= SYMMETRIC_WIRE_MAX else None
    try:
        found = _silhouette_centres(
            profiles_at, path, offsets, width_px, step_px, rough, window, prior
        )
    except ValueError:
        found = None
    if symmetry > SYMMETRIC_WIRE_MAX and (found is None or found[3] < SILHOUETTE_MIN_COVERAGE):
        # neither test says wire: the profiles are not symmetric (a lamp a few degrees above
        # the plate lights one flank only) and single profiles have the edges a width apart
        # along too little of it. On a grainy sheet the grain's gradient peaks are as strong
        # as a soft limb's; the wire's edges run on along it, the grain's do not: the edges
        # are looked for again on profiles averaged along a width of wire
        # (EDGE_AVERAGE_WIDTHS), kept where they follow more of it
        try:
            averaged = _silhouette_centres(
                profiles_at, path, offsets, width_px, step_px, rough, window, prior,
                along_widths=EDGE_AVERAGE_WIDTHS,
            )  # fmt: skip
        except ValueError:
            averaged = None
        if averaged is not None and (found is None or averaged[3] > found[3]):
            found = averaged
    # the silhouette edges must follow the wire as far as its symmetric centres do;
    # where they lose a stretch at an end the part would be cut short: keep the
    # symmetric centres and say so (centre_from)
    # unless those are no wire's (a side-lit wire far from symmetric, a shadow joined
    # to it: they wander off along the shadow), then most of the mask's own path
    reach_px = (
        SILHOUETTE_MIN_SHARE * path_length(centres)
        if symmetry <= SYMMETRIC_WIRE_MAX
        else SILHOUETTE_MIN_SHARE_OF_PATH * path_length(path)
    )
    if found is None or path_length(found[0]) < reach_px:
        return _EdgesRefused("no silhouette edges along the whole wire")
    # a wire stands out of what lies beside it: between its edges the profile rises above,
    # or falls below, both sides (a highlight, a dark limb) by more than the sides differ.
    # Where two surfaces meet (a board's edge seen beside a dark sheet: white, a banded
    # strip, black) the profile steps down twice, and bands inside the strip give pairs of
    # edges a wire's width apart that step opposite ways (at 0.11 mm/px such a strip 48 px
    # wide passed for a 28 px wire along its whole length)
    step_share = _step_share(found[1], offsets, width_px, step_px)
    if step_share > 0.5:
        return _EdgesRefused(
            f"its profile steps from one level to another across it along "
            f"{100 * step_share:.0f} % of it, an edge between two surfaces",
            no_wire_across=True,
        )
    # the edges found are not the wire's width apart even in their median (not noise
    # about it, a bias): what
    # steps there is not the silhouette (a polished tube's limbs mirror the sheet beside
    # them, so on a dark sheet only a lit flank and the highlight stand out, 7 of 11 px
    # apart), and a centre from one of them moved by half the width guesses which. Where
    # the profiles are a round wire's symmetric ones, their centre is the measured one
    misfit = found[6]
    if abs(misfit) > PAIR_TOLERANCE and symmetry <= SYMMETRIC_WIRE_MAX:
        return _EdgesRefused(
            f"the edges seen are {100 * abs(misfit):.0f} % off the wire's width apart (median)"
        )
    # nor, where the profiles are not symmetric either, edges closer together than the
    # wire's width in their median: a shadow joined to one flank moves that edge out (the
    # centre is then the other edge moved by half the width), nothing moves both in. Both
    # edges stepping opposite ways narrower than the wire are something else across (a
    # grainy strip at a sheet's edge, bright on one side and dark on the other, 7 px
    # across beside a 9.5 px wire: the centres from one of its edges passed for a wire's
    # along three quarters of it); neither test says round wire
    if misfit < -PAIR_TOLERANCE:
        return _EdgesRefused(
            f"the edges seen are {100 * -misfit:.0f} % narrower than the wire's width apart "
            "(median)",
            no_wire_across=True,
        )
    # edges along too little of the wire to say it is one (a grainy sheet's noise in its
    # flanks), while its profiles are a round wire's symmetric ones along it: those say it
    if found[3] < SILHOUETTE_MIN_COVERAGE and symmetry <= SYMMETRIC_WIRE_MAX:
        return _EdgesRefused(f"silhouette edges along only {100 * found[3]:.0f} % of it")
    return found[:6]


def _symmetric_on_crest(
    gray: np.ndarray,
    last_pass: tuple[np.ndarray, np.ndarray, np.ndarray, float, float],
    step_px: float,
    window: int,
    edge_centres: np.ndarray,
    width_px: float,
) -> tuple[np.ndarray, np.ndarray, int, float, float] | None:
    """The symmetric centres (as :func:`_final_symmetric` returns them) where they lie on
    the wire's crest along most of it, else None.

    ``gray``: the photo's grey levels; ``last_pass``: the symmetric passes' last centres,
    normals, profiles, window and search (:func:`_symmetric_passes`); ``edge_centres``
    (M, 2) the silhouette centres (:func:`_silhouette_centres`); ``width_px`` the stated
    width.

    A round wire's centre of symmetry lies on its crest, the brightest across it (the lamp's
    highlight, or the room mirrored in the flank facing the camera). One flank's dark valley
    is symmetric too, and on a light sheet it can be as wide as the window over a chord whose
    flanks the lamp lights alike (path-traced steel on white card: a last chord's centres
    9 px, a third of the wire, off the axis). So the search bars valleys (a profile's level
    below the mean of its levels a quarter of a width either side), and where the crest is
    not in reach the profile gives no centre (path-traced steel on white card: where a last
    chord's free search ran into a valley, the barred one keeps to the crest and the radius
    is 0.01 % off). The centres are taken where they follow most of the wire
    (``CREST_MIN_COVERAGE``), few lie in short runs between the long ones (where neither
    crest nor silhouette shows along a stretch, the search leaves a few centres off the wire
    there: dropped, up to ``STRAY_SHARE_MAX``), and hardly any still lie in a valley
    where the photo is sampled across their own path (``VALLEY_SHARE_MAX``), counted beside
    the edges' centreline (past its ends lie the caps and the sheet).
    """
    centres, normals, prof, rho, search = last_pass
    try:
        found = _final_symmetric(
            prof, centres, normals, rho, search, step_px, window,
            trim_share=HIGHLIGHT_TRIM_SHARE, valley_reach_px=VALLEY_REACH_WIDTHS * width_px,
        )  # fmt: skip
    except ValueError:  # no crest in reach along the wire
        return None
    sym, coverage, asymmetry = found[0], found[3], found[4]
    if asymmetry > SYMMETRIC_WIRE_MAX or coverage < CREST_MIN_COVERAGE:
        return None
    stray = _short_runs(sym, step_px, CREST_RUN_MIN_WIDTHS * width_px)
    if stray.mean() > STRAY_SHARE_MAX:
        return None
    if stray.any():  # off the wire: the stretch left without centres
        kept = ~stray
        coverage *= float(kept.mean())
        sym = sym[kept]
        found = (sym, found[1][kept], found[2] + int(stray.sum()), coverage, asymmetry)
    guide = resample_path(smooth_path(edge_centres, width_px / step_px), 0.25 * step_px)
    _, k = cKDTree(guide).query(sym)
    beside = (k > 0) & (k < len(guide) - 1)
    # the three levels only, at the profiles' sampling step
    side_px = round(VALLEY_REACH_WIDTHS * width_px / PROFILE_STEP_PX) * PROFILE_STEP_PX
    normals_sym = path_normals(smooth_path(sym, 0.5 * width_px / step_px))
    left, mid, right = sample_across(gray, sym, normals_sym, np.array([-side_px, 0.0, side_px])).T
    valley = mid < 0.5 * (left + right)
    if not beside.any() or float(np.mean(valley[beside])) > VALLEY_SHARE_MAX:
        return None
    return found


def _short_runs(centres: np.ndarray, step_px: float, min_run_px: float) -> np.ndarray:
    """True (M,) at the ``centres`` (M, 2; in order, every ``step_px`` where found) in runs
    shorter than ``min_run_px`` between two longer ones, the runs split where consecutive
    centres lie over 3 steps apart. Short runs before the first long one and after the
    last lie at the caps, whose centres the ends' rules judge."""
    stray = np.zeros(len(centres), dtype=bool)
    if len(centres) < 2:
        return stray
    gap = np.hypot(*np.diff(centres, axis=0).T) > 3.0 * step_px
    run = np.concatenate(([0], np.cumsum(gap)))
    short = np.bincount(run)[run] * step_px < min_run_px
    long_at = np.nonzero(~short)[0]
    if len(long_at):
        stray[long_at[0] : long_at[-1]] = short[long_at[0] : long_at[-1]]
    return stray


@dataclass(frozen=True)
class _EdgesRefused:
    """Why the silhouette edges were not used (:func:`_silhouette_if_whole`);
    ``no_wire_across``: that also says the line is no round wire across (both its edges
    closer together than the wire's width, or a step between two surfaces)."""

    reason: str
    no_wire_across: bool = False


def _step_share(prof: np.ndarray, offsets: np.ndarray, width_px: float, step_px: float) -> float:
    """Share of the profiles (centred between the edges) that step from one side's level to
    the other's: what lies between the edges rises above or falls below both sides by less
    than the sides differ. Each profile is averaged along a width of wire and smoothed across
    by a tenth of it first (sensor noise would make every flat side a small extremum)."""
    if len(prof) == 0:
        return 0.0
    along = max(1, int(round(width_px / step_px)))
    across = max(0.5, 0.1 * width_px / float(offsets[1] - offsets[0]))
    smooth = gaussian_filter1d(
        uniform_filter1d(prof, size=along, axis=0, mode="nearest"), across, axis=1
    )
    # the sides: the outer sixth of the profile each way (more than a width from the
    # centre: the profiles reach at least 1.25 widths + 5 px, beyond both edges)
    k = max(2, len(offsets) // 6)
    left, right = np.median(smooth[:, :k], axis=1), np.median(smooth[:, -k:], axis=1)
    inside = smooth[:, np.abs(offsets) <= 0.5 * width_px]
    beyond = np.maximum(0.0, inside.max(axis=1) - np.maximum(left, right)) + np.maximum(
        0.0, np.minimum(left, right) - inside.min(axis=1)
    )
    return float(np.mean(beyond < np.abs(left - right)))


def _like_the_wire(
    profiles: np.ndarray, offsets: np.ndarray, half_width: float, step_px: float, at: np.ndarray
) -> np.ndarray:
    """The correlation of the profiles of the centres ``at`` (indices) with the wire's own
    profile nearby.

    The wire's profile near a centre is the median of the profiles within
    ``LIKE_WINDOW_WIDTHS`` wire widths along it, over ``LIKE_SPAN`` half-widths either
    side of the centre (the wire, its silhouette and its foot on the sheet). A centre on
    the axis has a profile like its neighbours' (0.85-0.98 on full-size Mitsuba parts); a
    centre off it, or one whose normal crosses the wire (a skeleton's end branch turning
    into the sheet), does not (-0.7 to 0.5).
    """
    sel = np.abs(offsets) <= LIKE_SPAN * half_width
    block = profiles[:, sel].astype(np.float64)
    block = block - block.mean(axis=1, keepdims=True)
    n = len(block)
    half = max(2, int(round(LIKE_WINDOW_WIDTHS * half_width / step_px)))
    corr = np.empty(len(at))
    for j, i in enumerate(at):
        template = np.median(block[max(0, i - half) : min(n, i + half + 1)], axis=0)
        corr[j] = zero_mean_correlation(block[i : i + 1], template)[0][0]
    return corr


def _end_stretches_like(
    profiles: np.ndarray, offsets: np.ndarray, half_width: float, step_px: float
) -> tuple[np.ndarray, tuple[bool, bool]]:
    """True (M,) at the centres kept for the end points, and whether each end (head, tail)
    was cut back.

    At an end whose first centres are not like the wire (:func:`_like_the_wire`; a
    skeleton's branch turning into the sheet, a run of centres off the axis), the centres
    before the first one that is like it, and followed by such centres along a wire width,
    are dropped, and so are those unlike it within ``LIKE_END_WIDTHS`` widths of it. An
    end whose first centre is like the wire is left as it is. Nothing is dropped where that
    would leave under half the centres. The profiles are compared at the ends only, and
    past the first wire's width only where an end is cut.
    """
    n = len(profiles)
    keep = np.ones(n, dtype=bool)
    cut = [False, False]
    run, zone = _end_run_and_zone(half_width, step_px)
    searched = min(n // 4, n - run)
    for e, order in enumerate((np.arange(n), np.arange(n)[::-1])):
        if searched <= 0:
            break
        like = _like_the_wire(profiles, offsets, half_width, step_px, order[:run]) >= LIKE_MIN
        if like[0] and like.mean() >= LIKE_RUN_SHARE:
            continue  # like the wire from its first centre: left as it is
        idx = order[: min(n, searched + run + zone)]
        like = _like_the_wire(profiles, offsets, half_width, step_px, idx) >= LIKE_MIN
        first = next(
            (k for k in range(searched) if like[k] and like[k : k + run].mean() >= LIKE_RUN_SHARE),
            None,
        )
        if first is None:
            continue
        cut[e] = True
        keep[order[:first]] = False
        keep[idx[first : first + zone]] &= like[first : first + zone]
    if keep.sum() < n // 2:
        return np.ones(n, dtype=bool), (False, False)
    return keep, (cut[0], cut[1])


def _end_run_and_zone(half_width: float, step_px: float) -> tuple[int, int]:
    """Centres along a wire width, and along ``LIKE_END_WIDTHS`` widths."""
    run = max(2, int(round(2.0 * half_width / step_px)))
    return run, int(round(2.0 * LIKE_END_WIDTHS * half_width / step_px))


def _inside_ends(
    centres: np.ndarray, ends: np.ndarray, half_width: float, step_px: float
) -> np.ndarray:
    """True (M,) at the centres not beyond the end points (a skeleton's overshoot)."""
    keep = np.ones(len(centres), dtype=bool)
    k = min(5, len(centres) - 1)
    near = max(k, int(round(4.0 * half_width / step_px)))  # only the last few centres
    for end, inward, idx in (
        (ends[0], centres[k] - centres[0], np.arange(min(near, len(centres)))),
        (
            ends[1],
            centres[-1 - k] - centres[-1],
            np.arange(max(0, len(centres) - near), len(centres)),
        ),
    ):
        inward = inward / max(np.hypot(*inward), 1e-12)
        keep[idx] &= ((centres[idx] - end) @ inward) >= 0.5 * half_width
    return keep


def _symmetric_passes(
    profiles_at: Any,
    path: np.ndarray,
    offsets: np.ndarray,
    hw0: float,
    reach: float,
    step_px: float,
    window: int,
    known_hw: float | None = None,
    above_sheet: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float, float]:
    """The three passes of symmetric centres from the mask's ``path`` (the module notes).

    ``above_sheet``: beside a wire brighter than its sheet, the centres are looked for only
    above the sheet's floor (:func:`_sheet_floor`), the first pass's across the whole mask.

    Returns the last pass's centres, normals and profiles, the half-width measured
    about them (``known_hw`` when given), and the symmetry window and search (px) for the
    final pass.
    """
    normals = path_normals(path)
    prof = profiles_at(path, normals)
    centres = path
    # the rough path can sit off the axis (a shadow joined to the mask), which
    # inflates half-widths measured from it: centre with a small window first
    hws = half_width_px(prof, offsets, hw0)
    rough = float(np.nanmedian(hws)) if np.isfinite(hws).any() else hw0
    stated_hw = known_hw
    if known_hw is not None and _dark_on_sheet(prof, offsets, known_hw):
        # a dark wire on a light sheet: its polished limbs mirror the sheet beside them, the
        # flanks near 45 deg the dark room's horizon, so the mask holds one flank's dark
        # valley, itself symmetric, whose centre lies a third of the width off the axis on
        # the lamp's far side (a radius 1-3 % off on path-traced parts); the half-width
        # measured about it is the valley's. The window spans the whole wire, both flanks,
        # and stays so
        rough = known_hw
    else:
        known_hw = None
    # a window of most of the wire: a small one finds false centres in each
    # dark flank (a local valley is symmetric too)
    rho = max(0.85 * rough, _MIN_RHO_PX)
    if known_hw is not None:
        # on a light sheet even most of the wire's width holds one flank's valley and the
        # crest beside it, symmetric about the valley where the lamp fills the other
        # flank's valley (the centre 3.5 px off a 11 px wire on path-traced parts): the
        # first pass spans both silhouette steps to the sheet, which only the axis
        # centres; the later ones refine within that basin (KNOWN_WIDTH_REFINE)
        rho = KNOWN_WIDTH_FIRST_RHO * known_hw
    search = min(1.0 * rough + 1.0, reach - rho - 0.5)
    for n_pass, final in enumerate((False, False, True)):
        # the first pass across both silhouette steps (light sheet, known width) picks its
        # basin by the asymmetry itself, not relative to the window's variance: a window about
        # one flank's dark valley holds the sheet on one side only, more variance, and won by
        # the ratio along a whole end chord of a Mitsuba part on white card (3.5 px off the
        # axis: the radius 7 % off); elsewhere (no width, or a bright wire on a dark sheet)
        # the ratio keeps a flat soft shadow band, symmetric but featureless, from winning
        floor = _sheet_floor(prof, rho) if above_sheet else None
        reach_px = search
        if n_pass == 0 and floor is not None:
            # a bright wire on a dark sheet: the mask may hold its shadow too, parted from
            # a lifted end by a gap (the mask's path then runs beside the wire, 10-12 px
            # off a 19 px wire's axis 3 mm up), so the first pass looks for the wire's
            # centre across the whole mask, and across the stated wire's half-width where
            # that is wider (the mask can hold a bright flank's band only); the shadow's
            # valley is barred (the floor)
            reach_px = max(search, min(max(hw0 - rough, stated_hw or 0.0), reach - rho - 0.5))
        if floor is not None:
            # and a band beside the crest dimmer than it (:func:`_crest_level`)
            floor = np.maximum(floor, _crest_level(prof, offsets, reach_px + rho))
        shift, _ = symmetric_centres(
            prof, rho_px=rho, search_px=reach_px, max_slope_px=0.4 * step_px,
            by_variance=not (n_pass == 0 and known_hw is not None), min_level=floor,
        )  # fmt: skip
        shift = despike(shift, window)
        ok = np.isfinite(shift)
        if ok.sum() < 5:
            raise ValueError("no symmetric wire profile along the path")
        centres = resample_path((centres + shift[:, None] * normals)[ok], step_px)
        # normals from the centres found, smoothed along the wire
        smooth = smooth_path(centres, max(2.0, 2.0 * rough) / step_px)
        normals = path_normals(smooth)
        prof = profiles_at(centres, normals)
        if not final and known_hw is None:
            hws = half_width_px(prof, offsets, rough)
            rough = float(np.nanmedian(hws)) if np.isfinite(hws).any() else rough
        if not final and known_hw is not None:
            rho, search = 0.85 * known_hw, KNOWN_WIDTH_REFINE * known_hw
        elif not final:
            rho = max(0.6 * rough, min(0.85 * rough, rough - 0.8), _MIN_RHO_PX)
            search = min(0.5 * rough + 1.0, reach - rho - 0.5)
    return centres, normals, prof, rough, rho, search


def _crest_level(prof: np.ndarray, offsets: np.ndarray, reach_px: float) -> np.ndarray:
    """The level (P,) below which a bright wire's profile holds no crest: the sheet's
    (the brighter side's outer tenth) plus ``CREST_LEVEL_SHARE`` of the way up to the
    brightest within ``reach_px`` of the guess (``prof`` sampled at ``offsets``, px).

    A polished wire's crest is the brightest band across it, but not the only symmetric
    one: the other flank can mirror a dim band of the room, narrow and symmetric too, and a
    window sized to a narrow crest holds it as well as the crest. Where the crest is
    saturated it is flat, of little variance, and the band won by the asymmetry relative to
    the window's variance (path-traced 2 mm steel on black card under a low lamp: the
    centres 5 px off the axis on the band along 2.4 chords, at 0.45-0.5 of the crest's
    height over the sheet, two vertex bends 4.6 deg off at 3.4 stated sigma).
    """
    sheet = np.maximum(*side_levels(prof))
    peak = prof[:, np.abs(offsets) <= reach_px].max(axis=1)
    return sheet + CREST_LEVEL_SHARE * np.maximum(peak - sheet, 0.0)


def _dark_on_sheet(profiles: np.ndarray, offsets: np.ndarray, half_width: float) -> bool:
    """True when the band of the wire's width does not stand out brighter than the sheet
    beyond it on most of the profiles (``half_width`` in px).

    A polished wire mirrors the sheet in its limbs and the room in its flanks: on a dark
    sheet its band is far brighter than the sheet (about twice on dark card); on a light or
    mid-tone sheet (white, printed cork) it is darker or within a few tens of percent of it
    (``LIGHT_SHEET_BAND_MAX``).
    """
    bg = 0.5 * np.add(*side_levels(profiles))
    band = profiles[:, np.abs(offsets) <= max(half_width, 1.0)].mean(axis=1)
    return bool(np.mean(band <= LIGHT_SHEET_BAND_MAX * bg) > 0.5)


def _shadow_side(
    profiles: np.ndarray,
    normals: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    offsets: np.ndarray,
) -> np.ndarray | None:
    """The image direction (2,) in which the wire's shadow lies, or None when none is seen.

    Beside an edge, a flat stretch darker than the plate farther out on the same side
    is the shadow; the direction that has most of these sides' outward normals on
    its side (the middle of the best ones) is the way the light casts.
    """
    n = profiles.shape[1]
    outer = max(3, n // 12)
    votes = []
    for side, edge in ((-1.0, left), (1.0, right)):
        ok = np.isfinite(edge)
        k = np.clip(np.searchsorted(offsets, edge[ok] + side * 2.0), 0, n - 1)
        k2 = np.clip(np.searchsorted(offsets, edge[ok] + side * 4.0), 0, n - 1)
        rows = np.nonzero(ok)[0]
        near = 0.5 * (profiles[rows, k] + profiles[rows, k2])
        far = np.median(profiles[rows, -outer:] if side > 0 else profiles[rows, :outer], axis=1)
        dark = near < far - 0.15 * np.maximum(far, 10.0)
        votes.append(side * normals[rows[dark]])
    v = np.vstack(votes)
    if len(v) < 10:
        return None
    # the direction that puts the most votes on its side; of a tie, the middle
    angles = np.radians(np.arange(0.0, 360.0, 1.0))
    dirs = np.column_stack((np.cos(angles), np.sin(angles)))
    agree = ((v @ dirs.T) > 0).mean(axis=0)
    if agree.max() < 0.8:
        return None
    best = np.nonzero(agree >= agree.max() - 1e-9)[0]
    mean = dirs[best].sum(axis=0)
    return mean / max(float(np.hypot(*mean)), 1e-12)


def _silhouette_centres(
    profiles_at: Any,
    centres: np.ndarray,
    offsets: np.ndarray,
    width_px: float,
    step_px: float,
    smooth_px: float,
    window: int,
    prior: np.ndarray | None = None,
    along_widths: float = 0.0,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray | None, np.ndarray | None, float]:
    """Centres between the silhouette edges (:func:`outer_edges`), from rough ``centres``.

    The edges are the strongest gradient pair a width apart (within 8 %, or 0.5 px;
    :func:`silhouette_edges`), else those found from inside (:func:`outer_edges`);
    where they are a width apart the centre is their midpoint. Where such pairs cover
    most of the wire (``PAIRS_ONLY_SHARE``) the other profiles are left out. Where they are not, a shadow's penumbra joins the silhouette on the
    shadow side (its flat stretch too narrow to be seen), or a false flat stretch
    cut the wire, so the centre is one edge moved by half the width (the median
    width of the clean pairs): the lit side's, where the shadow's side is known
    (:func:`_shadow_side`, from the whole wire) and the wire runs across the light;
    else the sharper one. One rule holds along two widths of wire (the majority):
    an edge's shading
    bias is alike along a straight chord: a parallel shift, which leaves its
    direction, and so the bends, unchanged; a chord measured partly by pairs and
    partly by one edge would not be.

    But not along a lifted part: there the shadow parts from the wire as it rises, and
    the shadow side's edge shifts with the gap (about 0.4 px at half size over two chords of
    a part lifted 3 mm, lit at 50 deg elevation), which bends the pairs' midpoints at the
    vertices (0.05-0.13 deg at full size on parts of R 42-50 mm, 120 deg, N 7). So
    the lit centres are returned too: where the shadow's side is known, each pair's
    midpoint replaced by the lit side's edge moved by half the median width (the same
    rule along two widths of wire); noisier by up to sqrt(2), free of the shadow.

    ``prior``: the symmetric centres (M', 2), where those are a round wire's, else None;
    the first pass then looks for each pair about the symmetric centre beside its rough
    centre (within ``SYMMETRIC_REACH`` widths; :func:`_symmetric_prior`), and within
    ``FIRST_PASS_REACH`` of the rough centre only where none lies beside it.

    ``along_widths`` > 0: the edges are looked for on the profiles averaged along that
    length of wire (in widths; :func:`_edges_of_pass`), 0: on each profile alone.

    Returns the centres, their profiles, the edge widths (px, NaN where only one
    edge was used), the share of profiles with a centre, the image direction in
    which the wire's shadow lies (:func:`_shadow_side`, last pass; None when none is seen),
    the lit centres (None when the shadow's side is not seen) and how far all edges'
    distances (paired or not) are off the width, relative, by their median (last pass;
    negative: narrower, inf: none found).
    """
    coverage = 1.0
    typical_misfit = np.inf
    widths = np.zeros(0)
    lit = None
    # the edges' distance is the width within 5 %, or half a pixel on a thin wire (a
    # blurred 6 px wire's limbs read 4-5 % wide)
    tol = max(PAIR_TOLERANCE, 0.5 / width_px)
    stated_px = width_px
    along = max(1, int(round(along_widths * width_px / step_px)) | 1) if along_widths > 0 else 1
    for n_pass, final in enumerate((False, False, True)):
        normals = path_normals(smooth_path(centres, max(2.0, smooth_px) / step_px))
        # the mask's path can lie half a width off the axis or more (a shadow joined to the
        # mask, wider where a lifted end's shadow parts from the wire): the first pass looks
        # for the pair's midpoint within a width of it (FIRST_PASS_REACH). Within half a
        # width, the shadow's own band (as wide as the wire, the wire's edge on one side) was
        # the only pair in reach beside a dark sheet's shadow, and the wire's pair, whose
        # summed gradient is the larger (the plate's edge to the lit wire against the
        # shadow's soft outer edge), was not searched: the last centimetre of a lifted end
        # then lay on the shadow, or had no pairs. Where a symmetric centre lies beside the
        # path, the pass starts from it and looks within SYMMETRIC_REACH
        near: float | np.ndarray = 0.2
        if n_pass == 0:
            near = FIRST_PASS_REACH
            if prior is not None:
                moved = _symmetric_prior(centres, normals, prior, FIRST_PASS_REACH * width_px)
                centres = centres + np.nan_to_num(moved)[:, None] * normals
                near = np.where(np.isfinite(moved), SYMMETRIC_REACH, FIRST_PASS_REACH)
        prof = profiles_at(centres, normals)
        if n_pass == 0 and prior is not None:
            # the stated width is a prior the photo must agree with: the pairs about the
            # symmetric centres within twice the tolerance give the width the edges show
            # (a shadow joined to one flank moves its gradient peak out: 6-11 % wide on
            # the photo lab's light sheet), about which the pairs are then taken
            # only where such pairs run along nearly all of it: a polished tube's lit flank
            # and highlight on a dark sheet give a narrower pair along a part of it only
            _, _, seen_w, seen_pair = _edges_of_pass(
                prof, offsets, stated_px, 2.0 * tol, near, along
            )
            if seen_pair.mean() >= WIDTH_SEEN_SHARE and seen_pair.sum() >= 10:
                width_px = float(np.median(seen_w[seen_pair]))
        left, right, width, pair = _edges_of_pass(prof, offsets, width_px, tol, near, along)
        shift, from_left, from_right, shadow, towards = _one_rule_shift(
            prof, normals, offsets, left, right, width, pair, width_px, step_px
        )
        shift = despike(shift, window)
        ok = np.isfinite(shift)
        coverage = float(ok.mean())
        if ok.sum() < 5:
            raise ValueError("no silhouette edges of the wire's width along the path")
        if final and shadow is not None:
            lit = _lit_centres(
                centres, normals, shift, ok, towards, from_left, from_right, width_px, step_px
            )
        centres = (centres + shift[:, None] * normals)[ok]
        widths = np.where(pair, width, np.nan)[ok]
        seen = width[np.isfinite(width)] / stated_px - 1.0
        typical_misfit = float(np.median(seen)) if seen.size else np.inf
        if not final:
            centres = _next_pass_path(centres, max(2.0, smooth_px) / step_px, step_px)
    centres, widths, lit = _trim_stray_runs(centres, widths, lit, step_px, width_px)
    # the last profiles, re-centred on the edges' midpoints (for the end points)
    normals = path_normals(smooth_path(centres, max(2.0, smooth_px) / step_px))
    return centres, profiles_at(centres, normals), widths, coverage, shadow, lit, typical_misfit


def _next_pass_path(centres: np.ndarray, smooth_samples: float, step_px: float) -> np.ndarray:
    """The path (every ``step_px``) along which the next pass takes its profiles: a pass's
    edge midpoints as they lie, or smoothed where they zigzag.

    Midpoints that jump across the wire (pairs from its edge here, a joined shadow's there)
    trace a path many times the wire's length, which resampled as it lies piles its points
    up out of order along the wire (a 14 MP photo: 1633 centres tracing 9590 px along a
    1690 px wire became 17980 points); smoothed over ``smooth_samples`` it follows the wire.
    """
    smoothed = smooth_path(centres, smooth_samples)
    zigzag = path_length(centres) > ZIGZAG_LENGTH_RATIO * path_length(smoothed)
    return resample_path(smoothed if zigzag else centres, step_px)


def _symmetric_prior(
    path: np.ndarray, normals: np.ndarray, symmetric: np.ndarray, reach_px: float
) -> np.ndarray:
    """Offset (M,) px along each normal of ``path`` to the symmetric centre beside it.

    NaN where no symmetric centre lies within a pixel along the path of the normal's foot
    and within ``reach_px`` across (a stretch the symmetric centres lost).
    """
    dist, k = cKDTree(symmetric).query(path)
    d = symmetric[k] - path
    across = np.einsum("ij,ij->i", d, normals)
    along = np.sqrt(np.maximum(dist**2 - across**2, 0.0))
    return np.where((along <= 1.0) & (np.abs(across) <= reach_px), across, np.nan)


def _edges_of_pass(
    prof: np.ndarray,
    offsets: np.ndarray,
    width_px: float,
    tol: float,
    near: float | np.ndarray,
    along: int = 1,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Left and right silhouette edges of every profile (px), their width and the clean pairs.

    ``along``: how many neighbouring profiles along the wire are averaged before the edges
    are looked for (``EDGE_AVERAGE_WIDTHS``), 1: none.

    The strongest pair of gradient peaks a width apart about the centre (the midpoint
    within ``near`` widths of it, scalar or per profile); where there is none, the edges
    found from inside (:func:`outer_edges`).
    """
    # Not the other way round (a penumbra joined to one side blurs its edge): on a light
    # sheet a dark wire's gently shaded body is flat to that test and a soft shadow ramp
    # joins one side, so a shadow's outer edge and the highlight's can pass for the wire
    if along > 1:
        # a sheet's grain puts gradient peaks as strong as the wire's soft limb into each
        # single profile; the wire's edges run on along it, the grain's do not
        prof = uniform_filter1d(prof, size=along, axis=0, mode="nearest")
    left, right = silhouette_edges(prof, offsets, width_px, tolerance=tol, centre_tolerance=near)
    width = right - left
    pair = np.abs(width / width_px - 1.0) <= tol
    left2, right2 = outer_edges(prof[~pair], offsets, width_px)
    fill = np.nonzero(~pair)[0]
    left[fill], right[fill] = left2, right2
    width = right - left
    pair = np.abs(width / width_px - 1.0) <= tol
    return left, right, width, pair


def _one_rule_shift(
    prof: np.ndarray,
    normals: np.ndarray,
    offsets: np.ndarray,
    left: np.ndarray,
    right: np.ndarray,
    width: np.ndarray,
    pair: np.ndarray,
    width_px: float,
    step_px: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray | None, np.ndarray | None]:
    """Each profile's centre offset (px along its normal, NaN where none) by one rule.

    Returns the offsets, the centres from the left and from the right edge, the shadow's
    image direction (None when not seen) and each normal's component towards it.
    """
    towards = None
    w_eff = float(np.median(width[pair])) if pair.sum() >= 10 else width_px
    shift = np.where(pair, 0.5 * (left + right), np.nan)
    from_left = left + 0.5 * w_eff
    from_right = right - 0.5 * w_eff
    # the sharper edge (a penumbra joined to the silhouette softens it), unless
    # the shadow says; an edge that would move the centre far does not count
    sharp_l, sharp_r = edge_gradient(prof, offsets, left), edge_gradient(prof, offsets, right)
    near_l = np.abs(np.nan_to_num(from_left, nan=np.inf)) <= 0.25 * width_px
    near_r = np.abs(np.nan_to_num(from_right, nan=np.inf)) <= 0.25 * width_px
    use_left = near_l & (~near_r | (sharp_l >= sharp_r))
    shadow = _shadow_side(prof, normals, left, right, offsets)
    if shadow is not None:
        towards = normals @ shadow  # > 0: the shadow lies on the + (right) side
        use_left = np.where(np.abs(towards) > 0.05, towards > 0, use_left)
    # one rule along a stretch of wire (the majority over two widths), so that a
    # chord is not measured partly by pairs and partly by one edge
    rule = np.where(pair, 0, np.where(use_left & near_l, 1, np.where(near_r, 2, -1)))
    rule = majority_filter(rule, max(3, int(round(2.0 * width_px / step_px))))
    shift = np.where(
        (rule == 0) & pair,
        0.5 * (left + right),
        np.where(
            (rule == 1) & near_l, from_left, np.where((rule == 2) & near_r, from_right, np.nan)
        ),
    )
    if pair.mean() >= PAIRS_ONLY_SHARE:
        # clean pairs along most of the wire: the gaps are left open (the fits need no
        # centre there) rather than filled by one edge, which a shadow's or a
        # highlight's edge can stand in for over a stretch (4 px off on a lab render);
        # but not a gap as long as a chord (no clean pair along a chord near the light's
        # azimuth on a light sheet): without centres its line came from the centres
        # bracketing the gap, a vertex bend off by a degree or more
        long_gap = long_runs(~pair, LONG_GAP_WIDTHS * width_px / step_px)
        shift = np.where(pair, 0.5 * (left + right), np.where(long_gap, shift, np.nan))
    return shift, from_left, from_right, shadow, towards


def _lit_centres(
    centres: np.ndarray,
    normals: np.ndarray,
    shift: np.ndarray,
    ok: np.ndarray,
    towards: np.ndarray,
    from_left: np.ndarray,
    from_right: np.ndarray,
    width_px: float,
    step_px: float,
) -> np.ndarray:
    """The centres with the lit side's edge moved by half the width, where it is near."""
    # the lit side's edge moved by half the width, where a pair's midpoint is used
    lit_rule = np.where(np.abs(towards) > 0.05, np.where(towards > 0, 1, 2), 0)
    lit_rule = majority_filter(lit_rule, max(3, int(round(2.0 * width_px / step_px))))
    lit_edge = np.where(lit_rule == 1, from_left, np.where(lit_rule == 2, from_right, np.nan))
    # every centre (not only the pairs' midpoints: a chord would mix the two)
    swap = np.isfinite(lit_edge) & (np.abs(lit_edge) <= 0.25 * width_px)
    delta = np.where(swap & np.isfinite(shift), lit_edge - shift, 0.0)
    lit = (centres + (shift + delta)[:, None] * normals)[ok]
    return lit


def _trim_stray_runs(
    centres: np.ndarray,
    widths: np.ndarray,
    lit: np.ndarray | None,
    step_px: float,
    width_px: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Drop a short run of centres cut off from the rest by a gap at either end."""
    # a short run of centres cut off from the rest by a gap at either end (false edges
    # beside a cap's highlight: 3 px off the axis on a lab render) is not the wire's
    gap = np.nonzero(np.hypot(*np.diff(centres, axis=0).T) > 3.0 * step_px)[0]
    lo = int(gap[0]) + 1 if len(gap) and path_length(centres[: gap[0] + 1]) < width_px else 0
    hi = int(gap[-1]) + 1 if len(gap) and path_length(centres[gap[-1] + 1 :]) < width_px else None
    if len(centres[lo:hi]) >= 5:
        centres, widths = centres[lo:hi], widths[lo:hi]
        lit = None if lit is None else lit[lo:hi]
    return centres, widths, lit
