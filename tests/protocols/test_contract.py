"""The contract every registered protocol keeps, checked over the whole registry.

Each built-in protocol runs a tiny scenario (a shipped scenario, shortened) and must:

- give byte-identical trace files when run twice with the same seed;
- write the documented columns of the tables it fills (``estimates``, ``clocks``);
- never reach ground truth while it runs: no function of the kernel's truth (true positions
  and velocities in :mod:`aquasim_py.mobility`, true clocks in :mod:`aquasim_py.clock`, the
  simulation and channel internals, the trace tables, SimPy's true ``now``) is called directly
  from protocol code. A profile hook watches every call made from a frame of a file under
  ``protocols/`` during ``run``; calls through the node API (``depth()``, ``local_time()``,
  ...) are fine: the kernel answers them with noisy, local views.

A protocol added to the registry without a tiny scenario here fails ``test_every_protocol_has_a_case``.

Python has no privacy, so the rest of the contract is read from the source: a lint over the
shipped protocols (``protocols/**/*.py``) rejects the ways around the node API that a profile
hook cannot see: reading another object's underscore attributes (``x._y`` with ``x`` not
``self``/``cls``/``super()``), the introspection modules (``inspect``, ``gc``, ``ctypes``,
``sys._getframe``), and shared mutable class state (a class-level list/dict/set that code
mutates: one node's object, seen by all, is a channel that needs no packet).
"""

from __future__ import annotations

import ast
import filecmp
import sys
from pathlib import Path
from types import FrameType
from typing import Any, ClassVar

import pytest

from aquasim_py import registry, scenario, trace
from aquasim_py.channel import Constant
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import Box, ConstantVelocity
from aquasim_py.node import Node

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "scenarios"
PROTOCOLS_DIR = str(ROOT / "protocols")

# protocol -> (shipped scenario[#variant], --set overrides that make it tiny or switch to the protocol)
_ITMTL = ["simulation.duration_s=70.0"]


def _swap(name: str) -> list[str]:
    return [*_ITMTL, f'nodes.0.protocol="{name}"', f'nodes.1.protocol="{name}"', "nodes.1.params={}"]


CASES: dict[str, tuple[str, list[str]]] = {
    "beacon": ("beacon.toml", ["simulation.duration_s=40.0"]),
    "itmtl": ("itmtl.toml", _ITMTL),
    "tshl": ("itmtl.toml", _swap("tshl")),
    "mu_sync": ("itmtl.toml", _swap("mu_sync")),
    "mobi_sync": ("itmtl.toml", _swap("mobi_sync")),
    "ramezani": ("ramezani_localization.toml", ["simulation.duration_s=30.0"]),
    "mswpf": ("mswpf_2d.toml", ["simulation.duration_s=50.0"]),  # tracking starts at 45 s
    "svlpf": ("svlpf_gaussian.toml", ["simulation.duration_s=6.0"]),
    "stvf": ("stvf_quick.toml", ["simulation.duration_s=4.0"]),
    "slmp": (
        "stvf_quick.toml",
        [
            "simulation.duration_s=4.0",
            'nodes.0.protocol="slmp"',
            'nodes.1.protocol="slmp"',
            "nodes.0.params={training_s=1.0}",
            "nodes.1.params={training_s=1.0}",
        ],
    ),
    "genie_multilateration": ("stvf_quick.toml#genie_multilateration", ["simulation.duration_s=22.0"]),
    "traffic": (
        "mac_compare.toml#csma",
        ["simulation.duration_s=100.0", "nodes.1.count=20", 'trace.tables=["nodes", "packets"]'],
    ),
    "multilateration_all_refs": (
        "stvf_quick.toml",
        [
            "simulation.duration_s=4.0",
            'nodes.0.protocol="multilateration_all_refs"',
            'nodes.1.protocol="multilateration_all_refs"',
            "nodes.0.params={training_s=1.0}",
            "nodes.1.params={training_s=1.0}",
        ],
    ),
}

# documented columns (docs/node.md, "Trace tables"); protocols may add their own
DOCUMENTED = {
    "estimates": {"time", "node", "protocol", "x", "y", "z", "true_x", "true_y", "true_z", "error"},
    "clocks": {"time", "node", "protocol", "skew", "offset", "true_skew", "true_offset", "error"},
    "packets": {"time", "event", "reason", "node", "src", "dst", "uid", "kind", "bits", "tof", "snr_db"},
}

# files whose functions hold or compute ground truth; protocol code must not call into them
_TRUTH_FILES = tuple(
    str(ROOT / "aquasim_py" / f)
    for f in (
        "kernel.py",
        "nodecore.py",
        "mobility/",
        "clock.py",
        "trace/",
        "channel/acoustic.py",
        "channel/links.py",
        "channel/modem.py",
    )
)


def _builtin_protocols() -> list[str]:
    return [n for n in registry.available() if registry.get(n).__module__.startswith("aquasim_protocols.")]


def test_every_protocol_has_a_case() -> None:
    missing = sorted(set(_builtin_protocols()) - set(CASES))
    assert not missing, f"add a tiny scenario for {missing} to CASES"


def _watch(run: Any, code_files: tuple[str, ...]) -> list[str]:
    """Call ``run()`` while watching calls made from frames of ``code_files`` (path prefixes)
    into the truth files; returns one line per offending call site."""
    leaks: list[str] = []

    def hook(frame: FrameType, event: str, arg: Any) -> None:
        if event != "call":
            return
        caller = frame.f_back
        if caller is None or not caller.f_code.co_filename.startswith(code_files):
            return
        callee = frame.f_code.co_filename
        is_now = callee.endswith("simpy/core.py") and frame.f_code.co_name == "now"
        if callee.startswith(_TRUTH_FILES) or is_now:
            where = Path(callee)
            shown = where.relative_to(ROOT / "aquasim_py") if where.is_relative_to(ROOT / "aquasim_py") else where.name
            leaks.append(
                f"{Path(caller.f_code.co_filename).name}:{caller.f_lineno} calls {shown}:{frame.f_code.co_name}"
            )

    sys.setprofile(hook)
    try:
        run()
    finally:
        sys.setprofile(None)
    return leaks


def _run(name: str, out: Path, watch: bool = False) -> list[str]:
    """Build and run the case, write its traces to ``out``; returns the truth calls seen."""
    file, overrides = CASES[name]
    file, _, variant = file.partition("#")
    sc = scenario.load(SCENARIOS / file, overrides=overrides)
    if variant:
        sc = scenario.resolve(sc, variant=variant)
    sim = scenario.build(sc)
    until = sc.simulation.duration_s
    leaks = _watch(lambda: sim.run(until=until), (PROTOCOLS_DIR,)) if watch else (sim.run(until=until) or [])
    # the tables a run writes: the scenario's [trace] tables when it names them (a wall-clock
    # table such as mswpf_timing is measured, not simulated, and is left out there)
    frames = sim.trace.frames()
    wanted = sc.trace.tables
    trace.write_frames({k: v for k, v in frames.items() if not wanted or k in wanted}, out)
    return leaks


@pytest.mark.parametrize("name", sorted(CASES))
def test_protocol_contract(name: str, tmp_path: Path) -> None:
    assert name in registry.available()
    leaks = _run(name, tmp_path / "a", watch=True)
    assert not leaks, "protocol code reached ground truth:\n" + "\n".join(sorted(set(leaks)))
    _run(name, tmp_path / "b")
    files = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert files == sorted(p.name for p in (tmp_path / "b").iterdir())
    _same, mismatch, errors = filecmp.cmpfiles(tmp_path / "a", tmp_path / "b", files, shallow=False)
    assert not mismatch and not errors, f"rerun with the same seed differs in {mismatch + errors}"

    import pandas as pd

    own_rows = 0  # rows the protocol logged, in the documented tables or its own
    for path in sorted((tmp_path / "a").glob("*.csv")):
        df = pd.read_csv(path)
        cols = DOCUMENTED.get(path.stem)
        if cols is not None:
            assert cols <= set(df.columns), f"{path.name} lacks {sorted(cols - set(df.columns))}"
        if "protocol" in df.columns and path.stem != "nodes":
            own_rows += int((df["protocol"] == name).sum())
        elif path.stem == "packets" and getattr(registry.get(name), "net_metrics", False):
            own_rows += int(df["event"].isin(["offer", "tx"]).sum())  # its output is its frames
    assert own_rows, f"{name} logged nothing in its tiny run"


class _LeakyNode(Node):
    """Reads its true position the way only a bug could: through a mobility object it holds."""

    name = "leaky_probe"
    mobility: ClassVar[Any] = None  # handed over by the test, as a leaky plug-in might grab it

    def run(self) -> Any:
        yield self.sleep(1.0)
        self.log("leak", x=float(self.mobility.position(1.0)[0, 0]))


def test_truth_watch_catches_a_leaky_protocol() -> None:
    """The watch is not vacuous: a node whose code reads a true position is reported."""
    box = Box([0, 0, 0], [100, 100, 100])
    sim = Simulation(1, ssp=Constant(1500.0), volume=box)
    _LeakyNode.mobility = ConstantVelocity([[1.0, 2.0, 3.0]], box, velocity=[0.1, 0.0, 0.0])
    sim.add_group(_LeakyNode, 1, mobility=_LeakyNode.mobility)
    leaks = _watch(lambda: sim.run(until=2.0), (__file__,))
    assert any("calls mobility/" in leak for leak in leaks), leaks


# --------------------------------------------------------------------------- source lint

_MUTATORS = frozenset(
    [
        "append",
        "extend",
        "insert",
        "pop",
        "remove",
        "clear",
        "update",
        "add",
        "setdefault",
        "discard",
        "popitem",
        "sort",
        "reverse",
        "appendleft",
        "extendleft",
        "popleft",
    ]
)
_MUTABLE_CALLS = frozenset({"list", "dict", "set", "deque", "defaultdict", "OrderedDict", "Counter"})
_BANNED_MODULES = frozenset({"inspect", "gc", "ctypes"})


def _is_mutable_literal(v: ast.expr | None) -> bool:
    if isinstance(v, (ast.List, ast.Dict, ast.Set, ast.ListComp, ast.DictComp, ast.SetComp)):
        return True
    if isinstance(v, ast.Call):
        f = v.func
        name = f.id if isinstance(f, ast.Name) else f.attr if isinstance(f, ast.Attribute) else ""
        return name in _MUTABLE_CALLS
    return False


def lint_protocol_source(src: str, fname: str = "<src>") -> list[str]:
    """Contract violations in one protocol source file, one line each (empty = clean)."""
    tree = ast.parse(src)
    out: list[str] = []
    class_state: dict[str, int] = {}  # class-level mutable attribute -> line
    rebound: set[str] = set()  # attributes assigned on self (instance state shadowing a default)
    mutated: dict[str, int] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.ClassDef):
            for stmt in node.body:
                if isinstance(stmt, ast.Assign) and _is_mutable_literal(stmt.value):
                    targets = [t.id for t in stmt.targets if isinstance(t, ast.Name)]
                elif isinstance(stmt, ast.AnnAssign) and _is_mutable_literal(stmt.value):
                    targets = [stmt.target.id] if isinstance(stmt.target, ast.Name) else []
                else:
                    continue
                for t in targets:
                    class_state[t] = stmt.lineno
        elif isinstance(node, ast.Attribute):
            v = node.value
            if node.attr.startswith("_") and not (
                (isinstance(v, ast.Name) and v.id in ("self", "cls"))
                or (isinstance(v, ast.Call) and isinstance(v.func, ast.Name) and v.func.id == "super")
            ):
                out.append(f"{fname}:{node.lineno}: reads another object's private attribute: {ast.unparse(node)}")
            if isinstance(node.ctx, ast.Store) and isinstance(v, ast.Name) and v.id == "self":
                rebound.add(node.attr)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            mods = [a.name for a in node.names] if isinstance(node, ast.Import) else [node.module or ""]
            out.extend(
                f"{fname}:{node.lineno}: imports {m} (introspection is out of contract)"
                for m in mods
                if m.split(".")[0] in _BANNED_MODULES
            )
        # mutations of x.NAME: x.NAME.append(...), x.NAME[k] = v, del x.NAME[k], x.NAME += ...
        target: ast.expr | None = None
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr in _MUTATORS:
            target = node.func.value
        elif isinstance(node, ast.Subscript) and isinstance(node.ctx, (ast.Store, ast.Del)):
            target = node.value
        elif isinstance(node, ast.AugAssign):
            target = node.target
        if isinstance(target, ast.Attribute):
            mutated.setdefault(target.attr, target.lineno)
    lines = src.splitlines()
    for name, line in sorted(class_state.items()):
        # a content-addressed memo of a deterministic computation (keys hash every input, so a
        # hit equals a recomputation) carries nothing between nodes; it is declared as such
        declared_cache = "contract: deterministic cache" in lines[line - 1]
        if name in mutated and name not in rebound and not declared_cache:
            out.append(
                f"{fname}:{line}: class attribute {name} is mutable shared state (mutated at line {mutated[name]})"
            )
    return out


def test_shipped_protocols_pass_the_source_lint() -> None:
    files = sorted(Path(PROTOCOLS_DIR).rglob("*.py"))
    assert len(files) > 10
    problems = [p for f in files for p in lint_protocol_source(f.read_text(), str(f.relative_to(ROOT)))]
    assert not problems, "\n".join(problems)


_BAD = """
import gc
import sys
from inspect import currentframe


class Spy(Node):
    seen = []
    table: ClassVar[dict] = {}
    fine = []  # rebound per instance below: not shared

    def setup(self):
        self.fine = []

    def run(self):
        t = self.sleep(1.0)._delay
        f = sys._getframe(1)
        self.seen.append(t)
        Spy.table[self.id] = f
        self.fine.append(1)
        super().__init__
        yield t
"""


def test_source_lint_catches_each_kind_of_violation() -> None:
    """The lint is not vacuous: every kind of violation planted in ``_BAD`` is reported."""
    problems = lint_protocol_source(_BAD)
    text = "\n".join(problems)
    assert "imports gc" in text and "imports inspect" in text
    assert "._delay" in text and "sys._getframe" in text
    assert "class attribute seen" in text and "class attribute table" in text
    assert "fine" not in text and "super()" not in text
    assert len(problems) == 6, text
