"""What every printable sheet shares: its formats and how a figure becomes file bytes."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any, Literal

__all__ = ["SheetFormat", "sheet_format", "figure_bytes"]

SheetFormat = Literal["pdf", "svg", "png"]


def sheet_format(path: Path, fmt: str | None) -> SheetFormat:
    """The sheet format: ``fmt`` when given, else the file suffix; ValueError when unsupported."""
    f = (fmt or path.suffix.lstrip(".")).lower()
    if f not in ("pdf", "svg", "png"):
        raise ValueError(f"unsupported sheet format {f!r}: use .pdf, .svg or .png")
    return f  # type: ignore[return-value]


def figure_bytes(fig: Any, fmt: SheetFormat, *, dpi: float) -> bytes:
    """Save a matplotlib figure at true scale to bytes (PNG at ``dpi``, tagged with it)."""
    buf = io.BytesIO()
    kwargs: dict[str, Any] = {"format": fmt, "facecolor": "white"}
    if fmt == "png":
        kwargs["dpi"] = dpi
        kwargs["pil_kwargs"] = {"dpi": (dpi, dpi)}
    fig.savefig(buf, **kwargs)
    return buf.getvalue()
