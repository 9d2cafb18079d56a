"""The channel's neighbour index: a superset of the nodes in range (against brute force), and
the channel's packets identical with and without it."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.channel.neighbours import NeighbourIndex
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import Box, ConstantVelocity
from aquasim_py.node import Node

BOX = Box([0.0, 0.0, 0.0], [2000.0, 2000.0, 100.0])


def _moving(n: int, vmax: float, seed: int) -> ConstantVelocity:
    """n nodes in BOX at speeds up to vmax (m/s) in random 3-D directions (folded at the walls)."""
    rng = np.random.default_rng(seed)
    p0 = rng.uniform(BOX.lo, BOX.hi, (n, 3))
    d = rng.normal(size=(n, 3))
    v = d / np.linalg.norm(d, axis=1, keepdims=True) * rng.uniform(0.0, vmax, (n, 1))
    v[0] = d[0] / np.linalg.norm(d[0]) * vmax  # one node at the bound itself
    return ConstantVelocity(p0, BOX, velocity=v)


@settings(max_examples=40, deadline=None)
@given(
    seed=st.integers(0, 2**31 - 1),
    vmax=st.floats(0.0, 30.0),
    range_m=st.floats(50.0, 1500.0),
    t_build=st.floats(0.0, 500.0),
    # below 1: at the staleness bound itself, t_build + 20 - t_build can round past 20 (by 1.4e-14)
    age_frac=st.floats(0.0, 0.999),
)
def test_candidates_contain_every_node_in_range(
    seed: int, vmax: float, range_m: float, t_build: float, age_frac: float
) -> None:
    mob = _moving(60, vmax, seed)
    index = NeighbourIndex(range_m, vmax, staleness_s=20.0)
    index.neighbourhood(0, t_build, mob.n, mob.position)  # builds at t_build
    t = t_build + age_frac * 20.0
    pos = mob.position(t)
    for src in range(0, mob.n, 7):
        d = np.linalg.norm(pos - pos[src], axis=1)
        truth = set(np.flatnonzero(d <= range_m).tolist())
        hood = index.neighbourhood(src, t, mob.n, mob.position)
        assert truth <= set(hood.tolist())
        assert hood[0] == src and src not in hood[1:].tolist()  # the sender first, once
        assert np.all(np.diff(hood[1:]) > 0)  # sorted, no repeats
    assert index.rebuilds == 1  # never rebuilt within the staleness bound


def test_rebuilds_when_stale_or_grown() -> None:
    mob = _moving(10, 2.0, 1)
    index = NeighbourIndex(300.0, 2.0)
    assert index.staleness_s == pytest.approx(0.025 * 300.0 / 2.0)
    index.neighbourhood(0, 0.0, 10, mob.position)
    index.neighbourhood(0, index.staleness_s, 10, mob.position)
    assert index.rebuilds == 1
    index.neighbourhood(0, index.staleness_s * 1.01, 10, mob.position)
    assert index.rebuilds == 2
    index.neighbourhood(0, index.staleness_s * 1.01, 11, lambda t: np.vstack([mob.position(t), [[0.0, 0.0, 1.0]]]))
    assert index.rebuilds == 3
    static = NeighbourIndex(300.0, 0.0)
    static.neighbourhood(0, 0.0, 10, mob.position)
    static.neighbourhood(0, 1e9, 10, mob.position)
    assert static.rebuilds == 1
    with pytest.raises(ValueError):
        NeighbourIndex(300.0, float("inf"))


class _Chatter(Node):
    """Broadcasts every 0.5 s from a random phase and drains its inbox."""

    name = "test_neighbours_chatter"

    def run(self) -> Any:
        self.env.process(self._drain())
        yield self.sleep(float(self.rng.uniform(0.0, 0.5)))
        while True:
            yield self.broadcast("hello", None, 32)
            yield self.sleep(0.5)

    def _drain(self) -> Any:
        while True:
            yield self.recv()


def _packets(seed: int, bounded: bool, monkeypatch: pytest.MonkeyPatch) -> pd.DataFrame:
    if not bounded:  # no speed bound: the channel tests every node on every transmission
        monkeypatch.setattr(Simulation, "max_speed", lambda self: float("inf"))
    sim = Simulation(
        seed, ssp=Constant(1500.0), volume=BOX, channel=ChannelConfig(max_range_m=400.0, bitrate_bps=2000.0)
    )
    # 20 m/s: the tree is rebuilt every second (0.05 * 400 / 20), so queries see every age
    sim.add_group(_Chatter, 40, mobility=_moving(40, 20.0, seed))
    sim.run(12.0)
    monkeypatch.undo()
    return sim.trace.frames()["packets"]


def test_channel_packets_identical_with_and_without_index(monkeypatch: pytest.MonkeyPatch) -> None:
    with_index = _packets(3, True, monkeypatch)
    without = _packets(3, False, monkeypatch)
    assert (with_index["event"] == "rx").sum() > 200  # the test exercises real receptions
    pd.testing.assert_frame_equal(with_index, without)


def test_deliveries_of_a_transmission_take_one_queue_entry() -> None:
    """A broadcast heard by many nodes keeps one entry on SimPy's queue (the next delivery),
    and the receptions are still decided at their arrival instants, in time order."""
    n = 30
    rng = np.random.default_rng(5)
    pos = np.column_stack([rng.uniform(0.0, 1500.0, n), rng.uniform(0.0, 1500.0, n), rng.uniform(10.0, 90.0, n)])

    class _Once(Node):
        name = "test_neighbours_once"

        def run(self) -> Any:
            if self.id == 0:
                yield self.broadcast("hello", None, 32)

    sim = Simulation(1, ssp=Constant(1500.0), volume=BOX, channel=ChannelConfig(max_range_m=5000.0, bitrate_bps=2000.0))
    sim.add_group(_Once, n, positions=pos)
    sim.run(1e-6)  # node 0 has transmitted
    # 29 receptions pending, yet only the first delivery, node 0's end of transmission, the
    # position sampler and run()'s stop event are queued
    assert len(sim.env._queue) <= 4
    sim.run(10.0)
    p = sim.trace.frames()["packets"]
    rx = p[p["event"] != "tx"]
    assert len(rx) == n - 1
    dist = np.linalg.norm(pos[rx["node"].to_numpy()] - pos[0], axis=1)
    np.testing.assert_allclose(rx["time"].to_numpy(), dist / 1500.0, rtol=0.0, atol=1e-12)
    assert np.all(np.diff(rx["time"].to_numpy()) >= 0.0)
