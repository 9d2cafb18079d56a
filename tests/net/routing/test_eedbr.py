"""EEDBR: the named forwarders, the holding time by residual energy and rank, the stand-down,
and delivery over hellos and piggybacked tables."""

from __future__ import annotations

import numpy as np
import pytest
from routenet import FakePort, rows, run

from aquasim_py.net.routing.base import Datagram
from aquasim_py.net.routing.eedbr import Eedbr, EedbrHeader, EedbrParams, Hello
from aquasim_py.packet import Packet

P_MIN = 2 * 100.0 / 1500.0


def _hello(router: Eedbr, src: int, depth: float, energy: float) -> None:
    hello = Packet(0, src, None, "routing.hello", Hello(depth, energy), 56, 0.0)
    router.receive(hello, router.port.local_time(), 20.0, float("nan"))


def _copy(sender: int, named: tuple[int, ...], seq: int = 0) -> Datagram:
    return Datagram(EedbrHeader(9, seq, -2, 1, sender, depth=300.0, energy=1.0, forwarders=named), "data", None, 100)


def test_a_sender_names_its_shallower_neighbours_richest_first():
    port = FakePort(depth=200.0)
    r = Eedbr(port, EedbrParams())
    for src, depth, energy in [(2, 150.0, 0.5), (3, 120.0, 0.9), (4, 250.0, 1.0), (5, 180.0, 0.9), (6, 199.0, 0.2)]:
        _hello(r, src, depth, energy)
    assert r.forwarders(200.0) == (3, 5, 2, 6)  # 4 is deeper; 3 and 5 tie: the shallower first
    r2 = Eedbr(FakePort(depth=200.0), EedbrParams(max_forwarders=2))
    r2.neighbours = dict(r.neighbours)
    assert r2.forwarders(200.0) == (3, 5)


def test_neighbours_not_heard_for_the_timeout_are_forgotten():
    port = FakePort(depth=200.0)
    r = Eedbr(port, EedbrParams(neighbour_timeout_s=30.0))
    _hello(r, 2, 150.0, 1.0)
    port.env.run(20.0)
    _hello(r, 3, 120.0, 0.5)  # 2 heard at 0 s, 3 at 20 s
    port.env.run(40.0)
    assert r.forwarders(200.0) == (3,)


@pytest.mark.parametrize(("rank", "energy"), [(1, 1.0), (1, 0.25), (2, 0.5), (3, 0.8)])
def test_the_holding_time_is_energy_then_rank(rank, energy):
    port = FakePort(depth=200.0)
    port.energy = energy
    r = Eedbr(port, EedbrParams(holding_max_s=2.0))
    priority = 0.0 if rank == 1 else P_MIN * 2 ** (rank - 2)
    assert r.holding_time(rank) == pytest.approx((1 - energy) * 2.0 + priority)
    named = tuple(range(10, 10 + rank - 1)) + (port.index,)
    _hello(r, 50, 100.0, 1.0)  # a shallower neighbour, so that it can forward
    r.on_copy(_copy(3, named), 3)
    port.env.run(20.0)
    (t, payload) = next((t, p) for t, p in port.offered if isinstance(p, Datagram))
    assert t == pytest.approx(r.holding_time(rank))
    assert payload.header.forwarders == (50,) and payload.header.depth == 200.0


def test_a_node_not_named_drops_and_a_named_one_stands_down_for_another():
    port = FakePort(depth=200.0)
    r = Eedbr(port, EedbrParams())
    _hello(r, 50, 100.0, 1.0)
    r.on_copy(_copy(3, (7, 8)), 3)  # not named
    assert not r.held
    r.on_copy(_copy(3, (7, port.index), seq=1), 3)  # named second
    r.on_copy(_copy(7, (40,), seq=1), 7)  # the first named forwarder's copy
    port.env.run(20.0)
    assert not [p for _, p in port.offered if isinstance(p, Datagram)]
    assert port.events("suppress")[0][3] == 1


def test_a_node_with_no_shallower_neighbour_does_not_send():
    port = FakePort(depth=200.0)
    r = Eedbr(port, EedbrParams())
    _hello(r, 51, 250.0, 1.0)  # deeper only
    r.on_copy(_copy(3, (port.index,)), 3)
    port.env.run(20.0)
    assert port.events("drop")[0][1] == "no_forwarder"


def test_eedbr_delivers_over_hellos_on_a_static_network():
    rng = np.random.default_rng(3)
    sensors = rng.uniform([0.0, 0.0, 20.0], [150.0, 150.0, 250.0], (30, 3))
    deepest = int(np.argmax(sensors[:, 2]))
    t = run(sensors, [[75.0, 75.0, 0.0]], {deepest: [20.0, 40.0, 60.0]}, "eedbr", until=120.0, collision="destructive")
    hellos = t["packets"]
    assert ((hellos["event"] == "tx") & (hellos["kind"] == "routing.hello")).sum() == 31  # one each, sink too
    assert len(rows(t, "deliver")) == 3
    fwd = rows(t, "forward")
    assert fwd.groupby(["node", "origin", "seq"]).size().max() == 1
    depth = np.append(sensors[:, 2], 0.0)
    relays = fwd[fwd["prev"] >= 0]
    assert (depth[relays["node"]] < depth[relays["prev"]]).all()  # named: shallower than its sender


def test_the_battery_gauge_reads_the_modem_energy_drawn():
    from aquasim_py.channel import Constant
    from aquasim_py.channel.config import ChannelConfig, no_snr
    from aquasim_py.kernel import Simulation
    from aquasim_py.node import Node

    class Idle(Node):
        name = "idle"

    cfg = ChannelConfig(
        max_range_m=100.0, bitrate_bps=1000.0, tx_power_w=2.0, rx_power_w=0.5, idle_power_w=0.1, sleep_power_w=0.0
    )
    sim = Simulation(1, Constant(1500.0), channel=cfg, loss_model=no_snr)
    pos = [[0.0, 0.0, 100.0], [50.0, 0.0, 60.0]]
    sim.add_group(Idle, 2, positions=pos, routing="eedbr", battery_j=100.0, routing_params={"hello_spread_s": 1.0})
    sim.add_group(Idle, 1, positions=[[0.0, 0.0, 0.0]], role="sink", routing="eedbr", name="sink")
    sim.run(10.0)
    # each node: idle 10 s at 0.1 W, one 56-bit hello at 2 W, hellos heard at 0.5 W
    for core in sim._cores[:2]:
        gauge = core.router.port.residual_energy()
        drawn = sum(core.energy.joules)
        assert 1.0 - drawn / 100.0 == pytest.approx(gauge)
        assert 10 * 0.1 < drawn < 10 * 0.1 + 0.056 * 2.0 + 2 * 0.056 * 0.5 + 1e-9
    assert sim._cores[2].router.port.residual_energy() == 1.0  # the sink: no battery
