"""Where a scenario run spends time and memory: cProfile's top functions (cumulative and own
time), tracemalloc's top allocation sites at the end of the run and at its peak, and the
process's peak RSS. One run per mode (the profilers slow each other down).

    python tools/profile_scenario.py scenarios/stvf.toml --variant stvf --mode cpu
    python tools/profile_scenario.py scenarios/stvf.toml --variant stvf --mode mem --set simulation.duration_s=100
    python tools/profile_scenario.py scenarios/stvf.toml --variant stvf --mode rss    # plain run: wall, CPU, peak RSS

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
    ap.add_argument("--mode", choices=("cpu", "mem", "rss"), default="rss")
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


if __name__ == "__main__":
    main()
