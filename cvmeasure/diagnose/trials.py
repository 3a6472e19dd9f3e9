"""Measured trials (trials CSV) as arrays: the input of the diagnosis.

Trials CSV (spec): ``trial, commanded_pin_deg, loaded_bend_deg,
unloaded_bend_deg`` in the order executed, optional columns after. An empty
``loaded_bend_deg`` cell means the loaded angle was not photographed (the
diagnosis then works on unloaded angles only). Optional columns used here:
``measured_pin_deg`` (pin angle on the loaded photo, machine frame),
``bend_index`` (bends executed before this one, for drift; default the row
number from 0) and ``part`` (the group of grouped cross-validation; default
each trial its own group).

Observations are stacked in blocks, ``[loaded..., unloaded..., pin...]``
(:data:`BLOCKS`), NaN where not measured.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from os import PathLike
from typing import Any

import numpy as np
from numpy.typing import NDArray

from cvmeasure.errors import InputError

__all__ = ["TRIALS_COLUMNS", "BLOCKS", "TrialSet", "trials_from_rows"]

#: The measured quantities of a trial, in the order they are stacked.
BLOCKS: tuple[str, ...] = ("loaded_bend_deg", "unloaded_bend_deg", "measured_pin_deg")

#: Required columns of a trials CSV (spec).
TRIALS_COLUMNS: tuple[str, ...] = (
    "trial",
    "commanded_pin_deg",
    "loaded_bend_deg",
    "unloaded_bend_deg",
)


@dataclass(frozen=True)
class TrialSet:
    """Measured bends, one entry per trial, in the order executed (degrees).

    ``loaded_bend_deg`` / ``unloaded_bend_deg`` / ``measured_pin_deg`` hold
    NaN where not measured.
    """

    trial: tuple[str, ...]
    commanded_pin_deg: NDArray[np.float64]
    loaded_bend_deg: NDArray[np.float64]
    unloaded_bend_deg: NDArray[np.float64]
    bend_index: NDArray[np.float64]
    group: tuple[str, ...]
    measured_pin_deg: NDArray[np.float64] | None = None

    def __post_init__(self) -> None:
        n = len(self.trial)
        if self.measured_pin_deg is None:
            object.__setattr__(self, "measured_pin_deg", np.full(n, np.nan))
        else:
            object.__setattr__(
                self, "measured_pin_deg", np.asarray(self.measured_pin_deg, dtype=np.float64)
            )
        if np.shape(self.measured_pin_deg) != (n,):
            raise ValueError(f"measured_pin_deg must have shape ({n},)")
        for name in ("commanded_pin_deg", "loaded_bend_deg", "unloaded_bend_deg", "bend_index"):
            if np.shape(getattr(self, name)) != (n,):
                raise ValueError(f"{name} must have shape ({n},)")
        if len(self.group) != n:
            raise ValueError(f"group must have {n} entries")

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
    ) -> TrialSet:
        cmd = np.asarray(commanded_pin_deg, dtype=np.float64)
        n = cmd.shape[0]
        names = (
            tuple(str(t) for t in trial)
            if trial is not None
            else tuple(str(i + 1) for i in range(n))
        )
        return cls(
            trial=names,
            commanded_pin_deg=cmd,
            loaded_bend_deg=np.asarray(loaded_bend_deg, dtype=np.float64),
            unloaded_bend_deg=np.asarray(unloaded_bend_deg, dtype=np.float64),
            bend_index=(
                np.asarray(bend_index, dtype=np.float64)
                if bend_index is not None
                else np.arange(n, dtype=np.float64)
            ),
            group=tuple(str(g) for g in group) if group is not None else names,
            measured_pin_deg=measured_pin_deg,
        )

    def __len__(self) -> int:
        return len(self.trial)

    @property
    def direction(self) -> NDArray[np.float64]:
        """+1 for counter-clockwise (positive command), -1 for clockwise."""
        return np.where(self.commanded_pin_deg < 0, -1.0, 1.0)

    @property
    def has_loaded(self) -> bool:
        return bool(np.any(np.isfinite(self.loaded_bend_deg)))

    @property
    def has_pin(self) -> bool:
        return bool(np.any(np.isfinite(self.measured_pin_deg)))

    def observations(self) -> NDArray[np.float64]:
        """Every measured quantity stacked by :data:`BLOCKS` (shape (3 N,), NaN = not measured)."""
        return np.concatenate([self.loaded_bend_deg, self.unloaded_bend_deg, self.measured_pin_deg])

    @property
    def both_directions(self) -> bool:
        d = self.direction
        return bool(np.any(d > 0) and np.any(d < 0))

    def subset(self, mask: NDArray[np.bool_]) -> TrialSet:
        """The trials where ``mask`` is true (order and bend indices kept)."""
        idx = np.flatnonzero(mask)
        return TrialSet(
            trial=tuple(self.trial[i] for i in idx),
            commanded_pin_deg=self.commanded_pin_deg[idx],
            loaded_bend_deg=self.loaded_bend_deg[idx],
            unloaded_bend_deg=self.unloaded_bend_deg[idx],
            bend_index=self.bend_index[idx],
            group=tuple(self.group[i] for i in idx),
            measured_pin_deg=self.measured_pin_deg[idx],
        )

    def rows(self) -> list[dict[str, Any]]:
        """Trials CSV rows (NaN written as empty cells)."""
        out = []
        for i in range(len(self)):
            out.append(
                {
                    "trial": self.trial[i],
                    "commanded_pin_deg": float(self.commanded_pin_deg[i]),
                    "loaded_bend_deg": _cell(self.loaded_bend_deg[i]),
                    "unloaded_bend_deg": _cell(self.unloaded_bend_deg[i]),
                    "bend_index": int(self.bend_index[i]),
                    "part": self.group[i],
                    "measured_pin_deg": _cell(self.measured_pin_deg[i]),
                }
            )
        return out

    def to_dict(self) -> dict[str, Any]:
        return {"trials": self.rows()}


def _cell(value: float) -> float | None:
    return float(value) if math.isfinite(value) else None


def _number(source: Any, line: int, column: str, text: str, *, optional: bool) -> float:
    if text == "" and optional:
        return math.nan
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise InputError(source, f"line {line}: {column} {text!r} is not a number")
    return value


def trials_from_rows(
    rows: Sequence[Mapping[str, str]], *, source: str | PathLike[str] = "trials CSV"
) -> TrialSet:
    """Build a :class:`TrialSet` from trials CSV rows (as read by ``read_csv_rows``).

    Raises
    ------
    InputError
        Naming ``source`` when a value is not a number, a trial has neither
        angle, or there are too few trials.
    """
    if not rows:
        raise InputError(source, "no trials")
    missing = [c for c in TRIALS_COLUMNS if c not in rows[0]]
    if missing:
        raise InputError(source, f"missing column(s) {', '.join(missing)}")
    cmd, loaded, unloaded, index, group, pin = [], [], [], [], [], []
    for i, row in enumerate(rows):
        line = i + 2
        cmd.append(
            _number(source, line, "commanded_pin_deg", row["commanded_pin_deg"], optional=False)
        )
        loaded.append(
            _number(source, line, "loaded_bend_deg", row["loaded_bend_deg"], optional=True)
        )
        unloaded.append(
            _number(source, line, "unloaded_bend_deg", row["unloaded_bend_deg"], optional=True)
        )
        if math.isnan(loaded[-1]) and math.isnan(unloaded[-1]):
            raise InputError(
                source, f"line {line}: trial has neither a loaded nor an unloaded angle"
            )
        if row.get("bend_index", ""):
            index.append(_number(source, line, "bend_index", row["bend_index"], optional=False))
        else:
            index.append(float(i))
        group.append(row.get("part") or row["trial"])
        pin.append(
            _number(
                source, line, "measured_pin_deg", row.get("measured_pin_deg", ""), optional=True
            )
        )
    return TrialSet.from_arrays(
        cmd,
        loaded,
        unloaded,
        trial=[r["trial"] for r in rows],
        bend_index=index,
        group=group,
        measured_pin_deg=pin,
    )
