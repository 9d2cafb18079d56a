"""Parent-process memory over a long sweep: does it stay flat?

    python tools/bench_sweep_memory.py                    # 1000 runs, 2 local workers
    python tools/bench_sweep_memory.py --runs 200 --workers 1

Runs a small beacon scenario (2 anchors, 3 listeners, 20 s simulated) ``--runs`` times
through the local executor, exactly as ``aquasim-py sweep`` does (row journal, then
``sweep.csv`` and ``summary.csv`` from it), and samples the parent's resident set size after
every finished run. Reports the RSS after the first 5 % of runs (imports and pools warmed up),
at the end and the peak; the target is a growth below 50 MB over the sweep. With
``--workers 1`` the runs happen in the parent itself, so that mode also measures what a run
leaves behind. Not part of the test suite.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from aquasim_py import scenario, sweep

SCENARIO = """
[simulation]
duration_s = 20.0
seed = 7

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [800.0, 800.0, 60.0] }

[[nodes]]
role = "anchor"
protocol = "beacon"
placement = { kind = "explicit", positions = [[0.0, 0.0, 5.0], [800.0, 800.0, 5.0]] }
params = { period_s = 2.0 }

[[nodes]]
role = "ordinary"
count = 3
protocol = "beacon"
placement = { kind = "uniform" }

[sweep]
runs = {runs}
grid = {{}}
"""


def rss_mb() -> float:
    """This process's resident set size now (MB), from /proc (Linux)."""
    with open("/proc/self/statm") as fh:
        pages = int(fh.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2**20


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "mem.toml"
        path.write_text(SCENARIO.replace("{runs}", str(args.runs)).replace("{{}}", "{}"))
        sc = scenario.load(path)
        jobs = sweep.plan(sc)
        samples: list[float] = []

        def sample(done: int, total: int) -> None:
            samples.append(rss_mb())

        start_rss = rss_mb()
        t0 = time.perf_counter()
        with sweep.Journal(Path(d) / sweep.JOURNAL) as journal:
            sweep.run_jobs(sc, jobs, workers=args.workers, progress=sample, on_row=journal.append)
        rows, _ = sweep.finish(d, jobs)
        wall = time.perf_counter() - t0
        end_rss = rss_mb()
    warm = samples[max(0, len(samples) // 20 - 1)]
    print(f"{len(rows)} runs, {args.workers} worker(s), {wall:.1f} s")
    print(
        f"parent RSS: {start_rss:.1f} MB before, {warm:.1f} MB after 5 % of runs, {samples[-1]:.1f} MB after the last run,"
    )
    print(f"            {end_rss:.1f} MB after writing sweep.csv/summary.csv; peak {max(samples):.1f} MB")
    growth = samples[-1] - warm
    print(
        f"growth over the sweep (last run - 5 %): {growth:+.1f} MB (target < 50 MB): {'ok' if growth < 50 else 'FAIL'}"
    )


if __name__ == "__main__":
    main()
