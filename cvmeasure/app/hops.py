"""Grasshopper's Hops protocol, served by the app under ``/hops``.

The routes follow the ``ghhops-server`` package's protocol: ``GET /hops`` lists the
components, ``GET /hops/<name>`` describes one (inputs and outputs), ``POST /hops/solve``
(or ``POST /hops/<name>``) with ``{"pointer": "<name>", "values": [{"ParamName": ...,
"InnerTree": {"0": [{"type": "System.Double", "data": "45.0"}]}}]}`` computes and answers
``{"values": [...], "errors": [...]}`` in the same tree form. Every ``data`` is a JSON text
(a number ``"45.0"``, a string ``"\\"text\\""``, a point ``{"X": .., "Y": .., "Z": ..}``).
Polylines travel as lists of points, so no geometry library is needed on either side.
"""

from __future__ import annotations

import asyncio
import json
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse

from cvmeasure.app import adapter
from cvmeasure.errors import CvmeasureError

if TYPE_CHECKING:
    from cvmeasure.app.operator import Operator

__all__ = ["HopsParam", "HopsComponent", "hops_routes", "components"]

_TYPES = {
    "Number": "System.Double",
    "Text": "System.String",
    "Point": "Rhino.Geometry.Point3d",
    "Boolean": "System.Boolean",
}
_LIST_MAX = 2147483647


@dataclass(frozen=True)
class HopsParam:
    name: str
    kind: str  # Number, Text, Point, Boolean
    description: str
    many: bool = False
    optional: bool = False

    def encode(self) -> dict[str, Any]:
        return {
            "Name": self.name,
            "Nickname": self.name,
            "Description": self.description,
            "ParamType": self.kind,
            "ResultType": _TYPES[self.kind],
            "AtLeast": 0 if self.optional else 1,
            "AtMost": _LIST_MAX if self.many else 1,
        }

    def decode(self, items: list[dict[str, Any]]) -> Any:
        values = [_decode(self.kind, item.get("data")) for item in items]
        return values if self.many else (values[0] if values else None)

    def output(self, value: Any) -> dict[str, Any]:
        values = value if self.many else [value]
        return {
            "ParamName": self.name,
            "InnerTree": {
                "0": [{"type": _TYPES[self.kind], "data": _encode(self.kind, v)} for v in values]
            },
        }


def _decode(kind: str, data: Any) -> Any:
    value = json.loads(data) if isinstance(data, str) else data
    if kind == "Point":
        return (float(value["X"]), float(value["Y"]), float(value.get("Z", 0.0)))
    if kind == "Number":
        return float(value)
    if kind == "Boolean":
        return bool(value)
    return str(value)


def _encode(kind: str, value: Any) -> str:
    if kind == "Point":
        x, y = float(value[0]), float(value[1])
        return json.dumps({"X": x, "Y": y, "Z": 0.0})
    if kind == "Number":
        return json.dumps(float(value))
    if kind == "Boolean":
        return json.dumps(bool(value))
    return json.dumps(str(value))


@dataclass(frozen=True)
class HopsComponent:
    name: str
    description: str
    inputs: tuple[HopsParam, ...]
    outputs: tuple[HopsParam, ...]
    solve: Callable[..., tuple[Any, ...]]

    def encode(self) -> dict[str, Any]:
        return {
            "Uri": f"/{self.name}",
            "Name": self.name,
            "Nickname": self.name,
            "Description": self.description,
            "Category": "cvmeasure",
            "Subcategory": "wire bending",
            "Inputs": [p.encode() for p in self.inputs],
            "Outputs": [p.encode() for p in self.outputs],
        }


def components(op: Operator) -> dict[str, HopsComponent]:
    """The app's Hops components (they read the current calibration and the last part)."""

    def pin_angles(points: list[tuple[float, float, float]]) -> tuple[Any, ...]:
        if not points or len(points) < 3:
            raise ValueError("Points: give the polyline's vertices (at least 3 points)")
        pts = np.asarray([p[:2] for p in points], dtype=float)
        d = adapter.check_points(pts, op.calibration(), name="Grasshopper polyline")
        return list(d.pin_deg), list(d.bends_deg), d.gcode

    def springback(angle: float) -> tuple[Any, ...]:
        pin, spring = adapter.springback_for(op.calibration(), float(angle))
        return pin, spring

    def last_part(refresh: bool | None = None) -> tuple[Any, ...]:
        ins = op.state.inspect
        check = op.bending.last_check
        if check is None or check.vertices_mm is None:
            raise ValueError("no part measured yet: inspect a part in the app first")
        pts = [tuple(v) for v in np.asarray(check.vertices_mm)]
        return pts, list(check.error_deg), ins.verdict

    return {
        c.name: c
        for c in (
            HopsComponent(
                "pin_angles",
                "Compensated pin angles and TinyG G-code for a polyline (mm), current calibration",
                (HopsParam("Points", "Point", "the polyline's vertices, mm", many=True),),
                (
                    HopsParam("PinAngles", "Number", "pin command per bend, deg", many=True),
                    HopsParam("Bends", "Number", "design bend per vertex, deg", many=True),
                    HopsParam("GCode", "Text", "the job, TinyG G-code"),
                ),
                pin_angles,
            ),
            HopsComponent(
                "springback",
                "Pin command and springback for a wanted final bend angle (deg, signed)",
                (HopsParam("Angle", "Number", "wanted final bend angle, deg"),),
                (
                    HopsParam("Pin", "Number", "pin command, deg"),
                    HopsParam("Springback", "Number", "springback, deg"),
                ),
                springback,
            ),
            HopsComponent(
                "last_part",
                "The last measured part: its vertices (board frame, mm) and per-vertex bend errors",
                (HopsParam("Refresh", "Boolean", "any value: asks again", optional=True),),
                (
                    HopsParam("Points", "Point", "measured vertices, mm", many=True),
                    HopsParam("Deviations", "Number", "bend error per vertex, deg", many=True),
                    HopsParam("Verdict", "Text", "PASS/FAIL and the worst vertex"),
                ),
                last_part,
            ),
        )
    }


def _solve(comp: HopsComponent, payload: dict[str, Any]) -> JSONResponse:
    given = {v.get("ParamName"): v for v in payload.get("values", []) if isinstance(v, dict)}
    args = []
    for p in comp.inputs:
        tree = given.get(p.name, {}).get("InnerTree", {})
        items = next(iter(tree.values()), []) if tree else []
        if not items and not p.optional:
            return JSONResponse({"values": [], "errors": [f"missing input {p.name}"]}, 400)
        args.append(p.decode(items) if items else None)
    try:
        result = comp.solve(*args)
    except (ValueError, CvmeasureError) as exc:
        return JSONResponse({"values": [], "errors": [str(exc)]}, 400)
    return JSONResponse(
        {"values": [p.output(v) for p, v in zip(comp.outputs, result, strict=True)]}
    )


def hops_routes(app: FastAPI, op: Operator) -> None:
    """Add ``/hops``, ``/hops/<name>`` and ``/hops/solve`` to the app."""
    comps = components(op)

    @app.get("/hops", summary="Hops: the components")
    async def hops_list() -> list[dict[str, Any]]:
        return [c.encode() for c in comps.values()]

    @app.get("/hops/{name}", summary="Hops: one component's inputs and outputs")
    async def hops_describe(name: str) -> JSONResponse:
        comp = comps.get(name)
        if comp is None:
            return JSONResponse({"values": [], "errors": [f"unknown Hops component {name!r}"]}, 404)
        return JSONResponse(comp.encode())

    @app.post(
        "/hops/{name}", summary="Hops: solve (POST /hops/solve with pointer, or /hops/<name>)"
    )
    async def hops_solve(name: str, request: Request) -> JSONResponse:
        try:
            payload = await request.json()
        except ValueError:
            return JSONResponse({"values": [], "errors": ["the body is not JSON"]}, 400)
        pointer = str(payload.get("pointer", "")).strip("/") if name == "solve" else name
        pointer = pointer.rsplit("/", 1)[-1]
        comp = comps.get(pointer)
        if comp is None:
            return JSONResponse(
                {"values": [], "errors": [f"unknown Hops component {pointer!r}"]}, 404
            )

        return await asyncio.to_thread(_solve, comp, payload)
