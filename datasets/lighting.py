"""Light, lens and sensor: from a linear albedo image to a camera photo.

The pipeline, in order (all in linear light, RGB in the sRGB primaries):

1. illuminant: a Planckian light of ``cct_k`` (CIE xy by Kang 2002 via
   colour-science) multiplies the albedo (von Kries model in sRGB; the
   albedo is the colour seen under D65), normalised so its largest channel is 1;
2. exposure and vignetting (``1 - vignetting * (r / r_corner)^2``), lateral
   chromatic aberration (``lateral_ca``, off by default);
3. lens/sensor blur (Gaussian of ``blur_px``, in output pixels);
4. optionally an RGGB Bayer mosaic (``bayer``), demosaiced after the noise;
   sensor noise: shot noise (``full_well_e`` electrons at full scale)
   plus Gaussian read noise (both drawn as Gaussians), scaled by ``noise`` (0 = none);
5. white balance: the camera divides by the illuminant it *believes* in
   (``wb_cct_k`` if set, else ``cct_k + wb_error_k``), then clips to [0, 1];
6. outputs: 16-bit linear RGB (like a RAW developed linearly), and the 8-bit
   sRGB-encoded BGR image, JPEG-compressed at ``jpeg_quality`` (None: no JPEG).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from functools import lru_cache
from typing import Any

import numpy as np

__all__ = ["Lighting", "illuminant_rgb", "srgb8_to_linear", "develop", "Developed"]


@dataclass(frozen=True)
class Lighting:
    """Illumination and imaging conditions of one photo.

    Attributes
    ----------
    cct_k : correlated colour temperature of the light, K (2700 warm .. 6500 daylight).
    wb_error_k : error of the camera's automatic white balance, K.
    wb_cct_k : if set, a fixed white-balance preset (K) used instead of ``cct_k + wb_error_k``.
    exposure : multiplier on the signal (1 puts white paper near 80 % of full scale).
    vignetting : relative fall-off of brightness in the image corners.
    noise : multiplier on shot + read noise (0 = noiseless).
    full_well_e, read_noise_e : sensor electrons at full scale and read noise, e-.
    blur_px : Gaussian sigma of the lens + demosaicing blur, in output pixels.
    jpeg_quality : 1..100, or None for no JPEG compression.
    shadow_strength : darkness of cast shadows (0 = none).
    light_azimuth_deg : direction the light comes from, in the scene frame (shadows
        fall the opposite way).
    bayer : sample the light on an RGGB colour filter array (noise per photosite)
        and demosaic it (OpenCV edge-aware), as a real sensor does; off by default.
    lateral_ca : lateral chromatic aberration: red is magnified by ``1 + lateral_ca``
        and blue by ``1 - lateral_ca`` about the principal point (5e-4 is ~1.4 px
        of colour fringe in the corners of a 4608 px photo); the truth is green's.
    """

    cct_k: float = 5000.0
    wb_error_k: float = 250.0
    wb_cct_k: float | None = None
    exposure: float = 1.0
    vignetting: float = 0.2
    noise: float = 1.0
    full_well_e: float = 15000.0
    read_noise_e: float = 4.0
    blur_px: float = 0.6
    jpeg_quality: int | None = 92
    shadow_strength: float = 0.35
    light_azimuth_deg: float = 135.0
    bayer: bool = False
    lateral_ca: float = 0.0

    def __post_init__(self) -> None:
        if not 1667.0 <= self.cct_k <= 25000.0:
            raise ValueError(f"cct_k must be in [1667, 25000] K, got {self.cct_k}")
        if self.jpeg_quality is not None and not 1 <= int(self.jpeg_quality) <= 100:
            raise ValueError(f"jpeg_quality must be in 1..100 or None, got {self.jpeg_quality}")

    @property
    def camera_wb_cct_k(self) -> float:
        """The colour temperature the camera's white balance assumes, K."""
        if self.wb_cct_k is not None:
            return float(self.wb_cct_k)
        return float(np.clip(self.cct_k + self.wb_error_k, 1667.0, 25000.0))

    @classmethod
    def clean(cls, *, blur_px: float = 0.6) -> Lighting:
        """Daylight, perfect white balance, no vignetting, noise or JPEG (lens blur kept).

        ``blur_px`` stays at 0.6 px (sub-pixel detectors need a band-limited
        image, as every real lens gives them); pass ``blur_px=0`` for a bare render.
        """
        return cls(
            cct_k=6504.0,
            wb_error_k=0.0,
            vignetting=0.0,
            noise=0.0,
            blur_px=blur_px,
            jpeg_quality=None,
        )

    @classmethod
    def random(cls, seed: int) -> Lighting:
        """Plausible workshop lighting: 2700-6500 K, WB error up to +-600 K, ..."""
        rng = np.random.default_rng(seed)
        return cls(
            cct_k=float(rng.uniform(2700.0, 6500.0)),
            wb_error_k=float(rng.uniform(-600.0, 600.0)),
            exposure=float(rng.uniform(0.7, 1.15)),
            vignetting=float(rng.uniform(0.05, 0.35)),
            noise=1.0,
            blur_px=float(rng.uniform(0.5, 1.0)),
            jpeg_quality=int(rng.integers(80, 97)),
            light_azimuth_deg=float(rng.uniform(0.0, 360.0)),
        )

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["camera_wb_cct_k"] = self.camera_wb_cct_k
        return out


@lru_cache(maxsize=64)
def _illuminant_rgb_cached(cct_k: float) -> tuple[float, float, float]:
    import colour

    xy = colour.temperature.CCT_to_xy(cct_k, method="Kang 2002")
    rgb = colour.XYZ_to_sRGB(colour.xy_to_XYZ(xy), apply_cctf_encoding=False)
    rgb = np.asarray(rgb, dtype=np.float64) / float(np.max(rgb))
    return float(rgb[0]), float(rgb[1]), float(rgb[2])


def illuminant_rgb(cct_k: float) -> np.ndarray:
    """Linear sRGB of a Planckian light of ``cct_k`` K, largest channel 1 (3,)."""
    return np.array(_illuminant_rgb_cached(round(float(cct_k), 3)))


def srgb8_to_linear(srgb8: Any) -> np.ndarray:
    """8-bit gamma-encoded sRGB -> linear RGB in [0, 1] (IEC 61966-2-1, via colour-science)."""
    import colour

    return np.asarray(
        colour.cctf_decoding(np.asarray(srgb8, dtype=np.float64) / 255.0, function="sRGB")
    )


@lru_cache(maxsize=1)
def _encode_lut() -> np.ndarray:
    """16-bit linear code -> 8-bit sRGB code (65536,), uint8."""
    import colour

    lin = np.arange(65536, dtype=np.float64) / 65535.0
    enc = colour.cctf_encoding(lin, function="sRGB")
    return np.clip(np.round(enc * 255.0), 0, 255).astype(np.uint8)


def _lateral_ca(rgb: np.ndarray, ca: float, cx: float, cy: float) -> np.ndarray:
    """Magnify red by ``1 + ca`` and blue by ``1 - ca`` about (cx, cy); green is the truth."""
    import cv2

    h, w = rgb.shape[:2]
    xs = np.arange(w, dtype=np.float32)
    ys = np.arange(h, dtype=np.float32)
    out = rgb.copy()
    for ch, mag in ((0, 1.0 + ca), (2, 1.0 - ca)):
        map_x = np.broadcast_to(cx + (xs - cx) / mag, (h, w)).astype(np.float32)
        map_y = np.broadcast_to((cy + (ys - cy) / mag)[:, None], (h, w)).astype(np.float32)
        out[..., ch] = cv2.remap(
            np.ascontiguousarray(rgb[..., ch]),
            map_x,
            map_y,
            cv2.INTER_LINEAR,
            borderMode=cv2.BORDER_REPLICATE,
        )
    return out


def _mosaic_rggb(rgb: np.ndarray) -> np.ndarray:
    """Sample an RGB image (H, W, 3) on an RGGB Bayer colour filter array -> (H, W)."""
    m = np.empty(rgb.shape[:2], dtype=rgb.dtype)
    m[0::2, 0::2] = rgb[0::2, 0::2, 0]
    m[0::2, 1::2] = rgb[0::2, 1::2, 1]
    m[1::2, 0::2] = rgb[1::2, 0::2, 1]
    m[1::2, 1::2] = rgb[1::2, 1::2, 2]
    return m


@dataclass(frozen=True)
class Developed:
    """What the camera hands over: 8-bit BGR, optional 16-bit linear RGB and JPEG bytes."""

    bgr: np.ndarray
    linear_rgb16: np.ndarray | None
    jpeg_bytes: bytes | None


def develop(
    albedo_rgb: np.ndarray,
    lighting: Lighting,
    *,
    seed: int,
    keep_linear: bool = False,
    centre_px: tuple[float, float] | None = None,
) -> Developed:
    """Turn a linear albedo image (H, W, 3) float32 into a photo (see module docstring).

    ``centre_px`` is the optical centre for lateral chromatic aberration
    (default: the image centre).

    Deterministic for a given ``seed``.
    """
    import cv2

    rng = np.random.default_rng([seed, 0x5E45])
    h, w = albedo_rgb.shape[:2]
    gain = (illuminant_rgb(lighting.cct_k) * lighting.exposure).astype(np.float32)
    raw = albedo_rgb * gain
    if lighting.vignetting:
        yy, xx = np.ogrid[0:h, 0:w]
        r2 = ((xx - (w - 1) / 2) ** 2 + (yy - (h - 1) / 2) ** 2) / (
            ((w - 1) / 2) ** 2 + ((h - 1) / 2) ** 2
        )
        raw *= (1.0 - lighting.vignetting * r2).astype(np.float32)[..., None]
    if lighting.lateral_ca:
        cx, cy = centre_px if centre_px is not None else ((w - 1) / 2, (h - 1) / 2)
        raw = _lateral_ca(raw, lighting.lateral_ca, cx, cy)
    sigma = lighting.blur_px
    if sigma > 0.05:
        raw = cv2.GaussianBlur(raw, (0, 0), sigmaX=sigma, sigmaY=sigma)
    if lighting.bayer:
        raw = _mosaic_rggb(raw)
    if lighting.noise > 0:
        # shot (Gaussian limit of Poisson: thousands of electrons) and read noise, in place
        fw = np.float32(lighting.full_well_e)
        sd = np.maximum(raw, np.float32(0.0))
        sd *= fw
        sd += np.float32(lighting.read_noise_e**2)
        np.sqrt(sd, out=sd)
        sd *= np.float32(lighting.noise) / fw
        # OpenCV's generator is 4x faster than numpy's at 14 MP; seeded from ``seed``
        cv2.setRNGSeed(int(rng.integers(1, 2**31 - 1)))
        gauss = np.empty(raw.shape, dtype=np.float32)
        cv2.randn(gauss.reshape(h, -1), 0.0, 1.0)
        sd *= gauss
        raw += sd
        del sd, gauss
    np.clip(raw, 0.0, 1.0, out=raw)  # the sensor saturates before white balance
    if lighting.bayer:
        m16 = np.empty(raw.shape, dtype=np.uint16)
        np.copyto(m16, raw * np.float32(65535.0) + np.float32(0.5), casting="unsafe")
        raw = cv2.demosaicing(m16, cv2.COLOR_BayerRGGB2RGB_EA).astype(np.float32)
        raw *= np.float32(1.0 / 65535.0)
    wb = 1.0 / illuminant_rgb(lighting.camera_wb_cct_k)
    wb /= wb.min()  # cameras only amplify: the strongest channel keeps gain 1
    raw *= wb.astype(np.float32)
    np.clip(raw, 0.0, 1.0, out=raw)
    raw *= np.float32(65535.0)
    raw += np.float32(0.5)
    code16 = np.empty(raw.shape, dtype=np.uint16)
    np.copyto(code16, raw, casting="unsafe")  # truncation of x + 0.5: rounds
    del raw
    bgr = _encode_lut()[code16[..., ::-1]]
    linear = code16 if keep_linear else None
    jpeg = None
    if lighting.jpeg_quality is not None:
        ok, buf = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, int(lighting.jpeg_quality)])
        if not ok:  # pragma: no cover - OpenCV always encodes uint8 BGR
            raise RuntimeError("JPEG encoding failed")
        jpeg = buf.tobytes()
        bgr = cv2.imdecode(buf, cv2.IMREAD_COLOR)
    return Developed(bgr=bgr, linear_rgb16=linear, jpeg_bytes=jpeg)
