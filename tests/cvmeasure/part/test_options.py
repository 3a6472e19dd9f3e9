"""PartOptions: the defaults are the command line's, bad values refused when built."""

from __future__ import annotations

import dataclasses

import pytest

from cvmeasure.cli import build_parser
from cvmeasure.part.lift import MAX_LIFT_MM
from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions


def test_the_defaults_are_the_commands():
    args = build_parser().parse_args(["part", "p.jpg", "--board", "b.json", "--camera", "c.json"])
    opts = PartOptions()
    assert (opts.divisions, opts.method, opts.allow_mirror) == (None, args.method, True)
    assert opts.wire == WireOptions(None, args.ends, args.axis_height_mm)
    assert opts.lift == LiftOptions(shadow=args.shadow_lift is not False, max_lift_mm=MAX_LIFT_MM)


def test_older_method_names_are_read_and_bad_values_refused():
    assert PartOptions(method="ours").method == "centreline_fit"  # type: ignore[arg-type]
    assert PartOptions(method="ellipse") == PartOptions(method="seed_ellipse")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="method must be one of"):
        PartOptions(method="hough")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="divisions must be >= 1"):
        PartOptions(divisions=0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        PartOptions().divisions = 3  # type: ignore[misc]
