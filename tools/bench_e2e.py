"""End-to-end CPU per reception of a CLI run, split by stage, and the floor of the architecture.

    python tools/bench_e2e.py                        # static and moving, 10 s and 60 s, 3 rounds
    python tools/bench_e2e.py --speeds 0 --rounds 5 --ablate listen
    python tools/bench_e2e.py --floor-only

The scenario is tools/bench_acceptance.py's e2e one (200 beacon nodes, 100 anchors beaconing
once a second, ~16 neighbours, packets traced to CSV). Each run is a fresh process running
``aquasim_py.cli.main`` (what ``python -m aquasim_py.cli`` runs) with wrappers that add the CPU
time (``time.process_time``) of each stage, each stage's own time without the stages nested in
it:

* build: ``scenario.build`` (nodes, channel, processes);
* simulate: ``Simulation.run`` without the trace rows and files (kernel, channel, protocol,
  row appends to the tables' buffers);
* trace rows: ``Table._flush`` (a table's buffered row tuples into its typed columns);
* trace files: ``Table._spill`` (a chunk's hand-over: time order, the rows kept back), the
  sinks' ``write`` (formatting and writing chunks) and ``Trace.close``;
* metrics: ``metrics.summarize`` (reads the tables back);
* outputs: ``RunResult.write_into`` (derived tables, summary.json);
* rest: the process's CPU otherwise (imports, loading the scenario, the CLI, exit).

A stage's cost per reception is (its CPU in the long run - in the short run) / (receptions of
the long run - of the short), so what every run pays once cancels; the median over the rounds
(short and long alternating) is reported. ``--ablate listen`` adds runs whose listeners take each
beacon and do nothing with it (no payload read, no ``ranges`` row): the simulate stage's
difference is the protocol's receive work.

``--root DIR`` runs the children with another checkout's code (``DIR/.venv/bin/python`` in
``DIR``), for A/B runs against it in one session.

The floor (in this process, advanced alternately a simulated second at a time, as
bench_kernel.run_both): bare SimPy's one timeout per delivery (the acceptance baseline) against
the same timeouts whose callback also does what the cheapest reception of a process-based
receiver must do: succeed the receiver's pending event (one more SimPy step), resume its process
(a generator), which appends one row tuple to a list and waits on a new event.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Generator
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

ROOT = Path(__file__).resolve().parents[1]
STAGES = ("build", "simulate", "trace rows", "trace files", "metrics", "outputs", "rest")


# --------------------------------------------------------------------------- the child run
class _Clock:
    """Self CPU time per stage: a stage's time excludes the wrapped stages called inside it."""

    def __init__(self) -> None:
        self.total: dict[str, float] = dict.fromkeys(STAGES, 0.0)
        self._stack: list[list[float]] = []  # [start, time of nested stages]

    def wrap(self, owner: Any, attr: str, stage: str) -> None:
        fn = getattr(owner, attr)

        def timed(*args: Any, **kwargs: Any) -> Any:
            frame = [time.process_time(), 0.0]
            self._stack.append(frame)
            try:
                return fn(*args, **kwargs)
            finally:
                self._stack.pop()
                spent = time.process_time() - frame[0]
                self.total[stage] += spent - frame[1]
                if self._stack:
                    self._stack[-1][1] += spent

        setattr(owner, attr, timed)


def _drain_listen_loop(self: Any) -> Generator[Any, Any, None]:
    """--ablate listen: take every beacon, read nothing, log nothing."""
    while True:
        yield self.recv(kinds="beacon")


def child(toml: Path, out: Path, ablate: str) -> dict[str, float]:
    from aquasim_py import cli, metrics, runner, scenario, trace
    from aquasim_py.kernel import Simulation

    clock = _Clock()
    clock.wrap(scenario, "build", "build")
    clock.wrap(Simulation, "run", "simulate")
    clock.wrap(trace.Table, "_flush", "trace rows")
    files = ((trace.Table, "_spill"), (trace._CsvSink, "write"), (trace._ParquetSink, "write"), (trace.Trace, "close"))
    for owner, attr in files:
        clock.wrap(owner, attr, "trace files")
    clock.wrap(metrics, "summarize", "metrics")
    clock.wrap(runner.RunResult, "write_into", "outputs")
    if ablate == "listen":
        from aquasim_protocols.beacon.node import BeaconNode

        BeaconNode._listen_loop = _drain_listen_loop
    status = cli.main([str(toml), "--quiet", "--out", str(out)])
    if status:
        raise SystemExit(status)
    clock.total["rest"] = time.process_time() - sum(clock.total.values())
    return clock.total


def _child_run(toml: Path, out: Path, ablate: str, root: Path) -> tuple[dict[str, float], int, int]:
    """One child process (``root``'s code): its stage CPU, the receptions it decided (rx + drop
    rows) and the receptions a listener's process took (``ranges`` rows)."""
    import pandas as pd

    python = sys.executable if root == ROOT else str(root / ".venv" / "bin" / "python")
    res = subprocess.run(
        [python, __file__, "--child", str(toml), str(out), ablate],
        check=True,
        cwd=root,
        capture_output=True,
        text=True,
    )
    stages = json.loads(res.stdout.strip().splitlines()[-1])
    ev = pd.read_csv(out / "packets.csv", usecols=["event"])["event"]
    ranges = out / "ranges.csv"
    taken = len(pd.read_csv(ranges, usecols=["uid"])) if ranges.exists() else 0
    return stages, int(ev.isin(["rx", "drop"]).sum()), taken


def stages(
    speed: float, short: float, long: float, rounds: int, seed: int, ablate: str, root: Path = ROOT
) -> dict[str, Any]:
    """Median over ``rounds`` of each stage's CPU per reception (us), long run minus short."""
    import bench_acceptance as ba
    import bench_kernel as bk

    pos, rng_m = bk.layout(200, 16.0, seed)
    per: dict[str, list[float]] = {s: [] for s in (*STAGES, "total")}
    receptions = taken = 0
    with tempfile.TemporaryDirectory() as tmp:
        tomls = {}
        for dur in (short, long):
            tomls[dur] = Path(tmp) / f"e2e_{dur:g}.toml"
            tomls[dur].write_text(ba._scenario(pos, rng_m, speed, dur, seed))
        for r in range(rounds):
            (a, ra, ta), (b, rb, tb) = (
                _child_run(tomls[d], Path(tmp) / f"out_{r}_{d:g}", ablate, root) for d in (short, long)
            )
            receptions, taken = rb - ra, tb - ta
            for s in STAGES:
                per[s].append(1e6 * (b[s] - a[s]) / receptions)
            per["total"].append(1e6 * (sum(b.values()) - sum(a.values())) / receptions)
    return {
        "speed": speed,
        "ablate": ablate,
        "receptions": receptions,
        "taken": taken / receptions,
        **{s: statistics.median(v) for s, v in per.items()},
    }


# --------------------------------------------------------------------------- the floor
def floor(until: float, seed: int) -> dict[str, float]:
    """us per delivery: bare SimPy's timeout, and the timeout plus a receiver process's resume."""
    import bench_kernel as bk
    import simpy

    from aquasim_py.kernel import quiet_gc

    pos, rng_m = bk.layout(200, 16.0, seed)
    phases = bk.first_tx_phases(200, seed)
    nbrs = bk.neighbour_lists(pos, rng_m)
    delays = [
        (np.linalg.norm(pos[nb] - pos[i], axis=-1) / bk.SPEED + bk.BITS / bk.BITRATE).tolist()
        for i, nb in enumerate(nbrs[:100])
    ]

    def build(resume: bool) -> tuple[simpy.Environment, list[int], list[tuple[Any, ...]]]:
        env = simpy.Environment()
        count = [0]
        rows: list[tuple[Any, ...]] = []
        pending: list[simpy.Event] = [env.event() for _ in range(len(pos))]

        def receiver(j: int) -> Generator[Any, Any, None]:
            while True:
                value = yield pending[j]
                rows.append((env.now, j, value))
                pending[j] = env.event()

        def arrive(_ev: simpy.Event) -> None:
            count[0] += 1

        def make_deliver(j: int, src: int) -> Callable[[simpy.Event], None]:
            def deliver(_ev: simpy.Event) -> None:
                count[0] += 1
                pending[j].succeed(src)

            return deliver

        def sender(i: int) -> Generator[Any, Any, None]:
            cbs = [make_deliver(j, i) for j in nbrs[i]] if resume else [arrive] * len(nbrs[i])
            yield env.timeout(phases[i])
            while True:
                for dl, cb in zip(delays[i], cbs):
                    env.timeout(dl).callbacks.append(cb)
                yield env.timeout(bk.PERIOD)

        if resume:
            for j in range(len(pos)):
                env.process(receiver(j))
        for i in range(100):
            env.process(sender(i))
        return env, count, rows

    runs = {name: build(name == "resume") for name in ("bare", "resume")}
    cpu = dict.fromkeys(runs, 0.0)
    n = dict.fromkeys(runs, 0)
    t = 0.0
    while t < until:
        t += 1.0
        for name, (env, count, _) in runs.items():
            c0, k0 = time.process_time(), count[0]
            with quiet_gc():
                env.run(t)
            if t > 2.0:  # steady state, as the kernel figures
                cpu[name] += time.process_time() - c0
                n[name] += count[0] - k0
    bare = 1e6 * cpu["bare"] / n["bare"]
    resume = 1e6 * cpu["resume"] / n["resume"]
    return {"bare_us": bare, "resume_us": resume, "best_ratio": bare / resume}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--child", nargs=3, metavar=("TOML", "OUT", "ABLATE"), help=argparse.SUPPRESS)
    ap.add_argument("--speeds", default="0,1", help="node speeds (m/s) of the runs")
    ap.add_argument("--durations", default="10,60", help="short,long simulated seconds")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--ablate", default="", help="'listen': also runs whose listeners only drain")
    ap.add_argument("--floor-until", type=float, default=30.0, help="simulated s of the floor runs (0: none)")
    ap.add_argument("--floor-only", action="store_true")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--root", type=Path, default=ROOT, help="checkout whose code the CLI runs use")
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.child:
        toml, out, ablate = args.child
        print(json.dumps(child(Path(toml), Path(out), ablate)))
        return 0
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    results: dict[str, Any] = {"load": os.getloadavg()[0]}
    if not args.floor_only:
        short, long = (float(v) for v in args.durations.split(","))
        rows = []
        for speed in (float(s) for s in args.speeds.split(",")):
            for ablate in ("", *([args.ablate] if args.ablate else [])):
                rows.append(stages(speed, short, long, args.rounds, args.seed, ablate, args.root.resolve()))
                r = rows[-1]
                label = f"{'moving' if speed else 'static'}{', ' + ablate + ' ablated' if ablate else ''}"
                print(
                    f"{label} ({r['receptions']} receptions): "
                    + ", ".join(f"{s} {r[s]:.2f}" for s in (*STAGES, "total"))
                    + " us per reception",
                    flush=True,
                )
        results["stages"] = rows
    if args.floor_until <= 0:
        return _dump(results, args.json)
    fl = floor(args.floor_until, args.seed)
    results["floor"] = fl
    print(
        f"floor: bare SimPy {fl['bare_us']:.2f} us per delivery; with a receiver's step, resume and "
        f"row append {fl['resume_us']:.2f} us: best ratio {fl['best_ratio']:.3f}"
    )
    for r in (r for r in results.get("stages", []) if not r["ablate"]):
        # this scenario's floor: every reception one SimPy step (the bare timeout), the share a
        # listener's process takes (ranges rows) also the step, resume and append
        us = fl["bare_us"] + r["taken"] * (fl["resume_us"] - fl["bare_us"])
        print(
            f"  the e2e scenario ({'moving' if r['speed'] else 'static'}{', ' + r['ablate'] if r['ablate'] else ''}): "
            f"{r['taken']:.3f} of receptions resume a listener; floor {us:.2f} us per reception, "
            f"best ratio {fl['bare_us'] / us:.3f}; measured {r['total']:.2f} us, ratio {fl['bare_us'] / r['total']:.3f}"
        )
    return _dump(results, args.json)


def _dump(results: dict[str, Any], path: Path | None) -> int:
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
