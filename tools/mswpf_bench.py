"""Benchmark: one MSWPF filter step with 1000 particles and 3 sensors (Algorithm 1's body:
predicted MI of the 3 sensors (eq 23), fusion weights (eq 27), weighted likelihood (eq 25),
normalization, resampling, estimate, PCRLB information update and prediction; the sensors'
FIMs come from the selection, as in the fusion centre), and one PCRLB selection (eq 36) over
the qualified candidates of the 2-D grid.

    python tools/mswpf_bench.py [--repeat 200]

Prints the minimum and median wall time and CPU time (process_time, robust on a loaded
machine) per step in ms, and the same for a fixed reference workload (sorting 2e5 random
doubles) timed in the same run, interleaved with the steps: its figures say how fast the
machine was at the time, so that runs on different days or loads can be compared.
Single-threaded numpy (OMP_NUM_THREADS=1) as in the Monte Carlo runs.
"""

from __future__ import annotations

import argparse
import os

os.environ.setdefault("OMP_NUM_THREADS", "1")

import time

import numpy as np

from aquasim_protocols.mswpf.math import MswpfConfig, MswpfTracker, thresholds


def setup(L: int = 8, n: int = 1000, seed: int = 0) -> tuple[MswpfTracker, np.ndarray, np.ndarray]:
    g = np.arange(0.0, 1000.0, 120.0)
    sensors = np.array([[x, y, 100.0] for x in g for y in g])
    gam = thresholds(L, 5e4, 1.0, 50.0, 160.0)
    tr = MswpfTracker(
        MswpfConfig(gammas=tuple(gam), n_particles=n),
        [300.0, 310.0, 10.0, 10.0],
        10 * np.eye(4),
        np.random.default_rng(seed),
    )
    return tr, sensors, np.zeros(len(sensors))


def time_step(repeat: int = 200, L: int = 8) -> dict[str, float]:
    tr, sensors, loc = setup(L)
    sel = np.array([30, 31, 39])  # three sensors around (300, 310)
    levels = np.array([3, 4, 2])
    wall, cpu, swall, scpu, rcpu = [], [], [], [], []
    ref = np.random.default_rng(2).random(200_000)
    for _ in range(repeat):
        c0 = time.process_time()
        np.sort(ref)
        rcpu.append(time.process_time() - c0)
        tr.predicted[:, :2] = np.random.default_rng(1).normal([300.0, 310.0], 5.0, (len(tr.predicted), 2))
        w0, c0 = time.perf_counter(), time.process_time()
        _, infos = tr.select(sensors, loc)  # the FC selects before the step; its FIMs are reused
        swall.append(time.perf_counter() - w0)
        scpu.append(time.process_time() - c0)
        w0, c0 = time.perf_counter(), time.process_time()
        mi = tr.mi(sensors[sel], loc[sel])  # in the network each sensor computes its own
        tr.update(sensors[sel], loc[sel], levels, mi, infos)
        wall.append(time.perf_counter() - w0)
        cpu.append(time.process_time() - c0)
    ms = 1e3
    return {
        "step_wall_min_ms": ms * min(wall),
        "step_wall_median_ms": ms * float(np.median(wall)),
        "step_cpu_min_ms": ms * min(cpu),
        "step_cpu_median_ms": ms * float(np.median(cpu)),
        "select_wall_median_ms": ms * float(np.median(swall)),
        "select_cpu_median_ms": ms * float(np.median(scpu)),
        "reference_cpu_min_ms": ms * min(rcpu),
        "reference_cpu_median_ms": ms * float(np.median(rcpu)),
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=200)
    ap.add_argument("--levels", type=int, default=8)
    a = ap.parse_args()
    for k, v in time_step(a.repeat, a.levels).items():
        print(f"{k:24s} {v:8.3f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
