"""The Inspect page's part check keeps the part measurement's warnings."""

from __future__ import annotations

import pytest

from cvmeasure.app import adapter
from cvmeasure.warning import has_code

cvmeasure_datasets = pytest.importorskip("cvmeasure_datasets")


def test_a_coarse_part_photo_is_checked_with_its_warning(tmp_path):
    # R60 120 deg in 10 chords of 2 mm wire at 0.43 mm/px: under 3 px per wire radius, the
    # vertex bends may be off by degrees; the check the page draws must say so
    part = cvmeasure_datasets.arc_part(60.0, 120.0, 10)
    photo = cvmeasure_datasets.render_part_photo(
        part=part, board=adapter.BOARD, sheet="dark", seed=1, scale=0.3
    )
    points = " L ".join(f"{x:.4f} {100.0 - y:.4f}" for x, y in part.vertices_mm)
    design = tmp_path / "arc.svg"
    design.write_text(
        '<svg xmlns="http://www.w3.org/2000/svg" width="200mm" height="200mm" '
        f'viewBox="-100 -100 200 200"><path d="M {points}" fill="none" stroke="black"/></svg>\n',
        encoding="utf-8",
    )
    check = adapter.measure_finished_part(photo.bgr, photo.camera, design, "part.jpg")
    assert check.measurement.result.divisions == 10  # the design's plan: its 10 drawn chords
    assert has_code(check.warnings, "part_low_resolution")
    assert check.warnings == check.measurement.warnings  # all of them, in their order
