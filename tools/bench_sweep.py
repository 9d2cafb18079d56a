"""Sweep speed-up on local cores: the same CPU-bound sweep with 1 and with N worker processes.

    python tools/bench_sweep.py              # 8 runs, 1 vs 2 workers, 2 repetitions
    python tools/bench_sweep.py --runs 12 --workers 2 --repeat 3

Each run is a beacon-ranging scenario (20 drifting listeners, 6 anchors, 1200 s simulated,
~0.7 s of CPU on a quiet machine): SimPy and the channel hold the GIL, so only processes scale. Timings are
interleaved (1, N, 1, N, ...) so a load change on a shared machine hits both alike; the
reported speed-up is the ratio of the best wall times, and every repetition is printed.
The rows of the two sweeps are compared too: they must be identical. Each repetition also
measures the machine's ceiling: the speed-up the same worker count gets on ideal pure-Python
jobs at that moment (below the worker count when other processes load the cores).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
import tomllib

from aquasim_py import scenario, sweep

SCENARIO = """
[simulation]
duration_s = 1200.0
seed = 2024

[environment]
volume = { lo = [0.0, 0.0, 0.0], hi = [3000.0, 3000.0, 200.0] }
sound_speed = { model = "constant", speed_mps = 1500.0 }

[channel]
max_range_m = 5000.0
collision = "destructive"
jitter_std_s = 1e-4

[[nodes]]
name = "anchors"
role = "anchor"
count = 6
protocol = "beacon"
placement = { kind = "uniform", lo = [0.0, 0.0, 5.0], hi = [3000.0, 3000.0, 20.0] }
params = { period_s = 10.0 }

[[nodes]]
name = "listeners"
role = "ordinary"
count = 20
protocol = "beacon"
placement = { kind = "uniform", lo = [200.0, 200.0, 30.0], hi = [2800.0, 2800.0, 190.0] }
mobility = { model = "random_walk", speed_min = 0.2, speed_max = 1.0, leg_duration = 30.0 }
clock = { skew_std_ppm = 20.0, offset_std_s = 1e-3 }

[trace]
position_interval_s = 1.0

[sweep]
runs = 8
"""


def _cpu() -> float:
    """CPU seconds used so far by this process and its finished children."""
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def _spin(n: int) -> int:
    """Pure-Python CPU work with no I/O and no shared state: the ideal parallel job."""
    s = 0
    for i in range(n):
        s += i * i
    return s


def machine_ceiling(workers: int, jobs: int = 4, n: int = 6_000_000) -> float:
    """Speed-up that ``workers`` processes get right now on ideal jobs (the machine's ceiling:
    below ``workers`` when other processes share the cores)."""
    from concurrent.futures import ProcessPoolExecutor

    t0 = time.perf_counter()
    for _ in range(jobs):
        _spin(n)
    serial = time.perf_counter() - t0
    t0 = time.perf_counter()
    with ProcessPoolExecutor(workers) as ex:
        list(ex.map(_spin, [n] * jobs))
    return serial / (time.perf_counter() - t0)


def timed(sc: scenario.Scenario, jobs: list[sweep.Job], workers: int) -> tuple[float, float, list[dict]]:
    """(wall s, CPU s, rows) of one sweep."""
    c0, t0 = _cpu(), time.perf_counter()
    rows = sweep.run_jobs(sc, jobs, workers=workers)
    return time.perf_counter() - t0, _cpu() - c0, rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=2)
    ap.add_argument("--json", action="store_true", help="print the result as JSON")
    args = ap.parse_args(argv)

    raw = tomllib.loads(SCENARIO)
    raw["sweep"]["runs"] = args.runs
    sc = scenario.load_dict(raw, None)
    jobs = sweep.plan(sc)
    serial, parallel, cpu1, cpun, ceiling = [], [], [], [], []
    rows1 = rowsn = None
    load0 = os.getloadavg()[0]
    for _ in range(args.repeat):
        ceiling.append(machine_ceiling(args.workers))
        t, c, rows1 = timed(sc, jobs, 1)
        serial.append(t)
        cpu1.append(c)
        t, c, rowsn = timed(sc, jobs, args.workers)
        parallel.append(t)
        cpun.append(c)
    same = json.dumps(rows1) == json.dumps(rowsn)
    result = {
        "runs": args.runs,
        "workers": args.workers,
        "cpu_count": os.cpu_count(),
        "load_avg_1min_before": load0,
        "load_avg_1min_after": os.getloadavg()[0],
        "serial_s": serial,
        "parallel_s": parallel,
        "serial_cpu_s": cpu1,
        "parallel_cpu_s": cpun,
        "speedup_best": min(serial) / min(parallel),
        "speedup_median": sorted(serial)[len(serial) // 2] / sorted(parallel)[len(parallel) // 2],
        "ceiling_speedup": ceiling,
        "rows_identical": same,
    }
    if args.json:
        print(json.dumps(result, indent=2))
    else:
        print(
            f"{args.runs} runs, cpu_count={result['cpu_count']}, 1-min load average "
            f"{load0:.2f} before, {result['load_avg_1min_after']:.2f} after"
        )
        print("1 worker : wall", " ".join(f"{t:.2f}s" for t in serial), " cpu", " ".join(f"{t:.2f}s" for t in cpu1))
        print(
            f"{args.workers} workers: wall",
            " ".join(f"{t:.2f}s" for t in parallel),
            " cpu",
            " ".join(f"{t:.2f}s" for t in cpun),
        )
        print(f"speed-up (best/best): {result['speedup_best']:.2f}x; rows identical: {same}")
        print("machine ceiling now (ideal CPU-bound jobs, same worker count):", " ".join(f"{c:.2f}x" for c in ceiling))
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
