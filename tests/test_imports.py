"""Import structure, observed by importing in fresh interpreters: the channel loads without the
kernel, and modules load on their own (an import cycle shows up as a partially initialized
module when the cycle is entered from the wrong end)."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

#: the kernel / channel seam and what sits on either side of it
SEAM = [
    "aquasim_py.radio",
    "aquasim_py.packet",
    "aquasim_py.channel",
    "aquasim_py.channel.acoustic",
    "aquasim_py.node",
    "aquasim_py.kernel",
]

#: prints the aquasim_py modules loaded after importing each module named in argv[1:] alone
#: (every aquasim_py module is dropped from sys.modules first; third-party ones stay loaded)
_ALONE = textwrap.dedent(
    """
    import importlib, json, sys
    out = {}
    for name in sys.argv[1:]:
        for m in [m for m in sys.modules if m == "aquasim_py" or m.startswith("aquasim_py.")]:
            del sys.modules[m]
        try:
            importlib.import_module(name)
            out[name] = sorted(m for m in sys.modules if m.startswith("aquasim_py."))
        except Exception as e:
            out[name] = f"{type(e).__name__}: {e}"
    print(json.dumps(out))
    """
)

#: every module of the installed package (discovery imports the packages, so run it apart)
_LIST = textwrap.dedent(
    """
    import json, pkgutil
    import aquasim_py, aquasim_protocols
    names = {"aquasim_py"}
    for pkg in (aquasim_py, aquasim_protocols):
        names.update(m.name for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + "."))
    print(json.dumps(sorted(names)))
    """
)


def _python(code: str, *args: str) -> object:
    r = subprocess.run([sys.executable, "-c", code, *args], check=False, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def seam_alone() -> dict[str, object]:
    """Each seam module imported alone (one interpreter for all: the imports are the slow part)."""
    loaded = _python(_ALONE, *SEAM)
    assert isinstance(loaded, dict)
    return loaded


def test_channel_loads_without_kernel_or_node(seam_alone):
    loaded = seam_alone
    channel = loaded["aquasim_py.channel.acoustic"]
    assert isinstance(channel, list), channel
    assert "aquasim_py.radio" in channel
    assert "aquasim_py.kernel" not in channel and "aquasim_py.node" not in channel
    # the interface module is neutral: neither side comes with it
    radio = loaded["aquasim_py.radio"]
    assert isinstance(radio, list), radio
    assert not [m for m in radio if m.startswith(("aquasim_py.kernel", "aquasim_py.node", "aquasim_py.channel"))]


def test_seam_modules_load_alone(seam_alone):
    failed = {k: v for k, v in seam_alone.items() if isinstance(v, str)}
    assert not failed


@pytest.mark.slow
def test_every_module_loads_alone_in_a_fresh_interpreter():
    names = _python(_LIST)
    assert isinstance(names, list) and "aquasim_py.kernel" in names and "aquasim_protocols.beacon" in names
    failed = {}
    for name in names:
        r = subprocess.run(
            [sys.executable, "-c", f"import {name}"], check=False, capture_output=True, text=True, timeout=300
        )
        if r.returncode:
            failed[name] = r.stderr.strip().splitlines()[-1]
    assert not failed
