"""``cvmeasure ui``: the operator's local web app (Set up, Calibrate material, Bend, Inspect)."""

from __future__ import annotations

import argparse
import socket
from pathlib import Path

from cvmeasure.cli.options import int_in, positive_float

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "ui",
        help="the operator's web app beside the bender (and Grasshopper Hops endpoints)",
        description="Serve the operator's app on http://HOST:PORT/: set up the camera and the "
        "bender, calibrate the material, bend designs from a queue, inspect and correct parts. "
        "The JSON API is under /api (schema at /openapi.json), Grasshopper Hops under /hops. "
        "The workspace folder (--dir) keeps the session log, job journals and queue: a restarted "
        "app continues from them. --simulate runs against the TinyG double and the simulated "
        "camera. Needs the [app] extra (pip install 'cvmeasure[app]').",
    )
    p.add_argument("--port", type=int_in(1, 65535), default=8080, help="TCP port (default 8080)")
    p.add_argument("--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)")
    p.add_argument("--dir", type=Path, default=Path("cvmeasure-app"), help="workspace folder")
    p.add_argument("--simulate", action="store_true", help="the TinyG double + simulated camera")
    p.add_argument(
        "--scale", type=positive_float, default=0.25, help="render scale of simulated photos"
    )
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="a machine effect the simulated bender has and the app must find, e.g. "
        "backlash=0.5 (repeatable; --simulate)",
    )
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.errors import InputError

    # the options first (a bad one answers at once), then the web stack and the app
    if args.dir.exists() and not args.dir.is_dir():
        raise InputError(args.dir, "--dir must be a folder")
    if args.effect and not args.simulate:
        raise InputError("--effect", "machine effects are for the simulated bender (--simulate)")
    with socket.socket() as probe:  # a port in use is the operator's to fix: say so, exit 2
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)  # as uvicorn binds
        try:
            probe.bind((args.host, args.port))
        except OSError as exc:
            raise InputError(
                "--port", f"cannot listen on {args.host}:{args.port}: {exc.strerror}"
            ) from None
    try:
        import uvicorn

        from cvmeasure.app.operator import Operator
        from cvmeasure.app.server import create_app
    except ImportError as exc:
        raise InputError(
            "cvmeasure ui", f"{exc.name} is missing: pip install 'cvmeasure[app]'"
        ) from None
    simulated = None
    if args.simulate:
        from cvmeasure.sim import parse_effect
        from cvmeasure.sim.effects import check_effect_bounds
        from cvmeasure_datasets.simrig import SimRig

        try:
            effects = tuple(parse_effect(t) for t in args.effect)
            check_effect_bounds(effects, None)  # the rig simulates the built-in machine
        except ValueError as exc:
            raise InputError("--effect", str(exc)) from None

        def simulated() -> SimRig:
            return SimRig(scale=args.scale, effects=effects)

    op = Operator(args.dir, simulated=simulated)
    print(f"cvmeasure ui: http://{args.host}:{args.port}/ (workspace {args.dir})", flush=True)
    uvicorn.run(
        create_app(op),
        host=args.host,
        port=args.port,
        log_level="warning",
        timeout_graceful_shutdown=1,  # open event streams must not hold a stop up
    )
    return 0
