"""Small routed networks for the routing tests (not a test module): sources that originate
packets to the sinks on a plan, sinks that log what they get, and a run that returns the
tables."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np
import pandas as pd
from scipy.sparse.csgraph import connected_components
from scipy.spatial.distance import cdist

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig, no_snr
from aquasim_py.kernel import Simulation
from aquasim_py.node import ANY_SINK, Node, Role

#: node id -> [local time s of each packet it originates]
Plan = dict[int, list[float]]


class Planned(Node):
    """Originates a packet to ANY_SINK at each planned local time (open loop); a sink logs each
    packet it is handed to ``got``."""

    name = "planned_routing"
    plan: ClassVar[Plan] = {}

    def run(self):
        if self.role is Role.SINK:
            while True:
                rx = yield self.recv()
                self.log("got", src=rx.packet.src, kind=rx.packet.kind, payload=rx.packet.payload)
        for k, t_local in enumerate(self.plan.get(self.id, [])):
            wait = t_local - self.local_time()
            if wait > 0:
                yield self.sleep(wait)
            self.send(ANY_SINK, "data", (self.id, k), 200).callbacks.append(lambda _e: None)


def run(
    sensors: Sequence[Sequence[float]],
    sinks: Sequence[Sequence[float]],
    plan: Plan,
    routing: str,
    routing_params: dict[str, Any] | None = None,
    *,
    mac: str = "direct",
    until: float = 600.0,
    seed: int = 1,
    position_std: float = 0.0,
    cls: type[Planned] = Planned,
    **channel: Any,
) -> dict[str, pd.DataFrame]:
    """Run ``plan`` on static sensors and sinks (straight rays at 1500 m/s, no SNR loss, no
    collisions unless ``channel`` says otherwise; 10 kbps) with ``routing`` (the nodes: ``cls``);
    every table."""
    cls = type("P", (cls,), {"plan": plan})
    cfg = {"max_range_m": 100.0, "collision": "none", "bitrate_bps": 10_000.0, "snr_estimate_std_db": 0.0, **channel}
    sim = Simulation(seed, Constant(1500.0), channel=ChannelConfig(**cfg), loss_model=no_snr)
    fix = {"position": True, "position_std": position_std}
    from aquasim_py.node import Sensors

    sim.add_group(
        cls, len(sensors), positions=sensors, routing=routing, routing_params=routing_params, mac=mac,
        sensors=Sensors(**fix),
    )  # fmt: skip
    sim.add_group(
        cls, len(sinks), positions=sinks, role="sink", routing=routing, routing_params=routing_params, mac=mac,
        sensors=Sensors(**fix), name="sinks",
    )  # fmt: skip
    sim.run(until)
    return sim.trace.frames()


def connected(points: np.ndarray, range_m: float) -> bool:
    """Whether the graph of links shorter than ``range_m`` between ``points`` is connected."""
    adj = cdist(points, points) <= range_m
    n, _ = connected_components(adj, directed=False)
    return bool(n == 1)


def rows(tables: dict[str, pd.DataFrame], event: str) -> pd.DataFrame:
    r = tables.get("routes")
    if r is None:
        return pd.DataFrame(columns=["time", "node", "event", "origin", "seq", "hops", "prev", "value"])
    return r[r["event"] == event]


class FakePort:
    """A RouterPort for unit tests of one router's rules: a plain SimPy environment (local time
    = true time), a settable depth and position, and lists of what the router offered and
    wrote."""

    def __init__(self, index: int = 1, depth: float = 100.0, position=(0.0, 0.0, 100.0), sink: bool = False):
        import simpy

        self.index = index
        self.env = simpy.Environment()
        self.rng = np.random.default_rng(0)
        self.is_sink = sink
        self.max_range_m = 100.0
        self.directory: dict[str, Any] = {}
        self.depth_m = depth
        self.energy = 1.0
        self.pos = tuple(position)
        self.offered: list[tuple[float, Any]] = []
        self.rows: list[tuple[float, tuple]] = []
        self.delivered: list[Any] = []

    def local_time(self) -> float:
        return float(self.env.now)

    def depth(self) -> float:
        return self.depth_m

    def residual_energy(self) -> float:
        return self.energy

    def position(self):
        return self.pos

    def offer(self, dst, kind, payload, bits):
        self.offered.append((self.env.now, payload))
        return self.env.timeout(0.0)

    def deliver(self, packet, rx_local, snr_db, pressure):
        self.delivered.append(packet)

    def row(self, values):
        self.rows.append((self.env.now, values))

    def events(self, name: str) -> list[tuple]:
        return [v for _, v in self.rows if v[0] == name]
