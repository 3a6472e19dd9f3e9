"""From a wire design to TinyG G-code for the DIWire: bend list, pin commands, lines.

Three pure steps:

1. :func:`bend_list` - a polyline (design frame, mm) becomes feeds and signed
   bends, checked against the seed paper's rules: an open shape, every
   straight segment at least ``min_segment_mm`` (12 mm), every bend within
   ``max_bend_deg``. Bend angles are in the machine frame (counter-clockwise
   seen from above positive): the already fed leg turns about the die, so
   walking the design from its first point (fed first) the turn at a vertex is
   *minus* the machine bend.
2. :func:`pin_commands` - each wanted final bend goes through the springback
   compensation and the inverse motion function to a pin command (X, degrees
   of head rotation from home). Any object with ``compensate(target_deg) ->
   pin_deg`` works (:class:`cvmeasure.material.compensation.Compensation` from a
   calibration); the default is the simulation's own inverse
   (:func:`cvmeasure.sim.pin_command_for_angle`).
3. :func:`gcode_lines` - the bend list and pin commands become numbered
   G-code (``N1`` ...): ``G21`` always (X, Y, Z are linear axes on TinyG, so
   G20 would scale the degrees), X pin in degrees (absolute), Y feed in mm
   (relative, ``G91`` on the line itself), Z pin duck (``Z180`` ducked, ``Z0``
   up), the pin sent home to release each bend, a duck to change sides when
   the bend direction changes, and a bare ``N`` end marker. Every line is
   checked by :func:`~cvmeasure.gcode_line.encode_line`: never a realtime
   character, ``$``, ``?`` or a control character.

:func:`design_job` chains the three. Jobs are made here, on the design and material
side; :mod:`cvmeasure.driver` only streams them (it checks lines with the same
:func:`~cvmeasure.gcode_line.encode_line`). :mod:`cvmeasure.sim` is imported only
where the default compensator needs it: a job compensated from a calibration never does,
and it adds a tenth of a second to start-up.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike

from cvmeasure.design import bend_angles_deg, chord_lengths_mm
from cvmeasure.errors import CompensationRangeWarning, InputError
from cvmeasure.gcode_line import comment_text, encode_line
from cvmeasure.warning import StageWarning

__all__ = [
    "BendStep",
    "BendList",
    "MachineLayout",
    "GcodeJob",
    "Compensator",
    "SimCompensator",
    "bend_list",
    "pin_commands",
    "gcode_lines",
    "design_job",
    "job_header",
    "MIN_SEGMENT_MM",
    "MAX_BEND_DEG",
    "SHALLOW_SESSION_ANGLES_DEG",
]

#: Shortest straight segment the DIWire can grip and bend (seed paper, Wireware).
MIN_SEGMENT_MM = 12.0
#: Largest bend the rules allow (Berkeley DI-WIRE DFM rule, 1/8" wire).
MAX_BEND_DEG = 135.0
#: Turns smaller than this are treated as straight (no bend emitted), degrees.
MIN_BEND_DEG = 0.01
#: The calibration session for shallow parts (wanted loaded angles, both directions):
#: the standard angles plus 1.2, 1.9 and 2.5 deg, whose final bends (about 0.3, 1.0 and
#: 1.6 deg on a 3 mm steel wire) lie far enough apart to be separate calibration points.
#: It calibrates the seed paper's saddle (end bends of 0.91 deg); a bend below the
#: calibrated range is refused with this session's command rather than extrapolated.
SHALLOW_SESSION_ANGLES_DEG = (
    1.2, 1.9, 2.5, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0, 110.0, 130.0,
)  # fmt: skip


class Compensator(Protocol):
    """Anything that turns a wanted final bend (deg, signed) into a pin command (deg)."""

    def compensate(self, target_final_deg: float) -> float: ...


@dataclass(frozen=True)
class SimCompensator:
    """The simulation's inverse as a compensator (the default without a calibration).

    ``params`` / ``effects`` are those of :mod:`cvmeasure.sim` (None = defaults).
    """

    params: Any = None
    effects: tuple[Any, ...] = ()

    def compensate(self, target_final_deg: float) -> float:
        from cvmeasure.sim import pin_command_for_angle

        return float(pin_command_for_angle(float(target_final_deg), self.params, self.effects))

    def compensate_many(self, targets_deg: ArrayLike) -> np.ndarray:
        """Vectorised :meth:`compensate` (raises ValueError if any target is unreachable)."""
        from cvmeasure.sim import pin_command_for_angle

        t = np.asarray(targets_deg, dtype=np.float64)
        return np.asarray(pin_command_for_angle(t, self.params, self.effects), dtype=np.float64)


@dataclass(frozen=True)
class BendStep:
    """Feed ``feed_mm``, then bend by ``bend_deg`` (0 for the last, straight step)."""

    feed_mm: float
    bend_deg: float

    def to_dict(self) -> dict[str, float]:
        return {"feed_mm": self.feed_mm, "bend_deg": self.bend_deg}


@dataclass(frozen=True)
class BendList:
    """A part as feeds and bends, machine frame.

    ``steps[i]`` feeds, then bends (the last step only feeds). ``source`` names
    the design for messages.
    """

    steps: tuple[BendStep, ...]
    source: str = ""

    @property
    def bends_deg(self) -> np.ndarray:
        return np.array([s.bend_deg for s in self.steps[:-1]], dtype=np.float64)

    @property
    def total_feed_mm(self) -> float:
        return float(sum(s.feed_mm for s in self.steps))

    def to_dict(self) -> dict[str, Any]:
        return {"source": self.source, "steps": [s.to_dict() for s in self.steps]}


@dataclass(frozen=True)
class MachineLayout:
    """Where the DIWire's axes are, and how fast to move them.

    Attributes
    ----------
    home_ccw_deg, home_cw_deg : X of the pin at rest on the side of a CCW
        (positive) and CW bend; a pin command is added to the home of its side.
    duck_down, duck_up : Z ducked (the pin passes under the wire) and up.
    feed_rate_mm_min : Y feed rate (G1 F), mm/min.
    bend_rate_deg_min : X rate while bending (G1 F), deg/min.
    max_pin_deg : largest |X| the pin may be sent to.
    """

    home_ccw_deg: float = 0.0
    home_cw_deg: float = 0.0
    duck_down: float = 180.0
    duck_up: float = 0.0
    feed_rate_mm_min: float = 3000.0
    bend_rate_deg_min: float = 6000.0
    max_pin_deg: float = 200.0

    def home(self, direction: float) -> float:
        return self.home_cw_deg if direction < 0 else self.home_ccw_deg


@dataclass(frozen=True)
class GcodeJob:
    """A generated job: its lines, the bend list and pin commands it came from.

    ``header``: comment lines written before the commands (:func:`job_header`: what the
    job was made from and the polygon it bends, which ``part --job`` and ``correct
    --job`` read back); ``lines`` are the commands streamed to the bender.
    """

    lines: tuple[str, ...]
    bends: BendList
    pin_deg: tuple[float, ...]
    warnings: tuple[StageWarning, ...] = ()
    header: tuple[str, ...] = ()

    def text(self) -> str:
        """The job file: its header, then its commands, one per line."""
        return "\n".join((*self.header, *self.lines)) + "\n"

    def to_dict(self) -> dict[str, Any]:
        return {
            "lines": len(self.lines),
            "bends": len(self.pin_deg),
            "total_feed_mm": self.bends.total_feed_mm,
            "bend_list": self.bends.to_dict()["steps"],
            "pin_deg": list(self.pin_deg),
            "warnings": [w.to_json() for w in self.warnings],
        }


def bend_list(
    points_mm: ArrayLike,
    *,
    closed: bool = False,
    source: str = "design",
    min_segment_mm: float = MIN_SEGMENT_MM,
    max_bend_deg: float = MAX_BEND_DEG,
    bend_radius_mm: float = 0.0,
) -> BendList:
    """Feeds and machine-frame bends of an open polyline, checked against the rules.

    Parameters
    ----------
    points_mm : ndarray of shape (N, 2)
        Vertices in the design frame (x right, y up), mm; the first point is fed first.
    closed : the path is a closed shape (refused).
    source : the design's name, for messages.
    min_segment_mm : shortest allowed segment between bends.
    max_bend_deg : largest allowed |bend|.
    bend_radius_mm : wire centreline radius around the die; each feed is
        corrected by the setback ``r tan(a/2)`` and the arc ``r a / 2`` of its
        neighbouring bends (0 = sharp corners, the design's own lengths).

    Raises
    ------
    InputError
        Closed shape, fewer than 2 points, a segment shorter than
        ``min_segment_mm`` or a bend beyond ``max_bend_deg`` (named, with its value).
    """
    pts = np.asarray(points_mm, dtype=np.float64).reshape(-1, 2)
    if closed or (len(pts) > 2 and np.allclose(pts[0], pts[-1], atol=1e-6)):
        raise InputError(source, "closed shape: a wire part must have two free ends")
    if len(pts) < 2:
        raise InputError(source, "the wire path has fewer than 2 points")
    # merge collinear vertices (no bend there)
    keep = [0]
    turns = bend_angles_deg(pts)
    for i, t in enumerate(turns, start=1):
        if abs(t) >= MIN_BEND_DEG:
            keep.append(i)
    keep.append(len(pts) - 1)
    pts = pts[keep]
    lengths = chord_lengths_mm(pts)
    turns = bend_angles_deg(pts)
    for i, length in enumerate(lengths):
        if length < min_segment_mm - 1e-9:
            raise InputError(
                source,
                f"segment {i + 1} from ({pts[i, 0]:.2f}, {pts[i, 1]:.2f}) mm is {length:.2f} mm "
                f"long; the bender needs at least {min_segment_mm:g} mm",
            )
    for i, t in enumerate(turns, start=1):
        if abs(t) > max_bend_deg:
            raise InputError(
                source,
                f"bend at vertex {i} ({pts[i, 0]:.2f}, {pts[i, 1]:.2f}) mm is {t:.1f} deg; "
                f"the machine bends at most {max_bend_deg:g} deg",
            )
    bends = -turns  # machine frame: the fed leg turns about the die
    half = np.zeros(len(lengths) + 1)
    if bend_radius_mm > 0 and len(turns):
        a = np.radians(np.abs(turns))
        corr = bend_radius_mm * (a / 2.0 - np.tan(a / 2.0))
        half[1:-1] = corr
    feeds = lengths + half[:-1] + half[1:]
    steps = [BendStep(float(feeds[i]), float(bends[i])) for i in range(len(bends))]
    steps.append(BendStep(float(feeds[-1]), 0.0))
    return BendList(tuple(steps), source)


def pin_commands(
    bends: BendList,
    compensation: Compensator | Callable[[float], float] | None = None,
    *,
    warnings_out: list[StageWarning] | None = None,
) -> tuple[float, ...]:
    """Pin command (deg, signed) of each bend through the compensation.

    A bend a little below a calibration's range (within its lowest calibrated
    interval of the lowest point) is made by the stated extrapolation rule
    (:func:`_extrapolated_below`) and warned about (``bend_extrapolated``, appended to
    ``warnings_out``); further below, it is refused naming the session that calibrates it.

    Raises
    ------
    InputError
        A bend the compensation cannot reach (outside its calibrated range or
        beyond the machine), naming the design and the bend.
    """
    comp = compensation if compensation is not None else SimCompensator()
    many = getattr(comp, "compensate_many", None)
    if many is not None and len(bends.bends_deg):
        try:
            return tuple(float(p) for p in many(bends.bends_deg))
        except ValueError:
            pass  # find and name the bend one by one below
    fn = comp.compensate if hasattr(comp, "compensate") else comp
    out = []
    for i, target in enumerate(bends.bends_deg, start=1):
        try:
            out.append(float(fn(float(target))))  # type: ignore[operator]
            continue
        except ValueError as exc:
            made = _extrapolated_below(comp, float(target), i)
            if made is None:
                # below the calibration: the session to run, said in the one line there is
                why = _shallow_advice(comp, target) or f"cannot be made: {exc}"
                raise InputError(bends.source, f"bend {i} of {target:.2f} deg {why}") from None
        out.append(made[0])
        if warnings_out is not None:
            warnings_out.append(made[1])
    return tuple(out)


def _shallow_advice(compensation: Any, target_deg: float) -> str:
    """The session to run when a bend lies below the calibration's range ('' otherwise)."""
    domain = getattr(getattr(compensation, "compensation", compensation), "domain_deg", None)
    if domain is None or target_deg == 0:
        return ""
    try:
        low = float(domain("cw" if target_deg < 0 else "ccw")[0])
    except (KeyError, TypeError, ValueError):
        return ""
    if abs(target_deg) >= low:
        return ""
    angles = ",".join(f"{a:g}" for a in SHALLOW_SESSION_ANGLES_DEG)
    return (
        f"is below the calibrated {low:.2f} deg: calibrate with cvmeasure session --angles {angles}"
    )


def _lowest_interval(
    compensation: Any, target_deg: float
) -> tuple[float, float, float, float] | None:
    """(f0, l0, f1, l1): the two lowest calibrated (final, loaded) knots of the bend's side."""
    comp = getattr(compensation, "compensation", compensation)
    curves = getattr(comp, "springback", None)
    if not isinstance(curves, dict) or target_deg == 0:
        return None
    curve = curves.get("cw" if target_deg < 0 else "ccw")
    if curve is None or len(curve.final_deg) < 2:
        return None
    f, lo = curve.final_deg, curve.loaded_deg
    return float(f[0]), float(lo[0]), float(f[1]), float(lo[1])


def _extrapolated_below(
    compensation: Any, target_deg: float, index: int
) -> tuple[float, StageWarning] | None:
    """The stated rule for a bend just below the calibrated range, or None (refuse).

    Below the lowest calibrated final angle ``f0`` the calibration's curves are
    continued linearly (its ``outside="warn"``: the lowest interval's slope), down to
    ``max(f0 - (f1 - f0), f0 / 2)`` at most (nearer the yield the springback is no longer
    that of a yielded section). A shallow bend's springback is the elastic recovery of a
    just-yielded section, nearly constant; holding it at ``f0``'s value instead of
    continuing the slope gives the other plausible pin, and the two bends' difference,
    ``(f0 - |t|) |sb1 - sb0| / (f1 - f0)``, is the stated uncertainty.
    """
    knots = _lowest_interval(compensation, target_deg)
    if knots is None:
        return None
    f0, l0, f1, l1 = knots
    t = abs(target_deg)
    if t >= f0 or t < max(f0 - (f1 - f0), 0.5 * f0) or f1 <= f0:
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", CompensationRangeWarning)
            pin = float(compensation.compensate(target_deg, outside="warn"))
    except (TypeError, ValueError):
        return None
    sigma = (f0 - t) * abs((l1 - f1) - (l0 - f0)) / (f1 - f0)
    angles = ",".join(f"{a:g}" for a in SHALLOW_SESSION_ANGLES_DEG)
    warning = StageWarning(
        "bend_extrapolated",
        f"bend {index} of {target_deg:.2f} deg is below the calibrated {f0:.2f} deg: its pin "
        f"is extrapolated from the calibration's lowest interval (springback "
        f"{l0 - f0:.2f} deg), uncertain by about {sigma:.3f} deg; cvmeasure session "
        f"--angles {angles} calibrates it",
        f"bend {index}",
    )
    return pin, warning


def _num(value: float) -> str:
    text = f"{value:.3f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text


def gcode_lines(
    bends: BendList,
    pin_deg: Sequence[float],
    *,
    layout: MachineLayout | None = None,
    title: str = "",
) -> tuple[str, ...]:
    """Numbered TinyG G-code for a bend list and its pin commands.

    Raises
    ------
    InputError
        A pin command beyond ``layout.max_pin_deg``.
    """
    lay = layout or MachineLayout()
    body: list[str] = []
    comment = "".join(c for c in title if c.isalnum() or c in " ._-/")[:40]
    body.append(f"G21 G90 (cvmeasure {comment})".replace(" )", ")"))
    body.append(f"G0 Z{_num(lay.duck_up)}")
    side = 1.0
    first = next((b.bend_deg for b in bends.steps[:-1] if b.bend_deg != 0), 1.0)
    side = math.copysign(1.0, first)
    body.append(f"G0 X{_num(lay.home(side))}")
    fr, br = _num(lay.feed_rate_mm_min), _num(lay.bend_rate_deg_min)
    for i, step in enumerate(bends.steps):
        if step.feed_mm > 0:
            body.append(f"G91 G1 Y{_num(step.feed_mm)} F{fr}")
        if i == len(bends.steps) - 1:
            break
        pin = float(pin_deg[i])
        direction = math.copysign(1.0, step.bend_deg)
        if direction != side:
            body.append(f"G90 G0 Z{_num(lay.duck_down)}")
            if lay.home(direction) != lay.home(side):
                body.append(f"G0 X{_num(lay.home(direction))}")
            body.append(f"G0 Z{_num(lay.duck_up)}")
            side = direction
        x = lay.home(direction) + pin
        if abs(x) > lay.max_pin_deg:
            raise InputError(
                bends.source,
                f"bend {i + 1} needs the pin at {x:.1f} deg, beyond the machine's "
                f"{lay.max_pin_deg:g} deg",
            )
        body.append(f"G90 G1 X{_num(x)} F{br}")
        body.append(f"G0 X{_num(lay.home(direction))}")
    lines = [f"N{i} {text}" for i, text in enumerate(body, start=1)]
    lines.append(f"N{len(lines) + 1} (end)")
    for text in lines:
        encode_line(text)  # never a realtime character; raises ValueError if so
    return tuple(lines)


def job_header(
    title: str, job: GcodeJob, *, model: str | None = None, plan_lines: Sequence[str] = ()
) -> tuple[str, ...]:
    """The comment lines a job file starts with (``cvmeasure gcode`` and ``gcode_for``).

    ``title``: what the job was made from; ``model``: the compensation that set its pins
    (a summary line of bends and wire length with it); ``plan_lines``: the polygon bent
    (:meth:`cvmeasure.wireplan.WirePlan.header_lines`); the job's warnings last; each line
    as :func:`cvmeasure.gcode_line.comment_text` keeps it.
    """
    lines = [title]
    if model is not None:
        lines.append(
            f"; {len(job.pin_deg)} bends, wire {job.bends.total_feed_mm:.3f} mm, "
            f"compensation: {model}"
        )
    lines += list(plan_lines)
    lines += [f"; warning: {w}" for w in job.warnings]
    return tuple(comment_text(ln) for ln in lines)


def design_job(
    points_mm: ArrayLike,
    *,
    closed: bool = False,
    source: str = "design",
    compensation: Compensator | Callable[[float], float] | None = None,
    layout: MachineLayout | None = None,
    min_segment_mm: float = MIN_SEGMENT_MM,
    max_bend_deg: float = MAX_BEND_DEG,
    bend_radius_mm: float = 0.0,
) -> GcodeJob:
    """Polyline -> bend list -> pin commands -> G-code (see the module notes)."""
    bl = bend_list(
        points_mm,
        closed=closed,
        source=source,
        min_segment_mm=min_segment_mm,
        max_bend_deg=max_bend_deg,
        bend_radius_mm=bend_radius_mm,
    )
    notes: list[StageWarning] = []
    pins = pin_commands(bl, compensation, warnings_out=notes)
    lines = gcode_lines(bl, pins, layout=layout, title=source.rsplit("/", 1)[-1])
    return GcodeJob(lines, bl, pins, tuple(notes))
