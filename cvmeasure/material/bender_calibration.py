"""The material calibration file (``diwire-material/1``): raw bends plus fitted models.

A calibration records, for one wire on one machine, the calibration bends of
both directions (loaded and unloaded bend angles measured by the camera, their
uncertainties, the pin commands), the springback and motion curves fitted to
them (:mod:`cvmeasure.material.compensation`) and how every model scored.
The raw samples are always kept, so any model can be refitted later
(:meth:`BenderCalibration.refit`).

Format (JSON, all angles in degrees, signed angles counter-clockwise positive)::

    {
      "format": "diwire-material/1",
      "name": "steel-3mm-A",
      "created_utc": "2026-01-01T12:00:00+00:00",
      "wire": {"material": "low-carbon steel", "diameter_mm": 3.0},
      "machine": {"model": "DIWire v1", "controller": "TinyG v8"},
      "mode": "standard",                      # quick | standard | high | custom
      "angles_deg": [5, 10, 15, 20, 30, 45, 60, 75, 90, 110, 130],
      "samples": {                             # raw bends, per direction
        "ccw": [{"target_deg": 45.0, "commanded_pin_deg": 58.1,
                 "measured_pin_deg": 58.0,     # optional (camera)
                 "loaded_bend_deg": 46.7, "unloaded_bend_deg": 44.2,
                 "springback_deg": 2.5,        # sign(loaded) * (loaded - unloaded)
                 "uncertainty_deg": {"loaded_bend_deg": 0.01,
                                     "unloaded_bend_deg": 0.01,
                                     "springback_deg": 0.014},
                 "trial": 7, "source": "cv"}, ...],
        "cw": [...]                            # target_deg > 0, angles negative
      },
      "springback": {"model": "linear", "ccw": {...}, "cw": {...}},
      "motion": {"model": "pchip", "ccw": {...}, "cw": {...}},
      "scores": {"linear": {"ccw": {"loao_rmse_deg": ..., "loao_max_deg": ...}, ...}, ...},
      "provenance": {...}
    }

``springback`` and ``motion`` hold :class:`~cvmeasure.material.compensation.SpringbackCurve`
and :class:`~cvmeasure.material.compensation.MotionCurve` dictionaries.
:func:`load_calibration` validates the whole file and raises
:class:`~cvmeasure.errors.InputError` naming the file and the offending key.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from cvmeasure.contracts import Trial, TrialTable
from cvmeasure.errors import InputError
from cvmeasure.fileio import atomic_write_json, read_json, to_jsonable
from cvmeasure.material.compensation import (
    DIRECTIONS,
    MOTION_MODELS,
    SPRINGBACK_MODELS,
    Compensation,
    MotionModel,
    SpringbackModel,
    fit_compensation,
)

__all__ = [
    "FORMAT",
    "MODES",
    "BenderCalibration",
    "calibration_plan",
    "fit_calibration",
    "read_trials_csv",
    "load_calibration",
    "save_calibration",
    "validate_calibration_dict",
]

#: Format tag written to and required in every calibration file.
FORMAT = "diwire-material/1"

#: Calibration angles (deg) of each mode; every angle is bent in both directions.
#: ``quick`` and ``standard`` are the stock software's (seed paper); ``high`` is
#: ours: standard plus 2.5 and 7.5 deg, so that shallow parts (the seed's saddle
#: bends 3.48 deg per segment, below standard's smallest final angle) are inside
#: the calibrated range.
MODES: dict[str, tuple[float, ...]] = {
    "quick": (10.0, 20.0, 45.0, 75.0, 110.0),
    "standard": (5.0, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0, 110.0, 130.0),
    "high": (2.5, 5.0, 7.5, 10.0, 15.0, 20.0, 30.0, 45.0, 60.0, 75.0, 90.0, 110.0, 130.0),
}

_UNCERTAINTY_KEYS = ("loaded_bend_deg", "unloaded_bend_deg", "springback_deg")


def calibration_plan(mode: str | Sequence[float]) -> list[tuple[str, float]]:
    """The bends of a calibration session, in execution order.

    Parameters
    ----------
    mode : str or sequence of float
        ``"quick"``, ``"standard"``, ``"high"`` or an explicit list of angles (deg, > 0).

    Returns
    -------
    list of (direction, angle_deg)
        Every angle counter-clockwise first, then every angle clockwise.
    """
    angles = _mode_angles(mode)
    return [(d, a) for d in DIRECTIONS for a in angles]


def _mode_angles(mode: str | Sequence[float]) -> tuple[float, ...]:
    if isinstance(mode, str):
        try:
            return MODES[mode]
        except KeyError:
            raise ValueError(f"unknown mode {mode!r}; valid: {', '.join(MODES)}") from None
    angles = tuple(float(a) for a in mode)
    if not angles or any(not (0 < a < 180) for a in angles):
        raise ValueError("calibration angles must be in (0, 180) deg")
    return angles


def _mode_name(angles: Sequence[float]) -> str:
    for name, mode_angles in MODES.items():
        if tuple(angles) == mode_angles:
            return name
    return "custom"


@dataclass(frozen=True)
class BenderCalibration:
    """A material calibration: raw samples, fitted compensation and model scores.

    Build one with :func:`fit_calibration`; use :meth:`compensate` for pin
    commands; :func:`save_calibration` / :func:`load_calibration` for files.
    """

    samples: tuple[Trial, ...]
    compensation: Compensation
    scores: Mapping[str, Mapping[str, Mapping[str, float | None]]]
    name: str = "calibration"
    wire: Mapping[str, Any] = field(default_factory=dict)
    machine: Mapping[str, Any] = field(default_factory=dict)
    mode: str = "custom"
    angles_deg: tuple[float, ...] = ()
    created_utc: str = ""
    provenance: Mapping[str, Any] = field(default_factory=dict)

    @property
    def model(self) -> str:
        """The springback model in use."""
        return self.compensation.model

    def compensate(self, target_final_deg: float, **kwargs: Any) -> float:
        """Signed pin command (deg) for a wanted signed final angle; see :class:`Compensation`."""
        return self.compensation.compensate(target_final_deg, **kwargs)

    def samples_of(self, direction: str) -> tuple[Trial, ...]:
        return tuple(s for s in self.samples if s.direction == direction)

    def refit(
        self, model: SpringbackModel, *, motion_model: MotionModel | None = None
    ) -> BenderCalibration:
        """The same samples with another springback (and motion) model."""
        mm = motion_model or next(iter(self.compensation.motion.values())).model
        new = fit_calibration(
            self.samples,
            model=model,
            motion_model=mm,
            name=self.name,
            wire=self.wire,
            machine=self.machine,
            mode=self.mode,
            angles_deg=self.angles_deg,
        )
        return replace(new, created_utc=self.created_utc, provenance=self.provenance)

    def to_dict(self) -> dict[str, Any]:
        comp = self.compensation.to_dict()
        return {
            "format": FORMAT,
            "name": self.name,
            "created_utc": self.created_utc,
            "wire": dict(self.wire),
            "machine": dict(self.machine),
            "mode": self.mode,
            "angles_deg": list(self.angles_deg),
            "samples": {d: [s.to_dict() for s in self.samples_of(d)] for d in DIRECTIONS},
            "springback": comp["springback"],
            "motion": comp["motion"],
            "scores": to_jsonable(self.scores),
            "provenance": dict(self.provenance),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> BenderCalibration:
        """Build from a dictionary already checked by :func:`validate_calibration_dict`."""
        samples = tuple(
            Trial.from_dict(s) for direction in DIRECTIONS for s in d["samples"].get(direction, [])
        )
        return cls(
            samples=samples,
            compensation=Compensation.from_dict(
                {"springback": d["springback"], "motion": d["motion"]}
            ),
            scores=d.get("scores", {}),
            name=str(d.get("name", "calibration")),
            wire=dict(d.get("wire", {})),
            machine=dict(d.get("machine", {})),
            mode=str(d.get("mode", "custom")),
            angles_deg=tuple(float(a) for a in d.get("angles_deg", ())),
            created_utc=str(d.get("created_utc", "")),
            provenance=dict(d.get("provenance", {})),
        )


def _score_models(samples: Sequence[Trial]) -> dict[str, dict[str, dict[str, float | None]]]:
    pin, loaded, unloaded = _columns(samples)
    scores: dict[str, dict[str, dict[str, float | None]]] = {}
    for model in SPRINGBACK_MODELS:
        try:
            comp = fit_compensation(pin, loaded, unloaded, model=model)  # type: ignore[arg-type]
        except ValueError as exc:
            scores[model] = {"error": str(exc)}  # type: ignore[dict-item]
            continue
        scores[model] = {
            d: {
                "loao_rmse_deg": c.loao_rmse_deg,
                "loao_max_deg": c.loao_max_deg,
                "rmse_deg": c.rmse_deg,
            }
            for d, c in comp.springback.items()
        }
    return scores


def _columns(samples: Sequence[Trial]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    pin = np.array([s.commanded_pin_deg for s in samples], dtype=np.float64)
    loaded = np.array([s.loaded_bend_deg for s in samples], dtype=np.float64)
    unloaded = np.array([s.unloaded_bend_deg for s in samples], dtype=np.float64)
    return pin, loaded, unloaded


def fit_calibration(
    samples: Sequence[Trial],
    *,
    model: SpringbackModel = "linear",
    motion_model: MotionModel = "pchip",
    name: str = "calibration",
    wire: Mapping[str, Any] | None = None,
    machine: Mapping[str, Any] | None = None,
    mode: str | None = None,
    angles_deg: Sequence[float] | None = None,
    provenance: Mapping[str, Any] | None = None,
) -> BenderCalibration:
    """Fit the compensation to calibration samples and score every springback model.

    Parameters
    ----------
    samples : sequence of Trial (or a TrialTable)
        The calibration bends (both directions, any order), each with both
        bend angles; bends with a zero loaded angle (no direction) are left out.
    model, motion_model : str
        The springback and motion models the calibration uses for compensation.
    name, wire, machine, provenance : optional
        Descriptive fields written to the file.
    mode, angles_deg : optional
        The calibration mode and its angles; inferred from the samples'
        ``target_deg`` when omitted.

    Raises
    ------
    ValueError
        Unknown model or too few angles for it.
    """
    samples = [t for t in samples if t.loaded_bend_deg != 0]
    if not samples:
        raise ValueError("no calibration samples")
    missing = [t.trial for t in samples if not t.has_pair]
    if missing:
        raise ValueError(f"trial(s) {', '.join(missing)} lack a loaded or an unloaded angle")
    comp = fit_compensation(*_columns(samples), model=model, motion_model=motion_model)
    if angles_deg is None:
        targets = sorted({s.target_deg for s in samples if s.target_deg is not None})
        angles_deg = tuple(targets)
    angles = tuple(float(a) for a in angles_deg)
    return BenderCalibration(
        samples=tuple(samples),
        compensation=comp,
        scores=_score_models(samples),
        name=name,
        wire=dict(wire or {"material": "low-carbon steel", "diameter_mm": 3.0}),
        machine=dict(machine or {"model": "DIWire v1", "controller": "TinyG v8"}),
        mode=mode or _mode_name(angles),
        angles_deg=angles,
        created_utc=_dt.datetime.now(_dt.UTC).isoformat(timespec="seconds"),
        provenance=dict(provenance or {}),
    )


def read_trials_csv(path: str | os.PathLike[str]) -> TrialTable:
    """Read a spec trials CSV for fitting: every trial needs both bend angles.

    InputError names the file and the bad line or trial.
    """
    return TrialTable.read_csv(path).pairs(path)


# ----------------------------------------------------------------------------- file I/O


def _fail(path: Any, where: str, problem: str) -> InputError:
    return InputError(path, f"{where}: {problem}")


def _need(
    d: Mapping[str, Any], key: str, kind: type | tuple[type, ...], path: Any, where: str
) -> Any:
    if key not in d:
        raise _fail(path, where, f"missing key {key!r}")
    value = d[key]
    if kind in (float, (int, float)):
        if (
            isinstance(value, bool)
            or not isinstance(value, (int, float))
            or not math.isfinite(value)
        ):
            raise _fail(path, f"{where}.{key}", f"expected a finite number, got {value!r}")
        return float(value)
    if not isinstance(value, kind):
        raise _fail(
            path,
            f"{where}.{key}",
            f"expected {getattr(kind, '__name__', kind)}, got {type(value).__name__}",
        )
    return value


def _number_list(value: Any, path: Any, where: str, *, min_len: int = 0) -> None:
    if not isinstance(value, list) or len(value) < min_len:
        raise _fail(path, where, f"expected a list of at least {min_len} numbers")
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise _fail(path, f"{where}[{i}]", f"expected a finite number, got {v!r}")


def validate_calibration_dict(d: Any, path: str | os.PathLike[str] = "<calibration>") -> None:
    """Check a calibration dictionary against the ``diwire-material/1`` schema.

    Raises
    ------
    InputError
        Naming ``path`` and the first offending key, e.g.
        ``cal.json: samples.ccw[2].loaded_bend_deg: expected a finite number``.
    """
    if not isinstance(d, dict):
        raise InputError(path, "not a calibration: expected a JSON object")
    fmt = d.get("format")
    if fmt != FORMAT:
        raise InputError(path, f"format is {fmt!r}, expected {FORMAT!r}")
    for key in ("wire", "machine", "samples", "springback", "motion"):
        _need(d, key, dict, path, "calibration")
    for section in ("wire", "machine"):
        for key, value in d[section].items():
            # the wire's and machine's numbers (diameter_mm, ...) are used as numbers
            if (
                key.endswith(("_mm", "_deg", "_mpa"))
                and value is not None
                and (
                    isinstance(value, bool)
                    or not isinstance(value, (int, float))
                    or not math.isfinite(value)
                )
            ):
                raise _fail(path, f"{section}.{key}", f"expected a number, got {value!r}")
    mode = d.get("mode", "custom")
    if mode not in (*MODES, "custom"):
        raise _fail(path, "mode", f"unknown mode {mode!r}")
    if "angles_deg" in d:
        _number_list(d["angles_deg"], path, "angles_deg")
    for direction, samples in d["samples"].items():
        if direction not in DIRECTIONS:
            raise _fail(path, f"samples.{direction}", "unknown direction (ccw or cw)")
        if not isinstance(samples, list):
            raise _fail(path, f"samples.{direction}", "expected a list")
        sign = -1.0 if direction == "cw" else 1.0
        for i, s in enumerate(samples):
            where = f"samples.{direction}[{i}]"
            if not isinstance(s, dict):
                raise _fail(path, where, "expected an object")
            for key in ("commanded_pin_deg", "loaded_bend_deg", "unloaded_bend_deg"):
                _need(s, key, float, path, where)
            if s["loaded_bend_deg"] * sign <= 0:
                raise _fail(
                    path, f"{where}.loaded_bend_deg", f"sign does not match direction {direction}"
                )
            if "springback_deg" in s:
                sb = _need(s, "springback_deg", float, path, where)
                expect = sign * (s["loaded_bend_deg"] - s["unloaded_bend_deg"])
                if abs(sb - expect) > 1e-6:
                    raise _fail(
                        path,
                        f"{where}.springback_deg",
                        f"{sb} does not equal sign(loaded) * (loaded - unloaded) = {expect:.6f}",
                    )
            unc = s.get("uncertainty_deg", {})
            if not isinstance(unc, dict):
                raise _fail(path, f"{where}.uncertainty_deg", "expected an object")
            for key, value in unc.items():
                _need(unc, key, float, path, f"{where}.uncertainty_deg")
                if value < 0:
                    raise _fail(path, f"{where}.uncertainty_deg.{key}", "negative uncertainty")
    for block, models, lists in (
        ("springback", SPRINGBACK_MODELS, ("final_deg", "loaded_deg")),
        ("motion", MOTION_MODELS, ("loaded_deg", "pin_deg")),
    ):
        curves = {k: v for k, v in d[block].items() if k in DIRECTIONS}
        if not curves:
            raise _fail(path, block, "no fitted curve for any direction")
        for direction, curve in curves.items():
            where = f"{block}.{direction}"
            if not isinstance(curve, dict):
                raise _fail(path, where, "expected an object")
            model = _need(curve, "model", str, path, where)
            if model not in models:
                raise _fail(
                    path, f"{where}.model", f"unknown model {model!r}; valid: {', '.join(models)}"
                )
            for key in lists:
                _number_list(curve.get(key), path, f"{where}.{key}", min_len=2)
            if len(curve[lists[0]]) != len(curve[lists[1]]):
                raise _fail(path, where, f"{lists[0]} and {lists[1]} differ in length")
            _number_list(curve.get("domain_deg"), path, f"{where}.domain_deg", min_len=2)
            if block == "springback":
                _number_list(curve.get("coef", []), path, f"{where}.coef")
                need = {"cubic": 4, "physical": 2}.get(model, 0)
                if len(curve.get("coef", [])) != need:
                    raise _fail(path, f"{where}.coef", f"{model} needs {need} coefficients")


def save_calibration(path: str | os.PathLike[str], calibration: BenderCalibration) -> Path:
    """Validate, then write the calibration JSON atomically; return the path."""
    d = calibration.to_dict()
    validate_calibration_dict(d, path)
    return atomic_write_json(path, d)


def load_calibration(path: str | os.PathLike[str]) -> BenderCalibration:
    """Read and validate a calibration JSON; InputError names the file and the problem."""
    d = read_json(path, what="calibration JSON")
    validate_calibration_dict(d, path)
    try:
        return BenderCalibration.from_dict(d)
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(path, f"invalid calibration: {exc}") from None
