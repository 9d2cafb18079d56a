"""The examples of the docs run as printed: the protocol of docs/node.md ("Writing a protocol")
and the README's ten-line example."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MARKER = "<!-- example: kernel -->"


def _example_source() -> tuple[Path, str]:
    path = ROOT / "docs" / "node.md"
    text = path.read_text(encoding="utf-8")
    if MARKER not in text:
        pytest.fail(f"{path} does not contain {MARKER}")
    m = re.search(r"```python\n(.*?)```", text[text.index(MARKER) :], re.S)
    if m is None:
        pytest.fail(f"{path}: no ```python block after {MARKER}")
    return path, m.group(1)


def test_readme_protocol_example_runs(tmp_path, monkeypatch, capsys):
    path, code = _example_source()
    monkeypatch.chdir(tmp_path)  # anything the example writes stays in the temporary directory
    namespace = {"__name__": "readme_example"}
    exec(compile(code, f"{path.name}:example", "exec"), namespace)
    out = capsys.readouterr().out
    assert "error" in out  # it printed its estimates table
    est = namespace["est"]
    assert len(est) >= 5
    assert (est["error"] < 5.0).all()


def test_readme_example_runs(monkeypatch, tmp_path, capsys):
    """The README's ten-line example runs as printed (scenario paths from the repository root)."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    m = re.search(r"## A run from Python\n\n```python\n(.*?)```", text, re.S)
    assert m is not None, "README.md: no python block under 'A run from Python'"
    code = m.group(1).replace('"scenarios/', f'"{ROOT.as_posix()}/scenarios/')
    monkeypatch.chdir(tmp_path)  # what it writes (out/beacon-7) stays in the temporary directory
    exec(compile(code, "README.md:example", "exec"), {"__name__": "readme_example"})
    out = capsys.readouterr().out
    assert "itmtl" in out and "wsc" in out  # the comparison table, one row per variant
    assert (tmp_path / "out" / "beacon-7" / "summary.json").exists()
