"""Option types and the parser every command uses: values are checked as they are parsed.

A bad option value is a usage error: one line on stderr naming the option and
what is wrong (``cvmeasure render: argument --scale: must be > 0, got 0``), exit 2.

>>> positive_float("0.25")
0.25
>>> positive_int("0")
Traceback (most recent call last):
...
argparse.ArgumentTypeError: must be a whole number >= 1, got '0'
"""

from __future__ import annotations

import argparse
import math
import sys
from collections.abc import Callable
from typing import NoReturn

__all__ = [
    "OneLineParser",
    "positive_float",
    "non_negative_float",
    "positive_int",
    "non_negative_int",
    "int_in",
]


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line (``prog: message``), exit 2."""

    def error(self, message: str) -> NoReturn:
        print(f"{self.prog}: {message} (see {self.prog} --help)", file=sys.stderr)
        sys.exit(2)


def _number(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return value


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return value


def int_in(low: int, high: int | None = None) -> Callable[[str], int]:
    """A whole number in [low, high] (no upper bound when ``high`` is None)."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value > high):
            bound = f">= {low}" if high is None else f"in {low}..{high}"
            raise argparse.ArgumentTypeError(f"must be a whole number {bound}, got {text!r}")
        return value

    parse.__name__ = f"int_in_{low}_{high}"
    return parse


positive_int = int_in(1)
non_negative_int = int_in(0)


def downsample_blocks(text: str) -> int | None:
    """``auto`` (None: chosen from the wire's width) or a block size 1..8."""
    if text.strip().lower() == "auto":
        return None
    try:
        return int_in(1, 8)(text)
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"must be auto or a whole number in 1..8, got {text!r}"
        ) from None


def add_downsample_option(p: argparse.ArgumentParser, *, as_for: str = "") -> None:
    """``--downsample N|auto`` (:func:`downsample_blocks`), for ``part`` and the commands
    that measure a part as it does (``as_for`` begins the help with that)."""
    p.add_argument(
        "--downsample",
        type=downsample_blocks,
        default=1,
        metavar="N|auto",
        help=as_for + "measure the wire on the photo averaged over N x N pixel blocks (default 1: "
        "its own pixels); auto: with the wire's diameter, the blocks that bring it nearest 12 px "
        "wide. For a wire about 18 px wide or more (2-3 mm at 0.11 mm/px, a 24 MP camera's full "
        "size) 2 measured better on the held-out renders (docs/part-measurement.md says where it "
        "costs); the board's plane is always found at full size",
    )
