"""Rendered bender photos shared by the marker tests (rendered once per session)."""

from __future__ import annotations

import functools

import pytest

SCALE = 0.3  # 1382 x 922 px: fast, and still 19-24 px marker discs


def _render(pin=30.0, bend=25.0, light=None, seed=1, pose=None, occlude=(), geometry=None):
    from cvmeasure_datasets.lighting import Lighting

    light = light or Lighting(cct_k=2700.0, wb_error_k=600.0)
    return _cached(pin, bend, light, seed, pose, tuple(occlude), geometry)


@functools.cache
def _cached(pin, bend, light, seed, pose, occlude, geometry):
    from cvmeasure_datasets.bender import render_bender_photo

    return render_bender_photo(
        pin_angle_deg=pin,
        bend_angle_deg=bend,
        lighting=light,
        seed=seed,
        scale=SCALE,
        pose=pose,
        occlude=dict(occlude),
        geometry=geometry,
    )


@pytest.fixture(scope="session")
def render():
    """``render(pin=, bend=, light=, seed=, pose=, occlude=((role, frac),), geometry=)``, cached."""
    pytest.importorskip("cvmeasure_datasets.bender")
    return _render


@pytest.fixture(scope="session")
def flat_kit():
    """The built-in kit without heights: what the flat renders of ``render`` show."""
    from cvmeasure.kit import default_kit

    return default_kit().flat()
