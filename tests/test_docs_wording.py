"""The user pages describe the project as it is: no account of how it was developed (issue
numbers, helpers, operators, stopped sessions). History belongs in CHANGELOG.md, which
docs/changelog.md only includes."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = sorted(
    p
    for p in [ROOT / "README.md", *(ROOT / "docs").rglob("*")]
    if p.suffix in {".md", ".py", ".toml"} and p.name != "changelog.md" and "_build" not in p.parts
)

#: words about the project's development, not about what it does
WORDS = re.compile(
    r"\bissues?\s*#?\d+|\bthe issue\b|\bissue's\b|\bhelpers?\b|\boperators?\b|\bstopped (?:once|twice|by)\b",
    re.IGNORECASE,
)


def test_the_pages_are_found():
    names = {p.relative_to(ROOT).as_posix() for p in PAGES}
    assert {"README.md", "docs/index.md", "docs/reproductions/stvf.md"} <= names


@pytest.mark.parametrize("page", PAGES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_words_about_how_the_project_was_developed(page):
    hits = [
        f"{i}: {line.strip()}"
        for i, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1)
        if WORDS.search(line)
    ]
    assert not hits, "\n".join(hits)


@pytest.mark.parametrize(
    "line",
    [
        "as issue 33 asks",
        "Before issue 33 the default",
        "see #41 (issue #41)",
        "the other helpers idle",
        "stopped by its operator",
        "stopped twice and resumed",
        "The issue's goal",
    ],
)
def test_the_pattern_catches_such_words(line):
    assert WORDS.search(line)
