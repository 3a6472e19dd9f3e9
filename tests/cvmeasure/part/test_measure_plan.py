"""A part of unequal chords measured against the polygon bent (issue 36).

Compared with its design divided into equal chords, a perfect 40/42/40/42 mm zigzag
read -43.84/46.16/43.84 deg instead of +-45; measured with the polygon bent (the
plan's chords start the vertex fit and are the reference) it reads its true bends.
"""

from __future__ import annotations

import functools

import numpy as np
import pytest

import cvmeasure_datasets
from cvmeasure.board import CharucoBoardSpec
from cvmeasure.design import DesignPath
from cvmeasure.part.measure import measure_part
from cvmeasure.part.options import PartOptions
from cvmeasure.wireplan import polygon_from_chords

BOARD = CharucoBoardSpec(14, 10, 20.0, 15.0)
#: Rendered vertex bends are measured within this (deg; the part tests' tolerance).
VERTEX_BEND_DEG = 0.15

SHAPES = {
    "zigzag": ([40.0, 42.0, 40.0, 42.0], [45.0, -45.0, 45.0]),
    # an open polyline as operators draw them: chords 15-40 mm, bends 3-60 deg both ways
    "unequal": ([18.0, 38.0, 15.0, 31.0, 24.0, 40.0], [-12.0, 55.0, 3.5, -48.0, 27.0]),
}


@functools.cache
def _photo(name: str):
    chords, turns = SHAPES[name]
    verts = polygon_from_chords(chords, turns)
    verts = verts - verts.mean(axis=0)
    photo = cvmeasure_datasets.render_part_photo(
        part=cvmeasure_datasets.polyline_part(verts * np.array([1.0, -1.0])),
        board=BOARD,
        seed=11,
        scale=0.5,
    )
    return verts, photo


@pytest.mark.parametrize("name", sorted(SHAPES))
def test_unequal_chords_measured_against_the_polygon_bent(name):
    verts, photo = _photo(name)
    design = DesignPath(verts, False, "polyline", name)
    m = measure_part(
        photo.bgr,
        BOARD,
        photo.camera,
        design=design,
        options=PartOptions(allow_mirror=False),
        reference_mm=verts,
        source=name,
    )
    bends = m.comparison.bends
    np.testing.assert_allclose(bends.design_bend_deg, SHAPES[name][1], atol=1e-9)
    assert bends.max_abs_error_deg < VERTEX_BEND_DEG
    assert m.result.divisions == len(SHAPES[name][0])


def test_without_a_plan_the_corners_are_kept_and_equal_chords_misread():
    """A design with corners and a chord count (no job) is compared with its corners too;
    the old reference (the design in equal chords) errs by degrees: the test can fail."""
    verts, photo = _photo("zigzag")
    design = DesignPath(verts, False, "polyline", "zigzag")
    m = measure_part(
        photo.bgr,
        BOARD,
        photo.camera,
        options=PartOptions(divisions=4, allow_mirror=False),
        design=design,
    )
    assert m.comparison.bends.max_abs_error_deg < VERTEX_BEND_DEG
    old = measure_part(
        photo.bgr,
        BOARD,
        photo.camera,
        design=design,
        options=PartOptions(allow_mirror=False),
        reference_mm=design.chords(4),
    )
    assert old.comparison.bends.max_abs_error_deg > 1.0


def test_the_polygon_bent_sets_the_chord_count_even_when_the_photo_shows_another():
    """The job's polygon (here with a straight vertex the photo cannot see) fixes N; the
    photo's own count is only warned about. Taking the photo's count failed the fit."""
    verts, photo = _photo("zigzag")
    mid = 0.5 * (verts[1] + verts[2])
    bent = np.vstack((verts[:2], mid, verts[2:]))  # 5 chords, one vertex of 0 deg
    design = DesignPath(bent, False, "polyline", "zigzag")
    m = measure_part(
        photo.bgr,
        BOARD,
        photo.camera,
        design=design,
        options=PartOptions(allow_mirror=False),
        reference_mm=bent,
    )
    assert m.result.divisions == 5
    assert "divisions_mismatch" in [w.code for w in m.warnings]
    bends = m.comparison.bends
    np.testing.assert_allclose(bends.design_bend_deg, [45.0, 0.0, -45.0, 45.0], atol=1e-9)
    assert bends.max_abs_error_deg < VERTEX_BEND_DEG
    with pytest.raises(ValueError, match="polygon bent has 5 chords"):
        measure_part(
            photo.bgr, BOARD, photo.camera, options=PartOptions(divisions=4), reference_mm=bent
        )


def test_a_part_compared_with_another_jobs_polygon_is_said_not_to_be_its_part():
    """The same turns fed in chords a quarter longer (another job): compared vertex for
    vertex, the part's bends differ by what its shorter chords make of them and
    ``cvmeasure correct`` would fit the machine to that. The part's inner chords (median
    27.5 mm, measured within 0.5 mm) against the job's 34.4 mm say it is not that job's
    part, and a correction from it is refused; against its own polygon no such warning."""
    from cvmeasure.contracts import Trial
    from cvmeasure.errors import InputError
    from cvmeasure.material.bender_calibration import fit_calibration
    from cvmeasure.material.correct_part import correct_from_part

    verts, photo = _photo("unequal")
    chords, turns = SHAPES["unequal"]
    other = polygon_from_chords([1.25 * c for c in chords], turns)
    measured = {}
    for name, reference in (("own", verts), ("other", other)):
        measured[name] = measure_part(
            photo.bgr, BOARD, photo.camera, design=DesignPath(reference, False, "polyline", name),
            options=PartOptions(allow_mirror=False), reference_mm=reference, source="part.jpg",
        )  # fmt: skip
    assert not [w for w in measured["own"].warnings if w.code.startswith("part_chords_")]
    (differ,) = [w for w in measured["other"].warnings if w.code.startswith("part_chords_")]
    assert differ.code == "part_chords_shorter"
    part_mm = float(differ.message.split(" mm (median)")[0].rsplit(" ", 1)[1])
    assert abs(part_mm - 27.5) < 0.5
    assert "34.38 mm" in differ.message
    with pytest.raises(InputError, match="not corrected: the part's chords"):
        # a springback of 10 % at every angle, either way
        trials = [
            Trial(f"{a}{d}", 1.1 * a * d, a * d, a * d) for a in (15, 45, 90) for d in (1, -1)
        ]
        correct_from_part(
            fit_calibration(trials, model="linear"), measured["other"], design_name="other"
        )
