"""The HTTP app: pages, an OctoPrint-shaped JSON API, Server-Sent Events, the camera stream.

The pages use only the ``/api`` routes (documented by FastAPI's OpenAPI schema at
``/openapi.json`` and ``/docs``). Commands (POST) need the browser to control the machine:
the first browser that acts takes control; the others watch until one of them takes it over
(``POST /api/control``). A refused command is HTTP 409 with ``{"error": "..."}``; bad input
is HTTP 400 with the file or option named.
"""

from __future__ import annotations

import asyncio
import json
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from fastapi import FastAPI, File, Request, UploadFile
from fastapi.responses import (
    FileResponse,
    HTMLResponse,
    JSONResponse,
    Response,
    StreamingResponse,
)
from fastapi.staticfiles import StaticFiles
from jinja2 import Environment, FileSystemLoader, select_autoescape
from pydantic import BaseModel

from cvmeasure.app.charts import control_chart_svg, springback_svg
from cvmeasure.app.hops import hops_routes
from cvmeasure.app.operator import Operator
from cvmeasure.app.state import Busy
from cvmeasure.errors import CvmeasureError, InputError
from cvmeasure.fileio import to_jsonable

__all__ = ["create_app", "PAGES"]

HERE = Path(__file__).parent
#: Page slug -> title, in the order of the navigation bar.
PAGES = {"setup": "Set up", "material": "Calibrate material", "bend": "Bend", "inspect": "Inspect"}
CLIENT_COOKIE = "cvm_client"
#: Live view frame rate (frames per second) and width (px).
LIVE_FPS = 8.0


class Command(BaseModel):
    """A command to an API resource (OctoPrint's shape: ``{"command": ..., ...}``)."""

    command: str
    action: str | None = None
    port: str | None = None
    camera: str | None = None
    mode: str | None = None
    angles: list[float] | None = None
    design: str | None = None
    quantity: int | None = None
    item: str | None = None
    tolerance_deg: float | None = None
    after_lines: int | None = None


#: Raises :class:`Busy` unless the request comes from the controlling browser.
Controller = Callable[[Request], None]


def _error(status: int, message: str) -> JSONResponse:
    return JSONResponse({"error": message}, status_code=status)


def create_app(op: Operator) -> FastAPI:
    """The FastAPI app over one :class:`Operator`."""
    app = FastAPI(
        title="cvmeasure operator app",
        description="Set up, calibrate material, bend and inspect wire parts.",
        version="1",
    )
    app.state.op = op
    app.mount("/static", StaticFiles(directory=HERE / "static"), name="static")

    _error_handlers(app)
    controller = _controller(op)
    _page_routes(app, op)
    _state_routes(app, op)
    _machine_routes(app, op, controller)
    _camera_routes(app, op, controller)
    _material_routes(app, op, controller)
    _job_routes(app, op, controller)
    _inspect_routes(app, op, controller)
    if op.simulate:

        @app.get("/api/sim/bends", summary="Simulation only: every bend the double executed")
        async def sim_bends() -> dict[str, Any]:
            return {"bends": op.need_rig().truth()}

    hops_routes(app, op)
    return app


def _error_handlers(app: FastAPI) -> None:
    """Bad input is 400, a state or control conflict 409, a device failure 500."""

    @app.exception_handler(InputError)
    async def _bad_input(request: Request, exc: InputError) -> JSONResponse:
        return _error(400, str(exc))

    @app.exception_handler(Busy)
    async def _busy(request: Request, exc: Busy) -> JSONResponse:
        return _error(409, str(exc))

    @app.exception_handler(CvmeasureError)
    async def _failed(request: Request, exc: CvmeasureError) -> JSONResponse:
        return _error(500, str(exc))


def _controller(op: Operator) -> Controller:
    """The check every command makes: does this browser control the machine?"""

    def controller(request: Request) -> None:
        client = request.cookies.get(CLIENT_COOKIE) or request.headers.get("X-Client-Id")
        if not op.control.allows(client):
            raise Busy("another browser controls the machine: this one watches (take control)")

    return controller


def _page_routes(app: FastAPI, op: Operator) -> None:
    """Routes: pages."""
    env = Environment(loader=FileSystemLoader(HERE / "templates"), autoescape=select_autoescape())

    def page(slug: str, request: Request) -> HTMLResponse:
        client = request.cookies.get(CLIENT_COOKIE) or uuid.uuid4().hex
        html = env.get_template(f"{slug}.html").render(
            pages=PAGES, slug=slug, title=PAGES[slug], simulate=op.simulate,
            state=json.dumps(to_jsonable(op.snapshot())),
        )  # fmt: skip
        resp = HTMLResponse(html)
        resp.set_cookie(CLIENT_COOKIE, client, samesite="strict")
        return resp

    @app.get("/", include_in_schema=False)
    async def index(request: Request) -> HTMLResponse:
        return page("setup", request)

    @app.get("/ui/{slug}", include_in_schema=False)
    async def ui(slug: str, request: Request) -> Response:
        if slug not in PAGES:
            return _error(404, f"no page {slug!r}")
        return page(slug, request)


def _state_routes(app: FastAPI, op: Operator) -> None:
    """Routes: state, control, events."""

    @app.get("/api/state", summary="The whole server state, by section")
    async def state() -> dict[str, Any]:
        return op.snapshot()

    @app.get("/api/control", summary="Who controls the machine")
    async def get_control(request: Request) -> dict[str, Any]:
        client = request.cookies.get(CLIENT_COOKIE) or request.headers.get("X-Client-Id")
        holder = op.control.holder
        return {"held": holder is not None, "you": holder is not None and holder == client}

    @app.post("/api/control", summary="Take control of the machine (the others watch)")
    async def take_control(request: Request) -> dict[str, Any]:
        client = request.cookies.get(CLIENT_COOKIE) or request.headers.get("X-Client-Id")
        if not client:
            raise InputError("client", "no client id (cookie cvm_client or X-Client-Id)")
        op.control.take(client)
        op.bus.publish("control", {"holder_changed": True})
        return {"held": True, "you": True}

    @app.get("/api/events", summary="Server-Sent Events: one event per changed state section")
    async def events(request: Request) -> StreamingResponse:
        number = op.bus.parse_last_id(request.headers.get("last-event-id"))

        async def stream():
            last = op.bus.last_number()
            yield "retry: 1000\n\n"
            if number is None:  # a new client or another boot: the whole state first
                for name, data in op.snapshot().items():
                    yield _sse(f"{op.bus.boot}-{last}", name, data)
            else:
                last = number
            quiet = time.monotonic()
            while not await request.is_disconnected():
                evs = op.bus.since(last)
                for n, ev in evs:
                    last = n
                    yield _sse(ev.id, ev.kind, ev.data)
                if evs:
                    quiet = time.monotonic()
                elif time.monotonic() - quiet > 10:
                    quiet = time.monotonic()
                    yield ": keep-alive\n\n"
                await asyncio.sleep(0.05)

        return StreamingResponse(
            stream(), media_type="text/event-stream", headers={"Cache-Control": "no-store"}
        )


def _machine_routes(app: FastAPI, op: Operator, controller: Controller) -> None:
    """Routes: connection, machine."""

    @app.get("/api/connection", summary="Bender and camera connection (OctoPrint: connection)")
    async def connection() -> dict[str, Any]:
        return {
            "current": op.state.section("connection"),
            "options": {"ports": ["sim://"] if op.simulate else [], "simulate": op.simulate},
        }

    @app.post("/api/connection", status_code=204, summary="connect {port, camera} | disconnect")
    async def post_connection(cmd: Command, request: Request) -> Response:
        controller(request)
        if cmd.command == "connect":
            await asyncio.to_thread(op.connect, cmd.port or "", cmd.camera or "")
        elif cmd.command == "disconnect":
            await asyncio.to_thread(op.disconnect)
        elif cmd.command == "reconnect":
            await asyncio.to_thread(op.reconnect)
        elif cmd.command == "lose" and op.simulate:  # the simulated serial loss
            op.need_rig().lose_link(cmd.after_lines or 3)
        else:
            raise InputError("command", f"unknown connection command {cmd.command!r}")
        return Response(status_code=204)

    @app.get("/api/machine", summary="Machine state flags (OctoPrint: printer)")
    async def machine() -> dict[str, Any]:
        c, j, m = op.state.connection, op.state.job, op.state.material
        busy = j.status in ("bending", "paused") or m.status in ("running", "pausing", "paused")
        return {
            "state": {
                "operational": c.state == "operational",
                "bending": busy,
                "paused": "paused" in (j.status, m.status),
                "error": c.state == "lost",
                "ready": c.state == "operational" and not busy,
            },
            "connection": c.state,
        }


def _camera_routes(app: FastAPI, op: Operator, controller: Controller) -> None:
    """Routes: camera and set up."""

    @app.get("/api/camera", summary="Lens calibration, plane check and kit check")
    async def camera() -> dict[str, Any]:
        return {k: op.state.section(k) for k in ("lens", "plane", "kit")}

    @app.post("/api/camera", status_code=202, summary="view | solve | plane | kit")
    async def post_camera(cmd: Command, request: Request) -> Response:
        controller(request)
        actions = {
            "view": op.take_lens_view,
            "solve": op.solve_lens,
            "plane": op.check_plane,
            "kit": op.check_kit,
        }
        if cmd.command not in actions:
            raise InputError("command", f"unknown camera command {cmd.command!r}")
        await asyncio.to_thread(actions[cmd.command])
        return Response(status_code=202)

    @app.get("/api/camera/stream.mjpg", summary="Live view (MJPEG) with the markers drawn")
    async def stream_mjpg(width: int = 1280) -> StreamingResponse:
        width = max(320, min(int(width), 1920))
        return StreamingResponse(
            _mjpeg(op, width), media_type="multipart/x-mixed-replace; boundary=frame"
        )


def _material_routes(app: FastAPI, op: Operator, controller: Controller) -> None:
    """Routes: material."""

    @app.get("/api/material", summary="The material session: plan, bends, result")
    async def material() -> dict[str, Any]:
        return op.state.section("material")

    @app.post(
        "/api/material",
        status_code=202,
        summary="start | pause | resume | stop | continue | discard",
    )
    async def post_material(cmd: Command, request: Request) -> Response:
        controller(request)
        m = op.material
        if cmd.command == "start":
            await asyncio.to_thread(m.start, cmd.mode or "quick", list(cmd.angles or []))
        elif cmd.command in ("pause", "resume", "stop", "discard"):
            getattr(m, cmd.command)()
        elif cmd.command == "continue":
            await asyncio.to_thread(m.resume_session)
        else:
            raise InputError("command", f"unknown material command {cmd.command!r}")
        return Response(status_code=202)

    @app.get(
        "/api/material/curve.svg", summary="Springback against the loaded angle, per direction"
    )
    async def curve() -> Response:
        return Response(springback_svg(op.state.material.steps), media_type="image/svg+xml")

    @app.get("/api/material/photo/{name}", summary="A session photo")
    async def session_photo(name: str) -> Response:
        path = op.material.folder / "photos" / Path(name).name
        if not path.is_file():
            return _error(404, f"no photo {name!r}")
        return FileResponse(path)

    @app.get("/api/material/follow_up.csv", summary="The diagnosis's follow-up plan")
    async def follow_up() -> Response:
        path = op.material.folder / "follow_up.csv"
        if not path.is_file():
            return _error(404, "no follow-up plan: the diagnosis needs none")
        return FileResponse(path, media_type="text/csv", filename="follow_up.csv")

    @app.get("/api/material/calibration.json", summary="The current material calibration")
    async def calibration_file() -> Response:
        if not op.calibration_path.is_file():
            return _error(404, "no calibration yet")
        return FileResponse(op.calibration_path, media_type="application/json")


def _job_routes(app: FastAPI, op: Operator, controller: Controller) -> None:
    """Routes: files, queue, job."""

    @app.get("/api/files", summary="Uploaded designs with their bends and compensated pin angles")
    async def files() -> dict[str, Any]:
        return {"files": op.state.section("files")}

    @app.post("/api/files", status_code=201, summary="Upload a design (.svg or .dxf)")
    async def upload(request: Request, file: UploadFile = File(...)) -> dict[str, Any]:  # noqa: B008
        controller(request)
        data = await file.read()
        design = await asyncio.to_thread(op.bending.upload, file.filename or "", data)
        return {"name": design.name, "bends": design.bends}

    @app.get("/api/queue", summary="The queue: designs with quantities")
    async def queue() -> dict[str, Any]:
        return {"queue": op.state.section("queue")}

    @app.post("/api/queue", summary="add {design, quantity} | remove {item}")
    async def post_queue(cmd: Command, request: Request) -> dict[str, Any]:
        controller(request)
        if cmd.command == "add":
            item = op.bending.add(cmd.design or "", int(cmd.quantity or 1))
            return {"item": item.id}
        if cmd.command == "remove":
            op.bending.remove(cmd.item or "")
            return {}
        raise InputError("command", f"unknown queue command {cmd.command!r}")

    @app.get(
        "/api/job", summary="The job: progress as bends done / total, time left (OctoPrint: job)"
    )
    async def job() -> dict[str, Any]:
        j = op.state.job
        total = j.bends_total or 0
        return {
            "job": {"design": j.design, "part": j.part, "quantity": j.quantity},
            "progress": {
                "completion": (100.0 * j.bends_done / total) if total else None,
                "bends_done": j.bends_done,
                "bends_total": total,
                "elapsed_s": j.elapsed_s,
                "time_left_s": j.time_left_s,
                "time_left_from": j.time_left_from,
            },
            "state": j.status,
            "message": j.message,
        }

    @app.post("/api/job", status_code=204, summary="start | pause {action} | cancel | continue")
    async def post_job(cmd: Command, request: Request) -> Response:
        controller(request)
        b = op.bending
        if cmd.command == "start":
            await asyncio.to_thread(b.start)
        elif cmd.command == "pause":
            action = cmd.action or "toggle"
            if action == "toggle":
                action = "resume" if op.state.job.status == "paused" else "pause"
            (b.pause if action == "pause" else b.resume)()
        elif cmd.command == "cancel":
            b.cancel()
        elif cmd.command == "continue":
            await asyncio.to_thread(b.continue_part)
        else:
            raise InputError("command", f"unknown job command {cmd.command!r}")
        return Response(status_code=204)


def _inspect_routes(app: FastAPI, op: Operator, controller: Controller) -> None:
    """Routes: inspect."""

    @app.get("/api/inspect", summary="The last inspected part: deviations, PASS/FAIL")
    async def inspect() -> dict[str, Any]:
        return op.state.section("inspect")

    @app.post("/api/inspect", status_code=202, summary="photograph {tolerance_deg} | correct")
    async def post_inspect(cmd: Command, request: Request) -> Response:
        controller(request)
        if cmd.command == "photograph":
            op.bending.inspect(cmd.tolerance_deg or op.state.inspect.tolerance_deg)
        elif cmd.command == "correct":
            await asyncio.to_thread(op.bending.correct)
        else:
            raise InputError("command", f"unknown inspect command {cmd.command!r}")
        return Response(status_code=202)

    @app.get("/api/inspect/overlay.jpg", summary="The part photo with the design's deviations")
    async def overlay() -> Response:
        path = op.folder / "inspect" / "overlay.jpg"
        if not path.is_file():
            return _error(404, "no part inspected yet")
        return FileResponse(path, headers={"Cache-Control": "no-store"})

    @app.get("/api/inspect/chart.svg", summary="Control chart: worst vertex error per part")
    async def chart() -> Response:
        ins = op.state.inspect
        return Response(
            control_chart_svg(ins.history, ins.tolerance_deg), media_type="image/svg+xml"
        )


def _sse(event_id: str, kind: str, data: Any) -> str:
    return f"id: {event_id}\nevent: {kind}\ndata: {json.dumps(to_jsonable(data))}\n\n"


async def _mjpeg(op: Operator, width: int):
    """Frames at :data:`LIVE_FPS`: the rig's live frame, the time stamped on it."""

    period = 1.0 / LIVE_FPS
    while True:
        t0 = time.monotonic()
        rig = op.rig
        frame = None if rig is None else await asyncio.to_thread(rig.live_frame, width)
        if frame is None:
            frame = np.full((int(width * 2 / 3), width, 3), 40, np.uint8)
            cv2.putText(frame, "no camera connected", (30, 60), cv2.FONT_HERSHEY_SIMPLEX, 1.2,
                        (220, 220, 220), 2)  # fmt: skip
        else:
            frame = frame.copy()
        stamp = time.strftime("%H:%M:%S") + f".{int(time.time() * 10) % 10}"
        cv2.putText(frame, stamp, (10, frame.shape[0] - 12), cv2.FONT_HERSHEY_SIMPLEX, 0.6,
                    (255, 255, 255), 1, cv2.LINE_AA)  # fmt: skip
        ok, jpg = cv2.imencode(".jpg", frame, [cv2.IMWRITE_JPEG_QUALITY, 80])
        if ok:
            data = jpg.tobytes()
            yield (
                b"--frame\r\nContent-Type: image/jpeg\r\nContent-Length: "
                + str(len(data)).encode()
                + b"\r\n\r\n"
                + data
                + b"\r\n"
            )
        await asyncio.sleep(max(0.0, period - (time.monotonic() - t0)))
