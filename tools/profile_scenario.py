"""Where a scenario run spends time and memory: cProfile's top functions (cumulative and own
time), tracemalloc's top allocation sites at the end of the run and at its peak, and the
process's peak RSS. One run per mode (the profilers slow each other down).

    python tools/profile_scenario.py scenarios/stvf.toml --variant stvf --mode cpu
    python tools/profile_scenario.py scenarios/stvf.toml --variant stvf --mode mem --set simulation.duration_s=100
    python tools/profile_scenario.py scenarios/stvf.toml --variant stvf --mode rss    # plain run: wall, CPU, peak RSS
    python tools/profile_scenario.py scenarios/itmtl.toml --mode areas   # CPU by area of the code

``--mode areas`` charges each function's own time to the area of its module (SimPy, the
kernel, the channel, the trace, the metrics, the estimation package, each protocol, start-up);
time spent in a library (numpy, scipy, pandas, builtins) is charged to the code that called it,
split by the profiler's per-caller times, so "estimation" includes the numpy it calls.

The run goes through :func:`aquasim_py.run_scenario`: without ``--out`` every table is kept in
memory; with ``--out DIR`` the run writes there as the CLI does (tables stream to files and the
ones nobody reads are not kept).
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import resource
import time
import tracemalloc

from aquasim_py import run_scenario


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenario")
    ap.add_argument("--variant", default=None)
    ap.add_argument("--seed", type=int, default=None)
    ap.add_argument("--set", dest="sets", action="append", default=[], help="KEY.PATH=VALUE, as the CLI's --set")
    ap.add_argument("--mode", choices=("cpu", "areas", "mem", "rss"), default="rss")
    ap.add_argument("--top", type=int, default=15)
    ap.add_argument("--out", default=None, help="write the run's files there (replacing an earlier output)")
    a = ap.parse_args(argv)

    def run() -> None:
        res = run_scenario(
            a.scenario, variant=a.variant, seed=a.seed, overrides=a.sets, progress=False, out=a.out, overwrite=True
        )
        print("tables:", sorted(res.tables))

    t0, c0 = time.perf_counter(), time.process_time()
    if a.mode == "cpu":
        prof = cProfile.Profile()
        prof.runcall(run)
        st = pstats.Stats(prof)
        st.sort_stats("tottime").print_stats(a.top)
        st.sort_stats("cumulative").print_stats(a.top)
    elif a.mode == "areas":
        prof = cProfile.Profile(time.process_time)  # CPU: other jobs on the machine do not count
        prof.runcall(run)
        shares = areas(pstats.Stats(prof))
        total = sum(shares.values())
        for name, t in sorted(shares.items(), key=lambda kv: -kv[1]):
            print(f"{name:28s} {t:7.2f} s  {100 * t / total:5.1f} %")
    elif a.mode == "mem":
        tracemalloc.start(1)
        run()
        cur, peak = tracemalloc.get_traced_memory()
        print(f"tracemalloc: current {cur / 2**20:.1f} MiB, peak {peak / 2**20:.1f} MiB")
        for s in tracemalloc.take_snapshot().statistics("lineno")[: a.top]:
            print(s)
    else:
        run()
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"wall {wall:.1f} s, CPU {cpu:.1f} s, peak RSS {rss:.0f} MiB")


#: (path fragment, area) in order: the first fragment found in a function's file names its area
AREAS = (
    ("/simpy/", "SimPy"),
    ("aquasim_py/channel/", "channel"),
    ("aquasim_py/trace/", "trace"),
    ("aquasim_py/metrics", "metrics"),
    ("aquasim_py/estimation/", "estimation"),
    ("aquasim_py/mobility/", "mobility"),
    ("aquasim_py/clock", "clocks"),
    ("aquasim_py/kernel", "kernel"),
    ("aquasim_py/nodecore", "kernel"),
    ("aquasim_py/node", "kernel"),
    ("aquasim_py/packet", "kernel"),
    ("aquasim_py/scenario/", "start-up"),
    ("aquasim_py/", "aquasim_py (other)"),
)


def _area(filename: str) -> str | None:
    """The area of a function's file, None for a library or a builtin (charged to its caller)."""
    f = filename.replace("\\", "/")
    for frag, name in AREAS:
        if frag in f:
            return name
    for top in ("aquasim_protocols/", "/protocols/"):
        if top in f:
            return "protocol " + f.split(top, 1)[1].split("/", 1)[0]
    return None


def areas(st: pstats.Stats) -> dict[str, float]:
    """Own CPU seconds per area, libraries' time charged up to the first caller in an area."""
    stats = st.stats  # type: ignore[attr-defined]
    out: dict[str, float] = {}
    memo: dict[tuple[str, int, str], dict[str, float]] = {}

    def shares(func: tuple[str, int, str], seen: frozenset[tuple[str, int, str]]) -> dict[str, float]:
        """How one second of ``func``'s own time divides over areas (through its callers)."""
        if func in memo:
            return memo[func]
        if func[2] == "<module>" or "importlib" in func[0]:  # a module's top level: imports
            return {"start-up (imports)": 1.0}
        name = _area(func[0])
        if name is not None:
            return {name: 1.0}
        callers = stats[func][4]
        weights = {c: v[2] for c, v in callers.items() if c not in seen and c in stats}
        total = sum(weights.values())
        res: dict[str, float] = {}
        if total <= 0.0:
            res["unattributed (no caller in our code)"] = 1.0
        for c, w in weights.items():
            for k, v in shares(c, seen | {func}).items():
                res[k] = res.get(k, 0.0) + v * w / total
        memo[func] = res
        return res

    for func, (_cc, _nc, tt, _ct, _callers) in stats.items():
        for k, v in shares(func, frozenset()).items():
            out[k] = out.get(k, 0.0) + tt * v
    return dict(out)


if __name__ == "__main__":
    main()
