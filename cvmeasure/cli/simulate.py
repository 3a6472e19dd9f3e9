"""``cvmeasure simulate``: the forward model on a plan of pin commands."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from cvmeasure.cli.options import non_negative_float, non_negative_int

__all__ = ["register", "run", "SIMULATE_COLUMNS"]

#: Columns of the simulate output CSV (spec).
SIMULATE_COLUMNS: tuple[str, ...] = (
    "trial",
    "commanded_pin_deg",
    "pin_deg",
    "loaded_bend_deg",
    "unloaded_bend_deg",
    "springback_deg",
)


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate bends (pin command -> loaded and unloaded bend angle)",
        description="Read a plan CSV (trial, commanded_pin_deg; rows in the order executed), "
        "simulate the bender and wire described by the params JSON (defaults: 3 mm "
        "low-carbon steel, DIWire-like head) with any effects switched on, and write "
        "trial, commanded_pin_deg, pin_deg, loaded_bend_deg, unloaded_bend_deg, "
        "springback_deg.",
    )
    p.add_argument("plan", type=Path, help="plan CSV with columns trial, commanded_pin_deg")
    p.add_argument("--params", type=Path, help="params JSON (may carry an effects list)")
    p.add_argument(
        "--effect",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help="switch an effect on, e.g. backlash=1.2 (repeatable; names: backlash, offset, "
        "scale, drift, springback_asymmetry, camera_tilt, axis_offset, compliance)",
    )
    p.add_argument(
        "--noise-deg",
        type=non_negative_float,
        default=0.0,
        metavar="SIGMA",
        help="add Gaussian noise of this standard deviation (deg) to the loaded and unloaded "
        "angles, as a measurement would (default 0: exact)",
    )
    p.add_argument(
        "--seed", type=non_negative_int, default=0, help="random seed of the noise (default 0)"
    )
    p.add_argument("-o", "--out", type=Path, required=True, help="output CSV")
    p.add_argument("--json", action="store_true", help="print a JSON summary")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from cvmeasure.errors import InputError
    from cvmeasure.fileio import read_csv_rows, write_csv_rows
    from cvmeasure.sim import SimParams, params_from_json, parse_effect, simulate
    from cvmeasure.sim.model import add_noise

    rows = read_csv_rows(args.plan, required=("trial", "commanded_pin_deg"))
    if not rows:
        raise InputError(args.plan, "plan has no rows")
    commands = []
    for number, row in enumerate(rows, start=2):
        try:
            value = float(row["commanded_pin_deg"])
        except ValueError:
            value = math.nan
        if not math.isfinite(value):
            raise InputError(
                args.plan,
                f"line {number}: commanded_pin_deg {row['commanded_pin_deg']!r} is not a number",
            )
        commands.append(value)
    params, effects = params_from_json(args.params) if args.params else (SimParams(), ())
    try:
        effects = effects + tuple(parse_effect(text) for text in args.effect)
        result = simulate(commands, params, effects)  # checks each effect on this machine
    except ValueError as exc:
        raise InputError("--effect", str(exc)) from None
    if args.noise_deg > 0:
        result = add_noise(result, args.noise_deg, np.random.default_rng(args.seed))
    out_rows = result.rows([row["trial"] for row in rows])
    write_csv_rows(args.out, out_rows, SIMULATE_COLUMNS)
    if args.json:
        summary = {
            "out": str(args.out),
            "bends": len(out_rows),
            "effects": [e.to_dict() for e in effects],
            "noise_deg": args.noise_deg,
            "params": params.to_dict(),
        }
        print(json.dumps(summary, indent=2))
        return 0
    spring = np.asarray(result.springback_deg, dtype=float)
    named = ", ".join(f"{e.name}={e.value:g}" for e in effects) or "none"
    print(
        f"wrote {args.out}: {len(out_rows)} bends simulated (effects: {named}; "
        f"noise {args.noise_deg:g} deg); springback {np.min(spring):.3f} to "
        f"{np.max(spring):.3f} deg"
    )
    return 0
