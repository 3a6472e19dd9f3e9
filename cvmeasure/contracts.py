"""The types that cross stages: what one stage hands the next, typed, saved and loaded whole.

Every stage takes and returns these, never dicts or ``Any``:

- **Trials** (:class:`Trial`, :class:`TrialTable`): measured bends, one per row, in the
  order executed; the only reader and writer of the spec's trials CSV.
- **Per-photo measurements**: what measuring one photo gives, as written to and read
  back from the JSON Lines results.
- **The measurement plane** (:class:`PlaneModel`): camera + homography + pose; saved
  and loaded without loss, rescaled with the photo like the camera.

Frames and units follow docs/conventions.md: angles in degrees, lengths in mm,
pixels in the image frame (x right, y down, centre of the top-left pixel at (0, 0)).
"""

from __future__ import annotations

__all__: list[str] = []

# ----------------------------------------------------------------------------- trials

# ----------------------------------------------------------------------------- per-photo measurements

# ----------------------------------------------------------------------------- the measurement plane
