"""Import structure, observed by importing in fresh interpreters: the channel loads without the
kernel, modules load on their own (an import cycle shows up as a partially initialized
module when the cycle is entered from the wrong end), and the heavy libraries load only
where they are used (start-up time)."""

from __future__ import annotations

import json
import math
import resource
import subprocess
import sys
import textwrap
import time
from pathlib import Path

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


#: loaded only by the code that uses them: never by ``import aquasim_py``, ``aquasim-py --version``
#: or ``--help``, nor by the modules a run loads before its first event
HEAVY = ("scipy", "pandas", "networkx", "matplotlib", "sklearn", "numba")

#: the top-level packages loaded after each step (argv[1:]), in one fresh interpreter per step
_STEP = textwrap.dedent(
    """
    import contextlib, io, json, sys
    step = sys.argv[1]
    if step == "import":
        import aquasim_py
    elif step == "run-modules":  # what a run imports before its first event
        import aquasim_py.cli.run, aquasim_py.kernel, aquasim_py.runner, aquasim_py.scenario
        from aquasim_py import registry
        registry.available()  # imports every built-in protocol family
    else:
        from aquasim_py.cli import main
        with contextlib.redirect_stdout(io.StringIO()):
            assert main(sys.argv[2:]) == 0
    print(json.dumps(sorted({m.partition(".")[0] for m in sys.modules})))
    """
)


@pytest.mark.parametrize(
    "step",
    [["import"], ["cli", "--version"], ["cli", "--help"], ["cli", "sweep", "--help"], ["cli", "report", "--help"]],
    ids=" ".join,
)
def test_startup_loads_no_heavy_module(step):
    loaded = _python(_STEP, *step)
    assert isinstance(loaded, list) and "aquasim_py" in loaded
    assert not [m for m in HEAVY if m in loaded]
    if step != ["import"]:  # the command needs neither numpy nor pydantic until it runs something
        assert "numpy" not in loaded and "pydantic" not in loaded


def test_a_run_loads_heavy_modules_only_where_used():
    """The kernel, the runner and every built-in protocol load neither scipy nor the plotting,
    graph, learning or compiler libraries; pandas may come with the trace (its CSV writer and
    tables use it in every run)."""
    loaded = _python(_STEP, "run-modules")
    assert isinstance(loaded, list) and "aquasim_protocols" in loaded
    assert set(HEAVY) & set(loaded) <= {"pandas"}


def test_version_is_quick():
    """``aquasim-py --version`` takes well under 0.3 s on an idle machine (docs/performance.md);
    checked on its CPU time, which load barely changes, with the wall time as a loose bound."""
    exe = Path(sys.executable).parent / "aquasim-py"
    cmd = [str(exe)] if exe.exists() else [sys.executable, "-m", "aquasim_py.cli"]
    best_cpu = best_wall = math.inf
    for _ in range(3):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        r = subprocess.run([*cmd, "--version"], check=False, capture_output=True, text=True, timeout=60)
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        assert r.returncode == 0 and r.stdout.startswith("aquasim-py "), r.stderr
        cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
        best_cpu, best_wall = min(best_cpu, cpu), min(best_wall, wall)
    assert best_cpu < 0.3, f"aquasim-py --version used {best_cpu:.2f} s of CPU"
    assert best_wall < 3.0, f"aquasim-py --version took {best_wall:.2f} s"
