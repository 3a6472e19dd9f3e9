"""benchmarks.parts' "silently wrong" count: a part is excused only by a warning that covers
the quantity that is off (docs/conventions.md), not by any warning."""

import pytest

from benchmarks.parts import _silently_wrong


def _row(radius=0.0, segment=0.0, vertex=0.0, effects=(0.0, 0.0, 0.0), **warned):
    """A 'round' row: errors (%, deg, deg), part_lifted's stated effects, the warnings."""
    return {
        "round_radius_err_pct": radius,
        "round_segment_bend_err_deg": segment,
        "round_vertex_err_deg": vertex,
        "round_lift": {
            "effect_radius_pct": effects[0],
            "effect_segment_bend_deg": effects[1],
            "effect_bend_deg": effects[2],
        },
        **{f"round_{k}_warning": v for k, v in warned.items()},
    }


ALL = ("radius", "segment", "vertex")


@pytest.mark.parametrize(
    ("row", "silent"),
    [
        (_row(radius=0.1, vertex=0.01), False),  # on target
        (_row(radius=3.3), True),  # off, no warning
        # dev B4 (part14t): radius -12.9 % with part_lifted stating 0.27 % at most
        (_row(radius=-12.9, effects=(0.27, 0.02, 0.02), lifted=True), True),
        (_row(radius=0.9, effects=(0.94, 0.05, 0.1), lifted=True), False),  # within 0.94 %
        (_row(radius=0.9, effects=(0.5, 0.05, 0.1), lifted=True), True),  # beyond 0.5 %
        (_row(radius=3.3, arc=True), False),  # the circle's figures: part_arc_inconsistent
        (_row(vertex=5.5, arc=True), True),  # ... but not the vertex bends
        (_row(vertex=5.5, gap=True), False),  # a lost chord's vertices
        (_row(radius=1.0, gap=True), True),  # ... not the radius
        (_row(segment=0.1, end=True), False),  # an end point: the bend per chord
        (_row(vertex=0.1, end=True), True),  # ... "the vertex bends are not affected"
        # dev 9203 (part14v): a vertex 5.5 deg off, part_lifted stating 0.073 deg
        (_row(vertex=5.5, effects=(0.21, 0.019, 0.073), lifted=True), True),
        (_row(vertex=0.05, effects=(0.21, 0.019, 0.073), lifted=True), False),
    ],
)
def test_a_quantity_off_target_is_excused_only_by_a_warning_covering_it(row, silent):
    assert _silently_wrong(row, "round", ALL) is silent
