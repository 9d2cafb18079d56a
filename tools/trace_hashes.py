"""sha256 of every shipped scenario's traces: the table that shows a change left them alone.

Runs each ``scenarios/*.toml`` as ``aquasim-py SCENARIO --quiet`` (every variant; a sweep
scenario's base run, not its grid) into a temporary directory and hashes every trace file:
each CSV table, and ``summary.json``'s metrics and resolved scenario (:func:`_summary_digest`
leaves out what is not a result of the simulation). Files of wall-clock times (a variants
run's ``variants.csv``, MSWPF's timing table) are skipped.

    python tools/trace_hashes.py --json before.json            # on the old checkout
    python tools/trace_hashes.py --json after.json --compare before.json
    python tools/trace_hashes.py --rev HEAD --json head.json   # a commit, whatever the work tree holds

``--rev`` installs that revision into a temporary folder first (as tools/bench_scenarios.py
does) and runs its scenarios with its code. ``--compare`` prints the files whose hash changed, appeared or disappeared and exits 1 if any did.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bench_scenarios import _CLI as CLI  # tools/, beside this script
from bench_scenarios import install_revision

ROOT = Path(__file__).resolve().parents[1]
#: files whose content depends on the wall clock (a variants run's table, MSWPF's timing table)
SKIP = {"variants.csv", "mswpf_timing.csv", ".aquasim-output.json"}
#: metrics that are wall-clock measurements, not simulation results
WALL_CLOCK_METRICS = ("step_ms", "select_ms")


def _summary_digest(path: Path) -> str:
    """sha256 of a run's summary without what is not a result of the simulation: the wall time,
    the package version, where the scenario file and the output were (paths that differ
    between checkouts and runs) and wall-clock metrics."""
    doc = json.loads(path.read_text())
    for key in ("wall_time_s", "aquasim_py_version", "scenario_file"):
        doc.pop(key, None)
    scenario = doc.get("scenario")
    if isinstance(scenario, dict) and isinstance(scenario.get("output"), dict):
        scenario["output"].pop("directory", None)
    metrics = doc.get("metrics")
    if isinstance(metrics, dict):
        doc["metrics"] = {k: v for k, v in metrics.items() if not k.endswith(WALL_CLOCK_METRICS)}
    return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()


def hash_tree(out: Path) -> dict[str, str]:
    """relative path -> sha256 of every trace file under ``out``."""
    hashes: dict[str, str] = {}
    for f in sorted(out.rglob("*")):
        if not f.is_file() or f.name in SKIP or f.suffix not in {".csv", ".json"}:
            continue
        rel = f.relative_to(out).as_posix()
        hashes[rel] = _summary_digest(f) if f.name == "summary.json" else hashlib.sha256(f.read_bytes()).hexdigest()
    return hashes


def run(scenario: Path, cli: list[str], env: dict[str, str] | None = None) -> tuple[dict[str, str], float]:
    """(file -> sha256, wall s) of one CLI run of ``scenario`` (``cli``: the command before it)."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "out"
        t0 = time.perf_counter()
        # cwd outside the checkout: Python puts the current directory first on its path
        proc = subprocess.run(
            [*cli, str(scenario), "--quiet", "--out", str(out)],
            check=False,
            capture_output=True,
            text=True,
            env=env,
            cwd=tmp,
        )
        dt = time.perf_counter() - t0
        if proc.returncode != 0:
            raise SystemExit(f"{scenario.name}: exit {proc.returncode}\n{proc.stderr}")
        return hash_tree(out), dt


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenarios", nargs="*", type=Path, help="default: every scenarios/*.toml")
    ap.add_argument("--cli", default=str(Path(sys.executable).with_name("aquasim-py")), help="the aquasim-py to run")
    ap.add_argument("--json", type=Path, help="write {scenario: {file: sha256}} here")
    ap.add_argument("--compare", type=Path, help="a --json file of an earlier run to compare with")
    ap.add_argument("--rev", help="run this git revision's code and scenarios (installed into a temporary folder)")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="trace-hashes-") as tmp:
        # an absolute path: the runs start in a temporary directory
        cli, env, root = [os.path.abspath(args.cli) if os.sep in args.cli else args.cli], None, ROOT
        if args.rev:
            side = install_revision(args.rev, Path(tmp) / "rev")
            cli, root = [side.python, "-c", CLI], side.root
            env = {**os.environ, "PYTHONPATH": str(side.pythonpath)}
        paths = (
            [root / "scenarios" / p.name for p in args.scenarios]
            if args.scenarios
            else sorted((root / "scenarios").glob("*.toml"))
        )
        table: dict[str, dict[str, str]] = {}
        for p in paths:
            table[p.name], dt = run(p.resolve(), cli, env)
            print(f"{p.name:45s} {len(table[p.name]):3d} files  {dt:7.1f} s", flush=True)
    if args.json:
        args.json.write_text(json.dumps(table, indent=1, sort_keys=True) + "\n")
    if args.compare is None:
        return 0
    old = json.loads(args.compare.read_text())
    changed = 0
    for name in sorted(set(old) & set(table)):
        a, b = old[name], table[name]
        for f in sorted(set(a) | set(b)):
            if a.get(f) != b.get(f):
                changed += 1
                state = "new" if f not in a else "gone" if f not in b else "changed"
                print(f"{state:8s} {name}/{f}")
    print(f"{changed} file(s) differ" if changed else "all traces identical")
    return 1 if changed else 0


if __name__ == "__main__":
    raise SystemExit(main())
