"""``cvmeasure session``: the automatic calibration session (bend, photograph, measure, fit)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from cvmeasure.cli.options import non_negative_int, positive_float

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "session",
        help="automatic calibration session: bend, photograph, measure, write the calibration",
        description="For each calibration angle and direction: feed, bend, photograph loaded, "
        "release, photograph unloaded, measure the markers, append to the session log "
        "(<dir>/session.jsonl; a killed session resumes from it without re-bending a done "
        "angle). At the end write the calibration JSON, trials CSV and an HTML report. "
        "--simulate runs against the TinyG double on a pseudo-terminal and the simulated camera.",
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="calibration JSON to write")
    p.add_argument("--dir", type=Path, help="session folder (default: <out stem>_session/)")
    p.add_argument(
        "--simulate",
        action="store_true",
        help="the TinyG double on a pty (simulated machine) + the simulated camera",
    )
    p.add_argument("--port", help="the bender's serial port or URL (real sessions)")
    p.add_argument(
        "--camera", type=camera_url, help="camera URL: gphoto2://[port] or folder:///path"
    )
    p.add_argument(
        "--camera-setting",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="gphoto2 setting applied before the session, e.g. shutterspeed=1/125 (repeatable)",
    )
    p.add_argument(
        "--speedup",
        type=positive_float,
        default=200.0,
        help="time speed-up of the double (--simulate)",
    )
    p.add_argument(
        "--mode",
        choices=("quick", "standard", "high"),
        default="quick",
        help="quick: 10 20 45 75 110 deg; standard: 5 10 15 20 30 45 60 75 90 110 130 deg; "
        "high: standard plus 2.5 and 7.5 deg, for shallow parts (wanted loaded angles, "
        "both directions)",
    )
    p.add_argument(
        "--angles", type=angle_list, help="custom calibration angles, e.g. 2.5,5,10,20 (deg)"
    )
    p.add_argument("--model", choices=("linear", "cubic", "pchip", "physical"), default="linear")
    p.add_argument("--kit", type=Path, help="marker kit JSON (default: the built-in kit)")
    p.add_argument(
        "--flat-kit",
        action="store_true",
        help="the markers are flat stickers on the plate: the kit's heights removed",
    )
    p.add_argument("--camera-model", type=Path, help="camera JSON (lens model) for measuring")
    p.add_argument(
        "--plane",
        type=Path,
        help="plane JSON (`cvmeasure plane -o`): measure angles on the rectified marker plane "
        "(needs --camera-model)",
    )
    p.add_argument("--params", type=Path, help="sim params JSON (nominal machine; --simulate)")
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="machine effect of the simulated bender, e.g. backlash=0.5 (repeatable)",
    )
    p.add_argument("--scale", type=positive_float, default=0.25, help="render scale (--simulate)")
    p.add_argument("--seed", type=non_negative_int, default=0, help="render seed (--simulate)")
    p.add_argument("--feed-mm", type=positive_float, default=40.0, help="wire fed before each bend")
    p.add_argument("--report", type=Path, help="HTML report (default: <out stem>.html)")
    p.add_argument("--stop-after", type=non_negative_int, help=argparse.SUPPRESS)
    p.add_argument("--quiet", action="store_true", help="no progress lines")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


#: Camera URL schemes a real session can use.
CAMERA_SCHEMES = ("gphoto2://", "folder://")


def camera_url(text: str) -> str:
    """A camera URL (``gphoto2://[port]`` or ``folder:///path``), checked as it is parsed."""
    if not text.startswith(CAMERA_SCHEMES):
        lens = " (a camera JSON is the lens model: give it as --camera-model)"
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a camera URL; use gphoto2://[port] or folder:///path"
            + (lens if text.lower().endswith(".json") or Path(text).is_file() else "")
        )
    return text


def angle_list(text: str) -> tuple[float, ...]:
    """Calibration angles ``2.5,5,10`` (deg): at least 2 different, each in (0, 180)."""
    try:
        angles = tuple(float(a) for a in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a comma-separated list of numbers"
        ) from None
    if any(not 0 < a < 180 for a in angles):
        raise argparse.ArgumentTypeError(f"angles must be in (0, 180) deg, got {text!r}")
    if len(set(angles)) < 2:
        raise argparse.ArgumentTypeError(
            f"a calibration needs at least 2 different angles, got {text!r}"
        )
    return angles


def _check_camera_option(args: argparse.Namespace) -> None:
    """Refuse --camera with --simulate (the simulated camera takes the photos); a camera
    JSON given as --camera is refused as it is parsed (:func:`camera_url`)."""
    from cvmeasure.errors import InputError

    if args.camera is not None and args.simulate:
        raise InputError(
            "--camera",
            "--simulate photographs with the simulated camera: give no --camera (a lens "
            "model JSON is --camera-model)",
        )


def _check_options(args: argparse.Namespace) -> None:
    """Options that are wrong together (each is fine alone)."""
    from cvmeasure.errors import InputError

    if args.simulate and args.port:
        raise InputError("--port", "--simulate uses the TinyG double; drop --port")
    if args.plane and not args.camera_model:
        raise InputError(
            "--plane", "a plane JSON needs the camera it was measured with (--camera-model)"
        )


def _measure_inputs(args: argparse.Namespace) -> tuple[object, dict[str, object]]:
    """The kit (or None for the built-in one) and the measurement options (camera, plane)."""
    from cvmeasure.camera_model import load_camera
    from cvmeasure.contracts import PlaneModel
    from cvmeasure.kit import default_kit, load_kit

    kit = load_kit(args.kit) if args.kit else None
    if args.flat_kit:
        kit = (kit or default_kit()).flat()
    options: dict[str, object] = {}
    if args.camera_model:
        options["camera"] = load_camera(args.camera_model)
    if args.plane:
        options["plane"] = PlaneModel.load(args.plane, camera=options.get("camera"))
    return kit, options


def _machine_description(args: argparse.Namespace) -> tuple[object, tuple[object, ...]]:
    """The simulated machine's params and hidden effects (None, () when not given)."""
    from cvmeasure.errors import InputError
    from cvmeasure.sim import SimParams, params_from_json, parse_effect
    from cvmeasure.sim.effects import check_effect_bounds

    if not (args.params or args.effect):
        return None, ()
    params, effects = params_from_json(args.params) if args.params else (SimParams(), ())
    try:
        effects = tuple(effects) + tuple(parse_effect(t) for t in args.effect)
        check_effect_bounds(effects, params)  # a sized effect's bounds are the machine's
    except ValueError as exc:
        raise InputError("--effect", str(exc)) from None
    return params, effects


def _open_machine_and_camera(
    args: argparse.Namespace, session_dir: Path, params: object, effects: tuple[object, ...]
) -> tuple[object, object]:
    """The bender and the camera: the TinyG double + simulated camera, or the real ones."""
    from cvmeasure.driver.capture import open_capture
    from cvmeasure.driver.session import StreamedBender
    from cvmeasure.driver.transport import open_link
    from cvmeasure.errors import InputError

    if args.simulate:
        from cvmeasure.testing.bender import simulated_bender
        from cvmeasure_datasets.simcapture import SimulatedCapture, double_photo_state

        machine = simulated_bender(params=params, effects=effects, speedup=args.speedup)
        double = machine.double
        camera = SimulatedCapture(
            session_dir / "photos",
            lambda: double_photo_state(double, params),
            scale=args.scale,
            seed=args.seed,
        )
        return machine, camera
    if not (args.port and args.camera):
        raise InputError("--port", "a real session needs --port URL and --camera URL")
    options_cam = {}
    if args.camera_setting and not args.camera.startswith("gphoto2:"):
        raise InputError("--camera-setting", "settings apply to gphoto2:// cameras only")
    if args.camera_setting:
        pairs = [t.partition("=") for t in args.camera_setting]
        if any(not sep or not name for name, sep, _ in pairs):
            raise InputError("--camera-setting", "expected NAME=VALUE")
        options_cam["settings"] = {name: value for name, _, value in pairs}
    camera = open_capture(args.camera, session_dir / "photos", **options_cam)
    return StreamedBender(open_link(args.port)), camera


def _progress_printer(quiet: bool):
    """A ``progress(done, total, step)`` callback printing one line per bend to stderr."""

    def progress(done: int, total: int, step) -> None:
        if quiet:
            return
        codes = sorted({w.code for _, w in step.photo_warnings()})
        print(
            f"[{done:2d}/{total}] {step.direction:3s} {step.target_deg:6.1f} deg: "
            f"loaded {step.loaded.bend_angle_deg:8.3f}  unloaded "
            f"{step.unloaded.bend_angle_deg:8.3f}  springback {step.springback_deg:6.3f} deg"
            + (f"  ! {', '.join(codes)}" if codes else ""),
            file=sys.stderr,
            flush=True,
        )

    return progress


def _write_outputs(args: argparse.Namespace, result, session_dir: Path) -> dict[str, object]:
    """Write the calibration JSON, trials CSV and HTML report; return the JSON summary."""
    from dataclasses import replace

    from cvmeasure.contracts import TrialTable
    from cvmeasure.driver.session_report import write_session_report
    from cvmeasure.material.bender_calibration import save_calibration
    from cvmeasure.provenance import provenance

    calibration = result.calibration
    calibration = replace(calibration, provenance={**provenance(), **calibration.provenance})
    save_calibration(args.out, calibration)
    trials_path = session_dir / "trials.csv"
    TrialTable(calibration.samples).write_csv(trials_path)
    report = args.report or args.out.with_suffix(".html")
    write_session_report(report, calibration, result.steps, session_dir=session_dir)
    return {
        "out": str(args.out),
        "report": str(report),
        "log": str(result.log_path),
        "trials": str(trials_path),
        "resumed": result.resumed,
        "bent_this_run": len(result.bent_this_run),
        "bends": len(result.steps),
        "model": calibration.model,
        "scores": calibration.scores,
        "warnings": calibration.provenance.get("warnings", []),
    }


def _print_summary(
    args: argparse.Namespace, result, summary: dict[str, object], session_dir: Path
) -> None:
    """The JSON summary or the human lines, then the warning summary of every photo."""
    from cvmeasure.report.console import warning_summary

    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        if result.resumed:
            print(
                f"resumed {session_dir} from its log: "
                f"{len(result.steps) - len(result.bent_this_run)} bends already done, "
                f"{len(result.bent_this_run)} bent this run"
            )
        print(
            f"wrote {summary['out']}, {summary['report']} ({len(result.steps)} bends, "
            f"model {summary['model']})"
        )
    lines = warning_summary(
        [pw for s in result.steps for pw in s.photo_warnings()], n_photos=2 * len(result.steps)
    )
    for line in lines:
        print(line, file=sys.stderr if args.json else sys.stdout)


def run(args: argparse.Namespace) -> int:
    from cvmeasure.driver.session import SessionConfig, SessionInterrupted, run_session

    _check_camera_option(args)
    _check_options(args)
    session_dir = args.dir or args.out.with_name(args.out.stem + "_session")
    angles = args.angles or ()
    config = SessionConfig(
        mode="custom" if angles else args.mode, angles_deg=angles, feed_mm=args.feed_mm
    )
    kit, options = _measure_inputs(args)
    params, effects = _machine_description(args)
    machine, camera = _open_machine_and_camera(args, session_dir, params, effects)
    try:
        result = run_session(
            machine,
            camera,
            session_dir,
            config=config,
            kit=kit,
            measure_options=options,
            model=args.model,
            params=params,
            name=args.out.stem,
            progress=_progress_printer(args.quiet),
            stop_after=args.stop_after,
        )
    except SessionInterrupted as exc:
        print(f"cvmeasure session: {exc}; resume with the same command", file=sys.stderr)
        return 3
    finally:
        camera.close()
        machine.close()
    _print_summary(args, result, _write_outputs(args, result, session_dir), session_dir)
    return 0
