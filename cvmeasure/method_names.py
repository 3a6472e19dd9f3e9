"""Measurement method names, and the older names still read from scripts and result files.

A part photo is measured by ``centreline_fit`` (a polyline or circle fitted to the
wire's sub-pixel centreline) and, for comparison, by the seed paper's two methods on
the wire's outline, ``seed_ellipse`` and ``seed_sagitta``. A machine photo is
measured by ``edge_fit`` (colour model, sub-pixel fits of each marker disc's edge)
or by the seed paper's baseline ``seed_hough`` (colour boxes and Hough circles).
Older result files and scripts say ``ours``, ``ellipse``, ``sagitta`` and ``seed``;
:func:`part_method` and :func:`marker_method` map them to the names above, in this
one place.
"""

from __future__ import annotations

__all__ = [
    "MARKER_METHODS",
    "MARKER_METHOD_ALIASES",
    "PART_METHODS",
    "PART_METHOD_ALIASES",
    "marker_method",
    "part_method",
]

#: Part methods; the first is the default.
PART_METHODS: tuple[str, ...] = ("centreline_fit", "seed_ellipse", "seed_sagitta")
#: Older part-method names -> current ones.
PART_METHOD_ALIASES: dict[str, str] = {
    "ours": "centreline_fit",
    "ellipse": "seed_ellipse",
    "sagitta": "seed_sagitta",
}
#: Marker methods; the first is the default.
MARKER_METHODS: tuple[str, ...] = ("edge_fit", "seed_hough")
#: Older marker-method names -> current ones.
MARKER_METHOD_ALIASES: dict[str, str] = {"ours": "edge_fit", "seed": "seed_hough"}


def part_method(name: str) -> str:
    """The current name of a part method (an older name mapped; others unchanged)."""
    return PART_METHOD_ALIASES.get(name, name)


def marker_method(name: str) -> str:
    """The current name of a marker method (an older name mapped; others unchanged)."""
    return MARKER_METHOD_ALIASES.get(name, name)
