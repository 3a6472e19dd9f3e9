"""The types that cross stages: what one stage hands the next, typed, saved and loaded whole.

Every stage takes and returns these, never dicts or ``Any``:

- **Trials** (:class:`Trial`, :class:`TrialTable`): measured bends, one per row, in the
  order executed; the only reader and writer of the spec's trials CSV.
- **Per-photo measurements**: what measuring one photo gives, as written to and read
  back from the JSON Lines results.
- **The measurement plane** (:class:`PlaneModel`): camera + homography + pose; saved
  and loaded without loss, rescaled with the photo like the camera. It lives in
  :mod:`cvmeasure.plane_model` and is re-exported here on first use (PEP 562,
  ``docs/design/imports.md``): the plane loads OpenCV, which trials never need.

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

from cvmeasure._lazy import lazy_names
from cvmeasure.errors import InputError
from cvmeasure.fileio import read_csv_rows, write_csv_rows
from cvmeasure.kit import ROLES
from cvmeasure.method_names import marker_method
from cvmeasure.warning import StageWarning

#: The names re-exported from :mod:`cvmeasure.plane_model`, loaded on first use.
_PLANE_NAMES = ("PLANE_FORMAT", "PlaneModel", "apply_homography")

__all__ = [
    "BLOCKS",
    "TRIALS_COLUMNS",
    "TRIALS_OPTIONAL_COLUMNS",
    "Trial",
    "TrialTable",
    "MarkerMeasurement",
    "MachinePhotoResult",
    *_PLANE_NAMES,
]


__getattr__, __dir__ = lazy_names(
    __name__, globals(), dict.fromkeys(_PLANE_NAMES, "cvmeasure.plane_model")
)


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
    method: str = "edge_fit"
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
        if self.method != "edge_fit":
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
                method=marker_method(str(d.get("method", "edge_fit"))),
                frame=str(d.get("frame", "image")),
                heights=None if d.get("heights") is None else str(d["heights"]),
                height_bound_deg=None
                if d.get("height_bound_deg") is None
                else {k: float(v) for k, v in dict(d["height_bound_deg"]).items()},
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(source, f"not a machine photo measurement: {exc!r}") from None
