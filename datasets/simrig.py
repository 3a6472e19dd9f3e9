"""The simulated bench of the operator's app (``cvmeasure ui --simulate``).

The TinyG double on a pseudo-terminal and the photo lab's renderer: bender photos of the
double's machine state, board views held where the app tells the operator (the simulated
operator follows the guidance), a board flat on a plate 0.3 deg out of square, and the
finished part cut off the double's wire. It implements :class:`cvmeasure.app.rig.Rig`.
"""

from __future__ import annotations

import math
import threading
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.app import adapter
from cvmeasure.app.rig import PartMark, Rig

__all__ = ["SimRig"]


class SimRig(Rig):
    """The TinyG double and the photo lab (``--simulate``).

    ``scale`` is the render scale of every photo (1.0 = the seed camera's 4608 px); the
    lens calibration, the plane check and the part photos use the same lens at that scale.
    """

    simulated = True

    def __init__(
        self,
        *,
        scale: float = 0.25,
        speedup: float = 400.0,
        seed: int = 0,
        effects: tuple[Any, ...] = (),
    ) -> None:
        import cvmeasure_datasets
        from cvmeasure.testing.double import FakeTinyG

        self.scale = scale
        self.seed = seed
        self.double = FakeTinyG(speedup=speedup, sim_effects=effects).start()
        self.link = adapter.open_link("sim://", double=self.double)
        self.camera_model = cvmeasure_datasets.default_camera().scaled(scale)
        self.image_size_px = tuple(self.camera_model.image_size_px)
        self._mark = PartMark(0, 0.0)
        self._poses: list[Any] | None = None
        self.hint = ""  # the lens guidance shown to the operator, who follows it
        self._live_key: tuple[float, float] | None = None
        self._live_bgr: np.ndarray | None = None
        self._lock = threading.Lock()

    def bender_camera(self, folder: Path) -> Any:
        from cvmeasure_datasets.simcapture import SimulatedCapture, double_photo_state

        double = self.double
        return SimulatedCapture(
            folder, lambda: double_photo_state(double), scale=self.scale, seed=self.seed
        )

    def capture(self, kind: str, name: str, folder: Path, index: int = 0) -> Path:
        photo = self._render(kind, index)
        path, _ = photo.save(folder / name)
        return Path(path)

    def _render(self, kind: str, index: int) -> Any:
        import cvmeasure_datasets
        from cvmeasure_datasets.demo.calibration import planned_poses
        from cvmeasure_datasets.simcapture import double_photo_state

        board, cam, seed = adapter.BOARD, self.camera_model, self.seed + index
        if kind == "board_view":
            if self._poses is None:
                self._poses = planned_poses(12, self.seed + 7, board, cam)
            poses = self._poses
            pose = self._follow(poses[index % len(poses)], self.hint if index >= len(poses) else "")
            return cvmeasure_datasets.render_board_view(
                board=board, camera=cam, pose=pose, seed=seed
            )
        if kind == "plane":
            w, h = board.size_mm
            # the simulated stand is a little out of square: 0.3 deg, as a real one may be
            pose = cvmeasure_datasets.Pose(0.3, 200.0, 0.0, 900.0, (w / 2, h / 2))
            return cvmeasure_datasets.render_board_view(
                board=board, camera=cam, pose=pose, seed=seed
            )
        if kind == "kit":
            s = double_photo_state(self.double)
            return cvmeasure_datasets.render_bender_photo(
                pin_angle_deg=s.pin_angle_deg,
                bend_angle_deg=s.bend_angle_deg,
                scale=self.scale,
                seed=seed,
            )
        if kind == "part":
            shape = self.part_shape_mm()
            # the part lies design face up: the board frame has y down, the design y up
            return cvmeasure_datasets.render_part_photo(
                part=cvmeasure_datasets.polyline_part(shape * np.array([1.0, -1.0])),
                board=board,
                camera=cam,
                seed=seed,
            )
        raise ValueError(f"unknown photo kind {kind!r}")

    def _follow(self, pose: Any, hint: str) -> Any:
        """The simulated operator follows the guidance: the board moved towards the edges it
        names, by 30 % of the image (a part of the board may leave the view)."""
        from dataclasses import replace

        words = hint.split("hold the board", 1)[-1]
        dx = ("right" in words) - ("left" in words)
        dy = ("bottom" in words) - ("top" in words)
        if not (dx or dy):
            return pose
        w, h = self.image_size_px
        mm_per_px = pose.distance_mm / self.camera_model.fx
        ox, oy = pose.offset_mm
        return replace(
            pose, offset_mm=(ox - dx * 0.3 * w * mm_per_px, oy - dy * 0.3 * h * mm_per_px)
        )

    def mark_part(self) -> None:
        """A new part starts here: the wire fed before belongs to earlier work (cut off)."""
        state = self.double.machine_state()
        self._mark = PartMark(len(state.bends), float(state.feed_mm))

    def part_shape_mm(self) -> np.ndarray:
        """The wire bent since :meth:`mark_part` as a polyline (mm), as the cutter leaves it."""
        state = self.double.machine_state()
        bends = state.bends[self._mark.bends :]
        before = state.bends[: self._mark.bends]
        tail_before = self._mark.feed_mm - sum(b.feed_before_mm for b in before)
        fed = float(state.feed_mm) - self._mark.feed_mm
        legs = [b.feed_before_mm for b in bends]
        if legs:
            legs[0] -= tail_before
        legs.append(fed - sum(legs))
        pts = [np.zeros(2)]
        heading = 0.0
        for i, leg in enumerate(legs):
            pts.append(pts[-1] + leg * np.array([math.cos(heading), math.sin(heading)]))
            if i < len(bends):
                heading -= math.radians(bends[i].unloaded_bend_deg)
        return np.asarray(pts)

    def live_frame(self, width_px: int) -> np.ndarray | None:
        """The bender as the camera sees it now, with the markers found drawn on it."""
        import cv2

        import cvmeasure_datasets
        from cvmeasure_datasets.simcapture import double_photo_state

        s = double_photo_state(self.double)
        key = (round(s.pin_angle_deg, 1), round(s.bend_angle_deg, 1), width_px)
        with self._lock:
            if key == self._live_key and self._live_bgr is not None:
                return self._live_bgr
            photo = cvmeasure_datasets.render_bender_photo(
                pin_angle_deg=s.pin_angle_deg,
                bend_angle_deg=s.bend_angle_deg,
                image_size_px=(width_px, int(round(width_px * 2 / 3))),
                seed=self.seed,
            )
            bgr = np.ascontiguousarray(photo.bgr)
            try:
                found = adapter.find_marker_centres(bgr, adapter.default_kit())
            except Exception:  # a live view never stops on a frame it cannot read
                found = {}
            for role, (x, y, r) in found.items():
                cv2.circle(bgr, (int(x), int(y)), int(r) + 4, (0, 255, 0), 2, cv2.LINE_AA)
                cv2.putText(
                    bgr, role, (int(x + r + 6), int(y)), cv2.FONT_HERSHEY_SIMPLEX, 0.5,
                    (0, 255, 0), 1, cv2.LINE_AA,
                )  # fmt: skip
            self._live_key, self._live_bgr = key, bgr
            return bgr

    def reconnect(self) -> None:
        """Plug the double back in (after a loss) and open a fresh link to it."""
        try:
            self.link.close()
        except Exception:
            pass
        if self.double.vanished:
            self.double.reconnect()
        self.link = adapter.open_link("sim://", double=self.double)

    def lose_link(self, after_lines: int = 3) -> None:
        """Pull the double's cable ``after_lines`` lines from now (the simulated serial loss)."""
        from cvmeasure.testing.double import Fault

        with self.double._lock:
            line = self.double.stats.lines_received + after_lines
            self.double._faults.append(Fault("vanish", at_line=line))

    def truth(self) -> list[dict[str, Any]]:
        """Every bend the double executed (line number, pin, loaded and final angles): the
        simulation's truth that tests and benchmarks score the app against."""
        return [b.to_dict() for b in self.double.machine_state().bends]

    def close(self) -> None:
        try:
            self.link.close()
        finally:
            self.double.close()
