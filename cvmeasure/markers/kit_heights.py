"""Measuring the markers' heights above the plate from photos (``cvmeasure markers heights``).

A kit's heights are what each marker's face stands above the top plate; the angles
measured on a plane pose are as good as those heights (caps 10 % off their nominal
heights move the angles by tenths of a degree under a tilted camera). This step
measures them on the user's machine, from photos taken from the plane's pose:

* **bend photos** at several pin and bend angles (the pin holding the wire against
  the die: loaded photos). The pin marker turns about the die's axis, where the
  origin marker sits, and so do ``wire_a`` and ``wire_b`` (they ride on the bent leg,
  which leaves the die tangentially: the leg turns about the die's axis as it
  bends). Each of them therefore keeps one distance from the origin marker over the
  sweep, but only when every marker is mapped to the plane at its true height: a
  wrong height moves a marker about the camera's foot point (planes at two heights
  are a homothety about it), by an amount that depends on where it is.
* **straight photos** (optional, recommended): the wire fed straight, no bend. Then
  ``wire_a -> wire_b`` is parallel to ``axis -> origin`` (bend angle 0): it fixes
  the heights of the wire markers against the axis marker.

The heights are the least-squares solution of those conditions, each photo's
residuals whitened by their joint covariance from the centres' (they share the
origin marker's centre), with the kit's nominal heights as a prior:
each cap within :data:`~cvmeasure.markers.heights.NOMINAL_HEIGHT_TOLERANCE` of its
nominal height, as a rectangular distribution (standard uncertainty
``tolerance * height / sqrt(3)``). What the photos cannot see, every marker's
distance to the camera scaled by one factor (a near-common shift of the heights),
moves every disc by one homothety about the camera's foot point and so changes no
angle; it stays at the nominal heights with the prior's uncertainty, which thus
states the heights honestly without reaching the angles' sigma. The result is the kit with the measured ``height_mm``, their
``height_sigma_mm`` and their covariance ``height_covariance_mm2``, which a
measurement on a plane pose carries into every angle's uncertainty, and the plane's pose
(``heights_pose``). Fitted through that plane, the heights take up the errors it puts on
every photo (its pose's, the lens's, and each disc edge's pose-constant bias); a photo
measured through the same plane carries those errors again and they largely cancel, what
is left being about the fit's own scatter, which the covariance states (scaled by the
residuals' RMS), and the measurement leaves that bias out of the angles' sigma
(:func:`cvmeasure.markers.heights.heights_take_up_bias`). Through another
plane they do not cancel: a measurement warns (``heights_other_plane``).

Frames: the plate's frame of the plane pose (board frame), mm; heights along the
plate's normal towards the camera.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.linalg import block_diag
from scipy.optimize import least_squares

from cvmeasure.geometry import wrap_deg
from cvmeasure.kit import ROLES, HeightsPose, MarkerKit
from cvmeasure.markers.angles import pin_bend_deg
from cvmeasure.markers.heights import NOMINAL_HEIGHT_TOLERANCE, move_to_heights
from cvmeasure.warning import StageWarning

__all__ = ["SweepPhoto", "MeasuredHeights", "measure_heights", "prior_sigmas_mm", "PRIOR_SIGMA_MM"]

#: Standard uncertainty (mm) of a marker the kit gives no height (a flat sticker in the
#: kit, caps perhaps on the machine): nothing is known, a cap's few millimetres.
PRIOR_SIGMA_MM = 2.0
#: The roles that turn about the die's axis over a sweep.
TURNING = ("pin", "wire_a", "wire_b")
#: Fewest photos for a fit, and the smallest span of pin angles (deg) that is a sweep.
MIN_PHOTOS = 3
MIN_SPAN_DEG = 30.0
#: Smallest scale of the heights' covariance by the residuals' RMS (see measure_heights).
MIN_BIRGE = 0.5
#: Singular values of the photos' whitened Jacobian below this fraction of the largest:
#: directions the photos do not see (those seen are 1e-2 or more, the unseen 1e-5 or less).
DATA_RANK_RTOL = 1e-4
#: Whitened residuals' RMS above this: the photos disagree with the turning-markers model.
POOR_FIT_RMS = 3.0


@dataclass(frozen=True)
class SweepPhoto:
    """One photo's disc centres on the plate (mm), each mapped at the kit's height.

    ``straight``: the wire was straight in this photo (bend angle 0).
    """

    centres_mm: dict[str, np.ndarray]
    covariances_mm2: dict[str, np.ndarray]
    straight: bool = False
    source: str = ""


@dataclass(frozen=True)
class MeasuredHeights:
    """The measured heights and the kit that carries them.

    ``kit`` is the input kit with ``height_mm``, ``height_sigma_mm`` and
    ``height_covariance_mm2`` measured; ``nominal_mm`` the heights it started from;
    ``radii_mm`` the fitted distances of the turning markers from the origin marker;
    ``rms`` the RMS of the photos' residuals in units of their standard uncertainty, per
    degree of freedom (about 1 when the photos agree with the model); ``warnings`` what is
    in doubt.
    """

    kit: MarkerKit
    nominal_mm: dict[str, float]
    radii_mm: dict[str, float]
    rms: float
    n_photos: int
    n_straight: int
    warnings: tuple[StageWarning, ...] = ()

    @property
    def heights_mm(self) -> dict[str, float]:
        return {r: self.kit.height_mm(r) for r in ROLES}

    @property
    def sigma_mm(self) -> dict[str, float]:
        return {r: float(self.kit.by_role(r).height_sigma_mm or 0.0) for r in ROLES}

    def to_dict(self) -> dict[str, Any]:
        return {
            "heights_mm": {r: round(v, 4) for r, v in self.heights_mm.items()},
            "height_sigma_mm": {r: round(v, 4) for r, v in self.sigma_mm.items()},
            "nominal_mm": self.nominal_mm,
            "radii_mm": {r: round(v, 4) for r, v in self.radii_mm.items()},
            "rms": round(self.rms, 3),
            "n_photos": self.n_photos,
            "n_straight": self.n_straight,
            "warnings": [w.to_json() for w in self.warnings],
            "kit": self.kit.to_dict(),
        }


def _photo_residuals(
    c: dict[str, np.ndarray], radii: dict[str, float], straight: bool, y_down: bool
) -> np.ndarray:
    """One photo's raw residuals: each turning marker's distance from the origin marker
    less its radius (mm), and on a straight-wire photo the bend angle (deg)."""
    out = [float(np.hypot(*(c[role] - c["origin"]))) - radii[role] for role in TURNING]
    if straight:
        out.append(float(wrap_deg(pin_bend_deg(c, y_down=y_down)[1])))
    return np.asarray(out)


def _photo_whitening(photo: SweepPhoto, y_down: bool, step_mm: float = 1e-3) -> np.ndarray:
    """The matrix that whitens one photo's residuals (:func:`_photo_residuals`) by their
    joint covariance, from the centres' covariances.

    The residuals share centres: the origin marker's error enters every distance, and the
    wire markers' the bend too. Weighted one by one, each residual counted the shared
    centres' error afresh (the origin marker's three times in every photo), so the photos
    claimed more about the heights than they hold.
    """
    c = {r: np.asarray(v, dtype=np.float64) for r, v in photo.centres_mm.items()}
    zero = dict.fromkeys(TURNING, 0.0)
    cols, covs = [], []
    for role in ROLES:
        for axis in range(2):
            d = np.zeros(2)
            d[axis] = step_mm
            up = _photo_residuals({**c, role: c[role] + d}, zero, photo.straight, y_down)
            down = _photo_residuals({**c, role: c[role] - d}, zero, photo.straight, y_down)
            step = up - down
            if photo.straight:
                step[-1] = float(wrap_deg(step[-1]))
            cols.append(step / (2 * step_mm))
        covs.append(np.asarray(photo.covariances_mm2[role], dtype=np.float64))
    jac = np.column_stack(cols)
    cov = jac @ block_diag(*covs) @ jac.T
    try:
        return np.linalg.inv(np.linalg.cholesky(cov))
    except np.linalg.LinAlgError:
        raise ValueError(
            f"{photo.source or 'a photo'}: its centres' covariances give its residuals no "
            "positive variance"
        ) from None


def _residuals(
    x: np.ndarray,
    photos: Sequence[SweepPhoto],
    kit_mm: dict[str, float],
    prior_mm: np.ndarray,
    prior_sigma_mm: np.ndarray,
    camera_centre_mm: np.ndarray,
    y_down: bool,
    whitening: Sequence[np.ndarray],
) -> np.ndarray:
    heights = dict(zip(ROLES, x[: len(ROLES)], strict=True))
    radii = dict(zip(TURNING, x[len(ROLES) :], strict=True))
    out: list[np.ndarray] = []
    for photo, white in zip(photos, whitening, strict=True):
        c = move_to_heights(photo.centres_mm, kit_mm, heights, camera_centre_mm)
        out.append(white @ _photo_residuals(c, radii, photo.straight, y_down))
    out.append((x[: len(ROLES)] - prior_mm) / prior_sigma_mm)
    return np.concatenate(out)


def prior_sigmas_mm(kit: MarkerKit) -> np.ndarray:
    """Standard uncertainty (mm) of each nominal height in :data:`ROLES` order.

    A printed cap stands within :data:`NOMINAL_HEIGHT_TOLERANCE` of its nominal height,
    any value in it as likely (GUM's rectangular distribution: ``a / sqrt(3)`` for a
    half-width ``a``); a marker without a height: :data:`PRIOR_SIGMA_MM`.
    """
    tol = NOMINAL_HEIGHT_TOLERANCE / math.sqrt(3.0)
    return np.array([tol * h if (h := kit.height_mm(r)) > 0 else PRIOR_SIGMA_MM for r in ROLES])


def measure_heights(
    photos: Sequence[SweepPhoto],
    kit: MarkerKit,
    camera_centre_mm: Any,
    *,
    y_down: bool = True,
    prior_sigma_mm: float | None = None,
    plane_pose: tuple[Any, Any] | None = None,
) -> MeasuredHeights:
    """Measure the markers' heights from a sweep of photos from one plane pose.

    Parameters
    ----------
    photos : the photos' centres on the plate, mapped at ``kit``'s heights
        (:func:`cvmeasure.markers.measure.frame_centres` on the plane pose).
    kit : the kit the centres were mapped with; its heights are the prior (a flat kit:
        0 mm each).
    camera_centre_mm : the plane pose's camera centre in the plate frame (3,), mm.
    y_down : the plate frame's handedness as the measurement sees it.
    prior_sigma_mm : standard uncertainty of every nominal height as the prior, mm; None:
        from the caps' tolerance (:func:`prior_sigmas_mm`).

    Raises
    ------
    ValueError
        Fewer than :data:`MIN_PHOTOS` photos, a photo without every role, or one whose
        centres' covariances leave its residuals no variance.
    """
    if len(photos) < MIN_PHOTOS:
        raise ValueError(f"need at least {MIN_PHOTOS} photos of a bend sweep, got {len(photos)}")
    if prior_sigma_mm is not None and prior_sigma_mm <= 0:
        raise ValueError("prior_sigma_mm must be > 0")
    for p in photos:
        missing = [r for r in ROLES if r not in p.centres_mm]
        if missing:
            raise ValueError(f"{p.source or 'a photo'} lacks {', '.join(missing)}")
    centre = np.asarray(camera_centre_mm, dtype=np.float64).reshape(3)
    kit_mm = {r: kit.height_mm(r) for r in ROLES}
    prior = np.array([kit_mm[r] for r in ROLES])
    prior_sigma = (
        prior_sigmas_mm(kit) if prior_sigma_mm is None else np.full(len(ROLES), prior_sigma_mm)
    )
    whitening = [_photo_whitening(p, y_down) for p in photos]
    radii0 = [
        float(np.median([np.hypot(*(p.centres_mm[r] - p.centres_mm["origin"])) for p in photos]))
        for r in TURNING
    ]
    args = (photos, kit_mm, prior, prior_sigma, centre, y_down, whitening)
    fit = least_squares(_residuals, np.concatenate((prior, radii0)), args=args, x_scale=1.0)
    n = len(ROLES)
    jac = np.asarray(fit.jac)
    data, prior_rows = jac[:-n], jac[-n:]
    # the photos' scatter from their own residuals: the directions they leave to the prior
    # (the unseen scale, the axis marker's height from a square pose) take none of their
    # degrees of freedom, and the prior's residuals (caps off their nominal heights) are
    # no scatter of the photos
    sv = np.linalg.svd(data, compute_uv=False)
    seen = int(np.sum(sv > DATA_RANK_RTOL * sv[0]))
    res = fit.fun[:-n]
    rms = math.sqrt(float(res @ res) / max(res.size - seen, 1))
    # the photos' part scaled by that scatter (the Birge ratio), both ways, never below
    # MIN_BIRGE of the stated one (a lucky few photos must not claim too much); the
    # prior's rows are not: the photos say nothing about it
    info = data.T @ data / max(rms, MIN_BIRGE) ** 2 + prior_rows.T @ prior_rows
    h_cov = np.linalg.pinv(info)[:n, :n]
    h_sigma = np.sqrt(np.diag(h_cov))
    markers = tuple(
        replace(
            kit.by_role(r),
            height_mm=round(float(fit.x[i]), 4),
            height_sigma_mm=round(float(h_sigma[i]), 4),
        )
        for i, r in enumerate(ROLES)
    )
    order = {m.role: m for m in markers}
    new_kit = replace(
        kit,
        name=f"{kit.name.removesuffix('-flat')}-heights",
        markers=tuple(order[m.role] for m in kit.markers),
        height_covariance_mm2=_rows(h_cov),
        heights_pose=None if plane_pose is None else HeightsPose.of(*plane_pose),
    )
    warnings = _sweep_warnings(photos, rms, y_down)
    return MeasuredHeights(
        new_kit,
        kit_mm,
        {r: float(v) for r, v in zip(TURNING, fit.x[n:], strict=True)},
        rms,
        len(photos),
        sum(p.straight for p in photos),
        tuple(warnings),
    )


def _rows(cov: np.ndarray) -> tuple[tuple[float, ...], ...]:
    """A covariance as the kit holds it, made exactly symmetric."""
    sym = 0.5 * (cov + cov.T)
    return tuple(tuple(float(v) for v in row) for row in sym)


def _sweep_warnings(photos: Sequence[SweepPhoto], rms: float, y_down: bool) -> list[StageWarning]:
    """What a sweep leaves in doubt: too narrow, no straight photo, a poor fit."""
    out = []
    pins = np.array([pin_bend_deg(p.centres_mm, y_down=y_down)[0] for p in photos])
    span = float(np.ptp(np.unwrap(np.radians(pins)))) * 180.0 / math.pi
    if span < MIN_SPAN_DEG:
        out.append(
            StageWarning(
                "heights_sweep_narrow",
                f"the pin turns through only {span:.0f} deg over these photos: the heights "
                f"are poorly seen (photograph bends over at least {MIN_SPAN_DEG:.0f} deg, "
                "both directions)",
                "sweep",
            )
        )
    if not any(p.straight for p in photos):
        out.append(
            StageWarning(
                "heights_no_straight",
                "no photo of the straight wire: the wire markers' heights against the axis "
                "marker's are left to the kit's nominal values and their prior uncertainty "
                "(add one or more with --straight)",
                "sweep",
            )
        )
    if rms > POOR_FIT_RMS:
        out.append(
            StageWarning(
                "heights_fit_poor",
                f"the photos disagree with markers turning about the die's axis ({rms:.1f} "
                "standard uncertainties RMS): were they taken from the plane's pose, with the "
                "pin holding the wire against the die?",
                "sweep",
            )
        )
    return out
