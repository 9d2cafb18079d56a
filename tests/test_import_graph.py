"""tools/import_graph.py: every import kind counts, and the package has no cycle (issue 32)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def ig():
    spec = importlib.util.spec_from_file_location("import_graph", ROOT / "tools" / "import_graph.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["import_graph"] = mod
    spec.loader.exec_module(mod)
    return mod


def _package(tmp_path: Path, files: dict[str, str]) -> dict[Path, str]:
    pkg = tmp_path / "pkg"
    for name, text in files.items():
        f = pkg / name
        f.parent.mkdir(parents=True, exist_ok=True)
        f.write_text(text)
    return {pkg: "pkg"}


@pytest.mark.parametrize(
    ("a_text", "kind"),
    [
        ("from pkg import b\n", "top"),
        ("def f():\n    from pkg.b import g\n    return g\n", "lazy"),
        ("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from pkg.b import g\n", "typing"),
    ],
)
def test_a_cycle_of_any_kind_is_found(ig, tmp_path, a_text, kind):
    src = _package(tmp_path, {"__init__.py": "", "a.py": a_text, "b.py": "from pkg.a import x\ng = 1\n"})
    g = ig.graph(src)
    assert ("pkg.a", "pkg.b", kind) in set(g.edges(data="kind"))
    assert ig.cycles(g, {"top", "lazy", "typing"}) == [["pkg.a", "pkg.b"]]


def test_an_extension_module_is_a_leaf_not_the_package(ig, tmp_path):
    # `from . import _ext` (a compiled module: only its stub is in the source tree) names _ext,
    # not the package whose __init__ may import the importer lazily
    src = _package(
        tmp_path,
        {
            "__init__.py": "def __getattr__(n):\n    from pkg import a\n    return a\n",
            "a.py": "from . import _ext\n",
            "_ext.pyi": "def f() -> int: ...\n",
        },
    )
    g = ig.graph(src)
    assert ("pkg.a", "pkg._ext", "top") in set(g.edges(data="kind"))
    assert ig.cycles(g, {"top", "lazy", "typing"}) == []


def test_the_repository_has_no_import_cycle(ig, capsys):
    assert ig.main([]) == 0, capsys.readouterr().out
    assert "cycles among all imports (with lazy and TYPE_CHECKING ones): 0" in capsys.readouterr().out
