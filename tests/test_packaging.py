"""Packaging: every package folder is installed, under the aquasim_py namespace only."""

from __future__ import annotations

import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _folders(top: str, prefix: str) -> set[str]:
    base = ROOT / top
    return {
        ".".join([prefix, *p.parent.relative_to(base).parts]).rstrip(".")
        for p in base.rglob("__init__.py")
        if "__pycache__" not in p.parts
    }


def test_every_package_folder_is_listed_under_the_aquasim_py_namespace() -> None:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    on_disk = _folders("aquasim_py", "aquasim_py") | _folders("protocols", "aquasim_py.protocols")
    assert on_disk == listed, f"missing from pyproject: {sorted(on_disk - listed)}; stale: {sorted(listed - on_disk)}"
    assert cfg["package-dir"]["aquasim_py.protocols"] == "protocols"
    assert not any(p == "protocols" or p.startswith("protocols.") for p in listed)
