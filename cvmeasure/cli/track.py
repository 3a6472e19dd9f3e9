"""``cvmeasure track``: control charts, Cp/Cpk and a drift alarm per vertex over a run of parts."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from cvmeasure.cli.design_options import add_job_rule_options, add_plan_options, plan_from_args
from cvmeasure.cli.options import int_in

__all__ = ["register", "run"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "track",
        help="control charts, Cp/Cpk and a drift alarm per vertex over a run of parts",
        description="A run of parts of one design, in bending order: part result records "
        "(JSON Lines of `cvmeasure part --design ... -o`, or `cvmeasure batch` part records, "
        "compared with --design here) or part photos (measured here with --board and "
        "--camera). Per vertex: individuals / moving-range chart, Cp and Cpk against the "
        "seed's tolerance (1 deg and 10 %), and a drift alarm (Western Electric rules, "
        "CUSUM). Exit 0 also when an alarm is raised (it is in the output).",
    )
    p.add_argument("inputs", nargs="+", type=Path, help="RESULTS.jsonl or part photos, in order")
    p.add_argument(
        "--design",
        type=Path,
        required=True,
        help="the parts' design (.svg/.dxf), planned by cvmeasure gcode's rules",
    )
    add_plan_options(p, job=True)
    add_job_rule_options(p, feeds=False)
    p.add_argument("--board", type=Path, help="board JSON (to measure photos)")
    p.add_argument("--camera", type=Path, help="camera JSON (to measure photos)")
    p.add_argument(
        "--baseline",
        type=int_in(2, 1000),
        default=10,
        help="first parts whose mean is the centre line (default 10)",
    )
    p.add_argument("-o", "--out", type=Path, help="write the result JSON here")
    p.add_argument("--html", type=Path, help="write an HTML page with the charts")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.set_defaults(func=run)


def _records(args: argparse.Namespace, plan) -> list[dict]:
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import read_jsonl

    records: list[dict] = []
    photos = [p for p in args.inputs if p.suffix.lower() not in (".jsonl", ".json")]
    for path in args.inputs:
        if path not in photos:
            records += read_jsonl(path, skip_partial_last=True)
    if photos:
        if args.board is None or args.camera is None:
            raise InputError(photos[0], "measuring part photos needs --board and --camera")
        from cvmeasure.board import load_board
        from cvmeasure.camera_model import load_camera
        from cvmeasure.imageio import read_photo
        from cvmeasure.part.measure import measure_part

        board, camera = load_board(args.board), load_camera(args.camera)
        for photo in photos:
            m = measure_part(
                read_photo(photo).bgr,
                board,
                camera,
                design=plan.as_path(),
                design_source=str(args.design),
                source=str(photo),
                reference_mm=plan.vertices_mm,
            )
            records.append(m.to_dict())
    return [_with_comparison(r, plan, str(args.design)) for r in records]


def _with_comparison(record: dict, plan, design_source: str) -> dict:
    """A record without a design comparison but with vertex bends: compare it here."""
    if (record.get("comparison") or {}).get("bends") or not record.get("vertex_bend_deg"):
        return record
    import numpy as np

    from cvmeasure.part.measure import ArcResult, compare_with_design

    arc = ArcResult(
        "centreline_fit",
        float(record["radius_mm"]),
        float(record["chord_width_mm"]),
        float(record["height_mm"]),
        float(record["arc_angle_deg"]),
        int(record["divisions"]),
    )
    if arc.divisions != plan.divisions:
        return record  # not bent as this plan: left without a comparison (skipped)
    comp = compare_with_design(
        np.asarray(record["centreline_mm"], float),
        np.asarray(record["vertex_bend_deg"], float),
        arc,
        plan.as_path(),
        design_source=design_source,
        reference_mm=plan.vertices_mm,
    )
    return {**record, "comparison": comp.to_dict()}


def run(args: argparse.Namespace) -> int:
    from cvmeasure.errors import InputError
    from cvmeasure.fileio import atomic_write_json, atomic_write_text, to_jsonable
    from cvmeasure.part.track import bends_from_records, track_bends, tracking_png

    plan = plan_from_args(args, args.design)
    records = _records(args, plan)
    try:
        names, design_deg, measured = bends_from_records(records)
        result = track_bends(measured, design_deg, parts=names, baseline_parts=args.baseline)
    except ValueError as exc:
        raise InputError(args.inputs[0], str(exc)) from None
    out = result.to_dict()
    if args.out:
        atomic_write_json(args.out, out)
    if args.html:
        from cvmeasure.report.html import html_img, html_page

        body = [
            f"<p>{len(names)} parts of {args.design.name}</p>",
            html_img(tracking_png(result), "charts"),
        ]
        atomic_write_text(args.html, html_page("cvmeasure track", body))
    if args.json:
        print(json.dumps(to_jsonable(out), indent=2, allow_nan=False))
    else:
        state = "ALARM" if result.alarm else "in control"
        cpk = result.worst_cpk
        print(
            f"{len(names)} parts, {len(result.charts)} vertices: {state}"
            + (
                f" (vertices {out['alarmed_vertices']}, from part {out['first_alarm_part']})"
                if result.alarm
                else ""
            )
            + f"; worst Cpk {'-' if cpk is None else f'{cpk:.2f}'}"
        )
    return 0
