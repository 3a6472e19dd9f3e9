"""The order of a calibration session's bends, made so that the diagnosis can name a cause.

A calibration needs every angle in both directions once; the order does not matter to
it (the springback is fitted per direction along the angle). The diagnosis of the same
bends (``cvmeasure diagnose trials.csv``) needs more than one order can give when the
angles are swept each direction once: a backlash lost on reversals only, a drift, a
warm-up and a trend with the bend index all follow the index there, and the one
reversal tells nothing of what a reversal costs. The session's plan therefore:

- takes the angles in a low-discrepancy order (golden-ratio), not rising, so that no
  angle-dependent cause follows the bend index, in blocks of ``RUN_LENGTH``;
- bends a block one way, then the same angles the other way (the two directions of an
  angle are a few bends apart whatever drifts), the next block starting the way the
  last ended: runs of 4 and 8 bends one way, a sixth to a quarter of the bends after a
  reversal; a drift that shifts home walks through runs of two lengths, which neither
  an offset (constant per direction) nor a backlash on reversals (the first bend of a
  run) makes;
- runs the blocks a second time, from the middle of the first pass's order on, each
  bent the other way first and its angles backwards: every (angle, direction) is bent
  twice, at another place in its run (a drift, a warm-up or any index trend shows as the
  repeats' difference; identical commands are held out together by the diagnosis'
  cross-validation).

A session of ``n`` angles bends ``4 n``. Identifiability of the catalogue on these
plans: ``docs/diagnosis.md``, "The calibration session's plan".
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["DIRECTIONS", "diagnosis_plan", "swept_plan"]

DIRECTIONS: tuple[str, str] = ("ccw", "cw")
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0
#: Angles per block: a drift that shifts home walks by a run's loss before a reversal
#: takes it back (runs of 2 hid a 0.04 deg per bend drift to 0.02 deg rms; runs of 4 and
#: 8 show it at 0.10 deg), and enough bends follow a reversal for a backlash lost there.
RUN_LENGTH = 4


def _spread_order(n: int) -> list[int]:
    """Indices 0..n-1 in a low-discrepancy order (golden-ratio sequence ranks)."""
    keys = [((k + 1) * _GOLDEN) % 1.0 for k in range(n)]
    return sorted(range(n), key=keys.__getitem__)


def diagnosis_plan(
    angles_deg: Sequence[float], run_length: int = RUN_LENGTH
) -> list[tuple[str, float]]:
    """The session's bends in execution order: ``(direction, angle_deg)``, ``4 n`` of them.

    Parameters
    ----------
    angles_deg : sequence of float
        The calibration angles (wanted loaded bend magnitudes, deg), each bent twice in
        each direction (see the module notes for the order).
    run_length : int
        Angles per block: a block is bent one way, then the same angles the other way.
    """
    angles = sorted(float(a) for a in angles_deg)
    order = [angles[i] for i in _spread_order(len(angles))]
    blocks = [order[i : i + run_length] for i in range(0, len(order), run_length)]
    plan: list[tuple[str, float]] = []
    for k, block in enumerate(blocks):
        first, second = DIRECTIONS if k % 2 == 0 else DIRECTIONS[::-1]
        plan += [(first, a) for a in block] + [(second, a) for a in block]
    # the second pass: the blocks from the middle of the first pass's order on, each
    # bent the other way first and its angles backwards (a bend repeated at another
    # place in its run: a drift's loss differs between the two); not the first pass
    # backwards, which would give both bends of a repeat the same distance from the
    # session's middle, so that any even trend about it followed the angle
    m = len(blocks)
    for j in range(m):
        k = (j + m // 2) % m
        first, second = DIRECTIONS[::-1] if k % 2 == 0 else DIRECTIONS
        block = blocks[k][::-1]
        plan += [(first, a) for a in block] + [(second, a) for a in block]
    return plan


def swept_plan(angles_deg: Sequence[float]) -> list[tuple[str, float]]:
    """Every angle counter-clockwise rising, then every angle clockwise (a custom
    session's order: the angles the user listed, each once per direction)."""
    return [(d, float(a)) for d in DIRECTIONS for a in angles_deg]
