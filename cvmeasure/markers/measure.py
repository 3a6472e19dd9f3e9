"""The per-photo pipeline: a bender photo -> signed pin and bend angles with uncertainties.

``measure_machine_photo`` runs search (reduced copy, colour model adapted to the
photo's light), sub-pixel refinement at full resolution around each marker
only, the optional lens and plane corrections, and the machine-frame angles.
Its result's ``to_dict()`` is the spec's JSON Lines record of a machine photo.

Frames of the angle computation
-------------------------------
* no camera, no plane: image pixels as in the photo (angles are invariant to
  uniform scale, so no camera is needed for an ideal, parallel view);
* ``camera``: undistorted pixels (lens distortion removed from every edge point
  before the circle fit);
* ``plane``: millimetres on the plate (edge points undistorted and each
  disc's mapped through the plane pose to its own height above the plate,
  ``kit.height_mm(role)``, so the fitted circle's centre is the disc's true
  centre, not the centre of its perspective ellipse, and angles are true
  plate-plane angles whatever the discs' heights).

Marker heights without a plane pose cannot be applied exactly: the result says
so, and ``height_bound_deg`` bounds what they can do to the angles
(:mod:`cvmeasure.markers.heights`); ``heights="parallel"`` corrects them assuming
a camera square to the plate. A kit without heights is measured flat, with a
warning.

The reported ``markers`` are always centres in the photo's own pixels.
Stated uncertainties are sampling errors of the edge fits, taken where the disc is
a circle (on the plate on a plane pose), plus what the disc's edge read in another
channel weighting (green for luminance edges) disagrees on, never less than a floor per
centre (the shift demosaicing, blur, JPEG or shading gives an edge, which the residuals
cannot see; the floor alone where lateral colour switched the edges to green) and, for a disc
partly hidden or unevenly lit, what the halves of its edge disagree on beyond their
sampling; on a plane pose the kit's height uncertainties are added, and with heights
measured through that same plane the edge's pose-constant bias is left out (the heights
took it up: :func:`cvmeasure.markers.heights.heights_take_up_bias`). They do not
include camera or plane calibration errors (the plane pose's own uncertainty, from the
board photo's corner residuals, moves an angle by a fifth of its sigma or less on
poses 430-850 mm from the plate, 1-2 % in quadrature, so it is not carried), print or
mounting tolerances of the markers, or lateral chromatic aberration.

Edges are found in linear luminance for 8-bit photos (JPEG keeps it at full
resolution), in "shade" for 8-bit photos of a kit whose markers' faces stand on their
rings (``step_mm``: the steps' walls then count alike on every disc,
:data:`cvmeasure.markers.refine.SHADE_EDGES`) and in the green channel for RAW/16-bit
data (``edge=`` to choose): a lens's lateral chromatic aberration moves red and blue
edges. By default the
red and blue edges of the discs farthest from the image centre are compared with
green (a cheap probe of the regions already read); where they show lateral colour
(:data:`LATERAL_CA_THRESHOLD`) the edges are taken in green and a warning says so
(benchmarks: p95 0.006 deg with green vs 0.024 deg with luminance at 5e-4).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from cvmeasure import jpegplanes
from cvmeasure.board import BoardSpec
from cvmeasure.camera_model import CameraModel
from cvmeasure.contracts import MachinePhotoResult, MarkerMeasurement, PlaneModel, Trial
from cvmeasure.errors import InputError
from cvmeasure.geometry import CircleFit, fit_circle_robust, fit_circles_robust
from cvmeasure.imageio import (
    MAX_PHOTO_PIXELS,
    Photo,
    is_jpeg_data,
    is_linear_name,
    is_raw,
    read_photo,
    to_bgr8,
)
from cvmeasure.jpegplanes import LazyBGR
from cvmeasure.kit import ROLES, MarkerKit
from cvmeasure.lens.plane import estimate_plane
from cvmeasure.markers.angles import machine_angles
from cvmeasure.markers.checks import (
    HIDDEN_COVERAGE,
    PlaneDisc,
    anisotropy,
    colour_delta_e,
    lateral_ca_estimate,
    marker_warnings,
    plane_warnings,
)
from cvmeasure.markers.circles import (
    edge_mode_cov,
    refine_candidate,
    refine_candidates,
    split_half_cov,
)
from cvmeasure.markers.colour import ColourModel, ColourSpace, kit_colour_model
from cvmeasure.markers.detect import find_markers
from cvmeasure.markers.frame import MeasureFrame, measure_frame
from cvmeasure.markers.heights import (
    BOUND_TILT_DEG,
    HEIGHT_WARN_DEG,
    fallback_focal_px,
    height_parallax,
    heights_take_up_bias,
    plane_heights_sigma,
)
from cvmeasure.markers.refine import (
    CENTRE_FLOOR_PX,
    EDGE_MODE,
    EDGE_MODES,
    FIT_STOP_PX,
    SHADE_EDGES,
    UNEVEN_RING_SPREAD,
    channel_shifts_px,
    disc_edge_points,
    ray_correlation_factor,
)
from cvmeasure.markers.seed_baseline import seed_find_circles
from cvmeasure.method_names import MARKER_METHODS, marker_method
from cvmeasure.warning import StageWarning

__all__ = [
    "Method",
    "METHODS",
    "MarkerMeasurement",
    "MachinePhotoResult",
    "MarkerNotFoundError",
    "measure_machine_photo",
    "measure_photo_file",
    "measure_trial",
    "FrameCentres",
    "frame_centres",
    "refine_candidate",
    "refine_candidates",
    "lateral_ca_estimate",
    "LATERAL_CA_THRESHOLD",
    "SEED_CENTRE_SIGMA_PX",
]

Method = Literal["edge_fit", "seed_hough"]
METHODS: tuple[str, ...] = MARKER_METHODS
#: How marker heights are treated without a plane pose: "none" (bounded, warned
#: about) or "parallel" (corrected assuming a camera square to the plate; needs a camera).
HeightMode = Literal["none", "parallel"]
HEIGHT_MODES: tuple[str, ...] = ("none", "parallel")

#: Centre standard uncertainty (px per axis) stated for the seed method's Hough centres.
SEED_CENTRE_SIGMA_PX = 0.5
#: Lateral chromatic aberration (red magnified by 1 + k, blue by 1 - k about the
#: image centre) estimated at or above this ``|k|`` switches luminance edges to green
#: ones (luminance edges: p95 0.024 deg at k = 5e-4 in benchmarks/markers.py). JPEG
#: chroma subsampling makes the estimate read ~0.55-0.9 of the true k; photos
#: without lateral colour read |k| < 1.3e-4 at 0.3 scale, < 2e-5 at full size.
LATERAL_CA_THRESHOLD = 2e-4
#: How many discs (the farthest from the image centre) the lateral-colour probe reads.
LATERAL_CA_PROBES = 3
#: A photo whose white estimate has more than this share of clipped pixels is overexposed.
PHOTO_CLIPPED_FRACTION = 0.5


class MarkerNotFoundError(InputError):
    """A marker is missing or ambiguous in a photo. ``reasons`` maps role -> why."""

    def __init__(self, source: str | os.PathLike[str], reasons: Mapping[str, str], kit: MarkerKit):
        self.reasons = dict(reasons)
        parts = [
            f"marker {role!r} ({kit.by_role(role).name}) {why}"
            if why.startswith("ambiguous")
            else f"marker {role!r} ({kit.by_role(role).name}) not found: {why}"
            for role, why in self.reasons.items()
        ]
        super().__init__(source, "; ".join(parts))


def measure_trial(
    loaded: MachinePhotoResult,
    unloaded: MachinePhotoResult,
    trial: int | str | None = None,
    *,
    commanded_pin_deg: float = math.nan,
    target_deg: float | None = None,
) -> Trial:
    """Pair a loaded and an unloaded measurement of one bend into a :class:`Trial`."""
    return Trial.from_photos(
        loaded,
        unloaded,
        trial=str(trial) if trial is not None else "",
        commanded_pin_deg=commanded_pin_deg,
        target_deg=target_deg,
    )


_Fits = dict[str, tuple[CircleFit, Any]]
#: markers, centres, their covariances, the pose-constant part of those covariances, warnings
_Measured = tuple[
    dict[str, MarkerMeasurement],
    dict[str, np.ndarray],
    dict[str, np.ndarray],
    dict[str, np.ndarray],
    list[StageWarning],
]


def _lateral_colour(
    bgr: np.ndarray, fits: _Fits, search: Any, kit: MarkerKit
) -> StageWarning | None:
    """Probe the discs farthest from the image centre for lateral colour; where it is
    strong, take every edge again in green (``fits`` updated in place) and say so."""
    mid = ((bgr.shape[1] - 1) / 2.0, (bgr.shape[0] - 1) / 2.0)
    far = sorted(fits, key=lambda r: -math.dist(fits[r][0].centre, mid))[:LATERAL_CA_PROBES]
    shifts = {}
    for role in far:
        fit, edges = fits[role]
        shifts[role] = channel_shifts_px(
            bgr, fit.centre, fit.radius, edges.disc_bgr, edges.ring_bgr
        )
    k = lateral_ca_estimate(shifts, {r: f.centre for r, (f, _) in fits.items()}, bgr.shape)
    if k is None or abs(k) < LATERAL_CA_THRESHOLD:
        return None
    for role in list(fits):
        spec = kit.by_role(role)
        got = refine_candidate(
            bgr, search.found[role], spec.ring_mm / spec.diameter_mm, edge="green"
        )
        if not isinstance(got, str):
            fits[role] = got
    corner_px = abs(k) * 0.5 * math.hypot(bgr.shape[1], bgr.shape[0])
    return StageWarning(
        "lateral_colour",
        f"lateral chromatic aberration detected ({corner_px:.1f} px at the corners): edges "
        "taken in green",
    )


def _other_edges(
    bgr: np.ndarray, fits: _Fits, kit: MarkerKit, edge: str | None
) -> dict[str, np.ndarray]:
    """Each disc's edge points read in another channel weighting (green for luminance or
    colour edges, luminance for green ones) round its settled circle (image px): where
    the two disagree, demosaicing, blur, JPEG or shading moved the edge
    (:func:`edge_mode_cov`)."""
    # shade edges against luminance: the two weigh a light disc's wall and the shadow
    # on its ring differently, so they part by what that shading does to the edge
    other = "luma" if (edge or EDGE_MODE) in ("green", SHADE_EDGES) else "green"
    out = {}
    for role, (fit, edges) in fits.items():
        spec = kit.by_role(role)
        got = disc_edge_points(
            bgr,
            fit.centre,
            fit.radius,
            spec.ring_mm / spec.diameter_mm,
            edge=other,
            local_levels=edges.ring_spread >= UNEVEN_RING_SPREAD,
        )
        out[role] = got.points_px
    return out


def unseen_bias_cov(floor_cov: np.ndarray, edge_cov: np.ndarray | None) -> np.ndarray:
    """A centre's bias the edge residuals cannot see: what its edge read another way
    disagrees on (:func:`edge_mode_cov`), never less than the floor (by trace).

    Both estimate one bias (demosaicing, JPEG, colour fringes and shading move the edge):
    added together they counted it twice (photo-lab renders of flat markers: angles'
    |error| / sigma RMS 0.78 with both, 0.84 with the larger, 0.92 with the edge-mode term
    alone, 1.06 with the floor alone).
    """
    if edge_cov is None or np.trace(edge_cov) <= np.trace(floor_cov):
        return floor_cov
    return edge_cov


def _on_frame(
    fits: _Fits,
    uneven: set[str],
    kit: MarkerKit,
    frame: MeasureFrame,
    other: Mapping[str, np.ndarray],
    edge: str | None = None,
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], dict[str, np.ndarray], list[PlaneDisc]]:
    """Each disc's circle fitted in ``frame`` (its edge mapped at its own height above the
    plate on a plane pose): centres, their covariances, the pose-constant part of those
    (the unseen bias, :func:`unseen_bias_cov`), and the discs on the plane.

    A centre's covariance is the sampling error of the fit in the frame, where the disc
    is a circle (in the image a tilted view makes it an ellipse, and a circle fitted
    there reads that shape as edge noise: sigmas several times the errors), the floor
    mapped from the image, what the edge read another way (``other``, image px)
    disagrees on, and for the ``uneven`` roles (partly hidden or in a shadow) what the
    halves of the edge disagree on beyond their sampling, both fitted in the frame too.
    With ``edge`` "shade" on a plane pose, the other reading's walls (towards the camera's
    foot point) are left out of that disagreement (:func:`edge_mode_cov`)."""
    # the discs grouped by the height they are mapped at: without a plane pose, every
    # height maps alike (MeasureFrame.at_height), so all the discs go in one call
    heights = {r: kit.height_mm(r) if frame.plane is not None else 0.0 for r in fits}
    mapped: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    other_f: dict[str, np.ndarray] = {}
    for height in dict.fromkeys(heights.values()):
        # the discs at one height mapped in one call, their circles fitted together
        group = [r for r in fits if heights[r] == height]
        alts = [r for r in group if r in other]
        got = frame.at_height(height).mapped_with_jacobians(
            [fits[r][0].centre for r in group + alts],
            [fits[r][1].points_px for r in group] + [other[r] for r in alts],
        )
        mapped.update(zip(group, got[: len(group)], strict=True))
        other_f.update((r, g[2]) for r, g in zip(alts, got[len(group) :], strict=True))
    roles = list(fits)
    inits = []
    for role in roles:
        jac, c_f, _ = mapped[role]
        inits.append((c_f[0], c_f[1], fits[role][0].radius * math.sqrt(abs(np.linalg.det(jac)))))
    fits_f = fit_circles_robust(
        [mapped[r][2] for r in roles],
        inits=inits,
        correlation_factors=[ray_correlation_factor(fits[r][0].radius) for r in roles],
        stop=FIT_STOP_PX,
    )
    foot = None
    if edge == SHADE_EDGES and frame.plane is not None:
        foot = np.asarray(frame.plane.camera_centre_mm, dtype=np.float64)[:2]
    centres, covs, bias, discs = {}, {}, {}, []
    for role, init, fit_f in zip(roles, inits, fits_f, strict=True):
        fit = fits[role][0]
        jac, _, pts_f = mapped[role]
        if fit_f is None:  # no circle: fit_circle_robust says why
            fit_f = fit_circle_robust(
                pts_f,
                init=init,
                correlation_factor=ray_correlation_factor(fit.radius),
                stop=FIT_STOP_PX,
            )
        centres[role] = np.array(fit_f.centre)
        cov = np.asarray(fit_f.covariance)
        cf = ray_correlation_factor(fit.radius)
        if role in uneven:
            cov = cov + split_half_cov(pts_f, fit_f, correlation_factor=cf)
        edge_cov = (
            edge_mode_cov(other_f[role], fit_f, correlation_factor=cf, wall_towards=foot)
            if role in other_f
            else None
        )
        bias[role] = unseen_bias_cov(CENTRE_FLOOR_PX**2 * (jac @ jac.T), edge_cov)
        covs[role] = cov + bias[role]
        if frame.name == "plane":
            seen = fit.coverage >= HIDDEN_COVERAGE
            shape = anisotropy(pts_f - np.asarray(fit_f.centre)) if seen else None
            whole = seen and fits[role][1].ring_spread < UNEVEN_RING_SPREAD
            discs.append(PlaneDisc(role, float(fit_f.radius), shape, whole))
    return centres, covs, bias, discs


def _measure_ours(
    bgr: np.ndarray,
    bgr8: np.ndarray,
    kit: MarkerKit,
    model: ColourModel,
    frame: MeasureFrame,
    source: str,
    edge: str | None = None,
    probe_lateral: bool = True,
) -> _Measured:
    search = find_markers(bgr8, kit, model)
    failures = dict(search.failures)
    markers: dict[str, MarkerMeasurement] = {}
    warnings: list[StageWarning] = []
    fits: _Fits = {}
    found = [role for role in ROLES if role in search.found]
    ratios = [kit.by_role(r).ring_mm / kit.by_role(r).diameter_mm for r in found]
    refined = refine_candidates(bgr, [search.found[r] for r in found], ratios, edge=edge)
    for role, got in zip(found, refined, strict=True):
        if isinstance(got, str):
            failures[role] = got
        else:
            fits[role] = got
    if failures:
        raise MarkerNotFoundError(source, {r: failures[r] for r in ROLES if r in failures}, kit)
    if probe_lateral:  # default edges: green where the lens shows lateral colour
        lateral = _lateral_colour(bgr, fits, search, kit)
        warnings.extend([lateral] if lateral is not None else [])
        other = {} if lateral is not None else _other_edges(bgr, fits, kit, edge)
    else:
        other = _other_edges(bgr, fits, kit, edge)
    delta_e = colour_delta_e(kit, {r: e for r, (_, e) in fits.items()}, search.white)
    cov_imgs: dict[str, np.ndarray] = {}
    bias: dict[str, np.ndarray] = {}
    uneven: set[str] = set()
    for role, (fit, edges) in fits.items():
        cov_img = np.asarray(fit.covariance)
        cf = ray_correlation_factor(fit.radius)
        if fit.coverage < HIDDEN_COVERAGE or edges.ring_spread >= UNEVEN_RING_SPREAD:
            # partly hidden or in a shadow: what the edge's two halves disagree on, too
            uneven.add(role)
            cov_img = cov_img + split_half_cov(edges.points_px, fit, correlation_factor=cf)
        edge_img = edge_mode_cov(other[role], fit, correlation_factor=cf) if role in other else None
        bias[role] = unseen_bias_cov(np.eye(2) * CENTRE_FLOOR_PX**2, edge_img)
        cov_img = cov_img + bias[role]
        cov_imgs[role] = cov_img
        markers[role] = MarkerMeasurement(
            role,
            fit.centre[0],
            fit.centre[1],
            fit.radius,
            float(math.sqrt(0.5 * np.trace(cov_img))),
            fit.n_points,
            fit.coverage,
            edges.contrast,
            delta_e.get(role),
        )
        warnings.extend(marker_warnings(role, fit, edges, delta_e.get(role)))
    if frame.func is None:
        centres = {r: np.array(f.centre) for r, (f, _) in fits.items()}
        covs = dict(cov_imgs)
    else:
        centres, covs, bias, discs = _on_frame(fits, uneven, kit, frame, other, edge)
        if frame.plane is not None:
            height = abs(float(frame.plane.camera_centre_mm[2]))
            warnings.extend(plane_warnings(discs, kit, height))
    if search.white.clipped_fraction > PHOTO_CLIPPED_FRACTION:
        warnings.append(
            StageWarning(
                "photo_overexposed", "photo overexposed (the brightest pixels are clipped)"
            )
        )
    return markers, centres, covs, bias, warnings


def _measure_seed(bgr8: np.ndarray, kit: MarkerKit, space: str, source: str) -> _Measured:
    circles = seed_find_circles(bgr8, kit, space)
    failures = {
        r: "no Hough circle in its colour box" for r, c in circles.items() if c.centre_px is None
    }
    if failures:
        raise MarkerNotFoundError(source, failures, kit)
    markers, centres, covs = {}, {}, {}
    cov = np.eye(2) * SEED_CENTRE_SIGMA_PX**2
    for role, c in circles.items():
        if c.centre_px is None or c.radius_px is None:
            continue
        markers[role] = MarkerMeasurement(
            role, c.centre_px[0], c.centre_px[1], c.radius_px, SEED_CENTRE_SIGMA_PX
        )
        centres[role] = np.array(c.centre_px)
        covs[role] = cov
    warnings = [
        StageWarning("seed_many_circles", f"marker {r!r}: {c.n_circles} circles, took the first", r)
        for r, c in circles.items()
        if c.n_circles > 1
    ]
    return markers, centres, covs, {}, warnings


def _checked_options(method, space, edge, heights, camera, plane) -> Method:
    """The method's current name; ValueError naming any option out of its choices."""
    method = marker_method(method)
    if method not in METHODS:
        raise ValueError(f"unknown method {method!r}; valid: {METHODS}")
    if space not in ("lab", "rgb"):
        raise ValueError(f"unknown colour space {space!r}; valid: ('lab', 'rgb')")
    if edge is not None and edge not in EDGE_MODES:
        raise ValueError(f"unknown edge mode {edge!r}; valid: {EDGE_MODES}")
    if heights not in HEIGHT_MODES:
        raise ValueError(f"unknown heights mode {heights!r}; valid: {HEIGHT_MODES}")
    if heights == "parallel" and (camera is None or plane is not None):
        raise ValueError(
            "heights='parallel' corrects a camera-only measurement: it needs a camera and "
            "no plane (a plane pose applies the heights exactly)"
        )
    return method


def measure_machine_photo(
    bgr: np.ndarray,
    kit: MarkerKit,
    *,
    camera: CameraModel | None = None,
    plane: Any = None,
    method: Method = "edge_fit",
    space: ColourSpace = "lab",
    colour_model: ColourModel | None = None,
    linear: bool = False,
    edge: str | None = None,
    heights: HeightMode = "none",
    source: str = "photo",
    photo: str | None = None,
) -> MachinePhotoResult:
    """Measure the signed pin and bend angles of one bender photo.

    Parameters
    ----------
    bgr : ndarray of shape (H, W, 3), uint8 or uint16, the photo (OpenCV BGR), or a
        :class:`cvmeasure.jpegplanes.LazyBGR` (pixels made only where they are read).
    kit : the marker kit the photo shows.
    camera : lens model; with it, lens distortion is removed from the edge points.
    plane : the marker plane (:class:`cvmeasure.contracts.PlaneModel`, from ``cvmeasure
        plane`` or a board in the photo); with it, angles are computed on the plane through
        the plane's own camera (``camera`` must then be that camera or None).
    method : "edge_fit" (colour model + sub-pixel fits of the discs' edges) or "seed_hough"
        (the paper's baseline); the older "ours" / "seed" are read too.
    space : colour space of the segmentation, "lab" or "rgb".
    colour_model : a learnt colour model; the kit's colours (adapted to the photo's light) when None.
    linear : the image holds linear (gamma 1) data, e.g. from RAW.
    edge : where disc edges are found: "luma" (JPEG's full-resolution component), "green"
        (immune to lateral chromatic aberration), "colour" or "shade" (see
        :data:`cvmeasure.markers.refine.EDGE_MODE`). Default for 8-bit photos (JPEGs):
        "shade" for a kit whose faces stand on their rings (``step_mm``), else "luma", either
        switched to "green" with a warning where the discs show lateral chromatic
        aberration; "green" for RAW/linear or 16-bit data.
    heights : without a plane pose, how the kit's marker heights are treated: "none"
        (angles in the image, with ``height_bound_deg`` and a warning) or "parallel"
        (corrected assuming a camera square to the plate, needs ``camera``; the bound
        is then what a tilt up to :data:`cvmeasure.markers.heights.BOUND_TILT_DEG`
        leaves). With a plane pose the heights are always applied exactly.
    source : what error messages name (the file).
    photo : what the result's ``photo`` field says.

    Returns
    -------
    MachinePhotoResult

    Raises
    ------
    MarkerNotFoundError (an InputError)
        A marker is missing or ambiguous: names the role(s) and why.
    """
    method = _checked_options(method, space, edge, heights, camera, plane)
    got = _centres(
        bgr, kit, camera, plane, method, space, colour_model, linear, edge, heights, source
    )
    transform, centres, covs, warnings = got.frame, got.centres, got.covariances, got.warnings
    height_state, height_bound = got.height_state, got.height_bound
    if height_state == "plane" and transform.plane is not None:
        plane = transform.plane
        covs = heights_take_up_bias(covs, got.bias_covariances, kit, (plane.rvec, plane.tvec_mm))
    try:
        angles = machine_angles(centres, covs, y_down=transform.y_down)
    except ValueError as exc:
        raise InputError(source, str(exc)) from None
    sigma = {"pin_angle_deg": angles.pin_sigma_deg, "bend_angle_deg": angles.bend_sigma_deg}
    if height_state == "plane" and transform.plane is not None:
        plane = transform.plane
        sigma, height_bound = plane_heights_sigma(
            centres,
            kit,
            plane.camera_centre_mm,
            transform.y_down,
            sigma,
            warnings,
            plane_pose=(plane.rvec, plane.tvec_mm),
        )
    return MachinePhotoResult(
        angles.pin_angle_deg,
        angles.bend_angle_deg,
        got.markers,
        sigma,
        tuple(warnings),
        photo,
        method,
        space,
        transform.name,
        height_state,
        height_bound,
    )


@dataclass(frozen=True)
class FrameCentres:
    """The discs' centres in the angles' frame, before the angles (see :func:`frame_centres`).

    ``frame`` the frame (``frame.name``: "image", "undistorted" or "plane", mm);
    ``centres`` and ``covariances`` each role's centre (2,) and covariance (2, 2) in it
    (on a plane pose: each disc's centre on the plane at its kit height);
    ``markers`` the centres in the photo's own pixels; ``warnings`` as the result's;
    ``bias_covariances`` the pose-constant part of each covariance (the edge's unseen
    bias, the same on every photo from one pose), which measured heights take up
    (:func:`cvmeasure.markers.heights.heights_take_up_bias`).
    """

    frame: MeasureFrame
    markers: dict[str, MarkerMeasurement]
    centres: dict[str, np.ndarray]
    covariances: dict[str, np.ndarray]
    warnings: list[StageWarning]
    height_state: str | None = None
    height_bound: dict[str, float] | None = None
    bias_covariances: dict[str, np.ndarray] = field(default_factory=dict)


def _centres(
    bgr: Any,
    kit: MarkerKit,
    camera: CameraModel | None,
    plane: Any,
    method: str,
    space: str,
    colour_model: ColourModel | None,
    linear: bool,
    edge: str | None,
    heights: str,
    source: str,
) -> FrameCentres:
    """The markers found, refined and mapped into the angles' frame (options checked by
    :func:`measure_machine_photo`)."""
    # a LazyBGR (pixels made where read: measure_photo_file's JPEG path) stays one where
    # only regions and the search's copy are read; else its whole image is made here
    lazy = isinstance(bgr, LazyBGR) and not linear and method == "edge_fit"
    img = bgr if lazy else np.asanyarray(bgr)
    if img.ndim != 3 or img.shape[2] != 3:
        raise InputError(source, "not a colour photo")
    bgr8 = img if lazy else to_bgr8(img, linear=linear)
    if plane is not None and camera is not None and plane.camera is not camera:
        if not plane.camera.same_lens(camera):
            raise InputError(
                source, "the plane was measured with another camera than the one given"
            )
    height_state: str | None = None
    height_bound: dict[str, float] | None = None
    if method == "seed_hough":
        if camera is not None or plane is not None:
            raise ValueError(
                "the seed_hough method measures in image pixels: it takes no camera or plane"
            )
        transform = MeasureFrame("image")
        markers, centres, covs, bias, warnings = _measure_seed(bgr8, kit, space, source)
    else:
        transform = measure_frame(camera, plane, img.shape, source)
        model = colour_model or kit_colour_model(kit, space)
        work = bgr8 if linear or img.dtype == np.uint8 else img
        probe = edge is None
        if edge is None and (linear or img.dtype != np.uint8):
            # RAW or 16-bit data: no chroma subsampling to avoid, and no in-camera
            # lateral-colour correction either, so the green channel is the better edge
            edge = "green"
        elif edge is None and kit.has_steps:
            # faces standing on their rings: the steps' walls read alike on every disc
            # (SHADE_EDGES); flush faces keep luminance, which JPEG and demosaicing keep
            # sharpest (shade edges cost 2-3x the angle error on the photo lab's renders)
            edge = SHADE_EDGES
        markers, centres, covs, bias, warnings = _measure_ours(
            work, bgr8, kit, model, transform, source, edge, probe and edge != "green"
        )
        if not kit.has_heights:
            height_state = "flat"  # the spec: a kit without heights is flat stickers
        elif transform.plane is not None:
            height_state = "plane"
        else:
            height_state, height_bound = _heights_without_pose(
                centres, covs, markers, kit, camera, img.shape, transform, heights, warnings
            )
    return FrameCentres(
        transform, markers, centres, covs, warnings, height_state, height_bound, bias
    )


def frame_centres(
    bgr: Any,
    kit: MarkerKit,
    *,
    camera: CameraModel | None = None,
    plane: Any = None,
    linear: bool = False,
    edge: str | None = None,
    source: str = "photo",
) -> FrameCentres:
    """The discs' centres of one photo in the angles' frame (on a plane pose: the plate,
    mm, each disc at its kit height), what :func:`measure_machine_photo` turns into angles;
    for steps that fit the geometry across photos (``cvmeasure markers heights``)."""
    return _centres(bgr, kit, camera, plane, "edge_fit", "lab", None, linear, edge, "none", source)


def _heights_without_pose(
    centres: dict[str, np.ndarray],
    covs: dict[str, np.ndarray],
    markers: Mapping[str, MarkerMeasurement],
    kit: MarkerKit,
    camera: CameraModel | None,
    shape: tuple[int, ...],
    transform: MeasureFrame,
    mode: str,
    warnings: list[StageWarning],
) -> tuple[str, dict[str, float]]:
    """Bound (and with ``mode`` "parallel" correct, in place) the heights' effect; warn."""
    h, w = shape[:2]
    if camera is not None:
        cam = camera.for_image((w, h))
        focal = 0.5 * (cam.fx + cam.fy)
        pp = cam.principal_point_px
        lens = "the camera's focal length"
    else:
        focal = fallback_focal_px((w, h))
        pp = ((w - 1) / 2.0, (h - 1) / 2.0)
        lens = "no camera: a 90 deg lens assumed, a longer one gives less"
    par = height_parallax(
        centres,
        covs,
        {r: m.r_px for r, m in markers.items()},
        kit,
        focal_px=focal,
        principal_point_px=pp,
        y_down=transform.y_down,
    )
    if mode == "parallel":
        centres.update(par.centres)
        covs.update(par.covariances)
        bound = par.bound_parallel_deg
        code = "heights_parallel"
        what = (
            f"the marker heights were corrected assuming a camera square to the plate "
            f"({par.distance_mm:.0f} mm above it); a camera tilted up to {BOUND_TILT_DEG:g} deg "
            "leaves"
        )
    else:
        bound = par.bound_none_deg
        code = "heights_not_applied"
        what = "the marker heights, not applied without a plane pose, can add"
    if max(bound.values()) >= HEIGHT_WARN_DEG:
        warnings.append(
            StageWarning(
                code,
                f"the +- covers the edge fits only; {what} up to "
                f"{bound['pin_angle_deg']:.3f} deg (pin) and {bound['bend_angle_deg']:.3f} deg "
                "(bend) of error (height_bound_deg; camera "
                f"{par.distance_mm:.0f} mm above the plate from the discs' sizes and {lens}): "
                "give --plane or --board (the board photographed from this pose) to apply "
                "the heights exactly and remove this bound",
            )
        )
    return mode, bound


def measure_photo_file(
    photo: str | os.PathLike[str] | Photo,
    kit: MarkerKit,
    *,
    camera: CameraModel | None = None,
    plane: PlaneModel | None = None,
    board: BoardSpec | None = None,
    **options: Any,
) -> MachinePhotoResult:
    """Measure one bender photo file: the one path from a file to a result.

    ``photo`` is a path (JPEG, PNG, TIFF, RAW; read here) or a photo already read
    (:class:`cvmeasure.imageio.Photo`). ``plane`` measures on a saved plane;
    ``board`` finds that board in the photo and measures on its plane (needs
    ``camera``). Other options go to :func:`measure_machine_photo`. InputError
    names the file for an unreadable photo, a missing board or marker.
    """
    if not isinstance(photo, Photo):
        lazy = _jpeg_planes_bgr(photo, options) if board is None else None
        if lazy is not None:
            try:
                return measure_machine_photo(
                    lazy,
                    kit,
                    camera=camera,
                    plane=plane,
                    source=str(photo),
                    **{"photo": str(photo), **options, "linear": False},
                )
            except MarkerNotFoundError:
                pass  # measured again from the full decode: its result, its message
        photo = read_photo(photo)
    source = str(photo.path)
    if board is not None:
        if plane is not None:
            raise ValueError("give a plane or a board to find one in the photo, not both")
        if camera is None:
            raise InputError(source, "rectifying to a board's plane needs the camera")

        plane = estimate_plane(photo.gray8(), board, camera, source=source)
    options.setdefault("photo", source)
    options.setdefault("linear", photo.linear)
    return measure_machine_photo(
        photo.bgr, kit, camera=camera, plane=plane, source=source, **options
    )


def _jpeg_planes_bgr(path: str | os.PathLike[str], options: Mapping[str, Any]) -> Any:
    """The JPEG path of :func:`measure_photo_file`: the file decoded to its Y, Cb, Cr planes.

    Returns a :class:`cvmeasure.jpegplanes.LazyBGR` (BGR made only where the search and
    the refinement read: the search's reduced copy and the markers' regions, the same
    pixels as the full decode up to rounding), or None, and the caller decodes the whole
    file as before, for anything else: not a YCbCr JPEG with 4:4:4/4:2:2/4:2:0 chroma,
    a damaged file, more than :data:`cvmeasure.imageio.MAX_PHOTO_PIXELS`, no
    libturbojpeg, a linear file or options this path does not take (method "seed_hough").
    """
    p = Path(path)
    if (
        marker_method(options.get("method", "edge_fit")) != "edge_fit"
        or options.get("linear")
        or is_raw(p)
        or is_linear_name(p)
        or not jpegplanes.available()
        or not p.is_file()
    ):
        return None
    data = p.read_bytes()
    if not is_jpeg_data(data):
        return None
    planes = jpegplanes.read_planes(data, max_pixels=MAX_PHOTO_PIXELS)
    return None if planes is None else planes.lazy_bgr()
