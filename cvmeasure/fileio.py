"""File I/O at the edges: atomic writes, append-only logs, JSON/CSV reading.

Every writer here is atomic (temporary file in the same folder, fsync, then
``os.replace``), so no exit ever leaves a half-written file. Every reader turns
a missing or malformed file into an :class:`~cvmeasure.errors.InputError` that
names the file.
"""

from __future__ import annotations

import csv
import io
import json
import os
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from cvmeasure.errors import InputError

__all__ = [
    "MAX_CSV_ROWS",
    "MAX_TEXT_BYTES",
    "check_outputs",
    "read_text_file",
    "atomic_write_bytes",
    "atomic_write_text",
    "atomic_write_json",
    "append_jsonl",
    "repair_jsonl_tail",
    "read_json",
    "read_jsonl",
    "read_csv_rows",
    "sniff_kind",
    "STDIO",
    "set_stdout",
    "MAX_JSON_REAL",
    "write_csv_rows",
    "to_jsonable",
]


#: The file name that means standard output (a writer) or standard input (a reader).
STDIO = "-"
#: Where a write to ``-`` goes (the CLI points it at the real stdout and sends its own
#: messages to stderr, so that ``cvmeasure simulate plan.csv -o - | ...`` gets only data).
_stdout: list[Any] = []


def set_stdout(stream: Any | None) -> None:
    """Send writes to ``-`` to ``stream`` (None: back to ``sys.stdout``)."""
    _stdout.clear()
    if stream is not None:
        _stdout.append(stream)


def _write_stdout(data: bytes) -> None:
    stream = _stdout[0] if _stdout else sys.stdout
    buffer = getattr(stream, "buffer", None)
    if buffer is not None:
        stream.flush()
        buffer.write(data)
        buffer.flush()
    else:
        stream.write(data.decode("utf-8"))
        stream.flush()


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically; return the path (``-``: standard output)."""
    path = Path(path)
    if os.fspath(path) == STDIO:
        _write_stdout(data)
        return path
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        # mkstemp makes the file private (0600); give it the mode a plain open() would.
        os.chmod(tmp, 0o666 & ~_current_umask())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except FileNotFoundError:
            pass
        raise
    return path


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically; return the path."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def to_jsonable(obj: Any) -> Any:
    """Convert numpy scalars/arrays, paths and dataclass-like objects to JSON types."""
    import numpy as np  # here, not on import: `cvmeasure --help` builds its parser without numpy

    if hasattr(obj, "to_dict") and callable(obj.to_dict):
        return to_jsonable(obj.to_dict())
    if isinstance(obj, Mapping):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, os.PathLike):
        return os.fspath(obj)
    return obj


def atomic_write_json(path: str | os.PathLike[str], obj: Any, *, indent: int | None = 2) -> Path:
    """Serialise ``obj`` (after :func:`to_jsonable`) to ``path`` atomically."""
    text = json.dumps(to_jsonable(obj), indent=indent, allow_nan=False)
    return atomic_write_text(path, text + "\n")


def append_jsonl(path: str | os.PathLike[str], record: Any) -> None:
    """Append one JSON object as one line to ``path`` and fsync it.

    A crash can at worst leave a partial last line, which :func:`read_jsonl`
    reports as such (``skip_partial_last=True`` ignores it when resuming); the next
    append cuts it first (:func:`repair_jsonl_tail`), so a log torn by a kill stays
    readable after any number of resumes.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    line = json.dumps(to_jsonable(record), allow_nan=False, separators=(",", ":")) + "\n"
    repair_jsonl_tail(path)
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(line)
        fh.flush()
        os.fsync(fh.fileno())


def repair_jsonl_tail(path: str | os.PathLike[str]) -> bool:
    """Cut a partial last line (a write interrupted by a kill); True when one was cut.

    A missing or empty file, or one that ends with a newline, is left as it is.
    """
    try:
        fh = open(path, "rb+")
    except FileNotFoundError:
        return False
    with fh:
        fh.seek(0, os.SEEK_END)
        size = fh.tell()
        if size == 0:
            return False
        fh.seek(size - 1)
        if fh.read(1) == b"\n":
            return False
        block = min(size, 1 << 20)
        fh.seek(size - block)
        tail = fh.read(block)
        cut = tail.rfind(b"\n")
        fh.truncate(size - block + cut + 1 if cut >= 0 else size - block)
        fh.flush()
        os.fsync(fh.fileno())
    return True


#: Largest text file (JSON, JSON Lines, CSV) a reader accepts, bytes.
MAX_TEXT_BYTES = 256 * 1024 * 1024
#: Most rows a CSV reader accepts (a trials table or manual readings are far smaller).
MAX_CSV_ROWS = 200_000


def read_text_file(path: str | os.PathLike[str], *, what: str, encoding: str = "utf-8") -> str:
    """The text of an input file; every way it can fail is an InputError naming the file.

    Not found, a folder, unreadable, larger than :data:`MAX_TEXT_BYTES`, or not
    text in ``encoding`` (a binary file) each get one line saying which.
    """
    path = Path(path)
    if os.fspath(path) == STDIO:
        try:
            return sys.stdin.buffer.read().decode(encoding)
        except UnicodeDecodeError as exc:
            raise InputError(
                "standard input", f"byte {exc.start} is not {encoding} text (a binary file?)"
            ) from None
    try:
        if path.is_dir():
            raise InputError(path, f"is a folder, not a {what}")
        size = path.stat().st_size
        if size > MAX_TEXT_BYTES:
            raise InputError(
                path, f"{what} is {size / 1e6:.0f} MB; more than {MAX_TEXT_BYTES / 1e6:.0f} MB"
            )
        return path.read_text(encoding=encoding)
    except FileNotFoundError:
        raise InputError(path, f"{what} not found") from None
    except UnicodeDecodeError as exc:
        raise InputError(
            path, f"not a {what}: byte {exc.start} is not {encoding} text (a binary file?)"
        ) from None
    except OSError as exc:
        raise InputError(path, f"cannot read {what}: {exc.strerror or exc}") from None


#: Largest magnitude of a real number in an input JSON document: nothing cvmeasure reads
#: (pixels, millimetres, degrees, coefficients) is anywhere near it, and 1e308 is corruption.
MAX_JSON_REAL = 1e15


class _BadNumber(ValueError):
    pass


def _real(text: str) -> float:
    value = float(text)
    if not abs(value) <= MAX_JSON_REAL:
        raise _BadNumber(f"the number {text} is out of any sensible range")
    return value


def _constant(text: str) -> float:
    raise _BadNumber(f"{text} is not a number JSON allows")


def _loads(text: str, path: Path, where: str) -> Any:
    try:
        return json.loads(text, parse_float=_real, parse_constant=_constant)
    except _BadNumber as exc:
        raise InputError(path, f"corrupt {where}: {exc}") from None
    except json.JSONDecodeError as exc:
        raise InputError(
            path, f"corrupt {where}: {exc.msg} at line {exc.lineno} column {exc.colno}"
        ) from None
    except RecursionError:
        raise InputError(path, f"corrupt {where}: nested too deeply") from None


def read_json(path: str | os.PathLike[str], *, what: str = "JSON file") -> Any:
    """Read a JSON file; raise InputError naming the file when it cannot be read.

    When ``what`` is one of the kinds cvmeasure writes ("board JSON", "camera JSON",
    ...) and the document is recognisably another (a camera JSON given as
    ``--board``), the error says which kind it is rather than which key it lacks.
    """
    path = Path(path)
    data = _loads(read_text_file(path, what=what), path, what)
    expected = _KIND_OF_WHAT.get(what)
    found = _json_kind(data) if expected is not None else None
    if found is not None and found != expected:
        raise InputError(path, f"is {found}, not a {what}")
    return data


def read_jsonl(
    path: str | os.PathLike[str], *, skip_partial_last: bool = False
) -> list[dict[str, Any]]:
    """Read a JSON Lines file into a list of dicts (one JSON object per line).

    With ``skip_partial_last`` a malformed *last* line (a write cut by a crash)
    is dropped instead of raising; any other malformed line, or a line that is
    valid JSON but not an object, raises InputError naming the file and line.
    """
    path = Path(path)
    lines = read_text_file(path, what="JSON Lines file").splitlines()
    records: list[dict[str, Any]] = []
    for number, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            record = json.loads(line)
        except (json.JSONDecodeError, RecursionError) as exc:
            if skip_partial_last and number == len(lines):
                break
            kind = sniff_kind(path)
            if kind is not None and not kind.startswith("JSON Lines"):
                raise InputError(path, f"is {kind}, not a JSON Lines file") from None
            why = exc.msg if isinstance(exc, json.JSONDecodeError) else "nested too deeply"
            raise InputError(path, f"corrupt JSON on line {number}: {why}") from None
        if not isinstance(record, dict):
            raise InputError(
                path, f"line {number} is a JSON {type(record).__name__}, not an object"
            )
        records.append(record)
    return records


def read_csv_rows(
    path: str | os.PathLike[str],
    *,
    required: Sequence[str] = (),
    max_rows: int = MAX_CSV_ROWS,
) -> list[dict[str, str]]:
    """Read a CSV with a header row into dicts; check the required columns exist.

    InputError (naming the file, and the line where it applies) for a file that
    cannot be read, missing columns, a row with more cells than the header, a
    cell over the csv module's field limit, or more than ``max_rows`` rows.
    """
    path = Path(path)
    text = read_text_file(path, what="CSV file", encoding="utf-8-sig")
    if "\x00" in text:
        line = text.count("\n", 0, text.index("\x00")) + 1
        raise InputError(path, f"line {line}: a NUL byte; not a text CSV (a damaged file?)")
    reader = csv.DictReader(io.StringIO(text))
    try:
        header = [h.strip() for h in (reader.fieldnames or [])]
        twice = sorted({h for h in header if header.count(h) > 1})
        if twice:
            raise InputError(
                path, f"column(s) {', '.join(twice)} appear more than once in the header"
            )
        missing = [c for c in required if c not in header]
        if missing:
            kind = sniff_kind(path)
            if kind is not None and not kind.startswith("a CSV"):
                raise InputError(path, f"is {kind}, not a CSV table")
            raise InputError(
                path, f"missing column(s) {', '.join(missing)}; has {', '.join(header)}"
            )
        rows = []
        for row in reader:
            if None in row:
                raise InputError(
                    path, f"line {reader.line_num}: more cells than the header's {len(header)}"
                )
            if len(rows) >= max_rows:
                raise InputError(path, f"more than {max_rows} rows")
            rows.append({(k or "").strip(): (v or "").strip() for k, v in row.items()})
    except csv.Error as exc:
        raise InputError(path, f"line {reader.line_num + 1}: not a valid CSV row: {exc}") from None
    return rows


#: JSON documents cvmeasure writes: the ``what`` a reader names it by, how an error
#: describes it, and the keys that tell it apart (first match wins).
_JSON_KINDS: tuple[tuple[str, str, tuple[str, ...]], ...] = (
    (
        "calibration JSON",
        "a calibration JSON (`cvmeasure fit` / `session`)",
        ("samples", "angles_deg"),
    ),
    ("camera JSON", "a camera JSON (`cvmeasure calibrate`)", ("camera_matrix", "dist_coeffs")),
    ("plane JSON", "a plane JSON (`cvmeasure plane`)", ("H_board_image",)),
    ("board JSON", "a board JSON (`cvmeasure targets charuco`)", ("squares_x",)),
    ("kit JSON", "a marker kit JSON", ("markers", "wire_diameter_mm")),
    ("diagnosis JSON", "a diagnosis JSON (`cvmeasure diagnose`)", ("cause", "candidates")),
    ("part JSON", "a part result JSON (`cvmeasure part`)", ("radius_mm", "arc_angle_deg")),
    # SimParams' own keys: `diagnose --save-params` writes them with a "diagnosis" record
    ("params JSON", "a simulation params JSON", ("yield_mpa", "die_radius_mm")),
)
#: ``read_json``'s ``what`` -> the kind it expects (its description in ``_JSON_KINDS``).
_KIND_OF_WHAT: dict[str, str] = {what: kind for what, kind, _ in _JSON_KINDS}
_MAGIC: tuple[tuple[bytes, str], ...] = (
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"II*\x00", "a TIFF image"),
    (b"MM\x00*", "a TIFF image"),
    (b"%PDF", "a PDF document"),
    (b"PK\x03\x04", "a ZIP archive (or an Office document)"),
    (b"\x1f\x8b", "a gzip archive"),
)


def sniff_kind(path: str | os.PathLike[str]) -> str | None:
    """What kind of file ``path`` looks like, in words ("a camera JSON", "a JPEG image").

    For messages that refuse a file of the wrong kind: ``report cal.json`` can say the
    file is a calibration JSON rather than "corrupt JSON on line 1". None when the file
    cannot be read or is of no kind recognised here.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
        for magic, kind in _MAGIC:
            if head.startswith(magic):
                return kind
        stripped = head.lstrip(b"\xef\xbb\xbf \t\r\n")
        if stripped[:5].lower() in (b"<?xml", b"<svg ") or b"<svg" in head[:1024]:
            return "an SVG drawing"
        if stripped.startswith((b"{", b"[")):
            return _sniff_json(Path(path))
        if b"\x00" in head:
            return "a binary file"
        first = stripped.split(b"\n", 1)[0]
        if first.count(b",") >= 1 and not first.startswith((b"N", b"G", b"(")):
            return "a CSV table"
        if first[:1] in (b"N", b"G", b"M", b"(", b";"):
            return "a G-code file"
    except OSError:
        return None
    return None


def _sniff_json(path: Path) -> str | None:
    try:
        text = path.read_text(encoding="utf-8")
        obj = json.loads(text)
    except (OSError, UnicodeDecodeError, RecursionError):
        return None
    except json.JSONDecodeError:
        lines = [ln for ln in text.splitlines() if ln.strip()]
        try:
            records = [json.loads(ln) for ln in lines[:3]]
        except (json.JSONDecodeError, RecursionError):
            return None
        return "JSON Lines (one record per line)" if len(records) > 1 else None
    if isinstance(obj, dict):
        if len([ln for ln in text.splitlines() if ln.strip()]) == 1:
            return "JSON Lines (one record per line)"
        return _json_kind(obj) or "a JSON document"
    return "a JSON list" if isinstance(obj, list) else "a JSON value"


def _json_kind(obj: Any) -> str | None:
    """The kind of cvmeasure document ``obj`` is (``_JSON_KINDS``), or None."""
    if isinstance(obj, dict):
        for _, kind, keys in _JSON_KINDS:
            if all(k in obj for k in keys):
                return kind
    return None


def write_csv_rows(
    path: str | os.PathLike[str], rows: Iterable[Mapping[str, Any]], columns: Sequence[str]
) -> Path:
    """Write rows (dicts) with the given column order to a CSV, atomically."""
    buf = io.StringIO()
    writer = csv.DictWriter(
        buf, fieldnames=list(columns), extrasaction="ignore", lineterminator="\n"
    )
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _csv_cell(row.get(k)) for k in columns})
    return atomic_write_text(path, buf.getvalue())


def _csv_cell(value: Any) -> Any:
    if isinstance(value, float):
        return f"{value:.6f}"
    return "" if value is None else value


def check_outputs(
    outputs: Mapping[str, str | os.PathLike[str]],
    inputs: Iterable[str | os.PathLike[str]],
    *,
    folders: Iterable[str] = (),
) -> None:
    """Check where a command will write before it reads or writes anything.

    ``outputs`` maps a name (what the error says, e.g. ``--out``) to a path;
    names in ``folders`` are output folders, the others files. Raises
    :class:`InputError` naming the path when an output file is one of ``inputs``
    (it would overwrite the input), is an existing folder, or an output folder is
    an existing file. Paths are compared after resolving links.

    >>> check_outputs({"--out": "a.csv"}, ["b.csv"])  # fine: nothing returned
    """
    folder_names = set(folders)
    resolved_inputs = {}
    for path in inputs:
        try:
            resolved_inputs[Path(path).resolve()] = Path(path)
        except OSError:  # an unreadable input is the reader's to report
            continue
    for name, path in outputs.items():
        target = Path(path)
        if name in folder_names:
            if target.exists() and not target.is_dir():
                raise InputError(target, f"{name} must be a folder, but a file of that name exists")
            continue
        if target.is_dir():
            raise InputError(target, f"{name} is a folder; give a file name")
        if target.resolve() in resolved_inputs:
            raise InputError(target, f"{name} is also an input: refusing to overwrite it")
