"""Marker colours: white balance, chromatic adaptation and learnt colour classifiers.

The seed paper typed LAB/RGB thresholds by hand for one light. Here a
classifier is *derived*: each role is a Gaussian in a colour space (mean and
covariance), a pixel belongs to the nearest role by Mahalanobis distance when
that distance is below ``max_distance``. The means come from the kit JSON
(``lab_d65`` / ``srgb``) or are learnt from a reference photo; the photo is
first brought to D65 by a white balance measured on the photo itself (the
brightest unclipped pixels: the markers' white rings) and a chromatic
adaptation to D65: per-channel gains in linear RGB (von Kries in the camera's
RGB, the default: it undoes a camera's white-balance error exactly) or CAT02
(colour-science, perceptual).

Spaces
------
``"lab"`` : CIE L*a*b* under D65 (not OpenCV's 8-bit scaling), after adaptation.
``"rgb"`` : white-balanced, gamma-encoded sRGB in 0..255, after adaptation.

Speed: pixels are classified through a lookup table over 15-bit quantised
colours (32 levels per channel) computed only for the colours that occur, so
the colour science runs on a few thousand colours, not on every pixel.

colour-science is imported only for the CAT02 adaptation (one to two seconds on
import); the default adaptation never loads it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache
from typing import Any, Literal

import cv2
import numpy as np

from cvmeasure.colorimetry import (
    D65_XYZ,
    SRGB8_TO_LINEAR,
    SRGB_TO_XYZ,
    XYZ_TO_SRGB,
    srgb_decode,
    srgb_encode,
    xyz_to_lab_d65,
)
from cvmeasure.kit import ROLES, MarkerKit

__all__ = [
    "ColourSpace",
    "COLOUR_SPACES",
    "ADAPTATIONS",
    "WhiteEstimate",
    "ColourModel",
    "estimate_white",
    "adaptation_matrix",
    "bgr8_to_space",
    "kit_colour_model",
    "learnt_colour_model",
    "classify_bgr8",
    "DEFAULT_SIGMA",
    "RING_WHITE_Y",
    "CLIPPED_WHITE_FRACTION",
]

ColourSpace = Literal["lab", "rgb"]
COLOUR_SPACES: tuple[str, ...] = ("lab", "rgb")
#: Ways to bring the photo's white to D65 (see :func:`adaptation_matrix`).
ADAPTATIONS: tuple[str, ...] = ("rgb-gain", "cat02")

#: Default per-channel standard deviation of a marker's colour in each space
#: (shading, print and light variation left after white balance).
DEFAULT_SIGMA: dict[str, tuple[float, float, float]] = {
    "lab": (16.0, 9.0, 9.0),
    "rgb": (18.0, 18.0, 18.0),
}

_QUANT_SHIFT = 3  # 8-bit -> 5-bit per channel for the lookup table
#: Luminance factor Y of the markers' white rings against a perfect white diffuser
#: (white paper or white PLA: about L* 93); the measured white is mapped to it.
RING_WHITE_Y = 0.84
#: Share of the brightest pixels clipped above which the white's colour may be taken
#: from neutral pixels well below clipping (see :func:`estimate_white`).
CLIPPED_WHITE_FRACTION = 0.5
_SAFE_LINEAR = 0.7  # linear level (of full scale) below which a pixel is safe from clipping
_NEUTRAL_TOP_FRACTION = 0.005  # share of the safe pixels, the brightest, used for the colour


@dataclass(frozen=True)
class WhiteEstimate:
    """The photo's white: mean gamma-encoded sRGB (0..255, R, G, B order) of the whitest pixels.

    ``n_pixels`` is how many pixels it came from; ``clipped_fraction`` the share of
    the brightest pixels that had a clipped channel (a hint of overexposure).
    """

    srgb8: tuple[float, float, float]
    n_pixels: int
    clipped_fraction: float

    def to_dict(self) -> dict[str, Any]:
        return {
            "srgb8": [round(v, 2) for v in self.srgb8],
            "n_pixels": self.n_pixels,
            "clipped_fraction": round(self.clipped_fraction, 4),
        }


def estimate_white(
    bgr8: np.ndarray,
    *,
    top_fraction: float = 0.002,
    recover_clipped: bool = False,
    gray: np.ndarray | None = None,
    channels: tuple[np.ndarray, ...] | None = None,
) -> WhiteEstimate:
    """Estimate the light's white from the brightest unclipped pixels (the white rings).

    Its colour comes from the brightest unclipped pixels; where the rings are
    overexposed, its level is raised to that of the brightest pixels (so values
    above 255 are possible: the white lies beyond the sensor's range).

    With ``recover_clipped`` and more than ``CLIPPED_WHITE_FRACTION`` of the
    brightest pixels clipped (a strong cast drives one channel of the rings past
    full scale), the colour comes instead from neutral pixels well below clipping
    and the level from the rings' weakest channel (see ``_unclipped_white_colour``).
    That white is the light's, but where the marker discs clip as well the
    default (biased the same way as the discs) can classify them better, so the
    marker search tries it only when the default misses a marker.

    Parameters
    ----------
    bgr8 : ndarray of shape (H, W, 3), uint8
        The photo (any size; a reduced copy is enough).
    top_fraction : float
        Share of the unclipped pixels, by luminance, averaged into the white.
    recover_clipped : bool
        Recover the colour of a clipped white (see above).
    gray : ndarray (H, W), uint8, optional
        ``cv2.cvtColor(bgr8, cv2.COLOR_BGR2GRAY)`` where the caller has it (made here if None).
    channels : (b, g, r) ndarrays (H, W), uint8, optional
        ``cv2.split(bgr8)`` where the caller has it (made here if None).
    """
    img = np.ascontiguousarray(bgr8)
    b, g, r = cv2.split(img) if channels is None else channels
    maxc = cv2.max(cv2.max(b, g), r)
    unclipped = cv2.compare(maxc, 250, cv2.CMP_LT)  # 255 where every channel is below 250
    if gray is None:
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
    # grey histograms by calcHist (no int64 copy of the image, as np.bincount makes)
    hist = cv2.calcHist([gray], [0], unclipped, [256], [0, 256]).ravel().astype(np.int64)
    hist[0] = 0
    n_ok = int(hist.sum())
    if n_ok == 0:
        return WhiteEstimate((255.0, 255.0, 255.0), 0, 1.0)
    k = min(n_ok, max(20, int(np.ceil(top_fraction * n_ok))))
    above = np.cumsum(hist[::-1])[::-1]  # pixels with grey >= level
    level = int(np.flatnonzero(above >= k)[-1])
    select = cv2.bitwise_and(cv2.compare(gray, level, cv2.CMP_GE), unclipped)
    n_sel = int(cv2.countNonZero(select))
    mb, mg, mr, _ = cv2.mean(img, mask=select)
    hist_all = cv2.calcHist([gray], [0], None, [256], [0, 256]).ravel().astype(np.int64)
    above_all = np.cumsum(hist_all[::-1])[::-1]  # as above, every pixel
    n_bright = int(above_all[level])  # pixels with grey >= level
    clipped_fraction = 1.0 - n_sel / max(1, n_bright)
    white = np.array([mr, mg, mb])
    level_all = int(np.flatnonzero(above_all >= k)[-1])
    if recover_clipped and clipped_fraction > CLIPPED_WHITE_FRACTION:
        brightest = gray >= level_all
        colour = _unclipped_white_colour(img, maxc, white)
        # its level: the brightest pixels (the rings) in the white's weakest channel,
        # the one least likely clipped
        weak = int(np.argmin(colour))
        weak_px = img[..., 2 - weak][brightest]
        weak_px = weak_px[weak_px < 250]
        if weak_px.size >= 20:
            lin_weak = float(np.median(SRGB8_TO_LINEAR[weak_px]))
            lin_white = colour * (lin_weak / float(colour[weak]))
            white = 255.0 * srgb_encode(lin_white, clip=False)
            return WhiteEstimate(
                (float(white[0]), float(white[1]), float(white[2])), n_sel, float(clipped_fraction)
            )
    # Overexposed rings: their unclipped neighbours give the light's colour but not its
    # level. Raise the white (in linear light) to the brightest pixels' grey, clipped or not.
    # the mean grey of the pixels at or above level_all, from the histogram
    grey_all = float(np.arange(level_all, 256) @ hist_all[level_all:]) / int(above_all[level_all])
    grey_white = float(white @ np.array([0.299, 0.587, 0.114]))
    if grey_all > grey_white + 1.0:
        gain = srgb_decode(np.array(grey_all / 255.0)) / srgb_decode(np.array(grey_white / 255.0))
        white = 255.0 * srgb_encode(srgb_decode(white / 255.0) * float(gain), clip=False)
    return WhiteEstimate(
        (float(white[0]), float(white[1]), float(white[2])), n_sel, float(clipped_fraction)
    )


def _unclipped_white_colour(
    bgr8: np.ndarray, maxc: np.ndarray, white_rgb8: np.ndarray, *, iterations: int = 2
) -> np.ndarray:
    """The white's colour where the whitest pixels are clipped: from neutral pixels well below it.

    When a strong cast drives one channel of the rings (and of the lit plate) past
    full scale, the brightest pixels left unclipped are exactly those whose clipped
    channel happens to be low: a biased white. Instead take the brightest pixels that
    a white of the current estimate's colour would show *well* below clipping (its
    strongest channel at most ``_SAFE_LINEAR`` of full scale: shaded
    or vignetted plate, wire, ring edges), re-estimate the colour from their median
    chromaticity and repeat. Pixels are ranked by the white's two weakest channels,
    so the selection does not depend on the channel that clips.

    Returns the colour in linear RGB (R, G, B), its largest channel 1 (the caller sets
    the level).
    """
    lin = SRGB8_TO_LINEAR[bgr8[..., ::-1].reshape(-1, 3)]
    ok = maxc.reshape(-1) < 250
    w_lin = np.maximum(srgb_decode(white_rgb8 / 255.0), 1e-6)
    colour = w_lin / w_lin.max()
    for _ in range(iterations):
        # brightness from the two channels the white is weakest in: selecting on the
        # strongest channel (the one that clips) would bias the white away from it again
        weak = np.argsort(colour)[:2]
        k = lin[:, weak].sum(axis=1) / float(colour[weak].sum())
        valid = ok & (k < _SAFE_LINEAR)
        n_valid = int(np.count_nonzero(valid))
        if n_valid < 20:
            return colour
        kv = k[valid]
        n = max(20, int(_NEUTRAL_TOP_FRACTION * n_valid))
        select = valid & (k >= np.partition(kv, -n)[-n])
        chroma = lin[select] / np.maximum(lin[select].sum(axis=1, keepdims=True), 1e-6)
        colour = np.maximum(np.median(chroma, axis=0).astype(np.float64), 1e-6)
        colour = colour / colour.max()
    return colour


def adaptation_matrix(white: WhiteEstimate | None, adaptation: str = "rgb-gain") -> np.ndarray:
    """3x3 matrix: the photo's linear sRGB -> XYZ under D65, the white at Y = RING_WHITE_Y.

    Parameters
    ----------
    white : the photo's measured white; ``None`` = already balanced, white at 255.
    adaptation : ``"rgb-gain"`` divides each linear RGB channel by the white's (von Kries
        in the camera's RGB: what a camera's own white balance does, and what corrects
        its residual error); ``"cat02"`` is CAT02 von Kries from the white's chromaticity
        to D65 (colour-science), a perceptual chromatic adaptation.
    """
    if adaptation not in ADAPTATIONS:
        raise ValueError(f"unknown adaptation {adaptation!r}; valid: {ADAPTATIONS}")
    if white is None:
        return SRGB_TO_XYZ.copy()
    lin_white = np.maximum(srgb_decode(np.asarray(white.srgb8, dtype=np.float64) / 255.0), 1e-6)
    if adaptation == "rgb-gain":
        return SRGB_TO_XYZ @ np.diag(RING_WHITE_Y / lin_white)
    import colour

    xyz_white = SRGB_TO_XYZ @ lin_white
    cat = colour.adaptation.matrix_chromatic_adaptation_VonKries(
        xyz_white / xyz_white[1], D65_XYZ, transform="CAT02"
    )
    return cat @ SRGB_TO_XYZ * (RING_WHITE_Y / float(xyz_white[1]))


def _rgb8_to_space(rgb8: np.ndarray, matrix: np.ndarray, space: str) -> np.ndarray:
    """(N, 3) R, G, B values 0..255 of the photo -> (N, 3) in ``space`` after adaptation."""

    lin = srgb_decode(np.asarray(rgb8, dtype=np.float64) / 255.0)
    xyz = lin @ matrix.T
    if space == "lab":
        return xyz_to_lab_d65(xyz)
    if space == "rgb":
        return srgb_encode(xyz @ XYZ_TO_SRGB.T) * 255.0
    raise ValueError(f"unknown colour space {space!r}; valid: {COLOUR_SPACES}")


def bgr8_to_space(
    bgr8: np.ndarray,
    space: ColourSpace,
    white: WhiteEstimate | None = None,
    adaptation: str = "rgb-gain",
) -> np.ndarray:
    """Convert BGR pixels (..., 3), 0..255, to ``space`` after white balance to D65."""
    arr = np.asarray(bgr8)
    flat = arr.reshape(-1, 3)[:, ::-1]
    out = _rgb8_to_space(flat, adaptation_matrix(white, adaptation), space)
    return out.reshape(arr.shape[:-1] + (3,))


@dataclass(frozen=True)
class ColourModel:
    """One Gaussian per role in a colour space; nearest-role Mahalanobis classification.

    Attributes
    ----------
    space : "lab" or "rgb".
    roles : tuple of role names, the order of ``means_`` rows.
    means : ndarray (K, 3), float, each role's colour in ``space`` under D65.
    covariances : ndarray (K, 3, 3), float, each role's colour covariance.
    max_distance : float, largest Mahalanobis distance still counted as the role.
    adaptation : how the photo's white is brought to D65 (:func:`adaptation_matrix`).
    """

    space: str
    roles: tuple[str, ...]
    means: np.ndarray
    covariances: np.ndarray
    max_distance: float = 4.0
    adaptation: str = "rgb-gain"

    def __post_init__(self) -> None:
        if self.adaptation not in ADAPTATIONS:
            raise ValueError(f"unknown adaptation {self.adaptation!r}; valid: {ADAPTATIONS}")
        if self.space not in COLOUR_SPACES:
            raise ValueError(f"unknown colour space {self.space!r}; valid: {COLOUR_SPACES}")
        means = np.asarray(self.means, dtype=np.float64).reshape(-1, 3)
        covs = np.asarray(self.covariances, dtype=np.float64).reshape(-1, 3, 3)
        if len(self.roles) != means.shape[0] or covs.shape[0] != means.shape[0]:
            raise ValueError("roles, means and covariances must have the same length")
        object.__setattr__(self, "means", means)
        object.__setattr__(self, "covariances", covs)

    @cached_property
    def _inverses(self) -> tuple[np.ndarray, ...]:
        """Each role's inverse covariance, once (classify_bgr8 reads them for every photo)."""
        return tuple(np.linalg.inv(c) for c in self.covariances)

    def distances(self, values: np.ndarray) -> np.ndarray:
        """Mahalanobis distance of colours (N, 3) in ``space`` to every role: (N, K)."""
        v = np.asarray(values, dtype=np.float64).reshape(-1, 3)
        # every role at once: d (K, N, 3), d inv (a stacked matmul), its rows dotted with d
        d = v[None, :, :] - self.means[:, None, :]
        q = np.matmul(d, np.asarray(self._inverses))
        q *= d
        return np.sqrt(q.sum(axis=2)).T

    def to_dict(self) -> dict[str, Any]:
        return {
            "space": self.space,
            "roles": list(self.roles),
            "means": np.round(self.means, 3).tolist(),
            "covariances": np.round(self.covariances, 3).tolist(),
            "max_distance": self.max_distance,
            "adaptation": self.adaptation,
        }


def _marker_mean(marker: Any, space: str) -> np.ndarray:
    if space == "lab":
        return np.asarray(marker.lab_d65, dtype=np.float64)
    return np.asarray(marker.srgb, dtype=np.float64)


@lru_cache(maxsize=32)
def kit_colour_model(
    kit: MarkerKit,
    space: ColourSpace = "lab",
    *,
    max_distance: float = 4.0,
    adaptation: str = "rgb-gain",
) -> ColourModel:
    """The colour model of a kit: the kit's D65 colours, with its learnt spreads if it has them."""
    if space not in COLOUR_SPACES:
        raise ValueError(f"unknown colour space {space!r}; valid: {COLOUR_SPACES}")
    means, covs = [], []
    for role in ROLES:
        marker = kit.by_role(role)
        means.append(_marker_mean(marker, space))
        sigma = marker.colour_sigma(space) or DEFAULT_SIGMA[space]
        covs.append(np.diag(np.square(np.maximum(np.asarray(sigma, dtype=np.float64), 1.0))))
    return ColourModel(space, ROLES, np.array(means), np.array(covs), max_distance, adaptation)


def learnt_colour_model(
    samples: dict[str, np.ndarray],
    space: ColourSpace,
    *,
    max_distance: float = 4.0,
    adaptation: str = "rgb-gain",
) -> ColourModel:
    """A model from labelled colour samples: {role: (N, 3) values in ``space``}."""
    roles = tuple(r for r in ROLES if r in samples)
    means, covs = [], []
    for role in roles:
        v = np.asarray(samples[role], dtype=np.float64).reshape(-1, 3)
        if v.shape[0] < 10:
            raise ValueError(f"role {role!r}: need at least 10 colour samples, got {v.shape[0]}")
        means.append(v.mean(axis=0))
        covs.append(np.cov(v.T) + np.eye(3) * 1.0)
    return ColourModel(space, roles, np.array(means), np.array(covs), max_distance, adaptation)


def classify_bgr8(
    bgr8: np.ndarray,
    model: ColourModel,
    white: WhiteEstimate | None,
    channels: tuple[np.ndarray, ...] | None = None,
) -> np.ndarray:
    """Label each pixel with the index of its role in ``model.roles``, or -1 for none.

    Parameters
    ----------
    bgr8 : ndarray of shape (H, W, 3), uint8
    model : the colour model (means under D65).
    white : the photo's white (see :func:`estimate_white`); ``None`` = already balanced.
    channels : ``cv2.split(bgr8)`` where the caller has it (the search shares it with
        :func:`estimate_white`); made here if None.

    Returns
    -------
    labels : ndarray of shape (H, W), int8
    """
    img = np.asarray(bgr8)
    if img.dtype != np.uint8 or img.ndim != 3 or img.shape[2] != 3:
        raise ValueError("classify_bgr8 needs an (H, W, 3) uint8 BGR image")
    # the 15-bit R, G, B index of each pixel, built in place in uint16 (few temporaries)
    # from the contiguous planes cv2.split makes (casts of strided channels cost ~1.6x)
    if channels is None:
        b, g, r = cv2.split(img >> _QUANT_SHIFT)
    else:
        b, g, r = (c >> _QUANT_SHIFT for c in channels)
    idx = r.astype(np.uint16)
    idx <<= 5
    idx |= g
    idx <<= 5
    idx |= b
    # the flags and np.take index with intp: one cast for both (each casts a uint16 itself)
    idx = idx.astype(np.intp)
    # the colours present, ascending: a flag per 15-bit colour (half the CPU of
    # np.bincount, whose counts are not needed)
    seen = np.zeros(1 << 15, dtype=bool)
    seen[idx] = True
    used = np.flatnonzero(seen)
    rgb8 = np.column_stack(((used >> 10) & 31, (used >> 5) & 31, used & 31)).astype(np.float64)
    rgb8 = rgb8 * (1 << _QUANT_SHIFT) + (1 << _QUANT_SHIFT) / 2 - 0.5
    values = _rgb8_to_space(rgb8, adaptation_matrix(white, model.adaptation), model.space)
    dist = model.distances(values)
    best = np.argmin(dist, axis=1)
    lut_used = np.where(dist[np.arange(len(used)), best] <= model.max_distance, best, -1)
    lut = np.full(1 << 15, -1, dtype=np.int8)
    lut[used] = lut_used.astype(np.int8)
    return np.take(lut, idx)
