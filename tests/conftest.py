"""Shared test fixtures.

Real data lives in ``../shared/data/real`` beside the repository (never copied
into it); tests that need it take the ``shared_real`` fixture and are skipped,
saying why, where it is absent.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]
SHARED_ROOT = REPO_ROOT.parent / "shared"


@pytest.fixture(scope="session")
def shared_real() -> Path:
    """``../shared/data/real`` (skips the test when it is absent)."""
    path = SHARED_ROOT / "data" / "real"
    if not path.is_dir():
        pytest.skip(f"real data not found at {path} (the shared/ folder is absent)")
    return path


def _textured(seed: int, shape: tuple[int, int] = (120, 184), noise: float = 6.0) -> np.ndarray:
    """A BGR uint8 test image: colour gradients, a saturated disc with sharp edges, noise.

    What a JPEG's chroma upsampling and IDCT see at edges and in smooth areas.
    """
    rng = np.random.default_rng(seed)
    h, w = shape
    yy, xx = np.mgrid[0:h, 0:w]
    img = np.dstack((xx * 255 // w, yy * 255 // h, 128 + 0 * xx)).astype(np.float64)
    disc = (xx - w / 2) ** 2 + (yy - h / 2) ** 2 < (h / 4) ** 2
    img[disc] = (30, 140, 230)
    img += rng.normal(0, noise, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


@pytest.fixture(scope="session")
def textured_bgr() -> Callable[..., np.ndarray]:
    """``textured_bgr(seed, shape=(120, 184), noise=6.0)``: a BGR uint8 test image."""
    return _textured


def _arc_svg(path: Path, radius_mm: float, from_deg: float, to_deg: float) -> Path:
    """An SVG arc about (100, 100) mm from ``from_deg`` to ``to_deg`` (y down), written
    to ``path``."""
    a0, a1 = np.radians(from_deg), np.radians(to_deg)
    x0, y0 = 100 + radius_mm * np.cos(a0), 100 - radius_mm * np.sin(a0)
    x1, y1 = 100 + radius_mm * np.cos(a1), 100 - radius_mm * np.sin(a1)
    r = radius_mm
    path.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" '
        f'viewBox="0 0 200 200"><path d="M {x0} {y0} A {r} {r} 0 0 0 {x1} {y1}"/></svg>',
        encoding="utf-8",
    )
    return path


@pytest.fixture(scope="session")
def arc_svg() -> Callable[..., Path]:
    """``arc_svg(path, radius_mm, from_deg, to_deg)``: writes an SVG arc design, returns ``path``."""
    return _arc_svg
