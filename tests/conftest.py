"""Shared test fixtures.

Real data lives in ``../shared/data/real`` beside the repository (never copied
into it); tests that need it take the ``shared_real`` fixture and are skipped,
saying why, where it is absent.
"""

from __future__ import annotations

from pathlib import Path

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
