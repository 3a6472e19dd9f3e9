"""The closed loop's designs and hidden machines, drawn apart from the code they test.

Designs are written as the SVG files an operator would draw (millimetre documents):
polylines with equal and unequal chords, circular arcs and S-curves (two arcs of
opposite sense) as SVG arc paths, the seed paper's half circle (an arc, bent in 20
chords) and saddle (its 13-chord polygon). The machine is the simulation's bender
is the held-out bender model (``benchmarks/heldout``: its own wire, die and drive
physics) with effects the tool is not told of (backlash, home offset, drift, a
springback asymmetry).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cvmeasure.gcode import SHALLOW_SESSION_ANGLES_DEG

__all__ = ["LoopDesign", "draw_designs", "seed_designs", "hidden_machine", "SHALLOW_ANGLES"]

#: The calibration session for shallow parts (cvmeasure gcode's refusal names it):
#: wanted loaded angles, both directions, reaching final bends of about 0.3 deg.
SHALLOW_ANGLES = SHALLOW_SESSION_ANGLES_DEG

_SVG = (
    '<svg xmlns="http://www.w3.org/2000/svg" width="400mm" height="400mm" '
    'viewBox="0 0 400 400">{}</svg>\n'
)


@dataclass(frozen=True)
class LoopDesign:
    """One design of the loop: its file, its family and the gcode options it is bent with."""

    name: str
    family: str
    path: Path
    divisions: int | None = None
    unequal: bool = False


def _polygon(chords: np.ndarray, turns_deg: np.ndarray) -> np.ndarray:
    heading = np.concatenate(([0.0], np.cumsum(np.radians(turns_deg))))
    steps = chords[:, None] * np.column_stack((np.cos(heading), np.sin(heading)))
    pts = np.vstack(([0.0, 0.0], np.cumsum(steps, axis=0)))
    return pts - pts.mean(axis=0)


def _svg_polyline(pts: np.ndarray) -> str:
    q = [(200 + x, 200 - y) for x, y in pts]  # the SVG's y runs down
    return _SVG.format(
        '<polyline fill="none" stroke="black" points="'
        + " ".join(f"{x:.4f},{y:.4f}" for x, y in q)
        + '"/>'
    )


def _fits(pts: np.ndarray) -> bool:
    """Fits the photo's 250 mm sheet and does not come near itself."""
    extent = np.ptp(pts, axis=0)
    if np.max(extent) > 215.0:
        return False
    d = np.diff(pts, axis=0)
    for i in range(len(d)):
        for j in range(i + 2, len(d)):
            if _seg_dist(pts[i], pts[i + 1], pts[j], pts[j + 1]) < 8.0:
                return False
    return True


def _seg_dist(p, q, r, s) -> float:
    def to_seg(x, a, b):
        ab = b - a
        w = float(np.clip(np.dot(x - a, ab) / max(float(ab @ ab), 1e-12), 0.0, 1.0))
        return float(np.hypot(*(a + w * ab - x)))

    return min(to_seg(p, r, s), to_seg(q, r, s), to_seg(r, p, q), to_seg(s, p, q))


def _equal(rng: np.random.Generator) -> np.ndarray:
    n = int(rng.integers(6, 11))
    chord = float(rng.uniform(16.0, 22.0))
    turns = rng.uniform(3.0, 25.0, n - 1) * rng.choice([-1.0, 1.0], n - 1)
    return _polygon(np.full(n, chord), turns)


def _unequal(rng: np.random.Generator) -> np.ndarray:
    """Open polylines as in the issue: bends 3-60 deg of both signs, chords 15-40 mm."""
    n = int(rng.integers(4, 9))
    chords = rng.uniform(15.0, 40.0, n)
    turns = rng.uniform(3.0, 60.0, n - 1) * rng.choice([-1.0, 1.0], n - 1)
    return _polygon(chords, turns)


def _arc_path(rng: np.random.Generator) -> str:
    radius = float(rng.uniform(60.0, 140.0))
    sweep = float(rng.uniform(50.0, min(170.0, np.degrees(200.0 / radius))))
    a0 = np.radians(rng.uniform(0.0, 360.0))
    a1 = a0 + np.radians(sweep)
    x0, y0 = 200 + radius * np.cos(a0), 200 + radius * np.sin(a0)
    x1, y1 = 200 + radius * np.cos(a1), 200 + radius * np.sin(a1)
    large = 1 if sweep > 180 else 0
    d = f"M {x0:.4f} {y0:.4f} A {radius:.4f} {radius:.4f} 0 {large} 1 {x1:.4f} {y1:.4f}"
    return _SVG.format(f'<path fill="none" stroke="black" d="{d}"/>')


def _s_curve_path(rng: np.random.Generator) -> str:
    """Two tangent arcs of opposite sense (an S), each 40-90 deg of radius 50-110 mm."""
    r1, r2 = rng.uniform(50.0, 110.0, 2)
    s1, s2 = np.radians(rng.uniform(40.0, 90.0, 2))
    # start at the origin heading +x; first arc turns left (y-up frame), the second right
    c1 = np.array([0.0, r1])
    p1 = c1 + r1 * np.array([np.sin(s1), -np.cos(s1)])
    heading = s1
    c2 = p1 + r2 * np.array([np.sin(heading), -np.cos(heading)])
    p2 = c2 + r2 * np.array([-np.sin(heading - s2), np.cos(heading - s2)])
    pts = np.array([[0.0, 0.0], p1, p2])
    pts = pts - pts.mean(axis=0)
    q = [(200 + x, 200 - y) for x, y in pts]
    # SVG y down: a left turn in the y-up frame is sweep-flag 0
    d = (
        f"M {q[0][0]:.4f} {q[0][1]:.4f} A {r1:.4f} {r1:.4f} 0 0 0 {q[1][0]:.4f} {q[1][1]:.4f} "
        f"A {r2:.4f} {r2:.4f} 0 0 1 {q[2][0]:.4f} {q[2][1]:.4f}"
    )
    return _SVG.format(f'<path fill="none" stroke="black" d="{d}"/>')


def draw_designs(
    rng: np.random.Generator, folder: Path, counts: dict[str, int]
) -> list[LoopDesign]:
    """Draw ``counts[family]`` designs of each family into SVG files under ``folder``."""
    out: list[LoopDesign] = []
    for family, count in counts.items():
        for k in range(count):
            path = folder / f"{family}_{k}.svg"
            if family in ("equal", "unequal"):
                while True:
                    pts = _equal(rng) if family == "equal" else _unequal(rng)
                    if _fits(pts):
                        break
                path.write_text(_svg_polyline(pts), encoding="utf-8")
            elif family == "arc":
                path.write_text(_arc_path(rng), encoding="utf-8")
            else:
                path.write_text(_s_curve_path(rng), encoding="utf-8")
            out.append(LoopDesign(f"{family} {k}", family, path, None, family == "unequal"))
    return out


def seed_designs(folder: Path) -> list[LoopDesign]:
    """The seed paper's half circle (R 100 mm, 20 chords) and saddle (200 x 20 mm, 13 chords)."""
    import cvmeasure_datasets

    half = folder / "half_circle.svg"
    half.write_text(
        _SVG.format('<path fill="none" stroke="black" d="M 100 200 A 100 100 0 0 1 300 200"/>'),
        encoding="utf-8",
    )
    saddle = folder / "saddle.svg"
    saddle.write_text(
        _svg_polyline(cvmeasure_datasets.saddle_part(200.0, 20.0, 13).vertices_mm),
        encoding="utf-8",
    )
    return [
        LoopDesign("half circle", "seed", half, 20),
        LoopDesign("saddle", "seed", saddle, None),
    ]


def hidden_machine(rng: np.random.Generator):
    """The held-out DIWire with hidden effects (drawn): backlash, offset, drift, asymmetry.

    Its wire and drive are the held-out model's own physics
    (``benchmarks/heldout``), not the tool's simulation.
    """
    from benchmarks.heldout.machine import Effects

    return "diwire", Effects(
        backlash_deg=float(rng.uniform(0.5, 2.0)),
        offset_deg=float(rng.uniform(-1.5, 1.5)),
        drift_deg=float(rng.uniform(0.005, 0.04)),
        springback_asymmetry=float(rng.uniform(-0.05, 0.05)),
    )
