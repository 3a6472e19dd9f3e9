"""A G-code job as the streamer sends it: checked, numbered lines.

Every line carries an ``N`` number (added when the file has none), so the board's
``sr.line`` says which line the machine is executing, and a journal can name lines.
"""

from __future__ import annotations

import hashlib
from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from cvmeasure.driver.protocol import GcodeBlock, GcodeError, encode_line, parse_block
from cvmeasure.errors import InputError

__all__ = ["JobLine", "prepare_job", "job_sha256"]


@dataclass(frozen=True)
class JobLine:
    """One line of a job: its index, ``N`` number, text and bytes on the wire."""

    index: int
    number: int
    text: str
    block: GcodeBlock

    @property
    def nbytes(self) -> int:
        return len(self.text) + 1


def prepare_job(lines: Iterable[str], *, source: str = "job") -> list[JobLine]:
    """Check and number a job's lines.

    Blank and comment-only lines are dropped. Either every line carries an
    ``N`` word (strictly increasing, >= 1) or none does, and then N1, N2, ...
    are added. Every line must be sendable (:func:`encode_line`) and parse.

    Raises
    ------
    InputError
        Naming ``source`` and the line that is wrong.
    """
    texts = [t.strip() for t in lines]
    texts = [t for t in texts if t and t[0] not in "(;"]
    if not texts:
        raise InputError(source, "job has no G-code lines")
    blocks: list[GcodeBlock] = []
    for i, t in enumerate(texts, start=1):
        try:
            encode_line(t)
            blocks.append(parse_block(t))
        except (ValueError, GcodeError) as exc:
            raise InputError(source, f"line {i}: {exc}") from None
    numbered = [b.line_number is not None for b in blocks]
    if not any(numbered):
        texts = [f"N{i} {t}" for i, t in enumerate(texts, start=1)]
        blocks = [parse_block(t) for t in texts]
    elif not all(numbered):
        raise InputError(source, "some lines have N numbers and some do not")
    out: list[JobLine] = []
    previous = 0
    for i, (t, b) in enumerate(zip(texts, blocks, strict=True)):
        number = int(b.line_number or 0)
        if number <= previous:
            raise InputError(source, f"line {i + 1}: N{number} does not increase (N0 is reserved)")
        previous = number
        try:
            encode_line(t)
        except ValueError as exc:
            raise InputError(source, f"line {i + 1}: {exc}") from None
        out.append(JobLine(i, number, t, b))
    return out


def job_sha256(job: Sequence[JobLine]) -> str:
    """Identity of a job (its numbered lines) for the journal."""
    return hashlib.sha256("\n".join(j.text for j in job).encode("ascii")).hexdigest()
