"""The committed reproduction pages say how they were made: the exact command (in a code block)
and the commit whose code ran it, so that a reader can rerun them and tell a stale page."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

import aquasim_py.reproduce as rp

PAGES = Path(__file__).resolve().parents[2] / "docs" / "reproductions"


@pytest.mark.parametrize("key", sorted(rp.PAPERS))
def test_each_page_gives_its_command_and_commit(key):
    text = (PAGES / f"{key}.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```\n(.*?)```", text, flags=re.S)
    assert any(re.search(rf"\baquasim-py reproduce {key}\b", b) for b in blocks), key
    assert re.search(r"\bcommit `?[0-9a-f]{7,40}\b", text), key
    assert "](" + f"{key}.png)" in text, key  # the claims plot committed beside the page
    assert (PAGES / f"{key}.png").is_file()
