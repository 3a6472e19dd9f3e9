"""The bench the app drives: a bender link and a camera.

:class:`RealRig` is a serial port (or any link URL) and a gphoto2 camera or a watched
folder; the operator places the board or the part and the camera takes the photo. The
simulated bench (``--simulate``) is ``cvmeasure_datasets.simrig.SimRig``: it renders photos,
so it lives in the photo lab, and the CLI hands it to the app.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from cvmeasure.app import adapter
from cvmeasure.driver.capture import open_capture
from cvmeasure.errors import InputError

__all__ = ["Rig", "PartMark", "RealRig", "open_rig"]


@dataclass
class PartMark:
    """Where a part starts on the double's wire: bends so far and wire fed so far (mm)."""

    bends: int
    feed_mm: float


class Rig:
    """What the app needs from the bench (see the module notes)."""

    simulated = False
    link: Any = None
    double: Any = None
    hint = ""
    image_size_px: tuple[int, int] = (0, 0)

    def bender_camera(self, folder: Path) -> Any:  # Camera of the material session
        raise NotImplementedError

    def capture(self, kind: str, name: str, folder: Path, index: int = 0) -> Path:
        """A photo of ``kind`` (board_view, plane, kit, part) written in ``folder``."""
        raise NotImplementedError

    def live_frame(self, width_px: int) -> np.ndarray | None:
        raise NotImplementedError

    def reconnect(self) -> None:
        """Open the link again after a loss."""
        raise NotImplementedError

    def lose_link(self, after_lines: int = 3) -> None:
        raise InputError("serial loss", "only a simulated bender can be made to lose its link")

    def mark_part(self) -> None:
        pass

    def truth(self) -> list[dict[str, Any]]:
        """The bends really made (a simulated bench only)."""
        raise InputError("truth", "only a simulated bench knows the bends it made")

    def close(self) -> None:
        if self.link is not None:
            self.link.close()


class RealRig(Rig):
    """A bender on a port (or link URL) and a gphoto2 camera or a watched folder."""

    def __init__(self, port: str, camera_url: str, folder: Path) -> None:
        self.port = port
        self.link = adapter.open_link(port)
        try:
            self.camera = open_capture(camera_url, folder / "photos")
        except ValueError as exc:
            self.link.close()
            raise InputError("camera", str(exc)) from None
        self._last: Path | None = None

    def bender_camera(self, folder: Path) -> Any:
        return self.camera

    def capture(self, kind: str, name: str, folder: Path, index: int = 0) -> Path:
        shot = self.camera.capture(name)
        self._last = Path(shot.path)
        return self._last

    def live_frame(self, width_px: int) -> np.ndarray | None:
        """The last photo taken (a DSLR has no continuous view through this path)."""
        if self._last is None:
            return None

        img = cv2.imread(str(self._last))
        if img is None:
            return None
        h, w = img.shape[:2]
        return cv2.resize(img, (width_px, int(h * width_px / w)))

    def reconnect(self) -> None:
        try:
            self.link.close()
        except Exception:
            pass
        self.link = adapter.open_link(self.port)

    def close(self) -> None:
        try:
            self.link.close()
        finally:
            self.camera.close()


def open_rig(
    port: str, camera: str, folder: Path, *, simulated: Callable[[], Rig] | None = None
) -> Rig:
    """The bench for a connect request: ``simulated()`` for ``sim://`` (``--simulate``), or a
    real port and camera."""
    if simulated is not None and (port.startswith("sim://") or not port):
        return simulated()
    if port.startswith("sim://"):
        raise InputError(port, "a simulated bench needs `cvmeasure ui --simulate`")
    if not port or not camera:
        raise InputError(
            "connection", "give the bender's port and the camera (gphoto2:// or folder:///...)"
        )
    return RealRig(port, camera, folder)
