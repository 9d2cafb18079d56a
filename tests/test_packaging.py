"""Packaging: every package folder is installed, under aquasim_py or aquasim_protocols only."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _folders(top: str, prefix: str) -> set[str]:
    base = ROOT / top
    return {
        ".".join([prefix, *p.parent.relative_to(base).parts]).rstrip(".")
        for p in base.rglob("__init__.py")
        if "__pycache__" not in p.parts
    }


def test_every_package_folder_is_listed_under_its_import_name() -> None:
    cfg = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    listed = set(cfg["packages"])
    on_disk = _folders("aquasim_py", "aquasim_py") | _folders("protocols", "aquasim_protocols")
    assert on_disk == listed, f"missing from pyproject: {sorted(on_disk - listed)}; stale: {sorted(listed - on_disk)}"
    assert cfg["package-dir"]["aquasim_protocols"] == "protocols"
    assert not any(p == "protocols" or p.startswith("protocols.") for p in listed)


def _site_packages() -> list[str]:
    import site

    return [p for p in site.getsitepackages() if Path(p).is_dir()]


@pytest.mark.skipif(sys.platform == "win32", reason="paths joined with ':'")
def test_builtins_load_from_the_repository_root_after_a_plain_install(tmp_path: Path) -> None:
    """A non-editable install, Python started in the repository root: ``aquasim_py`` is then the
    source folder (the current directory comes first on sys.path), and the built-in protocols
    still load, from the installed ``aquasim_protocols``."""
    target = tmp_path / "site"
    # the wheel of this checkout, installed into a folder of its own (no editable finder: -S
    # below keeps site-packages' .pth hooks out, and the dependencies come in by PYTHONPATH)
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--no-deps",
            "--disable-pip-version-check",
            "--target",
            str(target),
            str(ROOT),
        ],
        check=True,
        env={**os.environ, "CC": "/bin/false"},
    )
    code = (
        "import aquasim_py, aquasim_protocols, pathlib;"
        "assert pathlib.Path(aquasim_py.__file__).parent == pathlib.Path.cwd() / 'aquasim_py', aquasim_py.__file__;"
        "r = aquasim_py.run_scenario('scenarios/beacon.toml', overrides={'simulation.duration_s': 20});"
        "print(r.metrics['packets.sent'])"
    )
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONPATH": os.pathsep.join([str(target), *_site_packages()])}
    out = subprocess.run(
        [sys.executable, "-S", "-c", code], check=False, cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert int(out.stdout.strip()) > 0


def test_without_the_builtins_an_unknown_protocol_says_why(tmp_path: Path) -> None:
    """Only the source folder on the path (nothing installed): the error names the reason."""
    code = (
        "from aquasim_py import registry\n"
        "try:\n    registry.get('beacon')\nexcept registry.UnknownProtocolError as e:\n    print(e)\n"
    )
    # the dependencies without this project: a non-editable install (CI's no-compiler lane) has
    # aquasim_protocols in site-packages, which would load the built-ins
    deps = tmp_path / "deps"
    deps.mkdir()
    for sp in _site_packages():
        for entry in Path(sp).iterdir():
            if not entry.name.startswith(("aquasim", "__editable__")) and not (deps / entry.name).exists():
                (deps / entry.name).symlink_to(entry)
    env = {"PATH": os.environ.get("PATH", ""), "PYTHONPATH": str(deps)}
    out = subprocess.run(
        [sys.executable, "-S", "-c", code], check=False, cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert out.returncode == 0, out.stderr
    assert "built-in protocols" in out.stdout and "aquasim_protocols" in out.stdout and "pip install" in out.stdout
