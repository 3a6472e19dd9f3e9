"""Typed warnings shared by every stage.

A stage that measures, fits or runs something and finds a reason to doubt its
result says so with a :class:`StageWarning`: a stable machine code (what tests,
benchmarks, the app and batch records match on), one sentence for the operator,
and the subject it is about (a file, a marker role, a bend number, ``"plane"``).
Codes are ``snake_case`` and listed in ``docs/conventions.md``; the prose may
change, the code may not.

In JSON a warning is an object ``{"code": ..., "message": ..., "subject": ...}``.
Readers also accept the older form, a string ``"code: message"`` (or prose with
no code, read as code ``"unspecified"``), so records written before the type
existed still load.

Examples
--------
>>> from cvmeasure.warning import StageWarning
>>> w = StageWarning("part_lifted", "the part stands 1.2 mm off the board", "part.jpg")
>>> str(w)
'part_lifted: the part stands 1.2 mm off the board (part.jpg)'
>>> StageWarning.from_json(w.to_json()) == w
True
>>> StageWarning.from_json("plane_pose: the plane was measured from another pose").code
'plane_pose'
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

__all__ = ["StageWarning", "codes", "has_code"]

_CODE = re.compile(r"^[a-z][a-z0-9_]*$")
UNSPECIFIED = "unspecified"


@dataclass(frozen=True)
class StageWarning:
    """One reason to doubt a result.

    Parameters
    ----------
    code : str
        Stable ``snake_case`` code (``docs/conventions.md`` lists them).
    message : str
        One sentence for the operator: what is wrong and, where known, what to do.
    subject : str, optional
        What the warning is about: a file path, a marker role, ``"bend 4"``,
        ``"plane"``. Empty when it is about the whole result.
    """

    code: str
    message: str
    subject: str = ""

    def __post_init__(self) -> None:
        if not _CODE.match(self.code):
            raise ValueError(f"warning code {self.code!r} is not snake_case")

    def __str__(self) -> str:
        text = f"{self.code}: {self.message}"
        return f"{text} ({self.subject})" if self.subject else text

    def to_json(self) -> dict[str, str]:
        """The JSON object form: ``{"code", "message", "subject"}``."""
        return {"code": self.code, "message": self.message, "subject": self.subject}

    @classmethod
    def from_json(cls, value: object) -> StageWarning:
        """Read a warning from its JSON object, or from the older ``"code: message"`` string.

        Raises
        ------
        ValueError
            When ``value`` is neither a string nor an object with ``code`` and ``message``.
        """
        if isinstance(value, dict):
            try:
                return cls(str(value["code"]), str(value["message"]), str(value.get("subject", "")))
            except KeyError as exc:
                raise ValueError(f"a warning object needs {exc.args[0]!r}") from None
        if isinstance(value, str):
            head, sep, rest = value.partition(":")
            if sep and _CODE.match(head.strip()):
                return cls(head.strip(), rest.strip())
            return cls(UNSPECIFIED, value.strip())
        raise ValueError(f"a warning must be an object or a string, not {type(value).__name__}")


def codes(warnings: Iterable[StageWarning]) -> set[str]:
    """The set of codes among ``warnings``.

    >>> codes([StageWarning("a_b", "x"), StageWarning("c", "y")]) == {"a_b", "c"}
    True
    """
    return {w.code for w in warnings}


def has_code(warnings: Iterable[StageWarning], code: str) -> bool:
    """Whether any of ``warnings`` carries ``code``.

    >>> has_code([StageWarning("part_lifted", "x")], "part_lifted")
    True
    """
    return any(w.code == code for w in warnings)
