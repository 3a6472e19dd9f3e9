"""The docs are for users: short pages, no session history, every page reachable.

README at most 1,500 words; every page in docs/ under 4,000; no commit hashes, development
seeds or tuning history in the README, docs/ or the runnable examples (history belongs to
CHANGELOG.md and benchmarks/RESULTS.md); the seed paper cited with author, title,
institution and year; every docs page linked from the README or docs/.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PAGES = sorted((ROOT / "docs").rglob("*.md"))
USER_TEXT = [ROOT / "README.md", *PAGES, *sorted((ROOT / "docs" / "examples").glob("*.py"))]

#: A git commit hash: 7-40 hex digits with at least one letter and one digit.
HASH = re.compile(r"\b(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}\b")
#: Development seeds and tuning history ("dev seed 2000", "seeds 100000-100029", "part14s").
HISTORY = re.compile(
    r"(?i)\b(dev(elopment)?\s+(seeds?|sets?|parts?|renders?|B\d)|tuning seeds?|seeds?\s+\d{3,}"
    r"|part14[a-z]|stop \d+|scratch (driver|harness|run))"
)


def _words(path: Path) -> int:
    return len(path.read_text(encoding="utf-8").split())


def test_readme_is_short():
    assert _words(ROOT / "README.md") <= 1500


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(ROOT)))
def test_pages_are_short(page):
    assert _words(page) < 4000


@pytest.mark.parametrize("path", USER_TEXT, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_history_in_user_text(path):
    text = path.read_text(encoding="utf-8")
    assert HASH.findall(text) == []
    assert [m.group(0) for m in HISTORY.finditer(text)] == []


def test_history_patterns_would_be_caught():
    assert HASH.search("regenerated at 828bf55 on main")
    assert not HASH.search("a 4608x3072 photo, colour #ffcc00, 1234567 bends")
    assert HISTORY.search("development seed 310064") and HISTORY.search("(part14s)")


def test_seed_paper_cited():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    for part in (
        "Mahmoud Abdel",
        "Improving accuracy in 2D wire bending machines",
        "Detmold",
        "2020",
    ):
        assert part in readme, part


def test_every_page_is_linked():
    linked = " ".join(p.read_text(encoding="utf-8") for p in [ROOT / "README.md", *PAGES])
    for page in PAGES:
        rel = page.relative_to(ROOT).as_posix()
        assert rel in linked or page.parent.relative_to(ROOT).as_posix() + "/" in linked, rel


#: Every library module: no development seeds or tuning history in code comments either.
LIBRARY = sorted((ROOT / "cvmeasure").rglob("*.py"))


@pytest.mark.parametrize("path", LIBRARY, ids=lambda p: str(p.relative_to(ROOT)))
def test_no_history_in_library_comments(path):
    text = path.read_text(encoding="utf-8")
    assert [m.group(0) for m in HISTORY.finditer(text)] == []
    assert HASH.findall(text) == []
