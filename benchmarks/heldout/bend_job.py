"""Bend a G-code job on the held-out machine and return the finished part.

The project's dialect (docs/streaming.md, "Lines"; checked black-box on
``cvmeasure gcode`` output): ``G21`` mm, ``G90``/``G91`` absolute/relative
distance (modal, any line may carry it), ``Y`` feeds wire (mm; relative under
``G91``), ``X`` is the head rotation from home (deg, signed: counter-clockwise
positive), ``Z`` the pin's duck (``Z180`` down, ``Z0`` up, around a change of
bend direction), ``N`` line numbers, ``( )`` and ``;`` comments, ``F`` rates.

Mapping onto the machine:

- every ``X`` move to a non-zero target is one bend to that commanded rotation,
  photographed nowhere, then released (the dialect always follows it with
  ``G0 X<home>``); moves to ``X0`` are the release; ``Z`` moves switch the pin's
  side, which the bend's sign already decides, so they change nothing else;
- a ``Y`` feed pushes ``feed * (1 - slip)`` mm of wire out of the die, ``slip``
  scattered about ``feed_slip`` (see :func:`bend_job`);
- the part is the wire from its first-fed end to the die exit after the last feed
  (cut there). Each bend leaves its released curvature (wrap and free span,
  :func:`benchmarks.heldout.mechanics.residual_zone`) on the wire just downstream
  of the die exit at the moment of the bend; the rest of the wire keeps its own
  coil set. Integrating the curvature along the wire gives the centreline.

Part frame: first-fed end at the origin, the first straight leg along +x, y up,
counter-clockwise positive; walking from the first-fed end the turn at a vertex is
minus the machine bend (the fed leg is what rotates about the die), as in the
project's design frame (SVG y flipped up).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.heldout.bender_physics import (
    MACHINES,
    BenderRun,
    BentZone,
    ExecutedBend,
    atomic_write,
    effect_names,
    resolve_machine,
)
from benchmarks.heldout.machine import Effects, Machine, machine_with, parse_effects

_WORD = re.compile(r"([A-Z])\s*([-+]?(?:\d+\.?\d*|\.\d+))")
_STEP_MM = 0.25


@dataclass(frozen=True)
class JobStep:
    """One machine action of a job: a feed (mm) or a bend (commanded deg)."""

    kind: str  # "feed" or "bend"
    value: float
    line: int


@dataclass(frozen=True)
class BentPart:
    """A finished part, its wire centreline in the part frame (mm, deg).

    Attributes
    ----------
    centreline_mm : numpy.ndarray
        (N, 2) points every 0.25 mm or less from the first-fed end to the cut end.
    vertices_mm : numpy.ndarray
        (K + 2, 2): the first-fed end, each bend's vertex (where the straight legs
        either side of its zone meet), the cut end.
    bend_deg : numpy.ndarray
        (K,) true released bend at each vertex, machine sign (CCW positive; the turn
        walking from the first-fed end is its negative).
    commanded_pin_deg : numpy.ndarray
        (K,) the job's X for each bend.
    feed_mm : numpy.ndarray
        (K + 1,) the job's feeds before each bend and after the last one (commanded).
    bends : tuple of ExecutedBend
        Each bend's truth (head rotation, torque, slips...).
    """

    centreline_mm: np.ndarray
    vertices_mm: np.ndarray
    bend_deg: np.ndarray
    commanded_pin_deg: np.ndarray
    feed_mm: np.ndarray
    bends: tuple[ExecutedBend, ...]


def parse_job(gcode_text: str) -> list[JobStep]:
    """Feeds and bends of a job in the project's dialect (ValueError names a bad line)."""
    steps: list[JobStep] = []
    relative = False
    x = y = 0.0
    for number, raw in enumerate(gcode_text.splitlines(), start=1):
        line = re.sub(r"\([^)]*\)", "", raw.split(";", 1)[0]).strip().upper()
        if not line:
            continue
        words = _WORD.findall(line)
        if not words and line:
            raise ValueError(f"line {number}: cannot read {raw.strip()!r}")
        for letter, value in words:
            if letter == "G" and float(value) in (90.0, 91.0):
                relative = float(value) == 91.0
        for letter, value in words:
            v = float(value)
            if letter == "Y":
                delta = v if relative else v - y
                y += delta
                if delta < 0:
                    raise ValueError(
                        f"line {number}: the wire cannot be pulled back ({raw.strip()!r})"
                    )
                if delta > 0:
                    steps.append(JobStep("feed", delta, number))
            elif letter == "X":
                target = x + v if relative else v
                if target != 0.0:
                    steps.append(JobStep("bend", target, number))
                x = target
    return steps


def bend_job(
    gcode_text: str,
    machine: Machine | str = "diwire",
    effects: Effects | None = None,
    seed: int = 0,
) -> BentPart:
    """Bend a G-code job on the machine with its hidden effects; return the part.

    Parameters
    ----------
    gcode_text : str
        The job (project dialect, see the module docstring).
    machine : Machine or str
    effects : Effects, optional
    seed : int
        Seed of the feed rolls' scatter: with ``feed_slip`` on, each feed slips
        ``feed_slip * (1 + 0.25 z)`` (``z`` standard normal, never below zero); the
        rest of the physics is deterministic.

    Returns
    -------
    BentPart
    """
    fx = effects or Effects()
    rng = np.random.default_rng(seed)
    run = BenderRun(resolve_machine(machine), fx)
    fed = 0.0
    zones: list[tuple[float, BentZone]] = []  # (material coordinate at the die exit, zone)
    bends: list[ExecutedBend] = []
    feeds: list[float] = [0.0]
    commanded: list[float] = []
    natural = 0.0
    for step in parse_job(gcode_text):
        if step.kind == "feed":
            slip = (
                fx.feed_slip * max(1.0 + 0.25 * rng.standard_normal(), 0.0) if fx.feed_slip else 0.0
            )
            fed += step.value * (1.0 - slip)
            feeds[-1] += step.value
            continue
        done, zone = run.execute_zone(step.value)
        natural = zone.natural_curvature_per_mm
        zones.append((fed, zone))
        bends.append(done)
        commanded.append(step.value)
        feeds.append(0.0)
    if fed <= 0.0:
        raise ValueError("the job feeds no wire")
    return _part(fed, zones, natural, bends, commanded, feeds)


def _zone_curvature(s: np.ndarray, exit_s: float, zone: BentZone) -> np.ndarray:
    """A zone's curvature on the wire grid, carrying its full rotation."""
    d, c = zone.distance_mm, zone.curvature_per_mm
    if d.size < 2:
        return np.zeros_like(s)
    material = exit_s - d  # material coordinate of each zone point
    order = np.argsort(material)
    profile = np.interp(s, material[order], c[order], left=0.0, right=0.0)
    total, dense = math.radians(zone.rotation_deg), float(np.trapezoid(profile, s))
    if dense != 0.0:
        profile *= total / dense
    return profile


def _part(fed, zones, natural, bends, commanded, feeds) -> BentPart:
    """Integrate the wire's curvature from the first-fed end to the cut end."""
    n = max(int(math.ceil(fed / _STEP_MM)), 2)
    s = np.linspace(0.0, fed, n + 1)
    # Machine-frame curvature (the leg's rotation per length away from the die);
    # walking along increasing s the heading turns by its negative.
    curvature = np.full_like(s, natural)
    spans = []
    for exit_s, zone in zones:
        curvature += _zone_curvature(s, exit_s, zone)
        reach = float(zone.distance_mm.max()) if zone.distance_mm.size else 0.0
        spans.append((max(exit_s - reach, 0.0), exit_s))
    turn = -curvature
    heading = np.concatenate(([0.0], np.cumsum(0.5 * (turn[1:] + turn[:-1]) * np.diff(s))))
    if spans and spans[0][0] > 0.0:
        heading -= np.interp(0.5 * spans[0][0], s, heading)  # the first leg along +x
    mid = 0.5 * (heading[1:] + heading[:-1])
    xy = np.zeros((s.size, 2))
    xy[1:, 0] = np.cumsum(np.diff(s) * np.cos(mid))
    xy[1:, 1] = np.cumsum(np.diff(s) * np.sin(mid))
    vertices = [xy[0]] + [_vertex(s, xy, heading, a, b) for a, b in spans] + [xy[-1]]
    return BentPart(
        centreline_mm=xy,
        vertices_mm=np.array(vertices),
        bend_deg=np.array([b.bend_deg for b in bends]),
        commanded_pin_deg=np.array(commanded),
        feed_mm=np.array(feeds),
        bends=tuple(bends),
    )


def _vertex(s, xy, heading, start, end) -> np.ndarray:
    """Where the tangent lines at a zone's two ends meet (its midpoint for a tiny bend)."""
    i = max(int(np.searchsorted(s, start, side="right")) - 2, 0)  # a point clear of the zone
    j = min(int(np.searchsorted(s, end)) + 1, s.size - 1)
    if i >= j:  # no zone (the pin never touched): the die exit's point
        return xy[j].copy()
    p, q = xy[i], xy[j]
    u = np.array([math.cos(heading[i]), math.sin(heading[i])])
    v = np.array([math.cos(heading[j]), math.sin(heading[j])])
    cross = u[0] * v[1] - u[1] * v[0]
    if abs(cross) < 1e-6:
        return 0.5 * (p + q)
    t = ((q - p)[0] * v[1] - (q - p)[1] * v[0]) / cross
    return p + t * u


def part_record(part: BentPart, machine: Machine, effects: Effects) -> dict:
    """JSON-ready part: vertices, bends, centreline, and the truth of every bend."""
    return {
        "model": "benchmarks.heldout.bend_job",
        "frame": "part: first-fed end at the origin, first leg along +x, y up, CCW positive",
        "machine": dataclasses.asdict(machine),
        "effects": effect_names(effects),
        "vertices_mm": part.vertices_mm.round(4).tolist(),
        "bend_deg": part.bend_deg.round(5).tolist(),
        "commanded_pin_deg": part.commanded_pin_deg.tolist(),
        "feed_mm": part.feed_mm.round(4).tolist(),
        "centreline_mm": part.centreline_mm.round(4).tolist(),
        "bends": [dataclasses.asdict(b) for b in part.bends],
    }


def main(argv: list[str] | None = None) -> int:
    """CLI: bend a G-code job on a held-out machine; write the part as JSON."""
    p = argparse.ArgumentParser(
        prog="python -m benchmarks.heldout.bend_job",
        description="Bend a G-code job (cvmeasure gcode dialect) on a held-out machine with "
        "hidden effects and write the finished part (vertices, bends, centreline) as JSON.",
    )
    p.add_argument("job", type=Path, help="G-code file")
    p.add_argument("--machine", default="diwire", help=f"machine ({', '.join(MACHINES)})")
    p.add_argument("--machine-param", action="append", default=[], metavar="KEY=VALUE")
    p.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE[,KEY=VALUE]")
    p.add_argument("-o", "--out", type=Path, required=True, help="part JSON to write")
    args = p.parse_args(argv)
    try:
        text = args.job.read_text(encoding="ascii")
        steps = parse_job(text)
        del steps
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        print(f"{args.job}: {exc}", file=sys.stderr)
        return 2
    try:
        machine = machine_with(resolve_machine(args.machine), args.machine_param)
        effects = parse_effects(args.effect)
        part = bend_job(text, machine, effects)
    except ValueError as exc:
        print(f"{args.job}: {exc}", file=sys.stderr)
        return 2
    atomic_write(args.out, json.dumps(part_record(part, machine, effects)) + "\n")
    print(f"wrote {args.out}: {part.bend_deg.size} bends, {part.vertices_mm.shape[0]} vertices")
    return 0


if __name__ == "__main__":
    sys.exit(main())
