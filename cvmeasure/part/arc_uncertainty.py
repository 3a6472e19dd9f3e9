"""The standard uncertainty of a part's radius and bend per chord, common-mode terms included.

The circle's own ``radius_sigma_mm`` is the sampling error of the fit from the vertices'
scatter about it; what moves every vertex alike leaves no scatter and is added here,
each term from what the photo itself states, and carried through the circle and the
ends' sweep by moving the vertices by it and refitting:

* the fit's sampling: the circle's own sigma from the vertices' scatter, or, where wider,
  the jackknife's spread of the circles through all vertices but one, which sees a single
  misplaced vertex (an end traced short, or onto its shadow) that pulls the circle without
  raising the scatter (held-out renders: the radius within 2 sigma on 96 % of 28 photos,
  89 % without it; the photo lab's unwarned arcs unchanged at 98 %, their median sigma
  0.18 -> 0.19 %);
* the plane's scale: the lens' position uncertainty on the plate
  (:meth:`cvmeasure.plane_model.PlaneModel.lens_uncertainty_mm`, the even/odd halves'
  disagreement where the camera carries it) at the part's two ends, over the chord
  between them; it scales the radius and leaves the angles;
* the centreline's offset across the wire: every vertex moved outward by d moves the
  radius by d and leaves the angles. Between silhouette edges the edges' shading bias
  (:data:`SILHOUETTE_OFFSET_PX`); from the profiles' symmetry a share of the wire's
  radius (:data:`SYMMETRY_OFFSET_SHARE`; the ``round_wire_edges_lost`` warning states the
  full radius as the bound);
* the end points along the wire: an end moved along its chord by u turns the arc by
  about u / R, and (the chord leaving the circle at half the bend) moves the radius a
  little. Each end's cap outline is located to about a pixel (:data:`END_ALONG_PX`); an
  end facing its shadow adds its stated one-sided range (``wire.end_uncertainty_px``)
  as a uniform spread;
* the sampling of the arc angle: the fitted centre's covariance swings the end vertices'
  directions from it;
* an arc whose vertices' spacing gives another bend per chord than its ends (the
  ``part_chord_spacing`` warning): the bend per chord is uncertain by their difference,
  and the radius by the same share (the wire's length along the arc, which the
  centreline measures best, is the radius times the angle);
* a part whose chords the photo did not show (no chord count: the radius is the wire's
  best circle): bent in chords, its vertices lie on the bend's circle and each chord
  inside it, at most by the sagitta s, so the best circle lies about 2/3 s inside and the
  centreline's residuals about it (the chords' scallop) have an RMS of about 0.30 s; the
  radius may so be low by up to :data:`UNSEEN_CHORDS_BIAS_PER_RMS` times that RMS
  (the centreline's noise counts in too, so a bound), a one-sided bias counted as a
  standard uncertainty of half of it, so that 2 sigma reaches it;
* a lift measured and corrected (a shadow or a moved photo): its 2-sigma effect
  (``lift.effect_*``) halved. A lift only bounded (``lift.used == "bound"``) is left out:
  its worst effect is stated in ``lift`` and the ``part_lifted`` warning.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from cvmeasure.geometry import fit_circle_taubin
from cvmeasure.part.fit import arc_sweep_rad
from cvmeasure.warning import StageWarning

__all__ = [
    "SILHOUETTE_OFFSET_PX",
    "SYMMETRY_OFFSET_SHARE",
    "END_ALONG_PX",
    "UNSEEN_CHORDS_BIAS_PER_RMS",
    "ArcUncertainty",
    "arc_uncertainty",
    "imprecision_warning",
]

#: Standard uncertainty (px) of a centreline between silhouette edges across the wire,
#: common to the whole wire: the edges' shading bias (the photo lab's round wires, dark and
#: light sheets, lamps 35-50 deg up: their silhouette centrelines' common radial offset
#: from the axis 0.003-0.03 of the wire's radius, 0.03-0.2 px).
SILHOUETTE_OFFSET_PX = 0.25

#: Standard uncertainty of a centreline from the profiles' symmetry across the wire, as a
#: share of the wire's radius. The highlight and the shadow pull the symmetric centre
#: towards the lamp, which for an arc is mostly a shift of the circle's centre and leaves
#: the radius; the part that is radial and common to every vertex is what moves it. Where
#: the part measurement falls back to it on the photo lab's round wires (10 photos without
#: a gap, chord-count or shape warning) the radius was off by under 0.1 of the wire's
#: radius on the 7 on the dark sheet; on the light sheet by 0.16, 0.6 and 1.0 radii, the
#: last two held by the spacing term below (``part_chord_spacing``). Beyond, the
#: ``round_wire_edges_lost`` warning's bound (the whole radius) stands: this sigma does not
#: cover the tail it states.
SYMMETRY_OFFSET_SHARE = 0.1

#: Standard uncertainty (px) of each end point along the wire: the cap's outline is one
#: edge across the axis, read at half contrast; unlike the centreline, between two flanks
#: whose shading biases cancel, nothing cancels its own, which the blur and the cap's
#: shading set at about a pixel (the photo lab's round wires at 0.16 and 0.28 mm/px: median
#: 0.25 px, RMS 0.96 px over 168 ends, leaving out 14 ends misplaced by over 5 px).
END_ALONG_PX = 1.0

#: How far below the vertices' circle the best circle of a part bent in chords can lie, in
#: units of the centreline's RMS about that circle: a chord's points lie inside the circle
#: by s (1 - phi^2 / alpha^2) (s the sagitta, phi the angle along the chord, alpha its half),
#: whose mean is 2/3 s and RMS about the mean 2 / sqrt(45) s: the ratio is sqrt(5).
UNSEEN_CHORDS_BIAS_PER_RMS = math.sqrt(5.0)


@dataclass(frozen=True)
class ArcUncertainty:
    """The standard uncertainties of a part's radius and bend per chord, and their terms.

    Attributes
    ----------
    radius_sigma_mm : one standard uncertainty of the radius, mm (the terms below in
        quadrature).
    arc_angle_sigma_deg : one standard uncertainty of the arc angle, degrees.
    segment_bend_sigma_deg : that over the chords, degrees (None without divisions).
    sampling_radius_mm, scale_radius_mm, offset_radius_mm, ends_radius_mm, lift_radius_mm,
    spacing_radius_mm, chords_radius_mm : the radius' terms: the circle fit's sampling, the
        plane's scale, the centreline's common offset across the wire, the end points' along
        it, a corrected lift's, the spacing's disagreement (where ``part_chord_spacing``
        warns), and unseen chords' (without a chord count; 0 with one); mm.
    sampling_arc_deg, ends_arc_deg, offset_arc_deg, lift_arc_deg, spacing_arc_deg : the
        arc angle's terms: the fitted centre's, the end points' along the wire, the
        centreline's offset, a corrected lift's, and the vertices' spacing's disagreement
        with the ends where ``part_chord_spacing`` warns; degrees.
    """

    radius_sigma_mm: float
    arc_angle_sigma_deg: float
    segment_bend_sigma_deg: float | None
    sampling_radius_mm: float
    scale_radius_mm: float
    offset_radius_mm: float
    ends_radius_mm: float
    lift_radius_mm: float
    spacing_radius_mm: float
    chords_radius_mm: float
    sampling_arc_deg: float
    ends_arc_deg: float
    offset_arc_deg: float
    lift_arc_deg: float
    spacing_arc_deg: float

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def arc_uncertainty(
    *,
    radius_mm: float,
    vertices_mm: np.ndarray,
    circle_centre_mm: tuple[float, float],
    circle_covariance_mm2: np.ndarray,
    circle_radius_sigma_mm: float,
    divisions: int | None,
    mm_per_px: float,
    wire_radius_mm: float,
    silhouette: bool,
    end_uncertainty_px: np.ndarray | list[float],
    lens_sigma_mm: float | None,
    lift_radius_sigma_mm: float = 0.0,
    lift_segment_bend_sigma_deg: float = 0.0,
    spacing_disagreement_deg: float = 0.0,
) -> ArcUncertainty | None:
    """The radius' and bend per chord's standard uncertainties (see the module notes).

    Parameters
    ----------
    radius_mm : the circle's radius, mm.
    vertices_mm : (N+1, 2) the polygon's vertices (or the centreline's points), mm, in
        order along the wire.
    circle_centre_mm, circle_covariance_mm2, circle_radius_sigma_mm : the circle through
        them, its centre's covariance (mm^2) and its radius' sampling sigma (mm).
    divisions : the chord count N, or None.
    mm_per_px : the plane's scale at the part.
    wire_radius_mm : the wire's radius (the stated diameter's half, else the apparent).
    silhouette : the centreline lies between silhouette edges (else profiles' symmetry).
    end_uncertainty_px : (2,) how far inside each end its cap's outline could lie, px.
    lens_sigma_mm : the lens' position uncertainty on the plate, mm (None: not known,
        left out).
    lift_radius_sigma_mm, lift_segment_bend_sigma_deg : a corrected lift's standard
        effect on the radius (mm) and the bend per chord (deg).
    spacing_disagreement_deg : how far the bend per chord lies from the vertices' spacing
        where the ``part_chord_spacing`` warning says so (deg; 0: consistent): an end
        misplaced beyond its own sigma, which the bend per chord is then uncertain by.

    Returns None for a circle of no finite radius (a straight line).
    """
    v = np.asarray(vertices_mm, dtype=np.float64).reshape(-1, 2)
    if not math.isfinite(radius_mm) or radius_mm <= 0.0 or len(v) < 2:
        return None
    sampling_r = float(circle_radius_sigma_mm) if math.isfinite(circle_radius_sigma_mm) else 0.0
    cov = np.asarray(circle_covariance_mm2, dtype=np.float64)
    if divisions:
        # one misplaced vertex (an end traced short or onto its shadow) pulls the circle
        # without raising the scatter the fit's own sigma is read from: the jackknife's
        # spread of the leave-one-vertex-out circles sees it; either, whichever is wider
        jack = _jackknife(v)
        if jack is not None:
            sampling_r = max(sampling_r, jack[1])
            if not np.all(np.isfinite(cov)) or np.trace(jack[0]) > np.trace(cov):
                cov = jack[0]
    chord_mm = float(np.hypot(*(v[-1] - v[0])))
    scale_rel = 0.0
    if lens_sigma_mm is not None and chord_mm > 0.0:
        # each end placed within the lens' sigma: the chord, and so the scale, by sqrt(2) of it
        scale_rel = math.sqrt(2.0) * float(lens_sigma_mm) / chord_mm
    scale_r = radius_mm * scale_rel
    offset_mm = (
        SILHOUETTE_OFFSET_PX * mm_per_px if silhouette else SYMMETRY_OFFSET_SHARE * wire_radius_mm
    )
    # the common terms through the circle and the sweep: each displacement applied to the
    # vertices and the circle refitted (Taubin's fit, which the robust fit starts from)
    base = _radius_and_sweep(v)
    if base is None:
        return None
    c = np.asarray(circle_centre_mm, dtype=np.float64)
    from_centre_mm = np.hypot(*(v - c).T)
    outward = (v - c) / from_centre_mm[:, None]
    moved = _radius_and_sweep(v + offset_mm * outward)
    offset_r, offset_arc = (0.0, 0.0) if moved is None else np.abs(np.subtract(moved, base))
    # an end off along the wire moves along its chord: the arc turns by about u / R, and
    # the chord leaving the circle at the bend's half-angle moves the radius too
    along_mm = END_ALONG_PX * mm_per_px
    # an end facing its shadow: its outline anywhere up to u farther in (uniform, rms u / sqrt 3)
    extra_mm = np.asarray(end_uncertainty_px, dtype=np.float64) * mm_per_px / math.sqrt(3.0)
    ends_r2 = ends_arc2 = 0.0
    for end, nb, extra in ((0, 1, extra_mm[0]), (-1, -2, extra_mm[-1])):
        u_mm = math.hypot(along_mm, float(extra))
        step = v[end] - v[nb]
        slid = v.copy()
        slid[end] = v[end] + u_mm * step / float(np.hypot(*step))
        got = _radius_and_sweep(slid)
        if got is not None:
            ends_r2 += (got[0] - base[0]) ** 2
            ends_arc2 += (got[1] - base[1]) ** 2
    ends_r, ends_arc = math.sqrt(ends_r2), math.sqrt(ends_arc2)
    lift_r = float(lift_radius_sigma_mm)
    n = divisions if divisions else None
    spacing_arc = abs(float(spacing_disagreement_deg)) * (n or 1)
    # the wire's length along the arc is what the centreline measures best: its radius is
    # that over the angle, so an angle uncertain by a share is a radius uncertain by it
    spacing_r = radius_mm * spacing_arc / base[1] if base[1] > 0.0 else 0.0
    chords_r = 0.0
    if n is None:
        # no chord count: chords the photo did not show may pull the best circle inside
        res = from_centre_mm - radius_mm
        chords_r = 0.5 * UNSEEN_CHORDS_BIAS_PER_RMS * math.sqrt(float(np.mean(res**2)))
    radius_sigma = math.sqrt(
        sampling_r**2
        + scale_r**2
        + offset_r**2
        + ends_r**2
        + lift_r**2
        + spacing_r**2
        + chords_r**2
    )

    # the arc angle is the end vertices' sweep about the centre: the centre moved by dc
    # turns each end's direction by (r_perp . dc) / R^2
    sampling_arc = 0.0
    if np.all(np.isfinite(cov)):
        g = np.zeros(2)
        for sign, p in ((-1.0, v[0]), (1.0, v[-1])):
            d = p - c
            g += sign * np.array([d[1], -d[0]]) / float(d @ d)
        sampling_arc = math.degrees(math.sqrt(max(0.0, float(g @ cov @ g))))
    lift_arc = float(lift_segment_bend_sigma_deg) * (n or 1)
    arc_sigma = math.sqrt(
        sampling_arc**2 + ends_arc**2 + offset_arc**2 + lift_arc**2 + spacing_arc**2
    )
    return ArcUncertainty(
        radius_sigma_mm=radius_sigma,
        arc_angle_sigma_deg=arc_sigma,
        segment_bend_sigma_deg=None if n is None else arc_sigma / n,
        sampling_radius_mm=sampling_r,
        scale_radius_mm=scale_r,
        offset_radius_mm=float(offset_r),
        ends_radius_mm=ends_r,
        lift_radius_mm=lift_r,
        spacing_radius_mm=spacing_r,
        chords_radius_mm=chords_r,
        sampling_arc_deg=sampling_arc,
        ends_arc_deg=ends_arc,
        offset_arc_deg=float(offset_arc),
        spacing_arc_deg=spacing_arc,
        lift_arc_deg=lift_arc,
    )


def _jackknife(v: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The jackknife's covariance of Taubin's circle centre (mm^2) and its radius' sigma
    (mm) from the circles through all vertices but one; None under four vertices."""
    n = len(v)
    if n < 4:
        return None
    fits = []
    for i in range(n):
        try:
            c, r = fit_circle_taubin(np.delete(v, i, axis=0))
        except ValueError:
            return None
        fits.append((c[0], c[1], r))
    d = np.asarray(fits, dtype=np.float64)
    d -= d.mean(axis=0)
    cov = (n - 1) / n * (d.T @ d)
    return cov[:2, :2], math.sqrt(cov[2, 2])


def _radius_and_sweep(v: np.ndarray) -> tuple[float, float] | None:
    """Taubin's circle through the vertices: its radius (mm) and the ends' sweep about its
    centre (deg, unwrapped through the vertices as :func:`cvmeasure.part.fit.arc_geometry`
    measures it); None when no circle describes them."""
    try:
        c, r = fit_circle_taubin(v)
    except ValueError:
        return None
    return float(r), math.degrees(arc_sweep_rad(c, v))


def imprecision_warning(
    uncertainty: ArcUncertainty, radius_mm: float, *, radius_pct: float, bend_deg: float
) -> StageWarning | None:
    """``part_imprecise`` when the photo states the radius or the bend per chord only to
    wider than ``radius_pct`` (%) / ``bend_deg`` (degrees) at 2 sigma, else None.

    A result is then within those tolerances only by chance: the camera's pixels across the
    wire, not the method, limit it, and a closer camera or a larger photo narrows it.
    """
    radius_2sigma_pct = 200.0 * uncertainty.radius_sigma_mm / radius_mm
    bend_2sigma = uncertainty.segment_bend_sigma_deg
    bend_2sigma = None if bend_2sigma is None else 2.0 * bend_2sigma
    wide = []
    if radius_2sigma_pct > radius_pct:
        wide.append(f"the radius to +-{radius_2sigma_pct:.2f} %")
    if bend_2sigma is not None and bend_2sigma > bend_deg:
        wide.append(f"the bend per chord to +-{bend_2sigma:.3f} deg")
    if not wide:
        return None
    return StageWarning(
        "part_imprecise",
        f"this photo pins {' and '.join(wide)} (2 sigma), wider than {radius_pct:g} % / "
        f"{bend_deg:g} deg: either may be off by that much; a closer camera or a larger "
        "photo (more pixels across the wire) narrows it",
    )
