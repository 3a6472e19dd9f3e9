"""Small server-side SVG charts: the springback curve as it grows, and the parts' control chart."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from html import escape
from typing import Any

__all__ = ["springback_svg", "control_chart_svg"]

_W, _H, _PAD = 480, 260, 40
_COLOURS = {"ccw": "#1f77b4", "cw": "#d62728"}


def _scale(values: Sequence[float], lo: float, hi: float, a: float, b: float) -> list[float]:
    span = (hi - lo) or 1.0
    return [a + (v - lo) / span * (b - a) for v in values]


def _frame(title: str, xlabel: str, ylabel: str, body: list[str]) -> str:
    return (
        f'<svg xmlns="http://www.w3.org/2000/svg" viewBox="0 0 {_W} {_H}" role="img" '
        f'aria-label="{escape(title)}"><rect width="{_W}" height="{_H}" fill="white"/>'
        f'<text x="{_W / 2}" y="16" text-anchor="middle" font-size="13">{escape(title)}</text>'
        f'<line x1="{_PAD}" y1="{_H - _PAD}" x2="{_W - 10}" y2="{_H - _PAD}" stroke="#444"/>'
        f'<line x1="{_PAD}" y1="24" x2="{_PAD}" y2="{_H - _PAD}" stroke="#444"/>'
        f'<text x="{_W / 2}" y="{_H - 8}" text-anchor="middle" font-size="11">{escape(xlabel)}</text>'
        f'<text x="12" y="{_H / 2}" font-size="11" transform="rotate(-90 12 {_H / 2})" '
        f'text-anchor="middle">{escape(ylabel)}</text>' + "".join(body) + "</svg>"
    )


def springback_svg(steps: Sequence[Any]) -> str:
    """Springback (deg) against the loaded bend angle (deg, magnitude), one line per direction."""
    body: list[str] = []
    if steps:
        xs = [abs(s.loaded_deg) for s in steps]
        ys = [s.springback_deg for s in steps]
        x0, x1 = 0.0, max(xs) * 1.1
        y0, y1 = min(0.0, min(ys)), max(ys) * 1.2 + 1e-6
        for direction, colour in _COLOURS.items():
            pts = sorted(
                (abs(s.loaded_deg), s.springback_deg) for s in steps if s.direction == direction
            )
            if not pts:
                continue
            px = _scale([p[0] for p in pts], x0, x1, _PAD, _W - 10)
            py = _scale([p[1] for p in pts], y0, y1, _H - _PAD, 24)
            path = " ".join(f"{x:.1f},{y:.1f}" for x, y in zip(px, py, strict=True))
            body.append(
                f'<polyline points="{path}" fill="none" stroke="{colour}" stroke-width="2"/>'
            )
            body += [
                f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{colour}"/>'
                for x, y in zip(px, py, strict=True)
            ]
            body.append(
                f'<text x="{px[-1] + 6:.1f}" y="{py[-1]:.1f}" font-size="11" fill="{colour}">{direction}</text>'
            )
        body.append(f'<text x="{_PAD + 4}" y="34" font-size="10">{y1:.2f}</text>')
        body.append(f'<text x="{_W - 40}" y="{_H - _PAD - 4}" font-size="10">{x1:.0f}</text>')
    return _frame("springback vs loaded angle", "loaded bend (deg)", "springback (deg)", body)


def control_chart_svg(history: Sequence[Mapping[str, Any]], tolerance_deg: float) -> str:
    """Worst vertex error (deg) of each inspected part in order, with the tolerance line."""
    body: list[str] = []
    if history:
        ys = [float(r.get("worst_deg") or 0.0) for r in history]
        y1 = max(max(ys), tolerance_deg) * 1.2
        px = _scale(list(range(len(ys))), 0, max(len(ys) - 1, 1), _PAD + 10, _W - 20)
        py = _scale(ys, 0.0, y1, _H - _PAD, 24)
        ty = _scale([tolerance_deg], 0.0, y1, _H - _PAD, 24)[0]
        body.append(
            f'<line x1="{_PAD}" y1="{ty:.1f}" x2="{_W - 10}" y2="{ty:.1f}" stroke="#d62728" stroke-dasharray="6 4"/>'
        )
        body.append(
            f'<text x="{_W - 12}" y="{ty - 4:.1f}" font-size="10" text-anchor="end" fill="#d62728">tolerance {tolerance_deg:g}</text>'
        )
        path = " ".join(f"{x:.1f},{y:.1f}" for x, y in zip(px, py, strict=True))
        body.append(f'<polyline points="{path}" fill="none" stroke="#555"/>')
        for x, y, r in zip(px, py, history, strict=True):
            colour = "#2ca02c" if r.get("passed") else "#d62728"
            body.append(
                f'<circle cx="{x:.1f}" cy="{y:.1f}" r="4" fill="{colour}"><title>{escape(str(r.get("design")))} part {r.get("part")}</title></circle>'
            )
    return _frame("worst vertex error per part", "part (in order)", "worst error (deg)", body)
