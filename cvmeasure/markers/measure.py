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
Stated uncertainties are sampling errors of the edge fits (with a floor per
centre); they do not include camera or plane calibration errors, print or
mounting tolerances of the markers, or lateral chromatic aberration.

Edges are found in linear luminance for 8-bit photos (JPEG keeps it at full
resolution) and in the green channel for RAW/16-bit data (``edge=`` to choose):
a lens's lateral chromatic aberration moves red and blue edges. By default the
red and blue edges of the discs farthest from the image centre are compared with
green (a cheap probe of the regions already read); where they show lateral colour
(:data:`LATERAL_CA_THRESHOLD`) the edges are taken in green and a warning says so
(benchmarks: p95 0.006 deg with green vs 0.024 deg with luminance at 5e-4).
"""

from __future__ import annotations

import functools
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any, Literal

import numpy as np

from cvmeasure.board import BoardSpec
from cvmeasure.camera import CameraModel
from cvmeasure.contracts import MachinePhotoResult, MarkerMeasurement, PlaneModel, Trial
from cvmeasure.errors import InputError
from cvmeasure.geometry import CircleFit, fit_circle_robust, fit_circles_robust
from cvmeasure.imageio import Photo, to_bgr8
from cvmeasure.kit import ROLES, MarkerKit
from cvmeasure.markers.angles import machine_angles
from cvmeasure.markers.colour import (
    ColourModel,
    ColourSpace,
    bgr8_to_space,
    kit_colour_model,
)
from cvmeasure.markers.detect import MarkerCandidate, find_markers
from cvmeasure.markers.heights import BOUND_TILT_DEG, fallback_focal_px, height_parallax
from cvmeasure.markers.refine import (
    CENTRE_FLOOR_PX,
    EDGE_MODES,
    FIT_STOP_PX,
    UNEVEN_RING_SPREAD,
    channel_shifts_px,
    disc_edge_points,
    edge_ray_count,
    ray_correlation_factor,
)
from cvmeasure.markers.seed_baseline import seed_find_circles

__all__ = [
    "Method",
    "METHODS",
    "MarkerMeasurement",
    "MachinePhotoResult",
    "MarkerNotFoundError",
    "measure_machine_photo",
    "measure_photo_file",
    "measure_trial",
    "refine_candidate",
    "refine_candidates",
    "lateral_ca_estimate",
    "LATERAL_CA_THRESHOLD",
    "SEED_CENTRE_SIGMA_PX",
]

Method = Literal["ours", "seed"]
METHODS: tuple[str, ...] = ("ours", "seed")
#: How marker heights are treated without a plane pose: "none" (bounded, warned
#: about) or "parallel" (corrected assuming a camera square to the plate; needs a camera).
HeightMode = Literal["none", "parallel"]
HEIGHT_MODES: tuple[str, ...] = ("none", "parallel")
#: Height bounds (deg) below this are not warned about (the heights barely matter).
HEIGHT_WARN_DEG = 1e-3

#: Centre standard uncertainty (px per axis) stated for the seed method's Hough centres.
SEED_CENTRE_SIGMA_PX = 0.5
#: Fewest edge points a disc needs for a centre.
MIN_EDGE_POINTS = 12
#: Warning thresholds.
HIDDEN_COVERAGE = 0.9
OVEREXPOSED_FRACTION = 0.5
FAR_DELTA_E = 25.0
#: A ring median channel at or above this (8-bit) counts as clipped: no white to balance on.
RING_CLIPPED_LEVEL = 250.0
LOW_CONTRAST = 25.0
#: Lateral chromatic aberration (red magnified by 1 + k, blue by 1 - k about the
#: image centre) estimated at or above this ``|k|`` switches luminance edges to green
#: ones (luminance edges: p95 0.024 deg at k = 5e-4 in benchmarks/markers.py). JPEG
#: chroma subsampling makes the estimate read ~0.55-0.9 of the true k; photos
#: without lateral colour read |k| < 1.3e-4 at 0.3 scale, < 2e-5 at full size.
LATERAL_CA_THRESHOLD = 2e-4
#: Markers measured on a plane whose size differs from the kit's by more than this
#: (median over the discs) mean the plane is from another camera pose or distance.
PLANE_SCALE_TOLERANCE = 0.02
#: Discs that come out elliptic on the plane by more than this, all in one direction,
#: mean the plane's tilt is not the photo's. A coarse check: JPEG edges already make
#: round discs read ~0.2 % elliptic, and a plane tilted 3 deg off (0.04 deg of angle
#: error) reads only ~0.3 % (benchmarks: the scale check catches another distance).
PLANE_SHAPE_TOLERANCE = 0.005
#: How many discs (the farthest from the image centre) the lateral-colour probe reads.
LATERAL_CA_PROBES = 3


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


@dataclass(frozen=True)
class _Transform:
    """Image pixels -> the measurement frame of the angles (``plane``: the pose's plane)."""

    name: str
    func: Any = None
    y_down: bool = True
    plane: PlaneModel | None = None

    def at_height(self, height_mm: float) -> _Transform:
        """The same frame for points ``height_mm`` above the plate (only a plane pose can)."""
        if self.plane is None or height_mm == 0.0:
            return self
        return replace(
            self, func=functools.partial(self.plane.image_to_plane_mm, height_mm=height_mm)
        )

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        return pts if self.func is None else np.asarray(self.func(pts), dtype=np.float64)

    def jacobian(self, xy: tuple[float, float], h: float = 0.5) -> np.ndarray:
        return self.mapped_with_jacobian(xy, np.zeros((0, 2)), h)[0]

    def mapped_with_jacobian(
        self, xy: tuple[float, float], pts: np.ndarray, h: float = 0.5
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Jacobian at ``xy`` by central differences of ``h`` px, ``xy`` mapped, ``pts`` mapped).

        One call of the mapping for all three (it maps each point on its own).
        """
        return self.mapped_with_jacobians([xy], [pts], h)[0]

    def mapped_with_jacobians(
        self, xys: list[tuple[float, float]], pts: list[np.ndarray], h: float = 0.5
    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """:meth:`mapped_with_jacobian` of several centres and their points, in one call
        of the mapping (it maps each point on its own: the same values)."""
        arrays = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in pts]
        if self.func is None:
            return [
                (np.eye(2), np.array(xy, dtype=np.float64), a)
                for xy, a in zip(xys, arrays, strict=True)
            ]
        parts = []
        for (x, y), a in zip(xys, arrays, strict=True):
            parts += [[[x + h, y], [x - h, y], [x, y + h], [x, y - h], [x, y]], a]
        q = self(np.vstack(parts))
        out, k = [], 0
        for a in arrays:
            qi = q[k : k + 5 + len(a)]
            k += 5 + len(a)
            jac = np.column_stack(((qi[0] - qi[1]) / (2 * h), (qi[2] - qi[3]) / (2 * h)))
            out.append((jac, qi[4], qi[5:]))
        return out


def _transform(
    camera: CameraModel | None, plane: PlaneModel | None, shape: tuple[int, ...], source: str
) -> _Transform:
    h, w = shape[:2]
    if plane is not None:
        own = plane.for_image((w, h), source)
        t = _Transform("plane", own.image_to_plane_mm)
        det = float(np.linalg.det(t.jacobian(((w - 1) / 2, (h - 1) / 2))))
        return _Transform("plane", own.image_to_plane_mm, y_down=det > 0, plane=own)
    if camera is not None:
        return _Transform("undistorted", camera.for_image((w, h), source).undistort_px)
    return _Transform("image")


def refine_candidate(
    bgr: np.ndarray, cand: MarkerCandidate, ring_ratio: float, *, edge: str | None = None
) -> tuple[CircleFit, Any] | str:
    """Sub-pixel circle of one found disc (image px) and its edge points, or why there is none.

    Edge points are re-extracted around the refined circle until it stops moving
    (at most three passes); where its ring is unevenly lit (a shadow across the
    marker), a last pass takes each ray's edge against that ray's own levels.
    """
    return refine_candidates(bgr, [cand], [ring_ratio], edge=edge)[0]


def refine_candidates(
    bgr: np.ndarray,
    cands: list[MarkerCandidate],
    ring_ratios: list[float],
    *,
    edge: str | None = None,
) -> list[tuple[CircleFit, Any] | str]:
    """:func:`refine_candidate` of several discs, their passes' circles fitted together.

    Each disc's passes, circles and result are those :func:`refine_candidate` gives it
    alone (:func:`cvmeasure.geometry.fit_circles_robust`: the same fits, one call per
    pass for all the discs still refining).
    """
    n = len(cands)
    centres = [c.centre_px for c in cands]
    radii = [c.radius_px for c in cands]
    fits: list[CircleFit | None] = [None] * n
    local = [False] * n  # the last pass, when the ring is unevenly lit: each ray's own levels
    passes = [0] * n
    results: list[tuple[CircleFit, Any] | str | None] = [None] * n
    pending = list(range(n))
    while pending:
        todo, edges_of = [], {}
        for i in pending:
            edges = disc_edge_points(
                bgr, centres[i], radii[i], ring_ratios[i], edge=edge, local_levels=local[i]
            )
            n_points = edges.points_px.shape[0]
            if local[i] and n_points < max(MIN_EDGE_POINTS, 0.3 * edge_ray_count(radii[i])):
                results[i] = (
                    "too little of its edge is clear of the shadow or cover across it "
                    f"({n_points} edge points)"
                )
            elif n_points < MIN_EDGE_POINTS:
                results[i] = f"no clear edge around it (contrast {edges.contrast:.0f}/255)"
            else:
                todo.append(i)
                edges_of[i] = edges
        got = fit_circles_robust(
            [edges_of[i].points_px for i in todo],
            inits=[
                None if (f := fits[i]) is None else (f.centre[0], f.centre[1], f.radius)
                for i in todo
            ],
            correlation_factors=[ray_correlation_factor(radii[i]) for i in todo],
            stop=FIT_STOP_PX,
        )
        pending = []
        for i, fit in zip(todo, got, strict=True):
            if fit is None:
                results[i] = "its edge points do not form a circle"
                continue
            moved = math.hypot(fit.centre[0] - centres[i][0], fit.centre[1] - centres[i][1])
            if not (0.5 * cands[i].radius_px < fit.radius < 1.6 * cands[i].radius_px):
                results[i] = (
                    f"its edge is not a circle of the expected size (r {fit.radius:.1f} px)"
                )
                continue
            fits[i], centres[i], radii[i] = fit, fit.centre, fit.radius
            passes[i] += 1
            if local[i]:
                results[i] = (fit, edges_of[i])
                continue
            if moved < 0.05 * radii[i] or passes[i] >= 3:
                if edges_of[i].ring_spread < UNEVEN_RING_SPREAD:
                    results[i] = (fit, edges_of[i])
                    continue
                local[i] = True  # settled on a circle: its ring samples now fall on the ring
            pending.append(i)
    return results  # type: ignore[return-value]


def _colour_delta_e(
    kit: MarkerKit, edges: Mapping[str, Any], search_white: Any = None
) -> dict[str, float]:
    """CIE76 difference between each disc's colour, balanced on the rings' white, and the kit's.

    Where the rings are clipped their median is no white (it loses the cast), so
    the white the marker search used (``search_white``) is taken instead.
    """
    from cvmeasure.markers.colour import WhiteEstimate

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


def _anisotropy(offsets: np.ndarray) -> np.ndarray:
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


def _split_half_cov(points_px: np.ndarray, fit: CircleFit) -> np.ndarray:
    """Centre covariance (px^2) from how fits to halves of the edge disagree with the whole.

    The inlier edge points are split in two halves round the centre, four ways (the
    split line every 45 deg); each half's circle, fitted with the radius free,
    differs from the whole's centre by ``d``; returns the mean of ``d d^T`` over the
    eight halves. For a whole, clean edge this is a few times the sampling
    covariance; for an edge bent by a cover or a shadow's edge, its systematic part.
    """
    pts = np.asarray(points_px, dtype=np.float64)
    c = np.asarray(fit.centre)
    off = pts - c
    resid = np.abs(np.hypot(off[:, 0], off[:, 1]) - fit.radius)
    keep = resid < 3.0 * max(fit.rms_residual, 0.05)
    pts, off = pts[keep], off[keep]
    theta = np.arctan2(off[:, 1], off[:, 0])
    diffs = []
    for split in np.radians([0.0, 45.0, 90.0, 135.0]):
        side = np.mod(theta - split, 2 * math.pi) < math.pi
        for half in (side, ~side):
            if half.sum() < MIN_EDGE_POINTS:
                continue
            try:
                part = fit_circle_robust(pts[half], init=(c[0], c[1], fit.radius), stop=FIT_STOP_PX)
            except (ValueError, np.linalg.LinAlgError):
                continue
            diffs.append(np.asarray(part.centre) - c)
    if not diffs:
        return np.zeros((2, 2))
    d = np.asarray(diffs)
    return d.T @ d / len(d)


def _marker_warnings(role: str, fit: CircleFit, edges: Any, delta_e: float | None) -> list[str]:
    out = []
    if fit.coverage < HIDDEN_COVERAGE:
        out.append(
            f"marker {role!r} partly hidden ({100 * fit.coverage:.0f} % of its edge visible)"
        )
    if edges.clipped_fraction > OVEREXPOSED_FRACTION:
        out.append(
            f"marker {role!r} overexposed ({100 * edges.clipped_fraction:.0f} % of its ring clipped)"
        )
    if edges.ring_spread >= UNEVEN_RING_SPREAD:
        out.append(
            f"marker {role!r} unevenly lit (its ring's level varies by {100 * edges.ring_spread:.0f}"
            " % of the disc-to-ring step: a shadow or an object across it?); edges taken "
            "against each ray's own levels"
        )
    if edges.contrast < LOW_CONTRAST:
        out.append(f"marker {role!r} has low contrast ({edges.contrast:.0f}/255)")
    if delta_e is not None and delta_e > FAR_DELTA_E:
        out.append(
            f"marker {role!r} colour far from the kit (Delta E {delta_e:.0f} after white balance)"
        )
    return out


def _measure_ours(
    bgr: np.ndarray,
    bgr8: np.ndarray,
    kit: MarkerKit,
    model: ColourModel,
    transform: _Transform,
    source: str,
    edge: str | None = None,
) -> tuple[dict[str, MarkerMeasurement], dict[str, np.ndarray], dict[str, np.ndarray], list[str]]:
    search = find_markers(bgr8, kit, model)
    failures = dict(search.failures)
    markers: dict[str, MarkerMeasurement] = {}
    centres: dict[str, np.ndarray] = {}
    covs: dict[str, np.ndarray] = {}
    warnings: list[str] = []
    fits: dict[str, tuple[CircleFit, Any]] = {}
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
    if edge is None:
        # default luminance edges: probe the discs farthest from the image centre
        # (ROIs only) for lateral colour and take the edges in green where it is strong
        mid = ((bgr.shape[1] - 1) / 2.0, (bgr.shape[0] - 1) / 2.0)
        far = sorted(fits, key=lambda r: -math.dist(fits[r][0].centre, mid))[:LATERAL_CA_PROBES]
        shifts = {}
        for role in far:
            fit, edges = fits[role]
            shifts[role] = channel_shifts_px(
                bgr, fit.centre, fit.radius, edges.disc_bgr, edges.ring_bgr
            )
        k = lateral_ca_estimate(shifts, {r: f.centre for r, (f, _) in fits.items()}, bgr.shape)
        if k is not None and abs(k) >= LATERAL_CA_THRESHOLD:
            for role in list(fits):
                spec = kit.by_role(role)
                got = refine_candidate(
                    bgr, search.found[role], spec.ring_mm / spec.diameter_mm, edge="green"
                )
                if not isinstance(got, str):
                    fits[role] = got
            corner_px = abs(k) * 0.5 * math.hypot(bgr.shape[1], bgr.shape[0])
            warnings.append(
                f"lateral chromatic aberration detected ({corner_px:.1f} px at the corners):"
                " edges taken in green"
            )
    delta_e = _colour_delta_e(kit, {r: e for r, (_, e) in fits.items()}, search.white)
    plane_scale: list[float] = []
    plane_shape: list[np.ndarray] = []
    cov_imgs: dict[str, np.ndarray] = {}
    for role, (fit, edges) in fits.items():
        cov_img = fit.covariance + np.eye(2) * CENTRE_FLOOR_PX**2
        if fit.coverage < HIDDEN_COVERAGE or edges.ring_spread >= UNEVEN_RING_SPREAD:
            # partly hidden or in a shadow: what the edge's two halves disagree on, too
            cov_img = cov_img + _split_half_cov(edges.points_px, fit)
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
        if transform.func is None:
            centres[role] = np.array(fit.centre)
            covs[role] = cov_img
        warnings.extend(_marker_warnings(role, fit, edges, delta_e.get(role)))
    if transform.func is not None:
        # on a plane pose, each disc's edge goes to its own height above the plate; the
        # discs at one height mapped in one call, their circles fitted together
        heights = {r: kit.height_mm(r) if kit.has_heights else 0.0 for r in fits}
        mapped: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        for height in dict.fromkeys(heights.values()):
            group = [r for r in fits if heights[r] == height]
            got = transform.at_height(height).mapped_with_jacobians(
                [fits[r][0].centre for r in group], [fits[r][1].points_px for r in group]
            )
            mapped.update(zip(group, got, strict=True))
        roles = list(fits)
        inits = []
        for role in roles:
            jac, c_f, _ = mapped[role]
            inits.append(
                (c_f[0], c_f[1], fits[role][0].radius * math.sqrt(abs(np.linalg.det(jac))))
            )
        fits_f = fit_circles_robust(
            [mapped[r][2] for r in roles],
            inits=inits,
            correlation_factors=[ray_correlation_factor(fits[r][0].radius) for r in roles],
            stop=FIT_STOP_PX,
        )
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
            covs[role] = jac @ cov_imgs[role] @ jac.T
            if transform.name == "plane":
                plane_scale.append(fit_f.radius / (0.5 * kit.by_role(role).diameter_mm))
                if fit.coverage >= HIDDEN_COVERAGE:
                    plane_shape.append(_anisotropy(pts_f - np.asarray(fit_f.centre)))
    if plane_scale:
        ratio = float(np.median(plane_scale))
        if abs(ratio - 1.0) > PLANE_SCALE_TOLERANCE:
            warnings.append(
                f"the markers measure {100 * (ratio - 1):+.1f} % in size on the plane against "
                "the kit's diameters: the plane is probably from another camera pose or "
                "distance (measure the plane again from this pose)"
            )
    if len(plane_shape) >= 3:
        shape = np.asarray(plane_shape)
        mean = shape.mean(axis=0)
        se = shape.std(axis=0, ddof=1) / math.sqrt(len(shape))
        size = float(np.hypot(*mean))
        if size > PLANE_SHAPE_TOLERANCE and size > 3.0 * float(np.hypot(*se)):
            warnings.append(
                f"the discs come out {100 * size:.1f} % elliptic on the plane, all alike: the "
                "plane's tilt is not this photo's (measure the plane again from this pose)"
            )
    if search.white.clipped_fraction > 0.5:
        warnings.append("photo overexposed (the brightest pixels are clipped)")
    return markers, centres, covs, warnings


def _measure_seed(
    bgr8: np.ndarray, kit: MarkerKit, space: str, transform: _Transform, source: str
) -> tuple[dict[str, MarkerMeasurement], dict[str, np.ndarray], dict[str, np.ndarray], list[str]]:
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
        f"marker {r!r}: {c.n_circles} circles, took the first"
        for r, c in circles.items()
        if c.n_circles > 1
    ]
    return markers, centres, covs, warnings


def measure_machine_photo(
    bgr: np.ndarray,
    kit: MarkerKit,
    *,
    camera: CameraModel | None = None,
    plane: Any = None,
    method: Method = "ours",
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
    method : "ours" (colour model + sub-pixel fits) or "seed" (the paper's baseline).
    space : colour space of the segmentation, "lab" or "rgb".
    colour_model : a learnt colour model; the kit's colours (adapted to the photo's light) when None.
    linear : the image holds linear (gamma 1) data, e.g. from RAW.
    edge : where disc edges are found: "luma" (JPEG's full-resolution component), "green"
        (immune to lateral chromatic aberration) or "colour" (see
        :data:`cvmeasure.markers.refine.EDGE_MODE`). Default: "luma" for 8-bit photos
        (JPEGs), switched to "green" with a warning where the discs show lateral
        chromatic aberration; "green" for RAW/linear or 16-bit data.
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
    from cvmeasure.jpegplanes import LazyBGR

    # a LazyBGR (pixels made where read: measure_photo_file's JPEG path) stays one where
    # only regions and the search's copy are read; else its whole image is made here
    lazy = isinstance(bgr, LazyBGR) and not linear and method == "ours"
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
    if method == "seed":
        if camera is not None or plane is not None:
            raise ValueError(
                "the seed method measures in image pixels: it takes no camera or plane"
            )
        transform = _Transform("image")
        markers, centres, covs, warnings = _measure_seed(bgr8, kit, space, transform, source)
    else:
        transform = _transform(camera, plane, img.shape, source)
        model = colour_model or kit_colour_model(kit, space)
        work = bgr8 if linear or img.dtype == np.uint8 else img
        if edge is None and (linear or img.dtype != np.uint8):
            # RAW or 16-bit data: no chroma subsampling to avoid, and no in-camera
            # lateral-colour correction either, so the green channel is the better edge
            edge = "green"
        markers, centres, covs, warnings = _measure_ours(
            work, bgr8, kit, model, transform, source, edge
        )
        if not kit.has_heights:
            height_state = "flat"
            warnings.append(
                "the kit gives no marker heights: measured as if every disc lay on the plate "
                "(put each disc's height_mm above the plate in the kit JSON)"
            )
        elif transform.plane is not None:
            height_state = "plane"
        else:
            height_state, height_bound = _heights_without_pose(
                centres, covs, markers, kit, camera, img.shape, transform, heights, warnings
            )
    try:
        angles = machine_angles(centres, covs, y_down=transform.y_down)
    except ValueError as exc:
        raise InputError(source, str(exc)) from None
    return MachinePhotoResult(
        angles.pin_angle_deg,
        angles.bend_angle_deg,
        markers,
        {"pin_angle_deg": angles.pin_sigma_deg, "bend_angle_deg": angles.bend_sigma_deg},
        tuple(warnings),
        photo,
        method,
        space,
        transform.name,
        height_state,
        height_bound,
    )


def _heights_without_pose(
    centres: dict[str, np.ndarray],
    covs: dict[str, np.ndarray],
    markers: Mapping[str, MarkerMeasurement],
    kit: MarkerKit,
    camera: CameraModel | None,
    shape: tuple[int, ...],
    transform: _Transform,
    mode: str,
    warnings: list[str],
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
        what = (
            f"marker heights corrected assuming a camera square to the plate ({par.distance_mm:.0f}"
            f" mm above it): for a tilt up to {BOUND_TILT_DEG:g} deg the angles may still be off"
        )
    else:
        bound = par.bound_none_deg
        what = (
            "marker heights not applied (no plane pose: give --plane or --board): the "
            "angles may be off"
        )
    if max(bound.values()) >= HEIGHT_WARN_DEG:
        warnings.append(
            f"{what} by up to {bound['pin_angle_deg']:.3f} deg (pin) and "
            f"{bound['bend_angle_deg']:.3f} deg (bend) (height_bound_deg; camera "
            f"{par.distance_mm:.0f} mm above the plate from the discs' sizes and {lens})"
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
    from cvmeasure.imageio import read_photo

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
        from cvmeasure.calibration.plane import estimate_plane

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
    libturbojpeg, a linear file or options this path does not take (method "seed").
    """
    from pathlib import Path

    from cvmeasure import jpegplanes
    from cvmeasure.imageio import MAX_PHOTO_PIXELS, is_jpeg_data, is_linear_name, is_raw

    p = Path(path)
    if (
        options.get("method", "ours") != "ours"
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
