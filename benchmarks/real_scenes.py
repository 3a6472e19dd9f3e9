"""Real scenes (issue 14): marker angles and parts under each real-photo effect alone and all together.

Bender photos rendered by cvmeasure_datasets.render_bender_photo with SceneEffects
(discs at their kit heights, printed supports, the wire as a shiny 3 mm cylinder,
depth of field, motion blur, Bayer mosaic + demosaic, textured backgrounds, stray
coloured objects), camera 500-600 mm above the plate and off the die by tens of mm.
Every photo is measured as a user would: through the camera calibrated from rendered
ChArUco photos and the plate's plane measured from a photo of the board lying on it
(benchmarks/_calibrated.py), with the kit with heights and with the same kit with its
heights removed (a flat-plane pipeline) on the same photos. Parts (3 mm wire) under
the 3D wire, the lift and all effects; stray objects and occlusion (a loose wire across
a ring's edge, a tool's shadow across a marker) scored as warned/refused vs silently wrong.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace
from typing import Any, NamedTuple

import numpy as np

from benchmarks import Metric, Table, finish

SECTION = (
    "Real scenes: marker heights, round wire, camera effects, clutter and occlusion (issue 14)"
)

ANGLE_TARGET_DEG = 0.02
RADIUS_TARGET_PCT = 0.3
BEND_TARGET_DEG = 0.03
#: rows of the per-effect table (each alone), then all together
ALONE = (
    "marker_heights",
    "supports",
    "wire_3d",
    "depth_of_field",
    "motion_blur_px",
    "bayer",
    "textured_background",
    "clutter",
)
KEYS = ("pin_angle_deg", "bend_angle_deg")


def _effects(row: str):
    from cvmeasure_datasets.effects import SceneEffects

    if row == "none (flat scene)":
        return SceneEffects()
    if row == "all together":
        return SceneEffects.all_on()
    fx = SceneEffects.only(row)
    # supports stand under discs at their heights: alone they are shown with the heights
    return replace(fx, marker_heights=True) if row == "supports" else fx


class _Scene(NamedTuple):
    """A bender scene: pin and bend angles (deg), camera pose and lighting."""

    pin_deg: float
    bend_deg: float
    pose: Any
    light: Any


def _scene(i: int, seed0: int) -> _Scene:
    """The i-th bender scene: angles, pose and light (the same for every effect row)."""
    from cvmeasure_datasets import Lighting, Pose

    rng = np.random.default_rng([seed0, i])
    pin = float(rng.uniform(-110.0, 110.0))
    bend = float(np.clip(pin * rng.uniform(0.8, 0.95), -100.0, 100.0))
    pose = Pose(
        yaw_deg=float(rng.uniform(-180.0, 180.0)),
        tilt_deg=float(rng.uniform(0.0, 8.0)),
        tilt_direction_deg=float(rng.uniform(0.0, 360.0)),
        distance_mm=float(rng.uniform(500.0, 600.0)),
        offset_mm=(float(rng.uniform(-40.0, 10.0)), float(rng.uniform(-20.0, 20.0))),
    )
    return _Scene(pin, bend, pose, Lighting.random(seed0 + i))


def _render(scene: _Scene, seed: int, scale: float, effects: Any) -> Any:
    """Render a scene of :func:`_scene` (angles, pose, light) with ``effects``, render ``seed``."""
    from cvmeasure_datasets import render_bender_photo

    pin, bend, pose, light = scene
    return render_bender_photo(
        pin_angle_deg=pin,
        bend_angle_deg=bend,
        pose=pose,
        lighting=light,
        seed=seed,
        scale=scale,
        effects=effects,
    )


def flat_kit(kit):
    """The same kit with its heights removed: what a flat-plane pipeline measures with."""
    return kit.flat()


def _measure(img, kit, plane):
    from cvmeasure.errors import InputError
    from cvmeasure.markers import measure_machine_photo

    try:
        return measure_machine_photo(img, kit, plane=plane)
    except InputError as exc:
        return exc


def _score(res, truth) -> dict:
    from cvmeasure.errors import InputError

    if isinstance(res, InputError):
        return {"refused": str(res), "errors": [], "z": [], "warnings": []}
    errs, zs = [], []
    for key in KEYS:
        err = (float(getattr(res, key) - truth[key]) + 180.0) % 360.0 - 180.0
        errs.append(err)
        zs.append(abs(err) / max(float(res.uncertainty_deg[key]), 1e-12))
    return {
        "refused": None,
        "errors": errs,
        "z": zs,
        "warnings": [str(w) for w in res.warnings if w.code != "heights_nominal"],
    }


def _worst(v):
    """Largest |value|, None for none."""
    return float(np.max(np.abs(v))) if v else None


def _p95(v):
    return float(np.percentile(np.abs(v), 95)) if len(v) else None


def _within2(z):
    return float(100.0 * np.mean(np.asarray(z) < 2.0)) if len(z) else None


_PLANES: dict[tuple[int, float], object] = {}


def _plane(i: int, pose, camera, scale: float, seed0: int):
    """The plate's plane for scene ``i``, measured once from a photo of the board on it."""
    from benchmarks._calibrated import plane_for_pose

    if (i, scale) not in _PLANES:
        _PLANES[(i, scale)] = plane_for_pose(pose, camera, scale=scale, seed=seed0 + 5000 + i)
    return _PLANES[(i, scale)]


def _bender_rows(args, scale, camera, kit, rows_n):
    flat = flat_kit(kit)
    out = {}
    for row, n in rows_n:
        fx = _effects(row)
        acc = {"heights": {"e": [], "z": [], "refused": 0, "warned": 0}}
        acc["flat kit"] = {"e": [], "z": [], "refused": 0, "warned": 0}
        t_render = []
        for i in range(n):
            scene = _scene(i, args.seed)
            plane = _plane(i, scene.pose, camera, scale, args.seed)
            t0 = time.process_time()
            photo = _render(scene, args.seed + i, scale, fx)
            t_render.append(time.process_time() - t0)
            # 'heights': the kit as the scene is built (flat scenes: the flat kit)
            built = kit if fx.marker_heights else flat
            for name, k in (("heights", built), ("flat kit", flat)):
                s = _score(_measure(photo.bgr, k, plane), photo.truth)
                a = acc[name]
                a["refused"] += s["refused"] is not None
                a["warned"] += bool(s["warnings"])
                a["e"] += s["errors"]
                a["z"] += s["z"]
        out[row] = {**acc, "n": n, "render_s": float(np.median(t_render))}
        h, f = acc["heights"], acc["flat kit"]
        print(
            f"{row}: p95 {_p95(h['e'])} (flat kit {_p95(f['e'])}), within 2 sigma "
            f"{_within2(h['z'])} %, refused {h['refused']}/{n}",
            flush=True,
        )
    return out


def _coverage_rows(args, scale, camera, kit, n):
    """All effects together, discs at their heights: stated sigma and the no-pose bound.

    Each photo measured four ways: on the plane with the heights (the pipeline), on
    the plane with the flat kit, and with the camera only (no pose): heights not
    applied (``height_bound_deg`` stated) and corrected for a square camera
    (``--heights parallel``). Scenes from :func:`_scene` with indices 100 on.
    """
    from cvmeasure.errors import InputError
    from cvmeasure.markers import measure_machine_photo
    from cvmeasure.markers.heights import BOUND_TILT_DEG
    from cvmeasure_datasets.effects import SceneEffects

    flat = flat_kit(kit)
    ways = ("plane, heights", "plane, flat kit", "camera only", "camera only, parallel")
    acc = {w: {"e": [], "z": [], "bound": [], "refused": 0, "warned": 0} for w in ways}
    for i in range(100, 100 + n):
        scene = _scene(i, args.seed)
        plane = _plane(i, scene.pose, camera, scale, args.seed)
        photo = _render(scene, args.seed + i, scale, SceneEffects.all_on())
        # the same scene with the discs on the plate: camera-only angles differ from it
        # by the heights' effect (the tilt's own foreshortening, which height_bound_deg
        # does not cover, is common to both)
        twin = _render(
            scene,
            args.seed + i,
            scale,
            SceneEffects.all_on(marker_heights=False, supports=False),
        )
        try:
            flat_res = measure_machine_photo(twin.bgr, flat, camera=camera)
        except InputError:
            flat_res = None
        for way in ways:
            opts = {"plane": plane} if way.startswith("plane") else {"camera": camera}
            if way.endswith("parallel"):
                opts["heights"] = "parallel"
            try:
                res = measure_machine_photo(
                    photo.bgr, flat if way.endswith("flat kit") else kit, **opts
                )
            except InputError:
                acc[way]["refused"] += 1
                continue
            a = acc[way]
            a["warned"] += any(not w.code.startswith("heights_") for w in res.warnings)
            for key in KEYS:
                err = (float(getattr(res, key) - photo.truth[key]) + 180.0) % 360.0 - 180.0
                a["e"].append(err)
                a["z"].append(abs(err) / max(float(res.uncertainty_deg[key]), 1e-12))
                if (
                    res.height_bound_deg is not None
                    and flat_res is not None
                    and scene.pose.tilt_deg <= BOUND_TILT_DEG  # what the bound assumes
                ):
                    effect = float(getattr(res, key) - getattr(flat_res, key))
                    if way.endswith("parallel"):
                        effect = err - float(getattr(flat_res, key) - twin.truth[key])
                    sigma = math.hypot(res.uncertainty_deg[key], flat_res.uncertainty_deg[key])
                    a["bound"].append(abs(effect) <= res.height_bound_deg[key] + 2 * sigma)
        print(f"coverage photo {i}: " + ", ".join(f"{w} {acc[w]['e'][-2:]}" for w in ways))
    return acc


def _occlusion_rows(args, scale, camera, kit, n):
    """Clutter + occlusion: each photo is refused, warned about, right, or silently wrong.

    The scenes (angles, pose, light) are those of the effect rows, with other seeds.
    """
    from cvmeasure.kit import ROLES
    from cvmeasure_datasets.effects import SceneEffects

    rows = []
    counts = {}
    for kind in ("stray objects (clutter 12)", "wire across a ring edge", "tool's shadow"):
        c = {"refused": 0, "named": 0, "warned": 0, "right": 0, "silently wrong": 0}
        for i in range(n):
            scene = _scene(i, args.seed)
            role = ROLES[(i + len(counts)) % len(ROLES)]
            fx = SceneEffects.all_on(clutter=12)
            if kind.startswith("wire"):
                fx = replace(fx, wire_across=(role,))
            elif kind.startswith("tool"):
                fx = replace(fx, tool_shadow=(role,))
            plane = _plane(i, scene.pose, camera, scale, args.seed)
            photo = _render(scene, args.seed + 100 + i, scale, fx)
            s = _score(_measure(photo.bgr, kit, plane), photo.truth)
            # a named warning names the marker concerned (for stray objects: any marker)
            names = ROLES if kind.startswith("stray") else (role,)
            named = any(f"'{r}'" in w for w in s["warnings"] for r in names)
            if s["refused"] is not None:
                verdict = "refused"
            elif named:
                verdict = "named"
            elif s["warnings"]:
                verdict = "warned"
            elif max(s["z"]) > 3.0:
                verdict = "silently wrong"
            else:
                verdict = "right"
            c[verdict] += 1
            rows.append(
                [
                    kind,
                    i,
                    role if not kind.startswith("stray") else "-",
                    verdict,
                    " / ".join(f"{e:+.4f}" for e in s["errors"]) or "-",
                    " / ".join(f"{z:.1f}" for z in s["z"]) or "-",
                    "; ".join(s["warnings"])[:120] or (s["refused"] or "")[:120],
                ]
            )
        counts[kind] = c
    return rows, counts


#: the part warnings that say a round wire's centreline or lift is in doubt
PART_WARNINGS = (
    "round_wire_edges_lost",
    "part_lifted",
    "part_end_uncertain",
    "part_centreline_gap",
    "part_arc_inconsistent",
)
#: The round-wire part rows' second photo: the part slid this far on the sheet (board y, mm,
#: alternately up and down), measured with ``measure_part(moved_image=...)`` (the two-photo
#: lift, ``cvmeasure part --moved``) beside the one-photo figures. Along y: the 250 mm sheet
#: leaves less room along x beside the board.
PART_SHIFT_MM = 40.0


def _part_rows(args, scale, camera, n):
    from cvmeasure.board import CharucoBoardSpec
    from cvmeasure.errors import InputError
    from cvmeasure.part.measure import measure_part
    from cvmeasure.part.options import LiftOptions, PartOptions, WireOptions
    from cvmeasure_datasets import Pose, arc_part, render_part_photo
    from cvmeasure_datasets.effects import SceneEffects

    board = CharucoBoardSpec(14, 10, 20.0, 15.0)
    bw, bh = board.size_mm
    rows_fx = {
        "none (flat scene)": SceneEffects(),
        "wire_3d": SceneEffects(wire_3d=True),
        "part_lift_mm (3D wire lifted 2 mm)": SceneEffects(wire_3d=True, part_lift_mm=2.0),
        "all together": SceneEffects.all_on(),
    }
    out = {}
    for row, fx in rows_fx.items():
        radius_err, bend_err, refused, warned, z, bound = [], [], 0, [], [], []
        moved = {"radius": [], "bend": [], "refused": 0, "warned": [], "lift": []}
        width = {"radius": [], "bend": [], "refused": 0, "warned": []}
        shadow_read = []  # the default's lift: corrected from the shadow (mm) or "bound"
        for i in range(n):
            rng = np.random.default_rng([args.seed, 77, i])
            part = arc_part(
                float(rng.uniform(45.0, 85.0)),
                float(rng.choice([90.0, 120.0, 150.0])),
                int(rng.integers(6, 10)),
                wire_diameter_mm=3.0,
            )
            pose = Pose(
                tilt_deg=float(rng.uniform(0.0, 4.0)),
                tilt_direction_deg=float(rng.uniform(0.0, 360.0)),
                distance_mm=900.0,
                offset_mm=((bw + 10.0 + 250.0 - 20.0) / 2 + 10.0, bh / 2),
            )
            photo = render_part_photo(
                part=part,
                board=board,
                sheet="dark" if i % 2 == 0 else "light",
                pose=pose,
                seed=args.seed + 300 + i,
                scale=scale,
                effects=fx,
            )
            try:
                m = measure_part(
                    photo.bgr,
                    board,
                    camera,
                    options=PartOptions(
                        divisions=part.divisions,
                        # a round wire: silhouette centreline, axis at its radius, lift bound
                        wire=WireOptions(
                            axis_height_mm=None if fx.wire_3d else 0.0,
                            diameter_mm=part.wire_diameter_mm if fx.wire_3d else None,
                        ),
                    ),
                )
            except InputError as exc:
                print(f"part {row} photo {i}: refused ({exc})", flush=True)
                refused += 1
                continue
            warned += [w.code for w in m.warnings if w.code in PART_WARNINGS]
            truth = photo.truth
            radius_err.append(100.0 * (m.result.radius_mm / truth["radius_mm"] - 1.0))
            bend_err.append(m.result.segment_bend_deg - truth["arc_angle_deg"] / part.divisions)
            if m.vertex_bend_deg is not None and m.vertex_bend_sigma_deg is not None:
                vb_err = np.abs(m.vertex_bend_deg) - truth["arc_angle_deg"] / part.divisions
                z += list(np.abs(vb_err) / np.asarray(m.vertex_bend_sigma_deg))
            if m.lift is not None:
                bound.append(float(m.lift.effect_radius_pct))
                shadow_read.append(
                    round(float(m.lift.lift_mm), 2) if m.lift.source == "shadow" else "bound"
                )
            if not fx.wire_3d:
                continue
            # the same photo with the lift only bounded from the width (--no-shadow-lift)
            try:
                m0 = measure_part(
                    photo.bgr,
                    board,
                    camera,
                    options=PartOptions(
                        divisions=part.divisions,
                        wire=WireOptions(axis_height_mm=None, diameter_mm=part.wire_diameter_mm),
                        lift=LiftOptions(shadow=False),
                    ),
                )
            except InputError as exc:
                print(f"part {row} photo {i} with --no-shadow-lift: refused ({exc})", flush=True)
                width["refused"] += 1
            else:
                width["warned"] += [w.code for w in m0.warnings if w.code in PART_WARNINGS]
                width["radius"].append(100.0 * (m0.result.radius_mm / truth["radius_mm"] - 1.0))
                width["bend"].append(
                    m0.result.segment_bend_deg - truth["arc_angle_deg"] / part.divisions
                )
            # the same part slid on the sheet: the two-photo lift (same seed: same placement)
            second = render_part_photo(
                part=part, board=board, sheet="dark" if i % 2 == 0 else "light", pose=pose,
                seed=args.seed + 300 + i, scale=scale, effects=fx,
                part_shift_mm=(0.0, PART_SHIFT_MM if i % 2 == 0 else -PART_SHIFT_MM),
            )  # fmt: skip
            try:
                m2 = measure_part(
                    photo.bgr,
                    board,
                    camera,
                    options=PartOptions(
                        divisions=part.divisions,
                        wire=WireOptions(axis_height_mm=None, diameter_mm=part.wire_diameter_mm),
                    ),
                    moved_image=second.bgr,
                )
            except InputError as exc:
                print(f"part {row} photo {i} with the slid photo: refused ({exc})", flush=True)
                moved["refused"] += 1
                continue
            moved["warned"] += [
                w.code for w in m2.warnings if w.code in (*PART_WARNINGS, "moved_photo_unused")
            ]
            moved["radius"].append(100.0 * (m2.result.radius_mm / truth["radius_mm"] - 1.0))
            moved["bend"].append(
                m2.result.segment_bend_deg - truth["arc_angle_deg"] / part.divisions
            )
            if m2.lift is not None and m2.lift.used == "correction":
                moved["lift"].append(round(float(m2.lift.lift_mm), 2))
        out[row] = {
            "radius": radius_err,
            "bend": bend_err,
            "refused": refused,
            "warned": warned,
            "n": n,
            "z": z,
            "lift_bound_radius_pct": bound,
            "moved": moved,
            "width": width,
            "shadow_read": shadow_read,
        }
        print(f"part {row}: radius {radius_err} bend {bend_err} warned {warned}", flush=True)
    return out


def main(argv: list[str] | None = None) -> dict:
    p = argparse.ArgumentParser(prog="python -m benchmarks.real_scenes", description=__doc__)
    p.add_argument("--quick", action="store_true", help="quarter-size photos, one per row")
    p.add_argument("--seed", type=int, default=1400, help="first render seed (default 1400)")
    p.add_argument(
        "--coverage",
        type=int,
        help="photos (all effects, heights) for the uncertainty and no-pose table "
        "(default 24, quick 4)",
    )
    args = p.parse_args(argv)

    import cv2

    from benchmarks._calibrated import calibrated_camera
    from cvmeasure.kit import default_kit

    cv2.setNumThreads(1)
    t_start = time.perf_counter()
    scale = 0.25 if args.quick else 1.0
    n_alone, n_all, n_occ, n_part = (1, 2, 1, 1) if args.quick else (2, 8, 3, 2)
    n_cov = args.coverage if args.coverage is not None else (4 if args.quick else 24)
    camera, calibration = calibrated_camera(scale)
    kit = default_kit()
    rows_n = [("none (flat scene)", n_alone)] + [(r, n_alone) for r in ALONE]
    rows_n.append(("all together", n_all))
    bender = _bender_rows(args, scale, camera, kit, rows_n)
    occ_rows, occ_counts = _occlusion_rows(args, scale, camera, kit, n_occ)
    parts = _part_rows(args, scale, camera, n_part)
    cov = _coverage_rows(args, scale, camera, kit, n_cov)
    cov_table = [
        [
            way,
            len(a["e"]) // 2,
            _p95(a["e"][0::2]),
            _p95(a["e"][1::2]),
            _within2(a["z"]),
            float(100.0 * np.mean(a["bound"])) if a["bound"] else None,
            f"{a['refused']} / {a['warned']}",
        ]
        for way, a in cov.items()
    ]
    cov_z = cov["plane, heights"]["z"]
    cov_w2 = _within2(cov_z)

    effect_table = []
    for row, n in rows_n:
        b = bender[row]
        h, f = b["heights"], b["flat kit"]
        effect_table.append(
            [
                row,
                n,
                _p95(h["e"]),
                _within2(h["z"]),
                f"{h['refused']} / {h['warned']}",
                _p95(f["e"]),
                _within2(f["z"]),
                b["render_s"],
            ]
        )
    part_table = []
    for row, r in parts.items():
        part_table.append(
            [
                row,
                r["n"] - r["refused"],
                float(np.max(np.abs(r["radius"]))) if r["radius"] else None,
                float(np.max(np.abs(r["bend"]))) if r["bend"] else None,
                r["refused"],
                ", ".join(r["warned"]) or "-",
                _within2(r["z"]),
                float(np.max(r["lift_bound_radius_pct"])) if r["lift_bound_radius_pct"] else None,
                _worst(r["moved"]["radius"]),
                _worst(r["moved"]["bend"]),
                ", ".join(r["moved"]["warned"]) or "-",
                ", ".join(str(v) for v in r["moved"]["lift"]) or "-",
                ", ".join(str(v) for v in r["shadow_read"]) or "-",
                _worst(r["width"]["radius"]),
                _worst(r["width"]["bend"]),
                ", ".join(r["width"]["warned"]) or "-",
            ]
        )
    occ_table = [
        [kind, c["refused"], c["named"], c["warned"], c["right"], c["silently wrong"]]
        for kind, c in occ_counts.items()
    ]
    allrow = bender["all together"]["heights"]
    p95_all = _p95(allrow["e"])
    w2_all = _within2(allrow["z"])
    # A rate in a 90-98 % band needs more than the 8 photos' 16 angles (at a true
    # 95 %, all 16 within 2 sigma happens 44 % of the time): the target is judged
    # on both all-effects sets pooled.
    pooled_z = list(allrow["z"]) + list(cov["plane, heights"]["z"])
    n_all_z, n_pooled_z = len(allrow["z"]), len(pooled_z)
    pooled_w2 = _within2(pooled_z)
    part_all = parts["all together"]
    r_all = float(np.max(np.abs(part_all["radius"]))) if part_all["radius"] else None
    b_all = float(np.max(np.abs(part_all["bend"]))) if part_all["bend"] else None
    silent = sum(c["silently wrong"] for c in occ_counts.values())
    wrong_unnamed = sum(
        1
        for r in occ_rows
        if r[3] == "warned" and r[5] != "-" and max(map(float, r[5].split(" / "))) > 3.0
    )
    n_occ_total = sum(sum(c.values()) for c in occ_counts.values())
    size = "1152x768" if args.quick else "4608x3072"
    metrics = [
        Metric.at_most(
            "pin/bend angle error p95, all effects together, kit with heights",
            p95_all,
            "deg",
            ANGLE_TARGET_DEG,
        ),
        Metric(
            "the same photos measured with the flat kit (heights removed)",
            _p95(bender["all together"]["flat kit"]["e"]),
            "deg",
        ),
        Metric(
            f"angles with |error| < 2 sigma, all effects together ({n_all_z} angles)",
            w2_all,
            "%",
        ),
        Metric(
            f"angles with |error| < 2 sigma, all effects, heights, {n_cov} more photos",
            cov_w2,
            "%",
        ),
        Metric(
            f"angles with |error| < 2 sigma, all effects, heights: both sets ({n_pooled_z} angles)",
            pooled_w2,
            "%",
            target="90-98",
            met=pooled_w2 is not None and 90.0 <= pooled_w2 <= 98.0,
        ),
        Metric.at_most(
            f"pin/bend p95 on those {n_cov} photos, heights applied (plane from photos)",
            _p95(cov["plane, heights"]["e"]),
            "deg",
            ANGLE_TARGET_DEG,
        ),
        Metric(
            "camera only (no pose): the heights' effect within height_bound_deg + 2 sigma",
            float(100.0 * np.mean(cov["camera only"]["bound"]))
            if cov["camera only"]["bound"]
            else None,
            "%",
            target="100",
            met=bool(cov["camera only"]["bound"]) and all(cov["camera only"]["bound"]),
        ),
        Metric(
            "photos refused, all effects together",
            bender["all together"]["heights"]["refused"],
            f"of {n_all}",
            target="0",
            met=bender["all together"]["heights"]["refused"] == 0,
        ),
        Metric.at_most(
            "part radius error (worst), all effects together",
            r_all,
            "%",
            RADIUS_TARGET_PCT,
        ),
        Metric.at_most(
            "part segment bend error (worst), all effects together",
            b_all,
            "deg",
            BEND_TARGET_DEG,
        ),
        Metric(
            "part radius error (worst), all effects together, one photo with --no-shadow-lift",
            _worst(part_all["width"]["radius"]),
            "%",
        ),
        Metric(
            "part segment bend error (worst), all effects together, one photo with "
            "--no-shadow-lift",
            _worst(part_all["width"]["bend"]),
            "deg",
        ),
        Metric.at_most(
            f"part radius error (worst), all effects together, two photos (slid "
            f"{PART_SHIFT_MM:.0f} mm)",
            _worst(part_all["moved"]["radius"]),
            "%",
            RADIUS_TARGET_PCT,
        ),
        Metric.at_most(
            "part segment bend error (worst), all effects together, two photos",
            _worst(part_all["moved"]["bend"]),
            "deg",
            BEND_TARGET_DEG,
        ),
        Metric(
            "stray objects / occlusion: photos silently wrong (|error| > 3 sigma, no warning)",
            silent,
            f"of {n_occ_total}",
            target="0",
            met=silent == 0,
        ),
        Metric(
            "stray objects / occlusion: photos wrong by > 3 sigma with only unrelated warnings",
            wrong_unnamed,
            f"of {n_occ_total}",
            target="0 (a named warning or a refusal)",
            met=wrong_unnamed == 0,
        ),
        Metric(
            "render time, all effects, one photo (median CPU)",
            bender["all together"]["render_s"],
            "s",
        ),
    ]
    return finish(
        __file__,
        SECTION,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[
            Table(
                "bender photos per effect (pin and bend pooled; kit with heights vs flat kit)",
                [
                    "effect",
                    "photos",
                    "p95 deg (heights)",
                    "% < 2 sigma (heights)",
                    "refused / warned",
                    "p95 deg (flat kit)",
                    "% < 2 sigma (flat kit)",
                    "render s (CPU)",
                ],
                effect_table,
            ),
            Table(
                f"markers at their heights, all effects, {n_cov} photos: with and without the "
                "heights applied, and without a pose",
                [
                    "measured",
                    "photos",
                    "pin p95 deg",
                    "bend p95 deg",
                    "% < 2 sigma",
                    "% within bound + 2 sigma",
                    "refused / warned",
                ],
                cov_table,
            ),
            Table(
                "parts (3 mm wire, chord arcs), worst over the photos",
                [
                    "effects",
                    "measured",
                    "radius err %",
                    "segment bend err deg",
                    "refused",
                    "warned",
                    "% vertex bends < 2 sigma",
                    "lift bound on radius % (largest)",
                    f"two photos (slid {PART_SHIFT_MM:.0f} mm): radius err %",
                    "two photos: segment bend err deg",
                    "two photos: warned",
                    "two photos: lift read mm",
                    "one photo: lift from the shadow mm (or bound)",
                    "--no-shadow-lift: radius err %",
                    "--no-shadow-lift: segment bend err deg",
                    "--no-shadow-lift: warned",
                ],
                part_table,
            ),
            Table(
                "stray objects and occlusion (all effects on): what each photo got",
                [
                    "case",
                    "refused",
                    "warned, naming the marker",
                    "other warnings only",
                    "right",
                    "silently wrong",
                ],
                occ_table,
            ),
            Table(
                "stray objects and occlusion, per photo",
                ["case", "photo", "role", "verdict", "pin / bend err deg", "|err|/sigma", "why"],
                occ_rows,
            ),
        ],
        notes=[
            f"photos at {size} (seed {args.seed}); Lighting.random (2700-6500 K, white balance "
            "off by up to 600 K, exposure, vignetting, noise, blur, JPEG 80-96); camera 500-600 "
            "mm above the plate, tilted 0-8 deg, random yaw, the die up to 40 mm off the axis.",
            "as a user measures: the camera calibrated from "
            f"{calibration['views']} rendered ChArUco photos (RMS {calibration['rms_px']:.3f} px, "
            f"focal length {calibration['focal_error_pct']:+.4f} %), and every photo on the plane "
            "measured from a photo of the board lying on the plate from the same pose "
            "(benchmarks/_calibrated.py). The renderer's truth only scores.",
            "'heights' measures with the kit as the scene is built: the built-in kit (its "
            "discs' heights above the plate, each disc's edge mapped to its own height through "
            "the plane pose) where the discs stand at their heights, the flat kit on flat "
            "scenes; 'flat kit' always with the kit without heights (a flat-plane pipeline).",
            "markers at their heights table: 'camera only' measures without a pose (heights "
            "not applied; height_bound_deg is the worst effect the heights can have for a "
            "camera tilted up to 3 deg); 'parallel' corrects them assuming a camera square "
            "to the plate (these scenes are tilted 0-8 deg, beyond what the bound allows for). "
            "'warned' counts warnings other than the no-pose heights warning. 'within bound': "
            "the heights' effect on the camera-only angles (against the same scene rendered "
            "with the discs on the plate, measured the same way) within height_bound_deg "
            "plus 2 sigma; the parallel row: its error against the flat twin's error; only "
            "photos whose camera is tilted up to 3 deg (the bound's assumption) count.",
            "the truth angles are plate-plane angles: from the marker centres projected along "
            "the plate normal onto the plate.",
            "effects alone: marker_heights (discs at 8.5-18 mm), supports (with the heights), "
            "wire_3d (ray-traced 3 mm cylinder at 5 mm with highlight and shadow), "
            "depth_of_field (f/4, 35 mm, focus 6 mm above the plate), motion_blur_px 1.5, "
            "bayer (RGGB + OpenCV demosaic), textured_background, clutter (8 stray objects, "
            "half within 12 sRGB levels of a kit colour); all together: all of them.",
            "stray objects and occlusion: 'warned, naming the marker' when a warning names "
            "the occluded marker (stray objects: any marker); 'other warnings only' when the "
            "photo's warnings are unrelated (e.g. the plane-size warning the heights cause); "
            "silently wrong: |error| > 3 sigma and no warning at all.",
            "parts: measure_part with the chord count and, when the wire is round, its "
            "3 mm diameter (centreline between the silhouette edges, axis at the wire's "
            "radius; the default: the lift read from the wire's cast shadow and corrected when "
            "its 2 sigma <= 2 mm and it is consistent with the lift bound (no more than 2 sigma "
            "above it; above it, corrected at the bound; a 2 sigma over 1 mm then the stated "
            "effect), else bounded from the edges' width); '--no-shadow-lift': the same photos "
            "with LiftOptions(shadow=False) (the lift only bounded); 'warned' lists "
            f"{', '.join(PART_WARNINGS)}; the lifted part's truth is the rigid part's own "
            "radius and bends. 'two photos': the round-wire rows measured again with a second "
            f"photo of the part slid {PART_SHIFT_MM:.0f} mm along the board's y "
            "(render_part_photo(part_shift_mm=...), measure_part(moved_image=...)): the lift "
            "read from the two views and corrected.",
            f"total run {time.perf_counter() - t_start:.0f} s",
        ],
    )


if __name__ == "__main__":
    main()
