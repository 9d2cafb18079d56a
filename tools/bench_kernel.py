"""Kernel benchmark: N nodes each broadcasting once a second with ~16 neighbours in range.

Measures wall time, receptions decided per wall-clock second (delivered + dropped at a
receiver), peak memory, and the ratio of that rate to a bare-SimPy loop that schedules the
same deliveries (same nodes, phases and delays) with one plain timeout per delivery, run in
the same process right after (so machine load affects both alike).

    python tools/bench_kernel.py            # 200 nodes, 500 s simulated
    python tools/bench_kernel.py --quick    # 200 nodes, 50 s
"""

from __future__ import annotations

import argparse
import gc
import resource
import sys
import time

import numpy as np
import simpy

from aquasim_py.channel import Constant
from aquasim_py.channel.acoustic import ChannelConfig
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node

SPEED = 1500.0
BITS = 64
BITRATE = 1000.0
PERIOD = 1.0


def layout(n: int, neighbours: float, seed: int) -> tuple[np.ndarray, float]:
    """Uniform positions in a 10 km square (depth 50-150 m) and the range giving the mean
    neighbour count asked for (bisection on the realized layout)."""
    rng = np.random.default_rng(seed)
    pos = np.column_stack([rng.uniform(0, 10_000, n), rng.uniform(0, 10_000, n), rng.uniform(50, 150, n)])
    d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    lo, hi = 0.0, 20_000.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if (d <= mid).sum(axis=1).mean() < neighbours else (lo, mid)
    return pos, hi


class Beacon(Node):
    """Broadcasts every PERIOD local seconds from a random phase; optionally drains its inbox."""

    name = "bench_beacon"
    listen = True

    def run(self):
        if self.listen:
            self.env.process(self._drain())
        yield self.sleep(float(self.rng.uniform(0.0, PERIOD)))
        while True:
            yield self.broadcast("beacon", None, BITS)
            yield self.sleep(PERIOD - BITS / BITRATE)

    def _drain(self):
        while True:
            yield self.recv()


def run_kernel(pos: np.ndarray, rng_m: float, until: float, listen: bool, seed: int) -> dict[str, float]:
    cls = type("B", (Beacon,), {"listen": listen})
    sim = Simulation(seed, ssp=Constant(SPEED), channel=ChannelConfig(max_range_m=rng_m, bitrate_bps=BITRATE,
                                                                      collision="destructive"))
    sim.add_group(cls, len(pos), positions=pos)
    gc.collect()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    sim.run(until)
    wall = time.perf_counter() - t0
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t1 = time.perf_counter()
    p = sim.trace.frames()["packets"]
    t_frames = time.perf_counter() - t1
    ev = p["event"].astype(str)
    decided = int((ev == "rx").sum() + (ev == "drop").sum())
    phases = []  # first transmission of every node, for the bare replay
    first = p[ev == "tx"].groupby("node")["time"].min()
    phases = first.reindex(range(len(pos))).to_numpy()
    return {"wall_s": wall, "receptions": decided, "rx": int((ev == "rx").sum()),
            "tx": int((ev == "tx").sum()), "rate": decided / wall, "peak_rss_growth_mb": (rss1 - rss0) / 1024.0,
            "frames_s": t_frames, "phases": phases}


def run_bare(pos: np.ndarray, rng_m: float, until: float, phases: np.ndarray) -> dict[str, float]:
    """The same deliveries with plain SimPy: one process per node, one timeout per delivery."""
    d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    nbrs = [np.flatnonzero(row <= rng_m).tolist() for row in d]
    delays = [(d[i, nb] / SPEED + BITS / BITRATE).tolist() for i, nb in enumerate(nbrs)]
    env = simpy.Environment()
    count = [0]

    def arrive(_ev: simpy.Event) -> None:
        count[0] += 1

    def node(i: int):
        yield env.timeout(phases[i])
        while True:
            for dl in delays[i]:
                env.timeout(dl).callbacks.append(arrive)
            yield env.timeout(PERIOD)

    for i in range(len(pos)):
        env.process(node(i))
    t0 = time.perf_counter()
    env.run(until)
    wall = time.perf_counter() - t0
    return {"wall_s": wall, "receptions": count[0], "rate": count[0] / wall}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nodes", type=int, default=200)
    ap.add_argument("--neighbours", type=float, default=16.0)
    ap.add_argument("--until", type=float, default=500.0, help="simulated seconds")
    ap.add_argument("--quick", action="store_true", help="50 simulated seconds")
    ap.add_argument("--no-listen", action="store_true", help="nodes never call recv (modem buffers fill)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    until = 50.0 if args.quick else args.until
    pos, rng_m = layout(args.nodes, args.neighbours, args.seed)
    d = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=-1)
    np.fill_diagonal(d, np.inf)
    mean_nb = float((d <= rng_m).sum(axis=1).mean())
    k = run_kernel(pos, rng_m, until, not args.no_listen, args.seed)
    b = run_bare(pos, rng_m, until, k.pop("phases"))
    print(f"nodes {args.nodes}, mean neighbours {mean_nb:.2f} (range {rng_m:.0f} m), {until:g} s simulated, "
          f"nodes {'do not listen' if args.no_listen else 'drain their inbox'}")
    print(f"kernel : wall {k['wall_s']:.2f} s, {k['tx']} tx, {k['receptions']} receptions decided "
          f"({k['rx']} delivered), {k['rate']:,.0f} receptions/s, peak RSS growth {k['peak_rss_growth_mb']:.0f} MB, "
          f"frames() {k['frames_s']:.2f} s")
    print(f"bare   : wall {b['wall_s']:.2f} s, {b['receptions']} deliveries, {b['rate']:,.0f} deliveries/s")
    print(f"ratio kernel / bare SimPy: {k['rate'] / b['rate']:.3f} (target >= 0.25)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
