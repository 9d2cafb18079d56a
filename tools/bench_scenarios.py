"""The research-run benchmark: wall time, CPU time and peak memory of the runs researchers make,
this checkout against another one, timed in the same session and alternated.

    python tools/bench_scenarios.py                        # against the previous commit (HEAD~1)
    python tools/bench_scenarios.py --baseline v0.1.0 --rounds 5
    python tools/bench_scenarios.py --baseline-python ../old/.venv/bin/python
    python tools/bench_scenarios.py --only itmtl,stvf_quick --json out/bench.json
    python tools/bench_scenarios.py --no-baseline --only slope,slope_flat,network,network_flat --rounds 1

Each run is the CLI on a shipped scenario (``aquasim-py SCENARIO --quiet``, every variant unless
one is named), in a fresh process, its CPU (user + system) and peak RSS read from the kernel's
accounting of that child (``os.wait4``). Both sides are installed alike, with ``pip install
--no-deps --target`` into a temporary folder (byte-compiled, their own compiled extensions, if
they have any, built as their setup says), and run by this interpreter with that folder first
on its path: this checkout as it is, and the baseline, a git revision; or the baseline is
another environment's Python (``--baseline-python``). Each round runs every scenario on
both sides, the side that goes first alternating between rounds; the table gives the medians
and the ratio of the medians (current / baseline).

The range-dependent runs (``slope``, ``network``) are not in the default set (``--only`` picks
them): each is timed with its flat, range-independent twin (same network, traffic and seed; one
profile over a flat floor), and the table gives the ratio of their CPU times ("vs flat twin")
when both ran.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

#: name -> (scenario file, extra CLI arguments): the research runs of the performance table
RUNS: dict[str, tuple[str, tuple[str, ...]]] = {
    "itmtl": ("scenarios/itmtl.toml", ()),
    "stvf_quick": ("scenarios/stvf_quick.toml", ()),
    "stvf_table1": ("scenarios/stvf.toml", ("--variant", "stvf")),
    "mswpf_2d": ("scenarios/mswpf_2d.toml", ()),
    "svlpf": ("scenarios/svlpf.toml", ()),
    "beacon": ("scenarios/beacon.toml", ()),
    # range-dependent runs and their flat twins (not in the default set)
    "slope": ("scenarios/slope.toml", ()),
    "slope_flat": ("scenarios/slope_flat.toml", ()),
    "network": ("scenarios/shelfbreak_network.toml", ()),
    "network_flat": ("scenarios/shelfbreak_network_flat.toml", ()),
    # 500 nodes routing for an hour: flooding (every node forwards every packet) and DBR (not in
    # the default set either)
    "routing_flooding_500": ("scenarios/routing_compare.toml", ("--variant", "flooding", "--set", "nodes.1.count=486")),
    "routing_dbr_500": ("scenarios/routing_compare.toml", ("--variant", "dbr", "--set", "nodes.1.count=486")),
}
#: the default set (the research runs of docs/performance.md's table)
DEFAULT = ("itmtl", "stvf_quick", "stvf_table1", "mswpf_2d", "svlpf", "beacon")
#: range-dependent run -> its flat, range-independent twin
TWINS = {"slope": "slope_flat", "network": "network_flat"}

#: runs named only with --only (not in the default set: a baseline from before their options
#: existed could not run them): the same research run under another reading of the channel
EXTRA_RUNS: dict[str, tuple[str, tuple[str, ...]]] = {
    "stvf_table1_sinr": ("scenarios/stvf.toml", ("--variant", "stvf", "--set", 'channel.reception="sinr"')),
}

#: runs the CLI of whatever aquasim_py comes first on the path (no console script needed)
_CLI = "import sys; from aquasim_py.cli import main; sys.exit(main(sys.argv[1:]))"


@dataclass
class Side:
    """One checkout to time: its interpreter, extra path entries and scenario folder."""

    label: str
    python: str
    root: Path
    pythonpath: str | None = None

    def run(self, scenario: str, extra: tuple[str, ...], out: Path) -> tuple[float, float, float]:
        """(wall s, CPU s, peak RSS MiB) of one CLI run."""
        env = dict(os.environ)
        if self.pythonpath is not None:
            env["PYTHONPATH"] = self.pythonpath
        cmd = [self.python, "-c", _CLI, str(self.root / scenario), "--quiet", "--out", str(out), *extra]
        t0 = time.perf_counter()
        # cwd outside both checkouts: Python puts the current directory first on its path
        proc = subprocess.Popen(cmd, env=env, cwd=out.parent, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        _, status, usage = os.wait4(proc.pid, 0)
        wall = time.perf_counter() - t0
        stderr = proc.stderr.read().decode() if proc.stderr else ""
        if proc.stderr:
            proc.stderr.close()
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            raise SystemExit(f"{self.label}: {scenario} exited {proc.returncode}\n{stderr}")
        shutil.rmtree(out, ignore_errors=True)
        return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def _install(tree: Path, site: Path) -> None:
    """``pip install --no-deps --target site tree``: the package as users get it (byte-compiled,
    its optional extension built if it has one), so both sides of a comparison start alike."""
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-deps",
         "--target", str(site), str(tree)],
        check=True,
    )  # fmt: skip


def install_revision(rev: str, tmp: Path) -> Side:
    """A side for git revision ``rev``: its files exported into ``tmp`` (``git archive``: no
    worktree for git to remember if the run is killed) and installed there."""
    tree, site = tmp / "tree", tmp / "site"
    tree.mkdir(parents=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", "--format=tar", rev], check=True, capture_output=True)
    subprocess.run(["tar", "-x", "-C", str(tree)], input=archive.stdout, check=True)
    _install(tree, site)
    shutil.copytree(tree / "scenarios", tmp / "scenarios")
    return Side(rev, sys.executable, tmp, pythonpath=str(site))


def install_checkout(tmp: Path) -> Side:
    """A side for this checkout as it is (uncommitted changes included), installed into ``tmp``:
    an editable install would be timed differently (no byte code where writing it is off,
    the editable finder on every import)."""
    _install(ROOT, tmp / "site")
    return Side("current", sys.executable, ROOT, pythonpath=str(tmp / "site"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    base = ap.add_mutually_exclusive_group()
    base.add_argument("--baseline", default="HEAD~1", help="git revision to compare with (default HEAD~1)")
    base.add_argument("--baseline-python", help="compare with the aquasim_py this Python imports")
    base.add_argument("--no-baseline", action="store_true", help="time this checkout alone")
    ap.add_argument(
        "--baseline-root", type=Path, help="scenario folder's parent for --baseline-python (default: this checkout)"
    )
    ap.add_argument("--rounds", type=int, default=3, help="rounds (default 3)")
    ap.add_argument("--only", help=f"comma-separated subset of {', '.join(RUNS)}, or of {', '.join(EXTRA_RUNS)}")
    ap.add_argument("--json", type=Path, help="write every measurement here")
    args = ap.parse_args(argv)
    if args.rounds < 1:
        ap.error("--rounds must be >= 1")
    names = list(DEFAULT) if not args.only else [n.strip() for n in args.only.split(",")]
    runs = {**RUNS, **EXTRA_RUNS}
    unknown = [n for n in names if n not in runs]
    if unknown:
        ap.error(f"unknown run(s) {unknown}; known: {', '.join(runs)}")

    with tempfile.TemporaryDirectory(prefix="bench-scenarios-") as tmp_s:
        tmp = Path(tmp_s)
        print("installing this checkout ...", file=sys.stderr, flush=True)
        sides = [install_checkout(tmp / "current")]
        if args.baseline_python:
            sides.append(Side("baseline", args.baseline_python, args.baseline_root or ROOT))
        elif not args.no_baseline:
            print(f"installing {args.baseline} ...", file=sys.stderr, flush=True)
            sides.append(install_revision(args.baseline, tmp / "baseline"))
        results: dict[str, dict[str, list[tuple[float, float, float]]]] = {
            n: {s.label: [] for s in sides} for n in names
        }
        for r in range(args.rounds):
            order = sides if r % 2 == 0 else sides[::-1]
            for name in names:
                scenario, extra = runs[name]
                for side in order:
                    m = side.run(scenario, extra, tmp / "out")
                    results[name][side.label].append(m)
                    print(f"round {r + 1} {name:12s} {side.label:10s} wall {m[0]:7.2f} s  CPU {m[1]:7.2f} s  "
                          f"peak {m[2]:6.0f} MiB", file=sys.stderr, flush=True)  # fmt: skip

    def med(ms: list[tuple[float, float, float]], i: int) -> float:
        return statistics.median(m[i] for m in ms)

    cur, old = sides[0].label, (sides[1].label if len(sides) > 1 else None)
    twins = any(name in TWINS and TWINS[name] in names for name in names)
    cols = ["run", "CPU s", "wall s", "peak MiB"]
    if old:
        cols += [f"CPU s ({old})", f"peak MiB ({old})", "CPU ratio"]
    if twins:
        cols += ["CPU vs flat twin"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for name in names:
        c = results[name][cur]
        row = f"| {name} | {med(c, 1):.2f} | {med(c, 0):.2f} | {med(c, 2):.0f} |"
        if old:
            b = results[name][old]
            row += f" {med(b, 1):.2f} | {med(b, 2):.0f} | {med(c, 1) / med(b, 1):.3f} |"
        if twins:
            flat = TWINS.get(name, "")
            row += f" {med(c, 1) / med(results[flat][cur], 1):.2f} |" if flat in names else " |"
        print(row)
    print(f"\nmedians of {args.rounds} round(s), sides alternated; CPU = user + system of the run's process")
    if args.json:
        args.json.write_text(
            json.dumps({"rounds": args.rounds, "sides": [s.label for s in sides], "results": results}, indent=1)
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
