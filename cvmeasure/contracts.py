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

import math
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.camera import CameraModel
from cvmeasure.errors import InputError
from cvmeasure.kit import ROLES
from cvmeasure.warning import StageWarning

__all__ = [
    "BLOCKS",
    "TRIALS_COLUMNS",
    "TRIALS_OPTIONAL_COLUMNS",
    "Trial",
    "TrialTable",
    "MarkerMeasurement",
    "MachinePhotoResult",
    "PLANE_FORMAT",
    "PlaneModel",
    "apply_homography",
]

# ----------------------------------------------------------------------------- trials

#: Required columns of a trials CSV (spec), in this order.
TRIALS_COLUMNS: tuple[str, ...] = (
    "trial",
    "commanded_pin_deg",
    "loaded_bend_deg",
    "unloaded_bend_deg",
)
#: Optional columns this project reads and writes, in the order written after the
#: required ones (a column is written when any trial has a value for it).
#: ``springback_deg`` and ``direction`` are derived: written for readers, ignored on read.
TRIALS_OPTIONAL_COLUMNS: tuple[str, ...] = (
    "measured_pin_deg",
    "springback_deg",
    "direction",
    "target_deg",
    "bend_index",
    "part",
    "loaded_uncertainty_deg",
    "unloaded_uncertainty_deg",
    "springback_sigma_deg",
    "photo_loaded",
    "photo_unloaded",
)
_DERIVED_COLUMNS = ("springback_deg", "direction")

#: The measured quantities of a trial, in the order :meth:`TrialTable.observations` stacks them.
BLOCKS: tuple[str, ...] = ("loaded_bend_deg", "unloaded_bend_deg", "measured_pin_deg")


@dataclass(frozen=True)
class Trial:
    """One bend as executed and measured (degrees, machine frame, signs of the spec).

    ``loaded_bend_deg`` / ``unloaded_bend_deg`` / ``measured_pin_deg`` are NaN when
    not measured (a trial has at least one bend angle). ``uncertainty_deg`` holds
    one standard uncertainty (deg) under the keys ``loaded_bend_deg``,
    ``unloaded_bend_deg`` and ``springback_deg`` where known. ``bend_index`` is the
    number of bends executed before this one (None: its row position); ``part`` the
    group of grouped cross-validation (None: the trial is its own group).
    ``extra`` keeps any other CSV column, so a table read and written loses nothing.
    """

    trial: str
    commanded_pin_deg: float
    loaded_bend_deg: float
    unloaded_bend_deg: float
    measured_pin_deg: float = math.nan
    target_deg: float | None = None
    bend_index: int | None = None
    part: str | None = None
    uncertainty_deg: Mapping[str, float] = field(default_factory=dict)
    photo_loaded: str | None = None
    photo_unloaded: str | None = None
    source: str = "csv"
    extra: Mapping[str, str] = field(default_factory=dict)
    warnings: tuple[StageWarning, ...] = ()

    def __post_init__(self) -> None:
        for name in (
            "commanded_pin_deg",
            "loaded_bend_deg",
            "unloaded_bend_deg",
            "measured_pin_deg",
        ):
            value = float(getattr(self, name))
            # one NaN object, so that trials read back compare equal
            object.__setattr__(self, name, math.nan if math.isnan(value) else value)
        object.__setattr__(self, "trial", str(self.trial))

    @property
    def has_pair(self) -> bool:
        """Both the loaded and the unloaded angle are measured."""
        return math.isfinite(self.loaded_bend_deg) and math.isfinite(self.unloaded_bend_deg)

    @property
    def springback_deg(self) -> float:
        """``sign(loaded) * (loaded - unloaded)`` (spec): positive when the wire opens; NaN without a pair.

        >>> Trial("1", 21.0, 20.0, 18.5).springback_deg
        1.5
        >>> Trial("2", -21.0, -20.0, -18.5).springback_deg
        1.5
        """
        if not self.has_pair:
            return math.nan
        return math.copysign(1.0, self.loaded_bend_deg) * (
            self.loaded_bend_deg - self.unloaded_bend_deg
        )

    @property
    def springback_sigma_deg(self) -> float:
        """One standard uncertainty of the springback (deg); NaN when unknown."""
        if "springback_deg" in self.uncertainty_deg:
            return float(self.uncertainty_deg["springback_deg"])
        lo = self.uncertainty_deg.get("loaded_bend_deg")
        un = self.uncertainty_deg.get("unloaded_bend_deg")
        return math.hypot(lo, un) if lo is not None and un is not None else math.nan

    @property
    def direction(self) -> str:
        """``"ccw"`` (positive bend angles) or ``"cw"``: the sign of the loaded angle
        (else the unloaded one, else the command)."""
        for value in (self.loaded_bend_deg, self.unloaded_bend_deg, self.commanded_pin_deg):
            if math.isfinite(value) and value != 0:
                return "cw" if value < 0 else "ccw"
        return "ccw"

    @classmethod
    def from_photos(
        cls,
        loaded: MachinePhotoResult,
        unloaded: MachinePhotoResult,
        *,
        trial: str,
        commanded_pin_deg: float = math.nan,
        target_deg: float | None = None,
        bend_index: int | None = None,
        source: str = "cv",
    ) -> Trial:
        """The trial measured on its loaded and unloaded photos (pin angle from the loaded one)."""
        u_lo = loaded.uncertainty_deg.get("bend_angle_deg")
        u_un = unloaded.uncertainty_deg.get("bend_angle_deg")
        unc = {}
        if u_lo is not None and u_un is not None:
            unc = {
                "loaded_bend_deg": float(u_lo),
                "unloaded_bend_deg": float(u_un),
                "springback_deg": math.hypot(u_lo, u_un),
            }
        return cls(
            trial=trial,
            commanded_pin_deg=commanded_pin_deg,
            loaded_bend_deg=loaded.bend_angle_deg,
            unloaded_bend_deg=unloaded.bend_angle_deg,
            measured_pin_deg=loaded.pin_angle_deg,
            target_deg=target_deg,
            bend_index=bend_index,
            uncertainty_deg=unc,
            photo_loaded=loaded.photo,
            photo_unloaded=unloaded.photo,
            source=source,
            warnings=tuple(loaded.warnings) + tuple(unloaded.warnings),
        )

    def csv_row(self) -> dict[str, Any]:
        """This trial as a trials CSV row (NaN and None as empty cells)."""
        unc = self.uncertainty_deg
        row: dict[str, Any] = {
            "trial": self.trial,
            "commanded_pin_deg": self.commanded_pin_deg,
            "loaded_bend_deg": _finite_or_none(self.loaded_bend_deg),
            "unloaded_bend_deg": _finite_or_none(self.unloaded_bend_deg),
            "measured_pin_deg": _finite_or_none(self.measured_pin_deg),
            "springback_deg": _finite_or_none(self.springback_deg),
            "direction": self.direction,
            "target_deg": self.target_deg,
            "bend_index": self.bend_index,
            "part": self.part,
            "loaded_uncertainty_deg": unc.get("loaded_bend_deg"),
            "unloaded_uncertainty_deg": unc.get("unloaded_bend_deg"),
            "springback_sigma_deg": _finite_or_none(self.springback_sigma_deg),
            "photo_loaded": self.photo_loaded,
            "photo_unloaded": self.photo_unloaded,
        }
        row.update(self.extra)
        return row

    def to_dict(self) -> dict[str, Any]:
        """JSON form (a calibration file's ``samples`` entry); NaN written as null."""
        d: dict[str, Any] = {
            "trial": int(self.trial) if self.trial.isdigit() else self.trial,
            "target_deg": self.target_deg,
            "commanded_pin_deg": self.commanded_pin_deg,
            "loaded_bend_deg": _finite_or_none(self.loaded_bend_deg),
            "unloaded_bend_deg": _finite_or_none(self.unloaded_bend_deg),
            "springback_deg": _finite_or_none(self.springback_deg),
            "uncertainty_deg": dict(self.uncertainty_deg),
            "source": self.source,
        }
        optional = {
            "measured_pin_deg": _finite_or_none(self.measured_pin_deg),
            "bend_index": self.bend_index,
            "part": self.part,
            "photo_loaded": self.photo_loaded,
            "photo_unloaded": self.photo_unloaded,
        }
        d.update({k: v for k, v in optional.items() if v is not None})
        if self.extra:
            d["extra"] = dict(self.extra)
        if self.warnings:
            d["warnings"] = [w.to_json() for w in self.warnings]
        return d

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, trial: str | None = None) -> Trial:
        """The inverse of :meth:`to_dict` (``trial`` names it when the dict has none)."""

        def num(key: str) -> float:
            value = d.get(key)
            return math.nan if value is None else float(value)

        name = d.get("trial")
        return cls(
            trial=str(name) if name is not None else (trial or ""),
            commanded_pin_deg=float(d["commanded_pin_deg"]),
            loaded_bend_deg=num("loaded_bend_deg"),
            unloaded_bend_deg=num("unloaded_bend_deg"),
            measured_pin_deg=num("measured_pin_deg"),
            target_deg=None if d.get("target_deg") is None else float(d["target_deg"]),
            bend_index=None if d.get("bend_index") is None else int(d["bend_index"]),
            part=None if d.get("part") is None else str(d["part"]),
            uncertainty_deg={k: float(v) for k, v in (d.get("uncertainty_deg") or {}).items()},
            photo_loaded=d.get("photo_loaded"),
            photo_unloaded=d.get("photo_unloaded"),
            source=str(d.get("source", "csv")),
            extra={str(k): str(v) for k, v in (d.get("extra") or {}).items()},
            warnings=tuple(StageWarning.from_json(w) for w in d.get("warnings") or ()),
        )


def _finite_or_none(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _csv_number(source: Any, line: int, column: str, text: Any, *, optional: bool) -> float:
    text = "" if text is None else str(text).strip()
    if text == "" and optional:
        return math.nan
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InputError(source, f"line {line}: {column} {text!r} is not a number")
    return value


@dataclass(frozen=True)
class TrialTable:
    """Trials in the order executed: the spec's trials CSV, read and written only here.

    Column views (``commanded_pin_deg`` ...) are NumPy arrays, NaN where not
    measured; ``group`` is each trial's cross-validation group.

    >>> t = TrialTable.from_arrays([10.0, -10.0], [9.0, -9.2], [8.0, -8.1])
    >>> t.direction_sign.tolist(), round(float(t.springback_deg[1]), 3)
    ([1.0, -1.0], 1.1)
    """

    trials: tuple[Trial, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "trials", tuple(self.trials))

    def __len__(self) -> int:
        return len(self.trials)

    def __iter__(self) -> Iterator[Trial]:
        return iter(self.trials)

    def __getitem__(self, index: int) -> Trial:
        return self.trials[index]

    # -- reading and writing

    @classmethod
    def read_csv(cls, path: str | os.PathLike[str], *, source: str = "csv") -> TrialTable:
        """Read a trials CSV; InputError names the file (and line) of any problem."""
        from cvmeasure.fileio import read_csv_rows

        return cls.from_rows(
            read_csv_rows(path, required=TRIALS_COLUMNS), source=path, origin=source
        )

    @classmethod
    def from_rows(
        cls,
        rows: Sequence[Mapping[str, str]],
        *,
        source: str | os.PathLike[str] = "trials CSV",
        origin: str = "csv",
    ) -> TrialTable:
        """Trials from CSV rows (strings, as :func:`cvmeasure.fileio.read_csv_rows` gives).

        Raises
        ------
        InputError
            Naming ``source`` and the line: no rows, a missing column, a value that
            is not a number, a trial with neither bend angle.
        """
        if not rows:
            raise InputError(source, "no trials")
        missing = [c for c in TRIALS_COLUMNS if c not in rows[0]]
        if missing:
            raise InputError(source, f"missing column(s) {', '.join(missing)}")
        known = set(TRIALS_COLUMNS) | set(TRIALS_OPTIONAL_COLUMNS)
        trials = []
        for i, row in enumerate(rows):
            line = i + 2

            def number(
                column: str, optional: bool = True, row: Mapping[str, str] = row, line: int = line
            ) -> float:
                return _csv_number(source, line, column, row.get(column), optional=optional)

            loaded, unloaded = number("loaded_bend_deg"), number("unloaded_bend_deg")
            if math.isnan(loaded) and math.isnan(unloaded):
                raise InputError(
                    source, f"line {line}: trial has neither a loaded nor an unloaded angle"
                )
            unc = {}
            for column, key in (
                ("loaded_uncertainty_deg", "loaded_bend_deg"),
                ("unloaded_uncertainty_deg", "unloaded_bend_deg"),
                ("springback_sigma_deg", "springback_deg"),
            ):
                value = number(column)
                if math.isfinite(value):
                    unc[key] = value
            if "springback_deg" not in unc and len(unc) == 2:
                unc["springback_deg"] = math.hypot(unc["loaded_bend_deg"], unc["unloaded_bend_deg"])
            target = number("target_deg")
            index = number("bend_index")
            if math.isfinite(index) and index != int(index):
                raise InputError(source, f"line {line}: bend_index {index} is not a whole number")
            trials.append(
                Trial(
                    trial=str(row.get("trial") or "").strip() or str(i + 1),
                    commanded_pin_deg=number("commanded_pin_deg", optional=False),
                    loaded_bend_deg=loaded,
                    unloaded_bend_deg=unloaded,
                    measured_pin_deg=number("measured_pin_deg"),
                    target_deg=abs(target) if math.isfinite(target) else None,
                    bend_index=int(index) if math.isfinite(index) else None,
                    part=str(row.get("part") or "").strip() or None,
                    uncertainty_deg=unc,
                    photo_loaded=str(row.get("photo_loaded") or "") or None,
                    photo_unloaded=str(row.get("photo_unloaded") or "") or None,
                    source=origin,
                    extra={
                        k: str(v) for k, v in row.items() if k not in known and v not in (None, "")
                    },
                )
            )
        return cls(tuple(trials))

    def rows(self) -> list[dict[str, Any]]:
        """Trials CSV rows (NaN and None as empty cells)."""
        return [t.csv_row() for t in self.trials]

    def columns(self) -> list[str]:
        """The CSV header: the required columns, then the optional ones any trial has."""
        rows = self.rows()
        optional = [c for c in TRIALS_OPTIONAL_COLUMNS if any(r.get(c) is not None for r in rows)]
        extra: list[str] = []
        for t in self.trials:
            extra.extend(k for k in t.extra if k not in extra)
        return [*TRIALS_COLUMNS, *optional, *extra]

    def write_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the trials CSV atomically; return its path."""
        from cvmeasure.fileio import write_csv_rows

        return write_csv_rows(path, self.rows(), self.columns())

    def to_dict(self) -> dict[str, Any]:
        return {"trials": [t.to_dict() for t in self.trials]}

    @classmethod
    def from_arrays(
        cls,
        commanded_pin_deg: Sequence[float] | NDArray[np.float64],
        loaded_bend_deg: Sequence[float] | NDArray[np.float64],
        unloaded_bend_deg: Sequence[float] | NDArray[np.float64],
        *,
        trial: Sequence[str] | None = None,
        bend_index: Sequence[float] | None = None,
        group: Sequence[str] | None = None,
        measured_pin_deg: Sequence[float] | NDArray[np.float64] | None = None,
        source: str = "sim",
    ) -> TrialTable:
        """Trials from equal-length columns (NaN = not measured)."""
        cmd = np.asarray(commanded_pin_deg, dtype=np.float64)
        n = cmd.shape[0]
        columns = {
            "loaded_bend_deg": np.asarray(loaded_bend_deg, dtype=np.float64),
            "unloaded_bend_deg": np.asarray(unloaded_bend_deg, dtype=np.float64),
            "measured_pin_deg": (
                np.full(n, np.nan)
                if measured_pin_deg is None
                else np.asarray(measured_pin_deg, dtype=np.float64)
            ),
        }
        for name, values in columns.items():
            if values.shape != (n,):
                raise ValueError(f"{name} must have shape ({n},)")
        names = [str(t) for t in trial] if trial is not None else [str(i + 1) for i in range(n)]
        index = list(bend_index) if bend_index is not None else [None] * n
        groups = [str(g) for g in group] if group is not None else [None] * n
        if not (len(names) == len(index) == len(groups) == n):
            raise ValueError(f"trial, bend_index and group must have {n} entries")
        return cls(
            tuple(
                Trial(
                    trial=names[i],
                    commanded_pin_deg=float(cmd[i]),
                    loaded_bend_deg=float(columns["loaded_bend_deg"][i]),
                    unloaded_bend_deg=float(columns["unloaded_bend_deg"][i]),
                    measured_pin_deg=float(columns["measured_pin_deg"][i]),
                    bend_index=None if index[i] is None else int(index[i]),
                    part=groups[i],
                    source=source,
                )
                for i in range(n)
            )
        )

    # -- column views

    @cached_property
    def names(self) -> tuple[str, ...]:
        return tuple(t.trial for t in self.trials)

    def _column(self, name: str) -> NDArray[np.float64]:
        return np.array([getattr(t, name) for t in self.trials], dtype=np.float64)

    @cached_property
    def commanded_pin_deg(self) -> NDArray[np.float64]:
        return self._column("commanded_pin_deg")

    @cached_property
    def loaded_bend_deg(self) -> NDArray[np.float64]:
        return self._column("loaded_bend_deg")

    @cached_property
    def unloaded_bend_deg(self) -> NDArray[np.float64]:
        return self._column("unloaded_bend_deg")

    @cached_property
    def measured_pin_deg(self) -> NDArray[np.float64]:
        return self._column("measured_pin_deg")

    @cached_property
    def springback_deg(self) -> NDArray[np.float64]:
        return self._column("springback_deg")

    @cached_property
    def bend_index(self) -> NDArray[np.float64]:
        """Bends executed before each trial (its row position where not given)."""
        return np.array(
            [i if t.bend_index is None else t.bend_index for i, t in enumerate(self.trials)],
            dtype=np.float64,
        )

    @cached_property
    def group(self) -> tuple[str, ...]:
        """Each trial's cross-validation group (its ``part``, else its own name)."""
        return tuple(t.part or t.trial for t in self.trials)

    @cached_property
    def direction_sign(self) -> NDArray[np.float64]:
        """+1 for counter-clockwise (positive command), -1 for clockwise."""
        return np.where(self.commanded_pin_deg < 0, -1.0, 1.0)

    @property
    def has_loaded(self) -> bool:
        return bool(np.any(np.isfinite(self.loaded_bend_deg)))

    @property
    def has_pin(self) -> bool:
        return bool(np.any(np.isfinite(self.measured_pin_deg)))

    @property
    def both_directions(self) -> bool:
        d = self.direction_sign
        return bool(np.any(d > 0) and np.any(d < 0))

    def observations(self) -> NDArray[np.float64]:
        """Every measured quantity stacked by :data:`BLOCKS` (shape (3 N,), NaN = not measured)."""
        return np.concatenate([self.loaded_bend_deg, self.unloaded_bend_deg, self.measured_pin_deg])

    def subset(self, mask: NDArray[np.bool_] | Sequence[bool]) -> TrialTable:
        """The trials where ``mask`` is true (order, bend indices and groups kept)."""
        idx = np.flatnonzero(np.asarray(mask, dtype=bool))
        index = self.bend_index
        group = self.group
        return TrialTable(
            tuple(replace(self.trials[i], bend_index=int(index[i]), part=group[i]) for i in idx)
        )

    def with_groups(self, groups: Sequence[str]) -> TrialTable:
        """The same trials with each one's cross-validation group (``part``) set."""
        if len(groups) != len(self):
            raise ValueError(f"need {len(self)} groups, got {len(groups)}")
        return TrialTable(
            tuple(replace(t, part=str(g)) for t, g in zip(self.trials, groups, strict=True))
        )

    def pairs(self, source: str | os.PathLike[str] = "trials") -> TrialTable:
        """The trials, checked to have both bend angles (fitting springback needs both).

        Raises InputError naming ``source`` and the first trial without a pair.
        """
        for t in self.trials:
            if not t.has_pair:
                raise InputError(source, f"trial {t.trial}: needs both loaded and unloaded angles")
        return self


# ----------------------------------------------------------------------------- per-photo measurements


@dataclass(frozen=True)
class MarkerMeasurement:
    """One marker's centre and radius in the photo's pixels, with quality figures.

    ``sigma_px`` is the centre's standard uncertainty (RMS of the two axes);
    ``coverage`` the share of its boundary seen; ``delta_e`` the CIE76 colour
    difference between the white-balanced disc and the kit's colour.
    """

    role: str
    x_px: float
    y_px: float
    r_px: float
    sigma_px: float
    n_edge_points: int = 0
    coverage: float = 1.0
    contrast: float = 0.0
    delta_e: float | None = None

    def to_dict(self) -> dict[str, Any]:
        """The spec's marker record (plus the centre's ``sigma_px``)."""
        return {"x_px": self.x_px, "y_px": self.y_px, "r_px": self.r_px, "sigma_px": self.sigma_px}

    @classmethod
    def from_dict(cls, role: str, d: Mapping[str, Any]) -> MarkerMeasurement:
        """The inverse of :meth:`to_dict` (quality figures not in the record take defaults)."""
        return cls(
            role=role,
            x_px=float(d["x_px"]),
            y_px=float(d["y_px"]),
            r_px=float(d["r_px"]),
            sigma_px=float(d.get("sigma_px", math.nan)),
        )


@dataclass(frozen=True)
class MachinePhotoResult:
    """The measurement of one machine photo (spec ``Per-photo results``).

    ``heights`` says how the markers' heights above the plate were treated (project
    addition, docs/conventions.md): "plane" (each disc's edge mapped to its own
    height through the plane pose), "parallel" (camera only: corrected assuming the
    optical axis is normal to the plate), "flat" (the kit gives no heights), "none"
    (not applied: no plane pose). ``height_bound_deg`` is, beside (not inside)
    ``uncertainty_deg``, the worst angle error the heights can still cause when they
    were not applied exactly (None when they were, or the kit is flat).
    """

    pin_angle_deg: float
    bend_angle_deg: float
    markers: Mapping[str, MarkerMeasurement]
    uncertainty_deg: Mapping[str, float]
    warnings: tuple[StageWarning, ...] = ()
    photo: str | None = None
    method: str = "ours"
    space: str = "lab"
    frame: str = "image"
    heights: str | None = None
    height_bound_deg: Mapping[str, float] | None = None

    def to_dict(self) -> dict[str, Any]:
        """The spec's JSON Lines record (plus ``photo``)."""
        out: dict[str, Any] = {}
        if self.photo is not None:
            out["photo"] = self.photo
        out.update(
            {
                "pin_angle_deg": round(self.pin_angle_deg, 6),
                "bend_angle_deg": round(self.bend_angle_deg, 6),
                "markers": {
                    r: {k: round(v, 4) for k, v in self.markers[r].to_dict().items()}
                    for r in ROLES
                    if r in self.markers
                },
                "uncertainty_deg": {k: round(v, 6) for k, v in self.uncertainty_deg.items()},
                "warnings": [w.to_json() for w in self.warnings],
            }
        )
        if self.frame != "image":
            out["frame"] = self.frame
        if self.method != "ours":
            out["method"] = self.method
        if self.heights is not None:
            out["heights"] = self.heights
        if self.height_bound_deg is not None:
            out["height_bound_deg"] = {k: round(v, 6) for k, v in self.height_bound_deg.items()}
        return out

    @classmethod
    def from_dict(cls, d: Mapping[str, Any], *, source: str = "measurement") -> MachinePhotoResult:
        """A machine photo's JSON Lines record read back; InputError names ``source``."""
        try:
            return cls(
                pin_angle_deg=float(d["pin_angle_deg"]),
                bend_angle_deg=float(d["bend_angle_deg"]),
                markers={
                    role: MarkerMeasurement.from_dict(role, m)
                    for role, m in dict(d["markers"]).items()
                },
                uncertainty_deg={k: float(v) for k, v in dict(d["uncertainty_deg"]).items()},
                warnings=tuple(StageWarning.from_json(w) for w in d.get("warnings", ())),
                photo=d.get("photo"),
                method=str(d.get("method", "ours")),
                frame=str(d.get("frame", "image")),
                heights=None if d.get("heights") is None else str(d["heights"]),
                height_bound_deg=None
                if d.get("height_bound_deg") is None
                else {k: float(v) for k, v in dict(d["height_bound_deg"]).items()},
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(source, f"not a machine photo measurement: {exc!r}") from None


# ----------------------------------------------------------------------------- the measurement plane

#: Format tag of a saved plane (``cvmeasure plane --json`` / ``-o plane.json``).
PLANE_FORMAT = "cvmeasure-plane/1"


def _pose_from_homography(
    camera: CameraModel, h_board_image: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(rvec, tvec_mm), camera <- plane, from an undistorted px -> plane mm homography.

    ``K^-1 H_image_board = s [r1 r2 t]``: the scale from the first two columns, the
    rotation completed and made orthonormal (nearest rotation, SVD), the sign chosen
    so that the plane lies in front of the camera.
    """
    import cv2

    m = np.linalg.inv(camera.camera_matrix) @ np.linalg.inv(h_board_image)
    m = m / math.sqrt(np.linalg.norm(m[:, 0]) * np.linalg.norm(m[:, 1]))
    if m[2, 2] < 0:
        m = -m
    r = np.column_stack((m[:, 0], m[:, 1], np.cross(m[:, 0], m[:, 1])))
    u, _, vt = np.linalg.svd(r)
    rot = u @ vt
    if np.linalg.det(rot) < 0:
        rot = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    return cv2.Rodrigues(rot)[0].reshape(3), m[:, 2].copy()


def apply_homography(h: NDArray[np.float64], points: Any) -> NDArray[np.float64]:
    """Points (N, 2) through the 3x3 homography ``h`` (homogeneous, divided out).

    >>> apply_homography(np.diag([2.0, 2.0, 1.0]), [[1.0, 3.0]]).tolist()
    [[2.0, 6.0]]
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    hom = np.column_stack((pts, np.ones(len(pts)))) @ np.asarray(h, dtype=np.float64).T
    return hom[:, :2] / hom[:, 2:3]


@dataclass(frozen=True)
class PlaneModel:
    """The measurement plane seen by one camera: camera + homography + pose.

    What ``cvmeasure plane`` measures from a board lying on the plane, saved with
    :meth:`save` and read back whole with :meth:`load` (camera included), and
    rescaled with the photo like the camera (:meth:`for_image`).

    Attributes
    ----------
    camera : CameraModel
        The camera (distortion is removed before the homography).
    H_board_image : ndarray (3, 3)
        Undistorted image px -> board mm (homogeneous, [2, 2] = 1).
    rvec, tvec_mm : ndarray (3,)
        Board pose, camera <- board (OpenCV convention; mm).
    tilt_deg : float
        Angle between the plane normal and the optical axis.
    tilt_direction_deg : float
        Image direction in which the plane recedes from the camera, degrees
        counter-clockwise from +x as seen in the photo (0 when the tilt is 0).
    mm_per_px : float
        Scale on the plane at the board centre, mm per (undistorted) pixel.
    worst_angle_error_deg : float
        Worst direction error over the board's region from ignoring the tilt
        (a rotation + uniform scale model instead of the homography).
    tolerance_deg : float
        What the affine verdict allows.
    rms_px : float
        RMS reprojection error of the board corners under the pose, px.
    corner_count : int
    source : str
        The photo the plane was measured on.
    """

    camera: CameraModel
    H_board_image: NDArray[np.float64]
    rvec: NDArray[np.float64]
    tvec_mm: NDArray[np.float64]
    tilt_deg: float
    tilt_direction_deg: float
    mm_per_px: float
    worst_angle_error_deg: float
    tolerance_deg: float
    rms_px: float
    corner_count: int
    source: str = "image"

    def __post_init__(self) -> None:
        h = np.asarray(self.H_board_image, dtype=np.float64).reshape(3, 3)
        object.__setattr__(self, "H_board_image", h / h[2, 2])
        object.__setattr__(self, "rvec", np.asarray(self.rvec, dtype=np.float64).reshape(3))
        object.__setattr__(self, "tvec_mm", np.asarray(self.tvec_mm, dtype=np.float64).reshape(3))

    @property
    def affine_ok(self) -> bool:
        """True when ignoring the tilt keeps angle errors within the tolerance."""
        return self.worst_angle_error_deg <= self.tolerance_deg

    @property
    def H_image_board(self) -> NDArray[np.float64]:
        """Board mm -> undistorted image px."""
        inv = np.linalg.inv(self.H_board_image)
        return inv / inv[2, 2]

    def image_to_plane_mm(self, points_px: Any, *, height_mm: float = 0.0) -> NDArray[np.float64]:
        """Photo pixels (N, 2), distorted as taken -> board-frame (x, y) mm (N, 2).

        ``height_mm`` 0 is the board's plane (its homography). Otherwise each pixel's
        undistorted ray meets the parallel plane ``height_mm`` above the board
        (towards the camera, whichever way the frame's z points): a marker on
        top of the pin, the axis of a wire lying on the plate. Mapping such a point
        to the board plane instead moves it about the camera's foot point by about
        height / distance of its offset (1 mm at 20 mm height, 25 mm off axis, 500 mm).
        """
        pts = np.asarray(points_px, dtype=np.float64).reshape(-1, 2)
        if len(pts) == 0:
            return np.zeros((0, 2))
        if height_mm == 0.0:
            return apply_homography(self.H_board_image, self.camera.undistort_px(pts))
        import cv2

        rot, _ = cv2.Rodrigues(self.rvec)
        rays = np.column_stack((self.camera.normalized(pts), np.ones(len(pts))))
        # board point X = R^T (s ray - t); pick s so that its z is -height
        rt_rays = rays @ rot  # rows: R^T ray
        rt_t = rot.T @ self.tvec_mm
        # the camera is at z = -rt_t[2]: a board frame's z points away from it (rt_t[2] > 0)
        towards = height_mm if rt_t[2] >= 0 else -height_mm
        scale = (rt_t[2] - towards) / rt_rays[:, 2]
        board = scale[:, None] * rt_rays - rt_t[None, :]
        return board[:, :2]

    @property
    def camera_centre_mm(self) -> NDArray[np.float64]:
        """The camera's centre (3,) in the board frame, mm (``-R^T t``; its z is negative for
        a plane from ``cvmeasure plane``: the board frame's z points away from the camera)."""
        import cv2

        rot, _ = cv2.Rodrigues(self.rvec)
        return -rot.T @ np.asarray(self.tvec_mm, dtype=np.float64).reshape(3)

    def plane_to_image_px(self, points_mm: Any) -> NDArray[np.float64]:
        """Board-frame mm (N, 2) on the plane, or board-frame points (N, 3) -> photo pixels (N, 2).

        With distortion. For (N, 3), z is the board frame's own (away from the camera for a
        plane from ``cvmeasure plane``: a height above the plate is -z).
        """
        import cv2

        arr = np.asarray(points_mm, dtype=np.float64)
        if arr.ndim == 2 and arr.shape[1] == 3:
            obj = arr
        else:
            pts = arr.reshape(-1, 2)
            obj = np.column_stack((pts, np.zeros(len(pts))))
        if len(obj) == 0:
            return np.zeros((0, 2))
        img, _ = cv2.projectPoints(
            obj.reshape(-1, 1, 3),
            self.rvec,
            self.tvec_mm,
            self.camera.camera_matrix,
            self.camera.dist_coeffs,
        )
        return img.reshape(-1, 2)

    def lens_uncertainty_mm(self) -> dict[str, float | None]:
        """The camera calibration's own uncertainty, in mm on this plane.

        ``sigma_mm``: median 1-sigma projection uncertainty (corner noise only);
        ``cross_validation_mm``: the even/odd halves' central disagreement, which
        also holds model error -- the honest figure. None when the camera JSON
        does not carry them (not written by ``cvmeasure calibrate``, or rescaled).
        """
        cal = self.camera.calibration or {}
        unc = (cal.get("projection_uncertainty") or {}).get("median_px")
        cv = (cal.get("cross_validation") or {}).get("central_60pct_rms_px")
        return {
            "sigma_mm": None if unc is None else float(unc) * self.mm_per_px,
            "cross_validation_mm": None if cv is None else float(cv) * self.mm_per_px,
        }

    def scaled(self, factor: float) -> PlaneModel:
        """The same plane for the photo resized by ``factor`` (camera and homography rescaled)."""
        camera = self.camera.scaled(factor)
        # undistorted px of the resized photo = S @ undistorted px of the original
        s = camera.camera_matrix @ np.linalg.inv(self.camera.camera_matrix)
        return replace(
            self,
            camera=camera,
            H_board_image=self.H_board_image @ np.linalg.inv(s),
            mm_per_px=self.mm_per_px / factor,
            rms_px=self.rms_px * factor,
        )

    def for_image(self, size_px: tuple[int, int], source: str = "photo") -> PlaneModel:
        """This plane for a photo of ``size_px`` (width, height): itself or rescaled.

        InputError naming ``source`` for a photo of another aspect ratio.
        """
        camera = self.camera.for_image(size_px, source)
        if camera is self.camera:
            return self
        return self.scaled(camera.image_size_px[0] / self.camera.image_size_px[0])

    def to_dict(self) -> dict[str, Any]:
        """The plane JSON: the check's figures, the homography, the pose and the camera."""
        return {
            "format": PLANE_FORMAT,
            "source": self.source,
            "tilt_deg": self.tilt_deg,
            "tilt_direction_deg": self.tilt_direction_deg,
            "mm_per_px": self.mm_per_px,
            "worst_angle_error_deg": self.worst_angle_error_deg,
            "tolerance_deg": self.tolerance_deg,
            "affine_ok": self.affine_ok,
            "rms_px": self.rms_px,
            "corner_count": self.corner_count,
            "H_board_image": self.H_board_image.tolist(),
            "homography_frames": "undistorted image px -> board mm",
            "rvec": self.rvec.tolist(),
            "tvec_mm": self.tvec_mm.tolist(),
            "lens_uncertainty_mm": self.lens_uncertainty_mm(),
            "camera": self.camera.to_dict(),
        }

    @classmethod
    def from_dict(
        cls,
        d: Any,
        *,
        camera: CameraModel | None = None,
        source: str | os.PathLike[str] = "plane JSON",
    ) -> PlaneModel:
        """Read a plane JSON back whole; InputError names ``source`` and the problem.

        A plane JSON carries its camera. ``camera``, when given, must be that camera
        (same intrinsics and distortion): a plane measured through one lens model
        does not map another's pixels. A plane JSON written before the camera was
        saved with it (no ``camera`` key) is read with ``camera``, and refused without.
        """
        if not isinstance(d, dict):
            raise InputError(source, "a plane JSON must be an object")
        try:
            h = np.asarray(d["H_board_image"], dtype=np.float64)
        except (KeyError, TypeError, ValueError):
            raise InputError(source, "plane JSON lacks a 3x3 'H_board_image'") from None
        if h.shape != (3, 3) or not np.all(np.isfinite(h)) or abs(np.linalg.det(h)) < 1e-15:
            raise InputError(source, "'H_board_image' must be a finite, invertible 3x3 matrix")
        saved = d.get("camera")
        if saved is not None:
            own = CameraModel.from_dict(saved, source=f"{source}: camera")
            if camera is not None and not own.same_lens(camera):
                raise InputError(
                    source,
                    "the plane was measured with another camera model than the one given "
                    "(re-run `cvmeasure plane` with this camera, or drop --camera)",
                )
            camera = own
        if camera is None:
            raise InputError(
                source, "plane JSON has no camera (written by an older cvmeasure): give --camera"
            )
        try:
            if "rvec" in d and "tvec_mm" in d:
                rvec = np.asarray(d["rvec"], dtype=np.float64).reshape(3)
                tvec = np.asarray(d["tvec_mm"], dtype=np.float64).reshape(3)
            else:  # an older plane JSON: the pose is in the homography and the camera
                rvec, tvec = _pose_from_homography(camera, h)
            numbers = {
                k: float(d.get(k, default))
                for k, default in (
                    ("tilt_deg", math.nan),
                    ("tilt_direction_deg", math.nan),
                    ("mm_per_px", math.nan),
                    ("worst_angle_error_deg", math.nan),
                    ("tolerance_deg", math.nan),
                    ("rms_px", math.nan),
                )
            }
            corners = int(d.get("corner_count", 0))
        except (TypeError, ValueError) as exc:
            raise InputError(source, f"plane JSON has a malformed value: {exc}") from None
        return cls(
            camera=camera,
            H_board_image=h,
            rvec=rvec,
            tvec_mm=tvec,
            corner_count=corners,
            source=str(d.get("source", source)),
            **numbers,
        )

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the plane JSON atomically; return its path."""
        from cvmeasure.fileio import atomic_write_json, to_jsonable

        return atomic_write_json(path, to_jsonable(self.to_dict()))

    @classmethod
    def load(cls, path: str | os.PathLike[str], *, camera: CameraModel | None = None) -> PlaneModel:
        """Read a plane JSON (see :meth:`from_dict`); InputError names the file."""
        from cvmeasure.fileio import read_json

        return cls.from_dict(read_json(path, what="plane JSON"), camera=camera, source=str(path))
