"""Kernel benchmark: N nodes each broadcasting once a second with ~16 neighbours in range.

Measures wall time, receptions decided (delivered + dropped at a receiver) per CPU second,
peak memory, and the ratio of that rate to a bare-SimPy loop that schedules the same
deliveries (same nodes, phases and delays) with one plain timeout per delivery, run in the
same process, the two advanced alternately a few simulated seconds at a time. Rates use
process CPU time, not wall time, so other jobs on a shared machine distort the ratio as
little as possible.

    python tools/bench_kernel.py            # 200 nodes, 500 s simulated
    python tools/bench_kernel.py --quick    # 200 nodes, 50 s
    python tools/bench_kernel.py --quick --nodes 5000 --until 4   # same density, 25x the area
    python tools/bench_kernel.py --quick --speed 1   # moving nodes
    python tools/bench_kernel.py --quick --receiver drop   # what the receivers do (RECEIVERS)

The reported "CPU per reception" (kernel CPU time / receptions decided) is the figure to
compare across network sizes at the same neighbour count.
"""

from __future__ import annotations

import argparse
import gc
import math
import resource
import sys
import time
from typing import Any

import numpy as np
import simpy
from scipy.spatial import cKDTree

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.kernel import Simulation, quiet_gc
from aquasim_py.mobility import Box, ConstantVelocity
from aquasim_py.node import Node
from aquasim_py.nodecore import NodeCore

SPEED = 1500.0
BITS = 64
BITRATE = 1000.0
PERIOD = 1.0


def side_m(n: int) -> float:
    """Side (m) of the square: 10 km at 200 nodes, scaled with sqrt(n) so the density, and so
    the range for a given neighbour count, stays the same at any n."""
    return 10_000.0 * math.sqrt(n / 200.0)


def neighbour_lists(pos: np.ndarray, rng_m: float) -> list[list[int]]:
    """Ids within rng_m of each node (itself excluded), sorted; a k-d tree, not an N x N matrix."""
    tree = cKDTree(pos)
    out = tree.query_ball_point(pos, rng_m, return_sorted=True)
    return [[j for j in nb if j != i] for i, nb in enumerate(out)]


def layout(n: int, neighbours: float, seed: int) -> tuple[np.ndarray, float]:
    """Uniform positions in a square of side_m(n) (depth 50-150 m) and the range giving the
    mean neighbour count asked for (bisection on the realized layout)."""
    rng = np.random.default_rng(seed)
    side = side_m(n)
    pos = np.column_stack([rng.uniform(0, side, n), rng.uniform(0, side, n), rng.uniform(50, 150, n)])
    tree = cKDTree(pos)
    lo, hi = 0.0, 20_000.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        mean = (tree.query_ball_point(pos, mid, return_length=True) - 1).mean()
        lo, hi = (mid, hi) if mean < neighbours else (lo, mid)
    return pos, hi


#: what the benchmark's receivers do with their receptions (``--receiver``)
RECEIVERS = {
    "recv": "a process per node takes each reception with recv() (the default: a resume per reception)",
    "take": "each node takes its inbox once a period with take_pending() (no resume per reception)",
    "none": "nodes never take their receptions (the inbox keeps growing)",
    "drop": "ablation: the kernel's deliver is a no-op (the channel and the senders alone)",
}


class BenchBeacon(Node):
    """Broadcasts every PERIOD local seconds from a random phase; takes its receptions as
    ``receiver`` says (RECEIVERS)."""

    name = "bench_beacon"
    receiver = "recv"

    def run(self):
        if self.receiver in ("recv", "take"):
            self.env.process(self._drain())
        yield self.sleep(float(self.rng.uniform(0.0, PERIOD)))
        while True:
            yield self.broadcast("beacon", None, BITS)
            yield self.sleep(PERIOD - BITS / BITRATE)

    def _drain(self):
        if self.receiver == "take":
            while True:
                yield self.sleep(PERIOD)
                self.take_pending()
        else:
            while True:
                yield self.recv()


def _dropped(core: NodeCore, packet: Any, rx_local: float, snr_db: float, pressure: float) -> None:
    """The ``drop`` ablation's deliver: the reception is decided and traced, then discarded."""


def build_kernel(pos: np.ndarray, rng_m: float, receiver: bool | str, seed: int, speed: float = 0.0) -> Simulation:
    """The benchmark's network; ``receiver``: one of RECEIVERS, or True / False for "recv" /
    "none" (nodes that listen or not)."""
    mode = receiver if isinstance(receiver, str) else ("recv" if receiver else "none")
    if mode not in RECEIVERS:
        raise ValueError(f"receiver must be one of {sorted(RECEIVERS)}, got {mode!r}")
    cls = type("B", (BenchBeacon,), {"receiver": mode})
    side = side_m(len(pos))
    box = Box([-1.0, -1.0, 0.0], [side + 1.0, side + 1.0, 200.0])
    sim = Simulation(
        seed,
        ssp=Constant(SPEED),
        volume=box,
        channel=ChannelConfig(max_range_m=rng_m, bitrate_bps=BITRATE, collision="destructive"),
    )
    # the channel takes each node's deliver when the node is attached: "drop" swaps the
    # kernel's for the no-op while the group is added, and only then
    kept = NodeCore.deliver
    if mode == "drop":
        NodeCore.deliver = _dropped  # type: ignore[method-assign,assignment]
    try:
        if speed > 0.0:
            # horizontal headings drawn per node: the channel then re-solves every delay per packet
            head = np.random.default_rng(seed + 1).uniform(0.0, 2.0 * np.pi, len(pos))
            vel = speed * np.column_stack([np.cos(head), np.sin(head), np.zeros(len(pos))])
            sim.add_group(cls, len(pos), mobility=ConstantVelocity(pos, box, velocity=vel))
        else:
            sim.add_group(cls, len(pos), positions=pos)
    finally:
        NodeCore.deliver = kept  # type: ignore[method-assign]
    return sim


def first_tx_phases(n: int, seed: int) -> np.ndarray:
    """The first transmit times of the kernel run: each Beacon's first draw from its own stream."""
    sim = Simulation(seed)
    return np.array([sim.rng("node", i, "protocol").uniform(0.0, PERIOD) for i in range(n)])


def build_bare(
    pos: np.ndarray, rng_m: float, phases: np.ndarray, senders: int | None = None
) -> tuple[simpy.Environment, list[int]]:
    """The same deliveries with plain SimPy: one process per sending node (the first
    ``senders``, default all), one timeout per delivery."""
    nbrs = neighbour_lists(pos, rng_m)
    n_send = len(pos) if senders is None else senders
    delays = [
        (np.linalg.norm(pos[nb] - pos[i], axis=-1) / SPEED + BITS / BITRATE).tolist()
        for i, nb in enumerate(nbrs[:n_send])
    ]
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

    for i in range(n_send):
        env.process(node(i))
    return env, count


def run_both(
    pos: np.ndarray,
    rng_m: float,
    until: float,
    receiver: bool | str,
    seed: int,
    speed: float,
    chunk: float = 1.0,
    warmup: float = 2.0 * PERIOD,
) -> dict[str, float]:
    """Advance the kernel and the bare loop alternately, ``chunk`` simulated seconds at a time,
    summing each one's CPU time: load from other jobs then hits both alike.

    Besides the totals, the "steady" figures count only the chunks after ``warmup`` simulated
    seconds: by then every node has sent (process start-up, a static sender's first link
    computation, the neighbour index's build are behind), so what is left is the cost that
    recurs with every reception, the one to compare across network sizes. Receptions decided
    per chunk are counted exactly: rows added to the packets table minus transmissions.
    ``receiver``: as for :func:`build_kernel`."""
    sim = build_kernel(pos, rng_m, receiver, seed, speed)
    env, count = build_bare(pos, rng_m, first_tx_phases(len(pos), seed))
    table = sim.trace.table("packets")
    gc.collect()
    rss0 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    cpu_k = cpu_b = wall_k = 0.0
    steady = {"cpu_k": 0.0, "cpu_b": 0.0, "rec": 0, "deliv": 0}
    t = 0.0
    while t < until:
        t_prev, t = t, min(until, t + chunk)
        rows0, tx0, n0 = table.n, sim.channel._uid, count[0]
        w0, c0 = time.perf_counter(), time.process_time()
        sim.run(t)
        c1 = time.process_time()
        wall_k += time.perf_counter() - w0
        with quiet_gc():  # the same garbage-collector treatment Simulation.run gives the kernel
            env.run(t)
        c2 = time.process_time()
        cpu_k += c1 - c0
        cpu_b += c2 - c1
        if t_prev >= warmup:
            steady["cpu_k"] += c1 - c0
            steady["cpu_b"] += c2 - c1
            steady["rec"] += (table.n - rows0) - (sim.channel._uid - tx0)
            steady["deliv"] += count[0] - n0
    rss1 = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t1 = time.perf_counter()
    p = sim.trace.frames()["packets"]
    t_frames = time.perf_counter() - t1
    ev = p["event"].astype(str)
    decided = int((ev == "rx").sum() + (ev == "drop").sum())
    out = {
        "wall_s": wall_k,
        "cpu_s": cpu_k,
        "receptions": decided,
        "rx": int((ev == "rx").sum()),
        "tx": int((ev == "tx").sum()),
        "rate": decided / cpu_k,
        "peak_rss_growth_mb": (rss1 - rss0) / 1024.0,
        "frames_s": t_frames,
        "bare_cpu_s": cpu_b,
        "bare_deliveries": count[0],
        "bare_rate": count[0] / cpu_b,
        "steady_receptions": steady["rec"],
    }
    if steady["rec"] and steady["deliv"]:
        out["steady_us_per_reception"] = 1e6 * steady["cpu_k"] / steady["rec"]
        out["steady_bare_us_per_delivery"] = 1e6 * steady["cpu_b"] / steady["deliv"]
        out["steady_ratio"] = out["steady_bare_us_per_delivery"] / out["steady_us_per_reception"]
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--nodes", type=int, default=200)
    ap.add_argument("--neighbours", type=float, default=16.0)
    ap.add_argument("--until", type=float, default=500.0, help="simulated seconds")
    ap.add_argument("--quick", action="store_true", help="50 simulated seconds")
    ap.add_argument("--no-listen", action="store_true", help="nodes never take their receptions (= --receiver none)")
    ap.add_argument(
        "--receiver",
        choices=sorted(RECEIVERS),
        default=None,
        help="what the nodes do with their receptions: " + "; ".join(f"{k}: {v}" for k, v in RECEIVERS.items()),
    )
    ap.add_argument(
        "--speed",
        type=float,
        default=0.0,
        help="node speed (m/s): > 0 moves every node (no per-sender link cache, fixed point per delivery)",
    )
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args(argv)
    if args.no_listen and args.receiver not in (None, "none"):
        ap.error(f"--no-listen and --receiver {args.receiver} disagree")
    receiver = args.receiver or ("none" if args.no_listen else "recv")
    until = min(50.0, args.until) if args.quick else args.until
    pos, rng_m = layout(args.nodes, args.neighbours, args.seed)
    mean_nb = float(np.mean([len(nb) for nb in neighbour_lists(pos, rng_m)]))
    k = run_both(pos, rng_m, until, receiver, args.seed, args.speed)
    print(
        f"nodes {args.nodes}, mean neighbours {mean_nb:.2f} (range {rng_m:.0f} m), {until:g} s simulated, "
        f"receivers: {RECEIVERS[receiver]}, "
        f"{f'moving at {args.speed:g} m/s' if args.speed > 0 else 'static'}"
    )
    print(
        f"kernel : wall {k['wall_s']:.2f} s (CPU {k['cpu_s']:.2f} s), {k['tx']} tx, {k['receptions']} "
        f"receptions decided ({k['rx']} delivered), {k['rate']:,.0f} receptions per CPU second, "
        f"peak RSS growth {k['peak_rss_growth_mb']:.0f} MB, frames() {k['frames_s']:.2f} s"
    )
    print(
        f"bare   : CPU {k['bare_cpu_s']:.2f} s, {k['bare_deliveries']} deliveries, "
        f"{k['bare_rate']:,.0f} deliveries per CPU second"
    )
    print(f"CPU per reception: {1e6 * k['cpu_s'] / k['receptions']:.2f} us")
    print(f"ratio kernel / bare SimPy: {k['rate'] / k['bare_rate']:.3f} (target >= 0.3 with moving nodes)")
    if "steady_ratio" in k:
        print(
            f"steady state (after {2.0 * PERIOD:g} s, {k['steady_receptions']} receptions): "
            f"{k['steady_us_per_reception']:.2f} us per reception, bare {k['steady_bare_us_per_delivery']:.2f} us "
            f"per delivery, ratio {k['steady_ratio']:.3f}"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
