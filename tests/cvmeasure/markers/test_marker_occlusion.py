"""No photo mis-measured silently (issue 14): a cover or a shadow across a marker is named or refused.

Photos: :mod:`cvmeasure_datasets.discs3d` (discs at their heights, a bar or a soft
shadow band across one marker), measured through the renderer's plane pose.
"""

from __future__ import annotations

import numpy as np
import pytest

from cvmeasure.kit import default_kit
from cvmeasure.markers import MarkerNotFoundError, measure_machine_photo

pytest.importorskip("cvmeasure_datasets.discs3d")

from cvmeasure_datasets.discs3d import (  # noqa: E402
    Bar,
    DiscScene,
    Stray,
    marker_centres_mm,
    render_discs_at_heights,
)

from .test_marker_heights import SQUARE, _camera, true_plane  # noqa: E402

PIN, BEND = -60.0, -50.0
KIT = default_kit()
CENTRES = marker_centres_mm(PIN, BEND)


def _measure(**effects):
    bgr, truth = render_discs_at_heights(
        DiscScene(PIN, BEND, pose=SQUARE, **effects), camera=_camera(), seed=3
    )
    return measure_machine_photo(bgr, KIT, plane=true_plane(_camera(), SQUARE)), truth


def _held(res, truth, key):
    """The error is within 3 stated sigma (plus 0.005 deg of rendering tolerance)."""
    err = abs(getattr(res, key) - truth[key])
    return err <= 3.0 * res.uncertainty_deg[key] + 0.005, err


def _across(role, offset_mm, direction_deg=70.0):
    d = np.array([np.cos(np.radians(direction_deg)), np.sin(np.radians(direction_deg))])
    return tuple(CENTRES[role] + d * offset_mm), direction_deg + 90.0


@pytest.mark.parametrize("offset_mm", [0.0, 3.5])
def test_a_tool_shadow_across_a_marker_is_named_and_held(offset_mm):
    through, direction = _across("pin", offset_mm + 3.0)
    shadow = Bar(through, direction, 6.0, height_mm=KIT.height_mm("pin") + 0.01, shadow=0.5,
                 soft_mm=2.0)  # fmt: skip
    res, truth = _measure(bars=(shadow,))
    assert any(w.code == "marker_uneven_light" and w.subject == "pin" for w in res.warnings), (
        res.warnings
    )
    ok, err = _held(res, truth, "pin_angle_deg")
    assert ok, (err, res.uncertainty_deg)


def test_a_wire_across_a_ring_edge_is_named_and_held():
    through, direction = _across("wire_b", 3.5)
    wire = Bar(through, direction, 3.0, height_mm=KIT.height_mm("wire_b") + 4.0,
               srgb=(170, 170, 175))  # fmt: skip
    res, truth = _measure(bars=(wire,))
    assert any(w.code == "marker_hidden" and w.subject == "wire_b" for w in res.warnings), (
        res.warnings
    )
    ok, err = _held(res, truth, "bend_angle_deg")
    assert ok, (err, res.uncertainty_deg)


@pytest.mark.parametrize("role", ["origin", "wire_b"])
def test_a_wire_across_a_disc_is_refused_naming_the_marker(role):
    through, direction = _across(role, 0.0 if role == "origin" else 2.0)
    wire = Bar(through, direction, 3.0, height_mm=KIT.height_mm(role) + 4.0,
               srgb=(170, 170, 175))  # fmt: skip
    with pytest.raises(MarkerNotFoundError) as info:
        _measure(bars=(wire,))
    assert set(info.value.reasons) == {role}
    assert "too little of its edge is clear" in info.value.reasons[role]


def test_stray_objects_of_a_markers_colour():
    pin = KIT.by_role("pin")
    c = CENTRES["pin"]
    # smaller and larger pieces of the pin's colour lying about, not on a white ring
    strays = (Stray(tuple(c + [0, 15]), 3.0, pin.srgb), Stray(tuple(c + [30, -25]), 8.0, pin.srgb))
    res, truth = _measure(strays=strays)
    assert _held(res, truth, "pin_angle_deg")[0]
    # a second disc of its colour and size on a white ring: refused, both places named
    twin = Stray(tuple(c + [-5, 30]), pin.diameter_mm / 2, pin.srgb, ring_mm=pin.ring_mm,
                 height_mm=pin.height_mm)  # fmt: skip
    with pytest.raises(MarkerNotFoundError) as info:
        _measure(strays=(twin,))
    assert set(info.value.reasons) == {"pin"}
    assert info.value.reasons["pin"].startswith("ambiguous: 2 discs")
