"""DBR: the holding time as printed, Q1's cancellation and update, Q2, and the property that no
node forwards unless it is more than the depth threshold shallower than the hop it answers."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from routenet import FakePort, rows, run

from aquasim_py.net.routing.base import Datagram
from aquasim_py.net.routing.dbr import Dbr, DbrHeader, DbrParams

R = 100.0
TAU = R / 1500.0


def test_the_holding_time_is_2tau_over_delta_times_r_minus_d():
    # source 300 m deep; one node 60 m above it, 50 m aside; the sink 80 m above that node
    sensors = [[0.0, 0.0, 300.0], [50.0, 0.0, 240.0]]
    t = run(sensors, [[50.0, 0.0, 160.0]], {0: [1.0]}, "dbr", until=30.0)
    fwd = rows(t, "forward").set_index("node")
    airtime = (200 + 56 + 16) / 10_000.0
    dist = np.hypot(50.0, 60.0)
    rx_end = 1.0 + dist / 1500.0 + airtime  # the node decides at the copy's last bit
    hold = 2.0 * TAU / (R / 2.0) * (R - 60.0)  # delta = R / 2 by default
    assert abs(fwd.loc[1, "time"] - (rx_end + hold)) < 1e-9
    assert abs(fwd.loc[1, "value"] - 60.0) < 1e-9
    # delta = R halves it
    t2 = run(sensors, [[50.0, 0.0, 160.0]], {0: [1.0]}, "dbr", {"delta_m": R}, until=30.0)
    assert abs(rows(t2, "forward").set_index("node").loc[1, "time"] - (rx_end + hold / 2)) < 1e-9


def test_a_held_packet_is_dropped_when_a_shallower_node_sends_it():
    # 1 gains 90 m and sends first; 2 gains 30 m and holds 4 tau 60 / 100 = 160 ms longer,
    # more than 1's copy takes to reach it (61 m, 41 ms, and its 27 ms airtime): it stands down
    sensors = [[0.0, 0.0, 300.0], [0.0, 10.0, 210.0], [10.0, 0.0, 270.0]]
    t = run(sensors, [[0.0, 10.0, 130.0]], {0: [1.0]}, "dbr", until=30.0)
    assert sorted(rows(t, "forward")["node"]) == [0, 1]
    sup = rows(t, "suppress")
    assert sup["node"].tolist() == [2] and sup["prev"].tolist() == [0]
    assert len(rows(t, "deliver")) == 1


def test_q1_rules_for_later_copies_and_q2():
    port = FakePort(depth=150.0)
    dbr = Dbr(port, DbrParams(depth_threshold_m=5.0))
    hold = dbr.holding_time

    def copy(sender: int, depth: float, seq: int = 0) -> None:
        dbr.on_copy(Datagram(DbrHeader(7, seq, -2, 1, sender, depth=depth), "data", None, 100), sender)

    copy(3, 200.0)  # gains 50 m: queued
    assert dbr.q1[(7, 0)].send_at == hold(50.0) and dbr.q1[(7, 0)].prev == 3
    copy(4, 250.0)  # gains 100 m: due earlier, the new sender is the previous hop
    assert dbr.q1[(7, 0)].send_at == hold(100.0) and dbr.q1[(7, 0)].prev == 4
    copy(5, 180.0)  # gains 30 m: later, no change
    assert dbr.q1[(7, 0)].send_at == hold(100.0) and dbr.q1[(7, 0)].prev == 4
    copy(6, 154.0)  # gains 4 m <= d_th: a node about as shallow sent it, stand down
    assert (7, 0) not in dbr.q1 and port.events("suppress")[0][6] == 4
    port.env.run(1.0)
    assert port.offered == []
    # a packet sent once is dropped at every later copy (Q2), however deep it comes from
    copy(3, 200.0, seq=1)
    port.env.run(2.0)
    assert [p.header.seq for _, p in port.offered] == [1]
    sent = port.offered[0][1].header
    assert sent.depth == 150.0 and sent.hops == 2 and sent.sender == 1
    copy(4, 290.0, seq=1)
    port.env.run(3.0)
    assert len(port.offered) == 1 and (7, 1) not in dbr.q1


def test_q1_sends_its_head_first_whatever_the_order_of_arrival():
    port = FakePort(depth=150.0)
    dbr = Dbr(port, DbrParams())
    for seq, depth in enumerate([190.0, 240.0, 170.0, 210.0]):
        dbr.on_copy(Datagram(DbrHeader(7, seq, -2, 1, 3, depth=depth), "data", None, 100), 3)
    port.env.run(1.0)
    assert [p.header.seq for _, p in port.offered] == [1, 3, 0, 2]  # most depth gained first
    assert [t for t, _ in port.offered] == sorted(dbr.holding_time(g) for g in (40.0, 90.0, 20.0, 60.0))


@settings(max_examples=25)
@given(
    seed=st.integers(0, 10_000),
    d_th=st.sampled_from([0.0, 10.0, 25.0]),
    n=st.integers(8, 30),
)
def test_no_node_forwards_unless_more_than_the_threshold_shallower_than_its_previous_hop(seed, d_th, n):
    rng = np.random.default_rng(seed)
    sensors = rng.uniform([0.0, 0.0, 30.0], [200.0, 200.0, 300.0], (n, 3))
    sinks = np.array([[100.0, 100.0, 0.0]])
    deepest = [int(np.argmax(sensors[:, 2]))]
    plan = {deepest[0]: [1.0, 20.0], int(rng.integers(n)): [40.0]}
    t = run(sensors, sinks, plan, "dbr", {"depth_threshold_m": d_th}, until=80.0, collision="destructive")
    fwd = rows(t, "forward")
    relays = fwd[fwd["prev"] >= 0]
    depth = np.concatenate([sensors[:, 2], sinks[:, 2]])
    gained = depth[relays["prev"].to_numpy(int)] - depth[relays["node"].to_numpy(int)]
    assert (gained > d_th).all()
    np.testing.assert_allclose(relays["value"], gained, atol=1e-9)  # what the node measured
    assert fwd.groupby(["node", "origin", "seq"]).size().max() == 1
