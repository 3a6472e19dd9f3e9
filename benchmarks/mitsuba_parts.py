"""Finished parts measured on photos path traced by Mitsuba 3, through the user's chain (issue 41).

The scenes come from ``benchmarks.heldout.mitsuba_scenes`` (a renderer the project did not
write): a round steel wire bent to N equal chords on a circle lies on a matte sheet (white,
dark grey or black card, printed cork) beside the board sheet, under the default lamp or a
low one. Each render then goes through a camera: the lens' distortion applied by remapping
(an OpenCV radial model), sensor noise (shot and read) and JPEG. The camera is calibrated
with ``cvmeasure calibrate`` from rendered board views through the same lens, and each part
photo is measured with ``cvmeasure part PHOTO --board --camera --wire-diameter-mm --json``
as a process. Radius and bend per chord are scored against the scene's exact truth; a photo
off target must be refused (exit 2) or carry a warning that covers the quantity.
"""

from __future__ import annotations

import argparse
import json
import math
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from benchmarks import Metric, Table, finish
from benchmarks.heldout.mitsuba_scenes import (
    BoardScene,
    CameraRig,
    PartScene,
    part_axis_mm,
    render_board,
    render_part,
)
from benchmarks.mitsuba_markers import (
    _RENDERED,
    _VIEWS,
    RENDER_CACHE,
    _render_cpu_h,
    _timed,
    record_render_set,
    whole_set_cpu_h,
)

SECTION = "Finished parts on Mitsuba 3 renders (held-out renderer)"

_CLI = str(Path(sys.executable).with_name("cvmeasure"))
RADIUS_TOL = 0.003
BEND_TOL_DEG = 0.03
MIN_CHORD_MM = 10.0
#: The lens: OpenCV (k1, k2, p1, p2, k3), a mild barrel as a 24-35 mm equivalent prime has.
LENS_DIST = (-0.08, 0.03, 0.0, 0.0, 0.0)
#: Which warning codes cover which quantity (docs/conventions.md's warning-code table).
COVERS = {
    "radius": {
        "part_lifted",
        "part_arc_inconsistent",
        "part_s_curve",
        "part_cut_off",
        "round_wire_edges_lost",
        # without the chord count the radius is the wire's circle, not the vertices' (the
        # warning says so and by how much it can lie inside)
        "part_chords_not_found",
    },
    "bend": {
        "part_lifted",
        "part_arc_inconsistent",
        "part_s_curve",
        "part_cut_off",
        "part_end_uncertain",
        "part_centreline_gap",
        "divisions_mismatch",
        "divisions_not_found",
        "part_chords_not_found",
        "part_chord_spacing",
    },
}
#: Matte sheets: name -> linear RGB reflectance (or None: the printed cork texture).
SHEETS = {
    "white": (0.8, 0.8, 0.8),
    "dark grey card": (0.06, 0.06, 0.065),
    "black card": (0.025, 0.025, 0.025),
    "cork": None,
}
#: Lamps (world mm): the scene's default desk lamp (elevation 22 deg) and a low one (8 deg)
#: casting long soft shadows across the sheet.
LAMPS = {"default": (300.0, 200.0, 150.0), "low": (-330.0, 200.0, 55.0)}
STEEL_ALPHAS = (0.1, 0.25, 0.4)


@dataclass(frozen=True)
class Shot:
    """One part photo: its scene, labels for the table and the photo as the camera saw it."""

    scene: PartScene
    sheet: str
    lamp: str
    photo: Path
    truth: dict


def part_rig(width_px: int, height_px: int) -> CameraRig:
    """Camera 650 mm above the table, looking down on board and part (fov 42 deg)."""
    return CameraRig(
        width_px=width_px,
        height_px=height_px,
        fov_x_deg=42.0,
        eye_mm=(-10.0, -20.0, 650.0),
        target_mm=(-10.0, 0.0, 0.0),
    )


def _view_rig(rig: CameraRig) -> CameraRig:
    """The same camera (size, fov) posed as mitsuba_markers' board views expect."""
    return CameraRig(rig.width_px, rig.height_px, rig.fov_x_deg)


#: Lifts of the parts rocked on one end (mm; the far end off the sheet).
LIFTS_MM = (1.0, 2.0, 3.0, 1.5)


def scenes(
    n: int, rig: CameraRig, spp: int, seed: int = 41, lifts: tuple[float, ...] = ()
) -> list[tuple[PartScene, str, str]]:
    """``n`` part scenes cycling sheets, lamps and steel finish; radius, arc and chords drawn.

    With ``lifts`` each scene's far end stands that much off the sheet (one scene per lift).
    """
    if lifts:
        n = len(lifts)
    rng = np.random.default_rng(seed)
    out = []
    names = list(SHEETS)
    while len(out) < n:
        i = len(out)
        radius = round(float(rng.uniform(40.0, 85.0)), 2)
        arc = round(float(rng.uniform(60.0, 150.0)), 2)
        most = int(radius * math.radians(arc) // MIN_CHORD_MM)
        chords = int(rng.integers(min(6, most), min(16, most) + 1))
        sheet = names[i % len(names)]
        lamp = "low" if (i // len(names)) % 2 else "default"
        scene = PartScene(
            radius_mm=radius,
            arc_angle_deg=arc,
            wire_diameter_mm=3.0 if i % 3 else 2.0,
            yaw_deg=round(float(rng.uniform(-15.0, 15.0)), 2),
            rig=rig,
            spp=spp,
            chords=chords,
            sheet_rgb=SHEETS[sheet] or (0.8, 0.8, 0.8),
            sheet_texture="cork" if SHEETS[sheet] is None else "",
            lamp_mm=LAMPS[lamp],
            steel_alpha=STEEL_ALPHAS[i % len(STEEL_ALPHAS)],
            lift_mm=lifts[i] if lifts else 0.0,
        )
        out.append((scene, sheet, lamp))
    return out


def cork_texture(path: Path, seed: int = 7) -> Path:
    """A cork-like print (granules of brown, 2048 px over the 200 x 190 mm sheet)."""
    if path.exists():
        return path
    rng = np.random.default_rng(seed)
    size = 2048
    base = np.zeros((size, size), np.float32)
    for sigma, weight in ((1.0, 0.5), (3.0, 0.35), (8.0, 0.15)):
        layer = cv2.GaussianBlur(
            rng.standard_normal((size, size)).astype(np.float32), (0, 0), sigma
        )
        base += weight * layer / layer.std()
    v = np.clip(0.5 + 0.18 * base, 0.0, 1.0)
    bgr = np.stack([70 + 60 * v, 110 + 80 * v, 150 + 90 * v], axis=-1)
    tmp = path.with_suffix(".tmp.png")
    cv2.imwrite(str(tmp), np.clip(bgr, 0, 255).astype(np.uint8))
    tmp.replace(path)
    return path


def through_camera(render_jpg: Path, rig: CameraRig, seed: int) -> Path:
    """The render as the camera records it: lens distortion, sensor noise, JPEG (cached)."""
    out = render_jpg.with_name(render_jpg.stem + "_cam.jpg")
    if out.exists():
        return out
    img = cv2.imread(str(render_jpg)).astype(np.float32)
    h, w = img.shape[:2]
    k = rig.matrix()
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pts = np.stack([xs.ravel(), ys.ravel()], axis=-1)[:, None, :]
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-9)
    ideal = cv2.undistortPoints(pts, k, np.asarray(LENS_DIST), R=None, P=k, criteria=crit)
    mx = ideal[:, 0, 0].reshape(h, w).astype(np.float32)
    my = ideal[:, 0, 1].reshape(h, w).astype(np.float32)
    seen = cv2.remap(img, mx, my, cv2.INTER_CUBIC, borderMode=cv2.BORDER_REPLICATE)
    rng = np.random.default_rng(seed)
    # shot noise (variance grows with the signal) and read noise, in 8-bit counts
    sigma = np.sqrt(1.0 + 0.04 * np.clip(seen, 0.0, 255.0))
    noisy = np.clip(seen + sigma * rng.standard_normal(seen.shape), 0.0, 255.0)
    tmp = out.with_suffix(".tmp.jpg")
    cv2.imwrite(str(tmp), noisy.round().astype(np.uint8), [cv2.IMWRITE_JPEG_QUALITY, 92])
    tmp.replace(out)
    return out


def _run(args: list[str]) -> subprocess.CompletedProcess:
    return subprocess.run([_CLI, *args], capture_output=True, text=True)


def measure(
    photo: Path, board: Path, cam: Path, wire_mm: float, extra: tuple[str, ...] = ()
) -> tuple[int, dict, str]:
    """``cvmeasure part`` as a process: exit code, result JSON (empty when refused), stderr.

    ``extra``: more options (``--downsample 2``)."""
    res = _run(
        [
            "part",
            str(photo),
            "--board",
            str(board),
            "--camera",
            str(cam),
            "--wire-diameter-mm",
            f"{wire_mm:g}",
            "--json",
            *extra,
        ]
    )
    rec = json.loads(res.stdout) if res.returncode == 0 and res.stdout.strip() else {}
    return res.returncode, rec, res.stderr.strip()


def _codes(rec: dict) -> list[str]:
    out = []
    for w in rec.get("warnings") or []:
        out.append(str(w.get("code")) if isinstance(w, dict) else str(w).split(":")[0])
    return out


def _covering(
    codes: set[str],
    quantity: str,
    lift_effect: float | None,
    error: float,
    two_sigma: float | None = None,
) -> bool:
    """Whether the warnings cover ``quantity`` off by ``error`` (%, deg): ``part_lifted``
    only as far as the effect it states on that quantity reaches (a warning that a lift
    may move the radius by 0.4 % does not excuse one 1.2 % off), ``part_imprecise`` as far
    as twice the quantity's stated sigma (``two_sigma``) reaches, the others whole."""
    if codes & (COVERS[quantity] - {"part_lifted"}):
        return True
    if "part_imprecise" in codes and (two_sigma or 0.0) >= error:
        return True
    return "part_lifted" in codes and (lift_effect or 0.0) >= error


def score(truth: dict, rc: int, rec: dict) -> dict:
    """One photo against its truth: errors, and for each quantity ok / refused / silent."""
    out = {"radius_err_pct": None, "bend_err_deg": None, "divisions": None}
    if rc != 0 or not rec:
        out.update(radius="refused", bend="refused", verdict="refused")
        return out
    codes = set(_codes(rec))
    r_err = 100.0 * (float(rec["radius_mm"]) - truth["radius_mm"]) / truth["radius_mm"]
    bend = rec.get("segment_bend_deg")
    if bend is None and rec.get("divisions"):
        bend = float(rec["arc_angle_deg"]) / int(rec["divisions"])
    b_err = None if bend is None else float(bend) - truth["segment_bend_deg"]
    out.update(radius_err_pct=r_err, bend_err_deg=b_err, divisions=rec.get("divisions"))
    r_err_mm = float(rec["radius_mm"]) - truth["radius_mm"]
    sigma_mm = (rec.get("circle") or {}).get("radius_sigma_mm")
    out["radius_z"] = None if not sigma_mm else r_err_mm / float(sigma_mm)
    # the errors in the part's stated standard uncertainties (None without them)
    r_sigma, b_sigma = rec.get("radius_sigma_mm"), rec.get("segment_bend_sigma_deg")
    out["radius_z_stated"] = None if not r_sigma else r_err_mm / float(r_sigma)
    out["bend_z_stated"] = None if not b_sigma or b_err is None else b_err / float(b_sigma)
    out["radius_sigma_pct"] = (
        None if not r_sigma else 100.0 * float(r_sigma) / float(rec["radius_mm"])
    )
    out["bend_sigma_deg"] = None if not b_sigma else float(b_sigma)
    ok_r = abs(r_err) <= 100.0 * RADIUS_TOL
    ok_b = b_err is not None and abs(b_err) <= BEND_TOL_DEG
    lift = rec.get("lift") or {}
    two_sigma = {
        "radius": None if not r_sigma else 2.0 * out["radius_sigma_pct"],
        "bend": None if not b_sigma else 2.0 * float(b_sigma),
    }

    def covered(warned: set[str]) -> dict[str, bool]:
        """Each quantity on target or covered by the warnings ``warned``."""
        return {
            q: ok
            or _covering(
                warned,
                q,
                lift.get(f"effect_{key}"),
                float("inf") if err is None else abs(err),
                two_sigma[q],
            )
            for q, ok, key, err in (
                ("radius", ok_r, "radius_pct", r_err),
                ("bend", ok_b, "segment_bend_deg", b_err),
            )
        }

    as_stated = covered(codes)
    out["radius"] = "ok" if ok_r else ("warned" if as_stated["radius"] else "silent")
    out["bend"] = "ok" if ok_b else ("warned" if as_stated["bend"] else "silent")
    states = {out["radius"], out["bend"]}
    out["verdict"] = "silent" if "silent" in states else ("warned" if "warned" in states else "ok")
    # Read strictly: an unmeasured lift's bound (every photo of a part that may not lie
    # flat carries it) covers only a part that is lifted, not an error from elsewhere.
    if lift.get("used") == "bound" and not truth.get("lift_mm"):
        codes = codes - {"part_lifted"}
    out["silent_strict"] = not all(covered(codes).values())
    out.update(_vertex_scores(truth, rec))
    return out


def _vertex_scores(truth: dict, rec: dict) -> dict:
    """Each vertex bend's error (deg) and its error in its stated sigma, on a flat part
    measured in its true chord count (what ``correct`` acts on; every vertex of these
    arcs is bent by the bend per chord). Lifted parts: their vertices' projections
    differ from the bend, so they are left out."""
    bends, sigmas = rec.get("vertex_bend_deg"), rec.get("vertex_bend_sigma_deg")
    if truth.get("lift_mm") or not bends or rec.get("divisions") != truth.get("divisions"):
        return {"vertex_err_deg": [], "vertex_z": []}
    err = np.abs(np.asarray(bends, float)) - truth["segment_bend_deg"]
    z = [] if not sigmas else list(err / np.asarray(sigmas, float))
    return {"vertex_err_deg": list(err), "vertex_z": z}


def _calibrate(rig: CameraRig, spp: int, board_png: Path, board: Path, cache: Path, work: Path):
    views = []
    for i, (rvec, shift) in enumerate(_VIEWS):
        scene = BoardScene(rvec, shift, _view_rig(rig), spp)
        jpg = _timed(cache, "board", render_board, scene, board_png, cache)
        views.append(through_camera(jpg, rig, seed=1000 + i))
    cam = work / "camera.json"
    res = _run(["calibrate", "--board", str(board), "-o", str(cam), *map(str, views)])
    if res.returncode != 0:
        raise RuntimeError(f"cvmeasure calibrate exit {res.returncode}: {res.stderr[-300:]}")
    return cam


_COLUMNS = [
    "photo",
    "sheet",
    "lamp",
    "steel_alpha",
    "wire_mm",
    "lift_mm",
    "R_mm",
    "arc_deg",
    "N",
    "N_found",
    "radius_err_pct",
    "bend_err_deg",
    "radius_err_sigmas",
    "bend_err_sigmas",
    "verdict",
    "axis_offset_px",
    "ends_along_px",
    "ends_across_px",
    "warnings / refusal",
]


#: An end point farther than this from the true axis's end (px, along or across) counts
#: as misplaced in the axis rows.
END_OFF_PX = 5.0


def _axis_px(scene: PartScene, rig: CameraRig, per_chord: int = 200) -> np.ndarray:
    """The rendered wire's axis in the photo (M, 2) px: its polygon sampled densely and
    projected through the rig and the lens distortion the photos are made with."""
    v = part_axis_mm(scene)
    t = np.linspace(0.0, 1.0, per_chord, endpoint=False)[:, None]
    dense = np.vstack([a + t * (b - a) for a, b in zip(v[:-1], v[1:], strict=True)] + [v[-1:]])
    rot, tvec = rig.world_to_camera()
    rvec, _ = cv2.Rodrigues(rot)
    px, _ = cv2.projectPoints(dense, rvec, tvec, rig.matrix(), np.asarray(LENS_DIST))
    return px[:, 0]


def axis_errors_px(scene: PartScene, rig: CameraRig, centreline_px: np.ndarray) -> dict:
    """Where a measured centreline (M, 2 px, end to end) lies against the rendered axis.

    ``offset_px``: the median over the centres of their distance from the axis, positive
    outside the arc (a common offset moves the radius by it); ``ends_along_px``: each end
    point's distance past the axis's end along the end chord (positive beyond, negative
    short), in the axis's order; ``ends_across_px``: its distance from the end chord's line.
    """
    # the closest points on the axis computed here, not by the measured package's own
    # (cvmeasure.part.compare.point_to_polyline): this module scores through the CLI only
    axis = _axis_px(scene, rig)
    pts = np.asarray(centreline_px, dtype=np.float64)
    if np.hypot(*(pts[0] - axis[0])) > np.hypot(*(pts[0] - axis[-1])):
        pts = pts[::-1]
    a, d = axis[:-1], np.diff(axis, axis=0)
    length2 = np.maximum((d * d).sum(axis=1), 1e-12)
    t = np.clip(((pts[:, None, :] - a[None]) * d[None]).sum(axis=2) / length2, 0.0, 1.0)
    foot = a[None] + t[..., None] * d[None]
    dist = np.hypot(*(pts[:, None, :] - foot).transpose(2, 0, 1))
    j = np.argmin(dist, axis=1)
    left = np.column_stack((-d[j, 1], d[j, 0])) / np.sqrt(length2[j])[:, None]
    side = ((pts - foot[np.arange(len(pts)), j]) * left).sum(axis=1)
    # the arc bends towards its centre: a left offset is outward where the axis turns right
    (ax, ay), (bx, by) = axis[len(axis) // 2] - axis[0], axis[-1] - axis[len(axis) // 2]
    turn = ax * by - ay * bx
    outward = -side if turn > 0 else side
    along, across = [], []
    for end, a0, a1 in ((pts[0], axis[0], axis[1]), (pts[-1], axis[-1], axis[-2])):
        u = (a0 - a1) / np.hypot(*(a0 - a1))  # outward along the end chord
        along.append(float((end - a0) @ u))
        across.append(float(abs((end - a0) @ np.array([-u[1], u[0]]))))
    return {
        "offset_px": float(np.median(outward[1:-1])),
        "ends_along_px": along,
        "ends_across_px": across,
    }


def _row(shot: Shot, rc: int, rec: dict, err: str, s: dict, ax: dict | None) -> list:
    sc = shot.scene
    why = "; ".join(_codes(rec)) if rc == 0 else f"exit {rc}: {err.splitlines()[-1] if err else ''}"
    rnd = lambda v, d: None if v is None else round(v, d)  # noqa: E731
    return [
        shot.photo.name,
        shot.sheet,
        shot.lamp,
        sc.steel_alpha,
        sc.wire_diameter_mm,
        sc.lift_mm,
        sc.radius_mm,
        sc.arc_angle_deg,
        sc.chords,
        s["divisions"],
        rnd(s["radius_err_pct"], 4),
        rnd(s["bend_err_deg"], 4),
        rnd(s.get("radius_z_stated"), 2),
        rnd(s.get("bend_z_stated"), 2),
        s["verdict"] + (" (lift bound only)" if s.get("silent_strict") else ""),
        None if ax is None else round(ax["offset_px"], 2),
        None if ax is None else " / ".join(f"{v:+.1f}" for v in ax["ends_along_px"]),
        None if ax is None else " / ".join(f"{v:.1f}" for v in ax["ends_across_px"]),
        why[:200],
    ]


#: The rows also reported over the parts lying flat (the lifted ones' lift is only bounded,
#: which the stated sigmas leave out).
_FLAT_ROWS = (
    "radius within 0.3 % and bend per chord within 0.03 deg",
    "radius within 0.3 %",
    "bend per chord within 0.03 deg",
    "refused or warned (covering the quantity off)",
    "silently wrong (off target, no covering warning)",
    "silently wrong, an unmeasured lift's bound covering lifted parts only",
    "radius within 2 stated sigma",
    "bend per chord within 2 stated sigma",
)


def _axis_metrics(axes: list[dict | None]) -> list[Metric]:
    """Rows on where the centrelines lie against the rendered axis (no targets: what the
    stated sigmas rest on, seen directly)."""
    got = [a for a in axes if a is not None]
    if not got:
        return []
    offsets = [abs(a["offset_px"]) for a in got]
    misplaced = sum(
        max(abs(v) for v in a["ends_along_px"] + a["ends_across_px"]) > END_OFF_PX for a in got
    )
    return [
        Metric(
            "centreline's common offset from the true axis, |median|, largest over photos",
            round(max(offsets), 2), "px", None, None,
        ),
        Metric(
            "centreline's common offset from the true axis, |median|, median over photos",
            round(float(np.median(offsets)), 2), "px", None, None,
        ),
        Metric(
            f"photos with an end point over {END_OFF_PX:g} px from the true axis's end",
            misplaced, "photos", None, None,
        ),
    ]  # fmt: skip


def _metrics(scores: list[dict], n: int) -> list[Metric]:
    both = sum(s["radius"] == "ok" and s["bend"] == "ok" for s in scores)
    refused = sum(s["verdict"] in ("refused", "warned") for s in scores)
    silent = sum(s["verdict"] == "silent" for s in scores)
    r_ok = sum(s["radius"] == "ok" for s in scores)
    b_ok = sum(s["bend"] == "ok" for s in scores)
    share = 100.0 * both / n if n else float("nan")
    errs_r = [abs(s["radius_err_pct"]) for s in scores if s["radius_err_pct"] is not None]
    errs_b = [abs(s["bend_err_deg"]) for s in scores if s["bend_err_deg"] is not None]
    med = lambda v: round(float(np.median(v)), 4) if v else None  # noqa: E731

    def within_2(key: str) -> float | None:
        z = [s[key] for s in scores if s.get(key) is not None]
        return round(100.0 * sum(abs(v) <= 2.0 for v in z) / len(z), 1) if z else None

    sig_r = [s["radius_sigma_pct"] for s in scores if s.get("radius_sigma_pct") is not None]
    sig_b = [s["bend_sigma_deg"] for s in scores if s.get("bend_sigma_deg") is not None]
    return [
        Metric("part photos", n, "", target=">= 24", met=n >= 24),
        Metric(
            "radius within 0.3 % and bend per chord within 0.03 deg",
            round(share, 1),
            "%",
            target=">= 95",
            met=share >= 95.0,
        ),
        Metric("radius within 0.3 %", r_ok, "photos", None, None),
        Metric("bend per chord within 0.03 deg", b_ok, "photos", None, None),
        Metric("refused or warned (covering the quantity off)", refused, "photos", None, None),
        Metric(
            "silently wrong (off target, no covering warning)",
            silent,
            "photos",
            target="0",
            met=silent == 0,
        ),
        Metric(
            "silently wrong, an unmeasured lift's bound covering lifted parts only",
            sum(bool(s.get("silent_strict")) for s in scores),
            "photos",
            None,
            None,
        ),
        Metric("median |radius error| (measured)", med(errs_r), "%", None, None),
        # the circle's radius_sigma_mm is the fit's sampling uncertainty from the vertices'
        # scatter only: how often it holds the error says what it leaves out
        Metric(
            "radius within 2 stated circle sigma (sampling only)",
            within_2("radius_z"),
            "%",
            None,
            None,
        ),
        # radius_sigma_mm / segment_bend_sigma_deg: the part's stated standard uncertainties,
        # sampling and what moves every vertex alike (scale, centreline offset, ends)
        Metric("radius within 2 stated sigma", within_2("radius_z_stated"), "%", None, None),
        Metric("bend per chord within 2 stated sigma", within_2("bend_z_stated"), "%", None, None),
        Metric("median stated radius sigma", med(sig_r), "%", None, None),
        Metric("median stated bend per chord sigma", med(sig_b), "deg", None, None),
        Metric("median |bend per chord error| (measured)", med(errs_b), "deg", None, None),
        *_vertex_metrics(scores),
    ]


def _vertex_metrics(scores: list[dict]) -> list[Metric]:
    """Rows on the vertex bends of flat parts measured in their true chord count (no
    targets: the issue sets none; ``correct`` acts on them and their stated sigmas)."""
    err = np.abs(np.concatenate([s.get("vertex_err_deg", []) for s in scores] + [[]]))
    z = np.abs(np.concatenate([s.get("vertex_z", []) for s in scores] + [[]]))
    if not len(err):
        return []
    return [
        Metric("vertex bends scored (flat parts, chord count right)", len(err), "", None, None),
        Metric("p95 |vertex bend error|", round(float(np.percentile(err, 95)), 4), "deg", None, None),
        Metric(
            "vertex bends within 2 stated sigma",
            None if not len(z) else round(100.0 * float(np.mean(z <= 2.0)), 1), "%", None, None,
        ),
        Metric(
            "photos with a vertex bend beyond 3 stated sigma",
            sum(bool(np.any(np.abs(s.get("vertex_z", [])) > 3.0)) for s in scores), "photos",
            None, None,
        ),
    ]  # fmt: skip


#: The rows repeated for photos measured with ``--downsample``.
_DOWNSAMPLE_ROWS = (
    "radius within 0.3 % and bend per chord within 0.03 deg",
    "silently wrong (off target, no covering warning)",
    "silently wrong, an unmeasured lift's bound covering lifted parts only",
    "radius within 2 stated sigma",
    "bend per chord within 2 stated sigma",
    "median stated radius sigma",
    "median stated bend per chord sigma",
)


def _downsampled_metrics(shots: list, board: Path, cam: Path, blocks: int) -> list[Metric]:
    """The same photos measured with ``--downsample blocks``: the main rows, no targets."""
    t = time.perf_counter()
    scores = []
    for shot in shots:
        rc, rec, _ = measure(
            shot.photo, board, cam, shot.scene.wire_diameter_mm, ("--downsample", str(blocks))
        )
        scores.append(score(shot.truth, rc, rec))
    wall_s = time.perf_counter() - t
    label = f"with --downsample {blocks}"
    return [
        Metric(f"{m.name}, {label}", m.value, m.unit, None, None)
        for m in _metrics(scores, len(scores))
        if m.name in _DOWNSAMPLE_ROWS
    ] + [Metric(f"measure time (all photos, wall), {label}", round(wall_s, 1), "s", None, None)]


#: The photo size of the default set (2.2 MP: about 0.28 mm/px on the sheet).
SMALL_PX = (1800, 1200)
#: The seed's camera at its full sensor size (Nikon D3100, 14.2 MP: about 0.11 mm/px here).
FULL_PX = (4608, 3072)


def _whole_set_budget(cache: Path) -> Metric:
    """Issue 41's render budget: every render of the held-out sets (bender photos, parts at
    both sizes, their board views) in CPU hours over 2 cores."""
    cpu_h, missing = whole_set_cpu_h(cache)
    name = "render budget: CPU time of every Mitsuba render (bender and part sets) / 2 cores"
    if missing:
        name += " (not known: " + ", ".join(missing) + ")"
    return Metric(name, round(cpu_h / 2, 3), "h", target="< 1", met=bool(cpu_h / 2 < 1.0))


def main(argv: list[str] | None = None) -> dict:
    return run(argv, size_px=SMALL_PX, file=__file__, section=SECTION)


def run(
    argv: list[str] | None,
    *,
    size_px: tuple[int, int],
    file: str,
    section: str,
    downsample: int | None = None,
) -> dict:
    """The benchmark with photos of ``size_px`` (same scenes, lens and field of view),
    published as ``file``'s ``section``; with ``downsample``, every photo measured again
    with ``--downsample`` (rows without targets: an option, not the default chain)."""
    name = Path(file).stem
    p = argparse.ArgumentParser(prog=f"python -m benchmarks.{name}", description=__doc__)
    p.add_argument("--quick", action="store_true", help="small renders, 4 part photos")
    p.add_argument(
        "--cache",
        type=Path,
        default=RENDER_CACHE,
        help="renders kept by their parameters (default: the user's cache folder)",
    )
    p.add_argument("--photos", type=int, help="part photos (default 24; 4 with --quick)")
    p.add_argument("--threads", type=int, default=1, help="render threads (default 1)")
    p.add_argument(
        "--lifted",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"also {len(LIFTS_MM)} parts lifted {min(LIFTS_MM):g}-{max(LIFTS_MM):g} mm at one end "
        "(default on; off with --quick)",
    )
    args = p.parse_args(argv)
    import drjit as dr

    dr.set_thread_count(args.threads)
    w, h = (size_px[0] * 2 // 3, size_px[1] * 2 // 3) if args.quick else size_px
    spp, n = 8, (4 if args.quick else 24)
    n = args.photos or n
    if args.lifted is None:
        args.lifted = not args.quick
    rig = part_rig(w, h)
    work = Path(tempfile.mkdtemp(prefix="mitsuba_parts_"))
    board_png = work / "board.png"
    res = _run(["targets", "charuco", "-o", str(board_png)])
    if res.returncode != 0:
        raise RuntimeError(res.stderr)
    board = work / "board.board.json"
    args.cache.mkdir(parents=True, exist_ok=True)
    cork = cork_texture(args.cache / "cork_texture.png")
    t0, c0 = time.perf_counter(), time.process_time()
    cam = _calibrate(rig, spp, board_png, board, args.cache, work)
    shots = []
    lifted = scenes(0, rig, spp, seed=43, lifts=LIFTS_MM) if args.lifted else []
    for i, (scene, sheet, lamp) in enumerate(scenes(n, rig, spp) + lifted):
        texture = cork if scene.sheet_texture else None
        jpg, truth = _timed(args.cache, "part", render_part, scene, board_png, args.cache, texture)
        shots.append(Shot(scene, sheet, lamp, through_camera(jpg, rig, seed=i), truth))
    render_s, render_cpu_s = time.perf_counter() - t0, time.process_time() - c0
    set_cpu_h = _render_cpu_h(("board", "part"))
    if not args.quick and args.photos is None and args.lifted:  # the set as defined
        record_render_set(args.cache, name, set_cpu_h, len(_RENDERED))
    rows, scores = [], []
    t1 = time.perf_counter()
    axes = []
    for shot in shots:
        rc, rec, err = measure(shot.photo, board, cam, shot.scene.wire_diameter_mm)
        s = score(shot.truth, rc, rec)
        scores.append(s)
        line = rec.get("centreline_px") if rc == 0 else None
        ax = None if not line else axis_errors_px(shot.scene, rig, np.asarray(line))
        axes.append(ax)
        rows.append(_row(shot, rc, rec, err, s, ax))
    measure_s = time.perf_counter() - t1
    calib = json.loads(cam.read_text())
    metrics = _metrics(scores, len(scores))
    flat = [s for s, shot in zip(scores, shots, strict=True) if shot.scene.lift_mm == 0.0]
    if len(flat) < len(scores):
        metrics += [
            Metric(f"{m.name}, flat parts only", m.value, m.unit, None, None)
            for m in _metrics(flat, len(flat))
            if m.name in _FLAT_ROWS
        ]
    metrics += _axis_metrics(axes)
    if downsample:
        metrics += _downsampled_metrics(shots, board, cam, downsample)
    metrics += [
        Metric("calibration rms", calib.get("rms_px"), "px", None, None),
        Metric(
            "render + camera time, this run (0 when cached)", round(render_s, 1), "s", None, None
        ),
        Metric(
            "render CPU time, this run (0 when cached)", round(render_cpu_s, 1), "s", None, None
        ),
        Metric("measure time (all photos, wall)", round(measure_s, 1), "s", None, None),
        Metric(
            "render budget: CPU time of this set's renders / 2 cores",
            round(set_cpu_h / 2, 3),
            "h",
            None,
            None,
        ),
    ]
    if size_px == FULL_PX and not args.quick:
        metrics.append(_whole_set_budget(args.cache))
    scale = 2.0 * 650.0 * math.tan(math.radians(21.0)) / w
    return finish(
        file,
        section,
        argv,
        quick=args.quick,
        metrics=metrics,
        tables=[Table("per part photo", _COLUMNS, rows)],
        notes=[
            f"Mitsuba 3 scalar_rgb path tracing, {w}x{h} px ({w * h / 1e6:.1f} MP), {spp} spp, "
            f"gaussian filter 0.5 px, fov 42 deg, camera 650 mm above the table "
            f"(about {scale:.2f} mm/px on the sheet)",
            f"each render through the camera: OpenCV lens distortion {LENS_DIST} applied by "
            "remapping, shot + read noise (sigma^2 = 1 + 0.04 * value, 8-bit), JPEG quality 92",
            f"camera from `cvmeasure calibrate` on {len(_VIEWS)} rendered board views "
            "(mitsuba_markers' poses) through the same lens",
            "parts: a round steel wire (rough conductor, GGX alpha 0.1/0.25/0.4; 2 or 3 mm) bent "
            f"to N equal chords of >= {MIN_CHORD_MM:g} mm (N 6-16) with vertices on the circle, "
            "R 40-85 mm, arc 60-150 deg, lying flat (and, unless --no-lifted, "
            f"{len(LIFTS_MM)} more rocked on one end, the far end {min(LIFTS_MM):g}-{max(LIFTS_MM):g} mm up); sheets white, dark grey card, black card, "
            "printed cork; the default lamp (22 deg) or a low one (8 deg)",
            "measured with `cvmeasure part PHOTO --board --camera --wire-diameter-mm D --json` "
            "(chord count found in the photo); truth: the circle's radius and arc angle / N",
            "axis columns: the record's centreline_px against the rendered axis projected into "
            "the photo through the rig and the lens distortion above: axis_offset_px the "
            "centres' median distance from it (+ outside the arc: a common offset moves the "
            "radius by it), ends_along_px each end point past (+) or short of (-) the axis's "
            "end along the end chord, ends_across_px its distance from that chord's line; "
            "their rows have no targets",
            "vertex rows (no targets; what `correct` acts on): each vertex bend of a flat part "
            "measured in its true chord count, its magnitude against the bend per chord, and "
            "that error in the vertex's stated vertex_bend_sigma_deg",
            "a miss counts as refused when exit 2 or a warning covering it: radius by "
            + ", ".join(sorted(COVERS["radius"]))
            + "; bend per chord also by "
            + ", ".join(sorted(COVERS["bend"] - COVERS["radius"]))
            + "; part_lifted only as far as the effect it states on the quantity "
            "(JSON lift.effect_radius_pct, lift.effect_segment_bend_deg) reaches the error; "
            "part_imprecise (the stated 2 sigma wider than the targets) as far as twice the "
            "quantity's stated sigma reaches it",
            "read strictly, an unmeasured lift's bound (part_lifted with lift.used 'bound', "
            "which a part that may not lie flat always carries) covers lifted parts only: "
            "a flat part off target with no other covering warning is marked "
            "'(lift bound only)' and counted in the strict silent row",
        ],
    )


if __name__ == "__main__":
    main()
