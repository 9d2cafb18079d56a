"""Small networks for the MAC tests (not a test module): nodes that offer frames on a plan
without waiting for them, and a run that returns the packets trace and what each offer gave."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import pandas as pd

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig, no_snr
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node

#: node id -> [(local time s, dst or None for a broadcast, bits)]
Plan = dict[int, list[tuple[float, int | None, int]]]


class Offers(Node):
    """Offers frames at planned local times, open loop (the next offer does not wait for the
    last frame); logs each offer's outcome (its event's value: a stamp, or None) to ``outcome``,
    and every reception it takes to ``got``."""

    name = "offers"
    plan: ClassVar[Plan] = {}

    def run(self):
        self.env.process(self._listen())
        for k, (t_local, dst, bits) in enumerate(self.plan.get(self.id, [])):
            wait = t_local - self.local_time()
            if wait > 0:
                yield self.sleep(wait)
            ev = self.broadcast("data", k, bits) if dst is None else self.send(dst, "data", k, bits)
            ev.callbacks.append(lambda e, k=k: self.log("outcome", k=k, value=e.value))

    def _listen(self):
        while True:
            rx = yield self.recv()
            self.log("got", src=rx.packet.src, uid=rx.packet.uid, kind=rx.packet.kind)


def run(
    positions: Sequence[Sequence[float]],
    plan: Plan,
    mac: str,
    mac_params: dict[str, Any] | None = None,
    until: float = 60.0,
    clocks: Sequence[Clock] | None = None,
    seed: int = 1,
    **channel: Any,
) -> tuple[pd.DataFrame, dict[str, pd.DataFrame]]:
    """Run ``plan`` on static nodes at ``positions`` (straight rays at 1500 m/s, no SNR loss,
    destructive collisions unless ``channel`` says otherwise) over ``mac``; returns the
    ``packets`` table and every table."""
    cls = type("Planned", (Offers,), {"plan": plan, "name": "planned"})
    cfg = {"max_range_m": 5000.0, "collision": "destructive", "snr_estimate_std_db": 0.0, **channel}
    sim = Simulation(seed, Constant(1500.0), channel=ChannelConfig(**cfg), loss_model=no_snr)
    sim.add_group(cls, len(positions), positions=positions, clocks=clocks, mac=mac, mac_params=mac_params)
    sim.run(until)
    tables = sim.trace.frames()
    return tables["packets"], tables
