"""The self-contained HTML report of a results file.

One HTML file, no network: CSS inline, every image (plots, overlay thumbnails)
embedded as a ``data:`` URI, no scripts.
"""

from __future__ import annotations

import base64
import html
from collections import Counter
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import cv2

from cvmeasure.part.track import bends_from_records, track_bends, tracking_png
from cvmeasure.report import plots
from cvmeasure.report.thumbnails import find_photo, overlay_thumbnail
from cvmeasure.warning import StageWarning

__all__ = ["build_report", "data_uri", "table_columns"]

#: Columns shown first when present, in this order; other numeric fields follow.
PREFERRED_COLUMNS: tuple[str, ...] = (
    "bend_angle_deg",
    "pin_angle_deg",
    "springback_deg",
    "loaded_bend_deg",
    "unloaded_bend_deg",
    "radius_mm",
    "chord_width_mm",
    "height_mm",
    "arc_angle_deg",
    "segment_bend_deg",
    "x_px",
    "y_px",
    "r_px",
)
_HIDDEN = {"seconds", "cpu_s", "worker_pid", "ok"}
#: Column headings for the operator: what it is, in words, and its unit.
COLUMN_NAMES: dict[str, str] = {
    "bend_angle_deg": "bend angle (deg)",
    "pin_angle_deg": "pin angle (deg)",
    "springback_deg": "springback (deg)",
    "loaded_bend_deg": "loaded bend (deg)",
    "unloaded_bend_deg": "unloaded bend, the part's (deg)",
    "target_deg": "target (deg)",
    "wanted_loaded_deg": "wanted loaded bend (deg)",
    "commanded_pin_deg": "pin command (deg)",
    "measured_pin_deg": "measured pin (deg)",
    "radius_mm": "radius (mm)",
    "chord_width_mm": "chord width (mm)",
    "height_mm": "arc height (mm)",
    "arc_angle_deg": "arc angle (deg)",
    "segment_bend_deg": "bend per chord (deg)",
    "wire_width_mm": "wire width (mm)",
    "divisions": "chords",
    "bend_index": "bend number",
    "x_px": "x (px)",
    "y_px": "y (px)",
    "r_px": "radius (px)",
}
_UNITS = (("_deg", "deg"), ("_mm", "mm"), ("_px", "px"), ("_pct", "%"), ("_s", "s"))
_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Roboto,sans-serif;margin:24px;color:#1b1b1b;max-width:1400px}
h1{font-size:1.5em;margin-bottom:4px}h2{font-size:1.2em;margin-top:28px;border-bottom:1px solid #ccc}
.meta{color:#555;font-size:.9em}
table{border-collapse:collapse;font-size:.85em;margin:8px 0}
th,td{border:1px solid #d0d0d0;padding:3px 7px;vertical-align:top;overflow-wrap:anywhere}
td.name{max-width:22em}td.notes{max-width:36em}
.wide{overflow-x:auto;max-width:100%}
th{background:#f0f0f0;text-align:left}td.num{text-align:right;font-variant-numeric:tabular-nums}
tr.fail td{background:#fff0f0}.bad{color:#a01010;font-weight:600}.good{color:#106010;font-weight:600}
.plots img,img.figure{max-width:640px;margin:6px 12px 6px 0;border:1px solid #ddd}
img.overlay{max-width:480px;margin:4px 8px 4px 0}
img.thumb{width:240px;height:auto;display:block}
"""


def data_uri(data: bytes, mime: str) -> str:
    """``data:<mime>;base64,...`` for embedding bytes in HTML."""
    return f"data:{mime};base64,{base64.b64encode(data).decode('ascii')}"


def html_page(title: str, body: Sequence[str]) -> str:
    """A whole self-contained HTML page: the reports' one page frame and style sheet.

    ``body`` holds HTML fragments (already escaped); the title is escaped here.
    """
    head = [
        "<!DOCTYPE html>",
        "<html lang=en><head><meta charset=utf-8>",
        "<meta name=viewport content='width=device-width, initial-scale=1'>",
        f"<title>{_e(title)}</title><style>{_CSS}</style></head><body>",
        f"<h1>{_e(title)}</h1>",
    ]
    return "\n".join([*head, *body, "</body></html>"]) + "\n"


def html_img(data: bytes, alt: str, *, mime: str = "image/png", css_class: str = "") -> str:
    """An ``<img>`` with ``data`` embedded (no file beside the page)."""
    cls = f" class={css_class}" if css_class else ""
    return f"<img{cls} alt='{_e(alt)}' src='{data_uri(data, mime)}'>"


def _e(value: Any) -> str:
    return html.escape(str(value), quote=True)


def _fmt(value: Any) -> str:
    if isinstance(value, int) and not isinstance(value, bool):
        return str(value)
    num = plots.numeric(value)
    if num is None:
        return "" if value is None else _e(value)
    return f"{num:.4f}" if abs(num) < 1e5 else f"{num:.6g}"


def table_columns(records: Sequence[Mapping[str, Any]], limit: int = 9) -> list[str]:
    """The numeric top-level fields to tabulate: preferred ones first, then the rest, sorted."""
    present: Counter[str] = Counter()
    for r in records:
        for k, v in r.items():
            if k not in _HIDDEN and plots.numeric(v) is not None:
                present[k] += 1
    first = [c for c in PREFERRED_COLUMNS if c in present]
    rest = sorted(k for k in present if k not in first)
    return (first + rest)[:limit]


def column_name(key: str) -> str:
    """The heading of a record field: :data:`COLUMN_NAMES`, else its words and unit.

    >>> column_name("bend_angle_deg"), column_name("lift_sigma_mm")
    ('bend angle (deg)', 'lift sigma (mm)')
    """
    if key in COLUMN_NAMES:
        return COLUMN_NAMES[key]
    for suffix, unit in _UNITS:
        if key.endswith(suffix):
            return f"{key[: -len(suffix)].replace('_', ' ')} ({unit})"
    return key.replace("_", " ")


def _uncertainty(record: Mapping[str, Any], key: str) -> float | None:
    """One standard uncertainty of ``record[key]`` where the record states one."""
    for field in ("uncertainty_deg", "uncertainty_mm"):
        table = record.get(field)
        if isinstance(table, Mapping) and plots.numeric(table.get(key)) is not None:
            return float(table[key])
    return None


def _value_cell(record: Mapping[str, Any], key: str) -> str:
    """A value with its standard uncertainty beside it (``40.0000 &plusmn; 0.0190``)."""
    u = _uncertainty(record, key)
    text = _fmt(record.get(key))
    if u is not None and text:
        text += f" &plusmn; {u:.4f}"
    return f"<td class=num>{text}</td>"


def verdict(
    record: Mapping[str, Any], tolerance_deg: float | None, tolerance_mm: float | None
) -> tuple[str, str] | None:
    """The record against the tolerance: ("within" | "out" | "undecided", why), or None.

    A bend with a target (``target_deg`` and its ``unloaded_bend_deg``, the part's angle):
    its error within the tolerance by more than 2 standard uncertainties is "within",
    beyond it by more than 2 is "out", else "undecided" (measure again or tighten the
    uncertainty). A part compared with its design: its largest deviation against
    ``tolerance_mm``.
    """
    target = plots.numeric(record.get("target_deg"))
    final = plots.numeric(record.get("unloaded_bend_deg"))
    if tolerance_deg is not None and target is not None and final is not None:
        err = abs(final) - abs(target)
        u = _uncertainty(record, "unloaded_bend_deg") or 0.0
        why = f"error {err:+.3f} deg &plusmn; {2 * u:.3f} (2 sigma), tolerance {tolerance_deg:g}"
        if abs(err) + 2 * u <= tolerance_deg:
            return "within", why
        if abs(err) - 2 * u > tolerance_deg:
            return "out", why
        return "undecided", why
    comparison = record.get("comparison")
    if tolerance_mm is not None and isinstance(comparison, Mapping):
        dev = comparison.get("deviation") or {}
        worst = plots.numeric(dev.get("max_mm")) if isinstance(dev, Mapping) else None
        if worst is not None:
            why = f"largest deviation {abs(worst):.2f} mm, tolerance {tolerance_mm:g}"
            return ("within" if abs(worst) <= tolerance_mm else "out"), why
    return None


def _kv_table(rows: Sequence[tuple[str, Any]]) -> str:
    body = "".join(f"<tr><th>{_e(k)}</th><td class=num>{_fmt(v)}</td></tr>" for k, v in rows)
    return f"<table>{body}</table>"


def _tolerance_text(tolerance: Any) -> str:
    rel = f"{100 * tolerance.relative:g} % relative and " if tolerance.relative else ""
    return _e(f"{rel}{tolerance.absolute_deg:g} deg absolute")


def _agreement_section(result: Any) -> list[str]:
    ba, tol = result.bland_altman, result.tolerance
    out = ["<h2 id=agreement>Agreement with manual readings</h2>"]
    out.append(
        f"<p>Difference = vision &minus; manual; {ba.n} photos, {ba.n_readings} manual readings. "
        f"Verdict against the tolerance ({_tolerance_text(tol.tolerance)}): "
        f"<span class={'good' if tol.verdict == 'within tolerance' else 'bad'}>{_e(tol.verdict)}</span>"
        f" ({tol.n_within} of {tol.n_pairs} readings within).</p>"
    )
    rows: list[tuple[str, Any]] = [
        ("bias (deg)", ba.bias_deg),
        ("bias 95 % CI low", ba.bias_ci_deg[0]),
        ("bias 95 % CI high", ba.bias_ci_deg[1]),
        ("lower limit of agreement (deg)", ba.loa_low_deg),
        ("upper limit of agreement (deg)", ba.loa_high_deg),
        ("SD of differences (deg)", ba.sd_deg),
        ("proportional-bias slope", ba.slope),
        ("proportional-bias p", ba.slope_p),
    ]
    if result.manual_rr is not None:
        rr = result.manual_rr
        rows += [
            ("manual repeatability SD (deg)", rr.repeatability_sd_deg),
            ("manual reproducibility SD (deg)", rr.reproducibility_sd_deg),
            ("%GRR of total", rr.grr_percent),
            ("distinct categories (ndc)", rr.ndc),
        ]
    if result.vision_repeatability_sd_deg is not None:
        rows.append(("vision repeatability SD (deg)", result.vision_repeatability_sd_deg))
    out.append(_kv_table(rows))
    out.append(
        f"<div class=plots><img alt='Bland-Altman plot' src='{data_uri(plots.bland_altman_png(result), 'image/png')}'></div>"
    )
    return out


def build_report(
    records: Sequence[Mapping[str, Any]],
    *,
    title: str = "cvmeasure results",
    source: str = "",
    photo_roots: Sequence[Path] = (),
    agreement: Any = None,
    thumbnails: bool = True,
    max_thumbnails: int = 500,
    thumb_width_px: int = 360,
    stamp: Mapping[str, Any] | None = None,
    progress: Callable[[int, int], None] | None = None,
    tolerance_deg: float | None = None,
    tolerance_mm: float | None = None,
) -> str:
    """The HTML text of the report of per-photo result records.

    Parameters
    ----------
    records : sequence of mappings
        Per-photo (or per-trial) result records, as in a results JSON Lines file;
        shown sorted by trial, then photo path.
    title, source : str
        Page title and the results file it shows.
    photo_roots : sequence of Path
        Folders where relative photo paths are looked up (besides as written).
    agreement : AgreementResult, optional
        Adds the agreement section (table and Bland–Altman plot).
    thumbnails : bool
        Embed an overlay thumbnail of each photo (first ``max_thumbnails``).
    stamp : mapping, optional
        Provenance shown in the header (command, version, time).
    progress : callable, optional
        Called with (thumbnails done, thumbnails to do).
    tolerance_deg, tolerance_mm : float, optional
        Judge each bend with a target, and each part compared with its design, against
        these (:func:`verdict`); a verdict column and its count in the summary.
    """
    roots = tuple(Path(r) for r in photo_roots)
    records = sorted(records, key=_sort_key)
    out: list[str] = []
    meta = [f"results: {_e(source)}"] if source else []
    for k, v in (stamp or {}).items():
        meta.append(f"{_e(k)}: {_e(v)}")
    out.append(f"<p class=meta>{' &middot; '.join(meta)}</p>")
    out += _summary_section(records, tolerance_deg, tolerance_mm)
    out += _warnings_section(records)

    figures = [
        ("angles", plots.angles_png(records)),
        ("springback", plots.springback_png(records)),
        ("parts", plots.part_png(records)),
        ("residuals and uncertainties", plots.residuals_png(records)),
    ]
    figures = [(name, png) for name, png in figures if png is not None]
    if figures:
        out.append("<h2 id=plots>Plots</h2><div class=plots>")
        out += [html_img(png, name) for name, png in figures]
        out.append("</div>")
    if agreement is not None:
        out += _agreement_section(agreement)
    out += _tracking_section(records)

    columns = table_columns(records)
    out.append("<h2 id=photos>Photos</h2><div class=wide><table><thead><tr>")
    verdicts = [verdict(r, tolerance_deg, tolerance_mm) for r in records]
    judged = any(v is not None for v in verdicts)
    head = (
        (["overlay"] if thumbnails else [])
        + ["photo", "kind"]
        + [column_name(c) for c in columns]
        + (["verdict"] if judged else [])
        + ["warnings / error"]
    )
    out.append("".join(f"<th>{_e(h)}</th>" for h in head) + "</tr></thead><tbody>")
    n_thumbs = min(len(records), max_thumbnails) if thumbnails else 0
    for i, rec in enumerate(records):
        row_class = " class=fail" if rec.get("ok") is False else ""
        cells = []
        if thumbnails:
            cells.append(_thumb_cell(rec, roots, thumb_width_px) if i < n_thumbs else "<td></td>")
            if progress and i < n_thumbs:
                progress(i + 1, n_thumbs)
        name = rec.get("file_name") or Path(str(rec.get("photo", ""))).name or rec.get("trial", "")
        cells.append(f"<td class=name title='{_e(rec.get('photo', ''))}'>{_e(name)}</td>")
        cells.append(f"<td>{_e(rec.get('kind', ''))}</td>")
        cells += [_value_cell(rec, c) for c in columns]
        if judged:
            v = verdicts[i]
            css = {"within": "good", "out": "bad"}.get(v[0], "") if v else ""
            cells.append(
                f"<td class={css or 'num'} title='{v[1]}'>{v[0]}</td>" if v else "<td></td>"
            )
        notes = [str(StageWarning.from_json(w)) for w in rec.get("warnings") or []]
        if rec.get("error"):
            notes.insert(0, str(rec["error"]))
        cells.append(f"<td class=notes>{'<br>'.join(_e(n) for n in notes)}</td>")
        out.append(f"<tr{row_class}>{''.join(cells)}</tr>")
    out.append("</tbody></table></div>")
    return html_page(title, out)


def _summary_section(
    records: Sequence[Mapping[str, Any]], tolerance_deg: float | None, tolerance_mm: float | None
) -> list[str]:
    """Counts: records, measured, failed, per kind, per verdict against the tolerance."""
    ok = [r for r in records if r.get("ok", True)]
    failed = [r for r in records if r.get("ok") is False]
    kinds = Counter(str(r.get("kind", "-")) for r in records)
    summary = [("records", len(records)), ("measured", len(ok)), ("failed", len(failed))]
    summary += [(f"kind {k}", n) for k, n in sorted(kinds.items())]
    judged = Counter(
        v[0] for v in (verdict(r, tolerance_deg, tolerance_mm) for r in records) if v is not None
    )
    summary += [(f"verdict {k}", n) for k, n in sorted(judged.items())]
    return ["<h2 id=summary>Summary</h2>", _kv_table(summary)]


def _warnings_section(records: Sequence[Mapping[str, Any]]) -> list[str]:
    """Every warning code among the records: how many photos gave it, and one message."""
    by_code: dict[str, list[tuple[str, StageWarning]]] = {}
    for rec in records:
        name = str(rec.get("photo") or rec.get("trial") or "")
        for raw in rec.get("warnings") or []:
            w = StageWarning.from_json(raw)
            by_code.setdefault(w.code, []).append((name, w))
    if not by_code:
        return ["<h2 id=warnings>Warnings</h2><p>No warnings.</p>"]
    rows = "".join(
        f"<tr><td>{_e(code)}</td><td class=num>{len({n for n, _ in got})}</td>"
        f"<td>{_e(got[0][1].message)}</td></tr>"
        for code, got in sorted(by_code.items(), key=lambda kv: -len(kv[1]))
    )
    return [
        "<h2 id=warnings>Warnings</h2><table><tr><th>code</th><th>photos</th>"
        f"<th>message (first)</th></tr>{rows}</table>"
    ]


def _tracking_section(records: Sequence[Mapping[str, Any]]) -> list[str]:
    """Control charts per vertex when at least 3 records carry bends against one design."""

    try:
        names, design_deg, measured = bends_from_records(records)
        result = track_bends(measured, design_deg, parts=names)
    except ValueError:
        return []
    d = result.to_dict()
    rows = [
        ("parts", len(names)),
        ("vertices", d["vertices"]),
        ("drift alarm", "yes" if result.alarm else "no"),
        ("alarmed vertices", ", ".join(str(v) for v in d["alarmed_vertices"]) or "-"),
        ("first alarm at part", d["first_alarm_part"]),
        ("worst Cpk", d["worst_cpk"]),
    ]
    return [
        "<h2 id=tracking>Production tracking</h2>",
        _kv_table(rows),
        html_img(tracking_png(result), "control charts per vertex"),
    ]


def _sort_key(record: Mapping[str, Any]) -> tuple[str, str]:
    """Photos in file-name order (a batch writes them in completion order)."""
    name = str(record.get("photo") or record.get("file_name") or "")
    return (str(record.get("trial", "")).zfill(12), name)


def _thumb_cell(record: Mapping[str, Any], roots: tuple[Path, ...], width_px: int) -> str:
    if not record.get("photo") and not record.get("file_name"):
        return "<td></td>"  # a trial or bend record: its photos have rows of their own
    path = find_photo(record, roots)
    if path is None:
        return "<td>photo not found</td>"

    try:
        jpeg = overlay_thumbnail(record, path, width_px=width_px)
    except (ValueError, OSError, cv2.error) as exc:  # an unreadable photo must not stop the report
        return f"<td>no thumbnail: {_e(exc)}</td>"
    alt = f"overlay of {path.name}"
    return f"<td><img class=thumb alt='{_e(alt)}' src='{data_uri(jpeg, 'image/jpeg')}'></td>"
