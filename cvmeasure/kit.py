"""The marker kit: five colour-coded discs on white rings (spec ``The marker kit``).

This module is the one place where the kit's colours and sizes live. A
measurement always reads the kit it is given (``--kit kit.json``); the default
kit below is what ``cvmeasure targets markers --format json`` prints.
``srgb`` is the printed colour under D65 (8-bit, gamma-encoded); ``lab_d65`` is
CIE L*a*b* (D65 white, 2 degree observer), computed from ``srgb`` with
colour-science.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from cvmeasure.colorimetry import srgb8_to_lab_d65
from cvmeasure.errors import InputError
from cvmeasure.fileio import read_json

__all__ = [
    "ROLES",
    "HeightsPose",
    "MarkerSpec",
    "MarkerKit",
    "default_kit",
    "load_kit",
    "srgb8_to_lab_d65",
]

#: The five roles of the spec, in the kit's order.
ROLES: tuple[str, ...] = ("origin", "axis", "pin", "wire_a", "wire_b")


@dataclass(frozen=True)
class MarkerSpec:
    """One marker of the kit: role, colour name, printed colour, sizes in mm.

    ``lab_sigma`` / ``rgb_sigma`` (optional) are the colour's standard deviations
    per channel in CIE L*a*b* and in 8-bit sRGB under D65, as learnt from a
    reference photo (``cvmeasure markers learn``); without them a measurement
    uses the defaults of :mod:`cvmeasure.markers.colour`.

    ``height_mm`` is the height of the disc's printed face above the bender's top
    plate (the measurement plane, where the board lies for ``cvmeasure plane``), mm,
    measured along the plate's normal towards the camera. ``None`` means the kit
    JSON did not say: the markers are flat stickers on the plate (the spec's rule).
    ``height_sigma_mm`` is the height's standard uncertainty, mm (a nominal height's
    tolerance, or what ``cvmeasure markers heights`` measured); a measurement on a
    plane pose carries it into the angles' stated uncertainty; 0 for a height known
    exactly. ``None``: no stated uncertainty, the height is nominal (on a plane pose the
    result bounds what caps off it can do, beside the sigma, and warns).

    ``step_mm`` is how far the disc's printed face stands above its white ring, mm (a
    coloured top printed or glued on the cap): the step's wall is then seen beside the
    disc on the side facing the camera, and the disc's edges are found where every shade
    of its colour reads as the disc (:data:`cvmeasure.markers.refine.SHADE_EDGES`).
    ``None`` or 0: the face is flush with its ring.
    """

    role: str
    name: str
    srgb: tuple[int, int, int]
    diameter_mm: float
    ring_mm: float
    lab_sigma: tuple[float, float, float] | None = None
    rgb_sigma: tuple[float, float, float] | None = None
    height_mm: float | None = None
    height_sigma_mm: float | None = None
    step_mm: float | None = None

    @property
    def lab_d65(self) -> np.ndarray:
        return srgb8_to_lab_d65(self.srgb)

    def colour_sigma(self, space: str) -> tuple[float, float, float] | None:
        """The learnt per-channel spread in ``space`` ("lab" or "rgb"), if any."""
        return {"lab": self.lab_sigma, "rgb": self.rgb_sigma}[space]

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "role": self.role,
            "name": self.name,
            "srgb": list(self.srgb),
            "lab_d65": [round(float(v), 1) for v in self.lab_d65],
            "diameter_mm": self.diameter_mm,
            "ring_mm": self.ring_mm,
        }
        if self.lab_sigma is not None:
            out["lab_sigma"] = [round(float(v), 2) for v in self.lab_sigma]
        if self.rgb_sigma is not None:
            out["rgb_sigma"] = [round(float(v), 2) for v in self.rgb_sigma]
        if self.height_mm is not None:
            out["height_mm"] = self.height_mm
        if self.height_sigma_mm is not None:
            out["height_sigma_mm"] = self.height_sigma_mm
        if self.step_mm is not None:
            out["step_mm"] = self.step_mm
        return out


#: A plane is the heights' own when its pose is within these of the recorded one: the same
#: plane measurement (a plane measured again from the same camera differs by far more).
SAME_POSE_RAD = 1e-6
SAME_POSE_MM = 1e-3


@dataclass(frozen=True)
class HeightsPose:
    """The plane pose a kit's heights were measured through (``cvmeasure markers heights``).

    ``rvec`` / ``tvec_mm``: the plane's pose (camera <- board, OpenCV convention, mm), as
    in the plane JSON. Heights fitted through a plane take up the errors that plane puts
    on every photo (its pose's, the lens's): through the same plane those errors and the
    heights' share of them largely cancel, and the heights' stated covariance holds;
    through another plane they do not cancel, and the angles can be off by more than
    their stated uncertainty (a measurement warns, ``heights_other_plane``).
    """

    rvec: tuple[float, float, float]
    tvec_mm: tuple[float, float, float]

    @classmethod
    def of(cls, rvec: Any, tvec_mm: Any) -> HeightsPose:
        """The pose of a plane's ``rvec`` and ``tvec_mm`` (any 3-element array-likes)."""
        r, t = (tuple(float(v) for v in np.reshape(x, 3)) for x in (rvec, tvec_mm))
        return cls(r, t)  # type: ignore[arg-type]

    def matches(self, rvec: Any, tvec_mm: Any) -> bool:
        """True when the pose (rvec, tvec_mm) is this one: the same plane measurement."""
        r = np.asarray(rvec, dtype=np.float64).reshape(3)
        t = np.asarray(tvec_mm, dtype=np.float64).reshape(3)
        return bool(
            np.max(np.abs(r - np.asarray(self.rvec))) <= SAME_POSE_RAD
            and np.max(np.abs(t - np.asarray(self.tvec_mm))) <= SAME_POSE_MM
        )

    def to_dict(self) -> dict[str, Any]:
        return {
            "rvec": [round(float(v), 12) for v in self.rvec],
            "tvec_mm": [round(float(v), 9) for v in self.tvec_mm],
        }

    @classmethod
    def from_dict(cls, data: Any) -> HeightsPose:
        """ValueError naming the field when malformed."""
        if not isinstance(data, dict):
            raise ValueError("heights_pose must be an object with rvec and tvec_mm")
        vectors = []
        for key in ("rvec", "tvec_mm"):
            try:
                vec = np.asarray(data.get(key), dtype=np.float64)
            except (TypeError, ValueError):
                vec = np.zeros(0)
            if vec.shape != (3,) or not np.all(np.isfinite(vec)):
                raise ValueError(f"heights_pose.{key} must be three finite numbers")
            vectors.append(vec)
        return cls.of(*vectors)


@dataclass(frozen=True)
class MarkerKit:
    """A named set of markers, one per role, and the wire they measure.

    ``wire_diameter_mm`` is the wire's diameter; ``wire_axis_height_mm`` the height
    of the wire's axis above the top plate (where the guides hold it), mm. ``None``
    means the kit JSON did not say (a flat kit, see :class:`MarkerSpec`).
    ``height_covariance_mm2`` is the 5 x 5 covariance of the markers' heights in
    :data:`ROLES` order, mm^2, when they were measured together (``cvmeasure markers
    heights``: their errors are correlated); None: the per-marker
    ``height_sigma_mm``, independent. ``heights_pose`` (optional): the plane pose the
    heights were measured through (:class:`HeightsPose`).
    """

    name: str
    markers: tuple[MarkerSpec, ...]
    wire_diameter_mm: float | None = None
    wire_axis_height_mm: float | None = None
    height_covariance_mm2: tuple[tuple[float, ...], ...] | None = None
    heights_pose: HeightsPose | None = None

    def __post_init__(self) -> None:
        roles = [m.role for m in self.markers]
        if sorted(roles) != sorted(ROLES):
            raise ValueError(f"a kit needs exactly one marker per role {ROLES}, got {roles}")

    @property
    def has_heights(self) -> bool:
        """True when every marker's height above the plate is known."""
        return all(m.height_mm is not None for m in self.markers)

    @property
    def heights_stated(self) -> bool:
        """True when the kit states how well its heights are known (a ``height_sigma_mm``
        on a marker, 0 for a height known exactly, or ``height_covariance_mm2``); False:
        the heights are nominal, caps perhaps off them by their build tolerance."""
        return self.height_covariance_mm2 is not None or any(
            m.height_sigma_mm is not None for m in self.markers if m.height_mm is not None
        )

    @property
    def has_steps(self) -> bool:
        """True when a marker's printed face stands above its ring (``step_mm`` > 0)."""
        return any((m.step_mm or 0.0) > 0.0 for m in self.markers)

    def height_mm(self, role: str) -> float:
        """The height of ``role``'s disc above the top plate, mm (0 for a flat kit)."""
        height = self.by_role(role).height_mm
        return 0.0 if height is None else float(height)

    def height_cov_mm2(self) -> np.ndarray:
        """The heights' covariance (5, 5) in :data:`ROLES` order, mm^2 (zeros: exact or flat)."""
        if self.height_covariance_mm2 is not None:
            return np.asarray(self.height_covariance_mm2, dtype=np.float64)
        sig = [self.by_role(r).height_sigma_mm or 0.0 for r in ROLES]
        return np.diag(np.square(sig))

    def heights_text(self) -> str:
        """The heights for a message: ``"origin 12, axis 12, pin 18, ... mm"`` or ``"flat"``."""
        if not self.has_heights:
            return "none (flat stickers)"
        return ", ".join(f"{r} {self.height_mm(r):g}" for r in ROLES) + " mm"

    def flat(self) -> MarkerKit:
        """The same kit without heights: flat stickers, every disc on the plate."""
        return replace(
            self,
            name=self.name if self.name.endswith("-flat") else f"{self.name}-flat",
            markers=tuple(replace(m, height_mm=None, height_sigma_mm=None) for m in self.markers),
            wire_axis_height_mm=None,
            height_covariance_mm2=None,
            heights_pose=None,
        )

    def by_role(self, role: str) -> MarkerSpec:
        for marker in self.markers:
            if marker.role == role:
                return marker
        raise KeyError(role)

    def to_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {"name": self.name, "markers": [m.to_dict() for m in self.markers]}
        if self.wire_diameter_mm is not None:
            out["wire_diameter_mm"] = self.wire_diameter_mm
        if self.wire_axis_height_mm is not None:
            out["wire_axis_height_mm"] = self.wire_axis_height_mm
        if self.height_covariance_mm2 is not None:
            out["height_covariance_mm2"] = [
                [round(float(v), 6) for v in row] for row in self.height_covariance_mm2
            ]
        if self.heights_pose is not None:
            out["heights_pose"] = self.heights_pose.to_dict()
        return out

    @classmethod
    def from_dict(cls, data: Any, *, source: str = "kit JSON") -> MarkerKit:
        """Validate and build a kit from the spec's kit JSON."""
        if not isinstance(data, dict) or not isinstance(data.get("markers"), list):
            raise InputError(source, "kit JSON must be an object with a 'markers' list")
        markers = []
        for i, m in enumerate(data["markers"]):
            try:
                srgb = tuple(int(v) for v in m["srgb"])
                if len(srgb) != 3 or not all(0 <= v <= 255 for v in srgb):
                    raise ValueError("srgb must be three values in 0..255")
                spec = MarkerSpec(
                    role=str(m["role"]),
                    name=str(m.get("name", m["role"])),
                    srgb=srgb,  # type: ignore[arg-type]
                    diameter_mm=float(m["diameter_mm"]),
                    ring_mm=float(m["ring_mm"]),
                    lab_sigma=_sigma(m.get("lab_sigma")),
                    rgb_sigma=_sigma(m.get("rgb_sigma")),
                    height_mm=_length(m.get("height_mm"), "height_mm", minimum=0.0),
                    height_sigma_mm=_length(
                        m.get("height_sigma_mm"), "height_sigma_mm", minimum=0.0
                    ),
                    step_mm=_length(m.get("step_mm"), "step_mm", minimum=0.0),
                )
            except (KeyError, TypeError, ValueError) as exc:
                raise InputError(source, f"marker #{i} is malformed: {exc}") from None
            if not 0 < spec.diameter_mm < spec.ring_mm:
                raise InputError(source, f"marker {spec.role!r}: need 0 < diameter_mm < ring_mm")
            markers.append(spec)
        with_heights = [m.role for m in markers if m.height_mm is not None]
        if with_heights and len(with_heights) < len(markers):
            without = [m.role for m in markers if m.height_mm is None]
            raise InputError(
                source,
                f"height_mm is given for {', '.join(with_heights)} but not for "
                f"{', '.join(without)}: give every marker's height or none (a flat kit)",
            )
        try:
            wire_d = _length(data.get("wire_diameter_mm"), "wire_diameter_mm", minimum=1e-6)
            wire_h = _length(data.get("wire_axis_height_mm"), "wire_axis_height_mm", minimum=0.0)
            cov = _covariance(data.get("height_covariance_mm2"))
            raw_pose = data.get("heights_pose")
            pose = None if raw_pose is None else HeightsPose.from_dict(raw_pose)
            return cls(str(data.get("name", "kit")), tuple(markers), wire_d, wire_h, cov, pose)
        except ValueError as exc:
            raise InputError(source, str(exc)) from None


def _length(value: Any, name: str, *, minimum: float) -> float | None:
    """An optional length in mm: None stays None; otherwise a finite number >= minimum."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name} must be a number of millimetres, got {value!r}")
    length = float(value)
    if not np.isfinite(length) or length < minimum:
        raise ValueError(f"{name} must be a finite length >= {minimum:g} mm, got {value!r}")
    return length


def _covariance(value: Any) -> tuple[tuple[float, ...], ...] | None:
    """An optional 5 x 5 symmetric, positive semi-definite covariance (mm^2)."""
    if value is None:
        return None
    try:
        cov = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ValueError("height_covariance_mm2 must be a 5 x 5 matrix of numbers") from None
    n = len(ROLES)
    if (
        cov.shape != (n, n)
        or not np.all(np.isfinite(cov))
        or not np.allclose(cov, cov.T, atol=1e-9)
        or np.linalg.eigvalsh(cov).min() < -1e-9
    ):
        raise ValueError(
            f"height_covariance_mm2 must be a symmetric positive semi-definite {n} x {n} "
            f"matrix in the role order {', '.join(ROLES)}"
        )
    return tuple(tuple(float(v) for v in row) for row in cov)


def _sigma(value: Any) -> tuple[float, float, float] | None:
    if value is None:
        return None
    sigma = tuple(float(v) for v in value)
    if len(sigma) != 3 or not all(v > 0 for v in sigma):
        raise ValueError("a colour sigma must be three positive values")
    return sigma  # type: ignore[return-value]


def default_kit() -> MarkerKit:
    """The project's kit ``seed-5``: the seed paper's five colours, made printable.

    Colours are spaced far apart in CIELAB (pairwise Delta E 2000 > 30) and are
    moderate-chroma, printable colours; sizes suit a 4608x3072 photo of the
    DIWire top plate from about 0.85 m (a 10 mm disc is ~80 px across).

    The pin's colour is a deeper, orange-yellow than the seed's pure yellow: on
    its white ring pure yellow differs almost only in chroma, which JPEG
    subsamples and quantises hardest, so its centre came out twice as noisy as
    the other markers' (rendered photos, benchmarks/markers.py); the
    orange-yellow doubles the luminance step and halves that noise.

    Heights above the top plate (mm, the printed face) are those of the printable
    kit on a DIWire-class head: the 3 mm wire's axis 5 mm above the plate (the
    guides' height), the wire clips' faces 2 mm above the wire's top (8.5 mm), the
    die cap and the upstream guide's cap at 12 mm, the pin cap at 18 mm. Measure
    your own with calipers and put them in your kit JSON.
    """
    return MarkerKit(
        "seed-5",
        (
            MarkerSpec("origin", "dark green", (0, 110, 70), 10.0, 14.0, height_mm=12.0),
            MarkerSpec("axis", "yellow-green", (140, 190, 40), 10.0, 14.0, height_mm=12.0),
            MarkerSpec("pin", "orange-yellow", (240, 140, 0), 8.0, 12.0, height_mm=18.0),
            MarkerSpec("wire_a", "blue", (20, 70, 180), 8.0, 12.0, height_mm=8.5),
            MarkerSpec("wire_b", "magenta", (200, 30, 130), 8.0, 12.0, height_mm=8.5),
        ),
        wire_diameter_mm=3.0,
        wire_axis_height_mm=5.0,
    )


def load_kit(path: str | os.PathLike[str]) -> MarkerKit:
    """Read a kit JSON file (spec)."""
    return MarkerKit.from_dict(read_json(path, what="kit JSON"), source=str(path))
