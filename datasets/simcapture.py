"""A simulated camera for calibration sessions: renders a simulated machine's state.

:class:`SimulatedCapture` implements :class:`cvmeasure.driver.capture.CaptureDevice`
(``capture(name) -> CapturedPhoto``) with the photo lab's
:func:`~cvmeasure_datasets.bender.render_bender_photo`; :func:`double_photo_state`
reads what a photo of the TinyG double's machine shows. It lives in the lab,
not in the driver, so that no measuring stage imports the renderer.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cvmeasure.driver.capture import CapturedPhoto

__all__ = ["PhotoState", "SimulatedCapture", "double_photo_state", "photo_state"]


@dataclass(frozen=True)
class PhotoState:
    """What a simulated photo shows: the pin angle and the wire's bend angle (deg, signed,
    machine frame)."""

    pin_angle_deg: float
    bend_angle_deg: float


@dataclass
class SimulatedCapture:
    """Renders the machine's current state with the synthetic photo lab.

    Parameters
    ----------
    out_dir : path
        Where photos (``<name>.jpg``) and their truth (``<name>.truth.json``) go.
    state : callable returning PhotoState
        Reads the machine's state at the moment of capture, e.g. the double's
        pin angle and the simulated wire's bend angle (:func:`double_photo_state`).
    scale : float
        Render scale (1.0 = the seed camera's 4608 x 3072 px).
    seed : int
        Base seed; photo ``k`` uses ``seed + k`` (noise differs between photos).
    render_options : mapping
        Passed on to :func:`~cvmeasure_datasets.bender.render_bender_photo`
        (kit, camera, pose, lighting, ...).
    """

    out_dir: Path
    state: Callable[[], PhotoState]
    scale: float = 0.25
    seed: int = 0
    render_options: Mapping[str, Any] = field(default_factory=dict)
    _count: int = 0

    def capture(self, name: str) -> CapturedPhoto:
        """Render the current state to ``<out_dir>/<name>.jpg`` (+ ``.truth.json``)."""
        from cvmeasure_datasets.bender import render_bender_photo

        s = self.state()
        photo = render_bender_photo(
            pin_angle_deg=s.pin_angle_deg,
            bend_angle_deg=s.bend_angle_deg,
            seed=self.seed + self._count,
            scale=self.scale,
            **dict(self.render_options),
        )
        self._count += 1
        out_dir = Path(self.out_dir)
        out_dir.mkdir(parents=True, exist_ok=True)
        photo_path, _ = photo.save(out_dir / name)
        return CapturedPhoto(path=Path(photo_path), truth=photo.truth, camera=photo.camera)

    def close(self) -> None:
        pass


def double_photo_state(double: Any, params: Any = None) -> PhotoState:
    """What a photo of the TinyG double's machine shows right now (see :func:`photo_state`).

    The pin is drawn where the head really is: the command less the machine's command
    effects (play lost, an offset, a drift), as a camera sees it, not at the controller's X.
    """
    state = double.machine_state()
    return photo_state(state.head_deg, state.bend_angle_deg, params)


def photo_state(pin_deg: float, bend_angle_deg: float, params: Any = None) -> PhotoState:
    """What a photo of the machine shows, from the pin command and the wire's bend angle.

    The pin's photo angle (origin -> pin from +x, deg) is its die-frame angle
    in the simulation's kinematics: first contact minus the approach plus the
    head rotation ``pin_deg``, mirrored for clockwise (negative) rotations;
    at home the side is taken from the bend (counter-clockwise when straight).
    """
    from cvmeasure.sim import SimParams
    from cvmeasure.sim.kinematics import contact_angle_deg, head_geometry

    params = params or SimParams()
    side = -1.0 if (pin_deg or bend_angle_deg) < 0 else 1.0
    geom = head_geometry(params, side)
    phi = float(contact_angle_deg(geom)) - params.approach_deg + abs(pin_deg)
    return PhotoState(pin_angle_deg=side * phi, bend_angle_deg=float(bend_angle_deg))
