"""The order of a calibration session's bends, made so that the diagnosis can name a cause.

A calibration needs every angle in both directions once; the order does not matter to
it (the springback is fitted per direction along the angle). The diagnosis of the same
bends (``cvmeasure diagnose trials.csv``) needs more than one order can give when the
angles are swept each direction once: a backlash lost on reversals only, a drift, a
warm-up and a trend with the bend index all follow the index there, and the one
reversal tells nothing of what a reversal costs. The session's plan therefore:

- bends each angle twice in a row, once each way (a *pair*), so the two directions of
  an angle are minutes apart whatever drifts;
- alternates the pairs' order (ccw-cw, then cw-ccw): every bend after the first follows
  a reversal (inside a pair) or a bend the same way (across pairs), half and half;
- takes the angles in a low-discrepancy order (golden-ratio), not rising, so that no
  angle-dependent cause follows the bend index;
- runs the pairs a second time, from the middle of the first pass's order on, each pair
  flipped: every (angle, direction) is bent twice, mostly once after a reversal and once
  after a bend the same way, ``n`` or ``3 n`` bends apart (a drift, a warm-up or any
  index trend shows as the repeats' difference; identical commands are held out
  together by the diagnosis' cross-validation).

A session of ``n`` angles bends ``4 n``. Identifiability of the catalogue on these
plans: ``docs/diagnosis.md``, "The calibration session's plan".
"""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["DIRECTIONS", "diagnosis_plan", "swept_plan"]

DIRECTIONS: tuple[str, str] = ("ccw", "cw")
_GOLDEN = (math.sqrt(5.0) - 1.0) / 2.0


def _spread_order(n: int) -> list[int]:
    """Indices 0..n-1 in a low-discrepancy order (golden-ratio sequence ranks)."""
    keys = [((k + 1) * _GOLDEN) % 1.0 for k in range(n)]
    return sorted(range(n), key=keys.__getitem__)


def diagnosis_plan(angles_deg: Sequence[float]) -> list[tuple[str, float]]:
    """The session's bends in execution order: ``(direction, angle_deg)``, ``4 n`` of them.

    Parameters
    ----------
    angles_deg : sequence of float
        The calibration angles (wanted loaded bend magnitudes, deg), each bent twice in
        each direction (see the module notes for the order).
    """
    angles = sorted(float(a) for a in angles_deg)
    order = [angles[i] for i in _spread_order(len(angles))]
    plan: list[tuple[str, float]] = []
    for k, angle in enumerate(order):
        first, second = DIRECTIONS if k % 2 == 0 else DIRECTIONS[::-1]
        plan += [(first, angle), (second, angle)]
    # the second pass: the same pairs from the middle of the first pass's order on, each
    # flipped (what followed a reversal now follows a bend the same way, and back); not
    # the first pass backwards, which would give both bends of a repeat the same
    # distance from the session's middle, so that any even trend about it followed the
    # angle
    n = len(order)
    for j in range(n):
        k = (j + n // 2) % n
        first, second = DIRECTIONS[::-1] if k % 2 == 0 else DIRECTIONS
        plan += [(first, order[k]), (second, order[k])]
    return plan


def swept_plan(angles_deg: Sequence[float]) -> list[tuple[str, float]]:
    """Every angle counter-clockwise rising, then every angle clockwise (a custom
    session's order: the angles the user listed, each once per direction)."""
    return [(d, float(a)) for d in DIRECTIONS for a in angles_deg]
