"""Scene effects of a real bender photo, each switchable: :class:`SceneEffects`.

``SceneEffects()`` (all off) is today's flat scene and keeps its renders
bit-identical. Each field switches one effect on or sets its magnitude; the
truth JSON of a photo records the effects it was rendered with.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields
from typing import Any

__all__ = ["EFFECT_NAMES", "SceneEffects"]


@dataclass(frozen=True)
class SceneEffects:
    """Which real-scene effects a render has, and how strong they are.

    Attributes
    ----------
    marker_heights : discs at their kit heights (``kit.height_mm(role)`` above the
        plate; every pixel's ray traced to the disc's own plane).
    supports : each disc on a printed cylinder (radius of the ring) standing on
        the plate (or on the wire for the wire clips); its side shows off-axis.
    wire_3d : the wire (and a finished part) as a cylinder at its axis height with
        diffuse + specular shading from the lamp and a soft cast shadow.
    part_lift_mm : a finished part rocks: one end lifted this much (0-3 mm), a rigid
        tilt about a line on the sheet.
    depth_of_field : thin-lens defocus from each pixel's depth (``f_number``,
        ``focal_length_mm``; focus on the plane ``focus_height_mm`` above the plate
        where the optical axis meets it).
    motion_blur_px : length of a straight motion smear, px (0: none), at
        ``motion_blur_deg`` from the image x axis.
    bayer : RGGB mosaic and OpenCV demosaic before the JPEG (:attr:`Lighting.bayer`).
    textured_background : a wood-grain table and a plate with stains and scratches.
    clutter : number of stray coloured objects (other sizes; some near the kit's
        colours) on the plate and the table, away from the markers.
    wire_across : roles whose ring edge a loose 3 mm wire crosses (above the disc).
    tool_shadow : roles with a tool's soft shadow across the marker.
    """

    marker_heights: bool = False
    supports: bool = False
    wire_3d: bool = False
    part_lift_mm: float = 0.0
    depth_of_field: bool = False
    f_number: float = 4.0
    focal_length_mm: float = 35.0
    focus_height_mm: float = 6.0
    motion_blur_px: float = 0.0
    motion_blur_deg: float = 30.0
    bayer: bool = False
    textured_background: bool = False
    clutter: int = 0
    wire_across: tuple[str, ...] = ()
    tool_shadow: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if not 0.0 <= self.part_lift_mm <= 10.0:
            raise ValueError(f"part_lift_mm must be in [0, 10], got {self.part_lift_mm}")
        if self.f_number <= 0 or self.focal_length_mm <= 0:
            raise ValueError("f_number and focal_length_mm must be positive")
        if self.motion_blur_px < 0 or self.clutter < 0:
            raise ValueError("motion_blur_px and clutter must be >= 0")
        object.__setattr__(self, "wire_across", tuple(self.wire_across))
        object.__setattr__(self, "tool_shadow", tuple(self.tool_shadow))

    @classmethod
    def all_on(cls, **overrides: Any) -> SceneEffects:
        """Every effect of a real photo on, at typical magnitudes (no occlusion)."""
        base = dict(
            marker_heights=True,
            supports=True,
            wire_3d=True,
            part_lift_mm=2.0,
            depth_of_field=True,
            motion_blur_px=1.5,
            bayer=True,
            textured_background=True,
            clutter=8,
        )
        base.update(overrides)
        return cls(**base)

    @classmethod
    def only(cls, name: str, **overrides: Any) -> SceneEffects:
        """One effect of :meth:`all_on` alone (``name`` from :data:`EFFECT_NAMES`)."""
        if name not in EFFECT_NAMES:
            raise ValueError(f"unknown effect {name!r}; known: {', '.join(EFFECT_NAMES)}")
        on = cls.all_on()
        kw: dict[str, Any] = {name: getattr(on, name)}
        kw.update(overrides)
        return cls(**kw)

    @classmethod
    def parse(cls, text: str) -> SceneEffects:
        """Effects from text: ``"all"`` or names, comma-separated, optionally ``NAME=VALUE``.

        ``"marker_heights,wire_3d"``; ``"all,clutter=12"``; ``"part_lift_mm=2"``;
        ``"wire_across=wire_b+pin"`` (roles joined by ``+``). A bare name switches the
        effect on at its :meth:`all_on` magnitude. Raises ValueError naming the problem.
        """
        items = [t.strip() for t in text.split(",") if t.strip()]
        kw: dict[str, Any] = {}
        if items and items[0] == "all":
            kw = SceneEffects.all_on().to_dict()
            items = items[1:]
        names = {f.name for f in fields(cls)}
        on = cls.all_on()
        for item in items:
            name, eq, value = item.partition("=")
            if name not in names:
                raise ValueError(f"unknown effect {name!r}; known: all, {', '.join(sorted(names))}")
            current = getattr(cls(), name)
            if isinstance(current, tuple):
                if not value:
                    raise ValueError(f"{name} needs roles, e.g. {name}=wire_b+pin")
                kw[name] = tuple(v for v in value.split("+") if v)
            elif isinstance(current, bool):
                if not eq or value.lower() in ("1", "true", "on", "yes"):
                    kw[name] = True
                elif value.lower() in ("0", "false", "off", "no"):
                    kw[name] = False
                else:
                    raise ValueError(f"{name} is on or off, got {value!r}")
            elif not eq:
                kw[name] = getattr(on, name)
            else:
                try:
                    kw[name] = type(current)(value)
                except ValueError:
                    raise ValueError(f"{name} needs a number, got {value!r}") from None
        return cls.from_dict(kw)

    @property
    def flat(self) -> bool:
        """True when nothing is on (today's flat scene)."""
        return self == SceneEffects()

    def names_on(self) -> list[str]:
        """The effects switched on (:data:`EFFECT_NAMES` order)."""
        off = SceneEffects()
        return [n for n in EFFECT_NAMES if getattr(self, n) != getattr(off, n)]

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["wire_across"] = list(self.wire_across)
        out["tool_shadow"] = list(self.tool_shadow)
        return out

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SceneEffects:
        known = {f.name for f in fields(cls)}
        return cls(
            **{k: (tuple(v) if isinstance(v, list) else v) for k, v in data.items() if k in known}
        )


#: The switchable effects (the benchmark's rows), in rendering order.
EFFECT_NAMES: tuple[str, ...] = (
    "marker_heights",
    "supports",
    "wire_3d",
    "part_lift_mm",
    "depth_of_field",
    "motion_blur_px",
    "bayer",
    "textured_background",
    "clutter",
    "wire_across",
    "tool_shadow",
)
