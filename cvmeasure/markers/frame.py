"""The frame a photo's angles are computed in: image px, undistorted px or the plate (mm).

``measure_frame`` picks it from what the measurement has: a plane pose maps image
pixels to millimetres on the plate (and, :meth:`MeasureFrame.at_height`, on a plane
any height above it); a camera alone removes lens distortion; neither leaves the
photo's own pixels.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cvmeasure.camera_model import CameraModel
from cvmeasure.contracts import PlaneModel

__all__ = ["MeasureFrame", "measure_frame"]


@dataclass(frozen=True)
class MeasureFrame:
    """Image pixels -> the measurement frame of the angles (``plane``: the pose's plane)."""

    name: str
    func: Any = None
    y_down: bool = True
    plane: PlaneModel | None = None

    def at_height(self, height_mm: float) -> MeasureFrame:
        """The same frame for points ``height_mm`` above the plate (only a plane pose can)."""
        if self.plane is None or height_mm == 0.0:
            return self
        return replace(
            self, func=functools.partial(self.plane.image_to_plane_mm, height_mm=height_mm)
        )

    def __call__(self, pts: np.ndarray) -> np.ndarray:
        return pts if self.func is None else np.asarray(self.func(pts), dtype=np.float64)

    def jacobian(self, xy: tuple[float, float], h: float = 0.5) -> np.ndarray:
        return self.mapped_with_jacobian(xy, np.zeros((0, 2)), h)[0]

    def mapped_with_jacobian(
        self, xy: tuple[float, float], pts: np.ndarray, h: float = 0.5
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(Jacobian at ``xy`` by central differences of ``h`` px, ``xy`` mapped, ``pts`` mapped).

        One call of the mapping for all three (it maps each point on its own).
        """
        return self.mapped_with_jacobians([xy], [pts], h)[0]

    def mapped_with_jacobians(
        self, xys: list[tuple[float, float]], pts: list[np.ndarray], h: float = 0.5
    ) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """:meth:`mapped_with_jacobian` of several centres and their points, in one call
        of the mapping (it maps each point on its own: the same values)."""
        arrays = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in pts]
        if self.func is None:
            return [
                (np.eye(2), np.array(xy, dtype=np.float64), a)
                for xy, a in zip(xys, arrays, strict=True)
            ]
        parts = []
        for (x, y), a in zip(xys, arrays, strict=True):
            parts += [[[x + h, y], [x - h, y], [x, y + h], [x, y - h], [x, y]], a]
        q = self(np.vstack(parts))
        out, k = [], 0
        for a in arrays:
            qi = q[k : k + 5 + len(a)]
            k += 5 + len(a)
            jac = np.column_stack(((qi[0] - qi[1]) / (2 * h), (qi[2] - qi[3]) / (2 * h)))
            out.append((jac, qi[4], qi[5:]))
        return out


def measure_frame(
    camera: CameraModel | None, plane: PlaneModel | None, shape: tuple[int, ...], source: str
) -> MeasureFrame:
    h, w = shape[:2]
    if plane is not None:
        own = plane.for_image((w, h), source)
        t = MeasureFrame("plane", own.image_to_plane_mm)
        det = float(np.linalg.det(t.jacobian(((w - 1) / 2, (h - 1) / 2))))
        return MeasureFrame("plane", own.image_to_plane_mm, y_down=det > 0, plane=own)
    if camera is not None:
        return MeasureFrame("undistorted", camera.for_image((w, h), source).undistort_px)
    return MeasureFrame("image")
