"""Flooding on a connected static network: every packet delivered, every node forwarding each
packet once; and the routing layer's contract (delivery at the first sink, duplicates, hop
limit, unrouted traffic)."""

from __future__ import annotations

import numpy as np
import pytest
from routenet import connected, rows, run


def _network(seed: int, n: int = 40, side: float = 300.0, range_m: float = 100.0):
    rng = np.random.default_rng(seed)
    while True:
        sensors = rng.uniform([0.0, 0.0, 20.0], [side, side, side], (n, 3))
        sinks = np.array([[side / 4, side / 2, 0.0], [3 * side / 4, side / 2, 0.0]])
        # the sensors connected among themselves (sinks do not forward), a sink in range of one
        if connected(sensors, range_m) and connected(np.vstack([sensors, sinks]), range_m):
            return sensors, sinks


@pytest.mark.parametrize("seed", [1, 2])
def test_flooding_delivers_every_packet_and_each_node_forwards_it_once(seed):
    sensors, sinks = _network(seed)
    # one packet in flight at a time (20 s apart; a flood takes under 2 s): no node is ever
    # sending while its first copy arrives, and the channel has no collisions and no loss;
    # only later copies can arrive while a node sends its own (half-duplex)
    plan = {node: [5.0 + 20.0 * j] for j, node in enumerate(range(0, 40, 3))}
    t = run(sensors, sinks, plan, "flooding", until=400.0)
    packets = t["packets"]
    assert set(packets.loc[packets["event"] == "drop", "reason"]) <= {"half_duplex"}
    made = rows(t, "originate")
    assert len(made) == len(plan)
    got = rows(t, "deliver")
    assert sorted(zip(got["origin"], got["seq"])) == sorted(zip(made["origin"], made["seq"]))
    fwd = rows(t, "forward")
    per_node = fwd.groupby(["node", "origin", "seq"]).size()
    assert per_node.max() == 1
    # every sensor (the source included) sent each packet exactly once; no sink forwarded
    assert (fwd.groupby(["origin", "seq"]).size() == len(sensors)).all()
    assert fwd["node"].max() < len(sensors)
    # each sink protocol got each packet at most once, from its origin, and the network once
    sink_got = t["got"]
    assert len(sink_got) == len(plan)
    assert sorted(p[0] for p in sink_got["payload"]) == sorted(plan)
    assert (sink_got["src"] == [p[0] for p in sink_got["payload"]]).all()


def test_later_copies_at_the_sinks_are_duplicates_and_hops_count_transmissions():
    # a vertical chain 80 m apart up to a sink; a second sink beside the first (both heard)
    sensors = [[0.0, 0.0, 320.0 - 80.0 * i] for i in range(4)]
    sinks = [[0.0, 0.0, 0.0], [30.0, 0.0, 0.0]]
    t = run(sensors, sinks, {0: [1.0]}, "flooding", until=60.0)
    deliver = rows(t, "deliver")
    assert len(deliver) == 1 and deliver["hops"].iloc[0] == 4  # sent by 0, 1, 2 and 3
    assert len(rows(t, "sink_copy")) == 1  # the other sink heard node 3 too
    assert len(t["got"]) == 1


def test_the_hop_limit_stops_forwarding():
    sensors = [[0.0, 0.0, 320.0 - 80.0 * i] for i in range(4)]
    t = run(sensors, [[0.0, 0.0, 0.0]], {0: [1.0]}, "flooding", {"max_hops": 2}, until=60.0)
    assert rows(t, "deliver").empty
    drop = rows(t, "drop")
    assert drop["reason"].tolist() == ["max_hops"] and drop["node"].tolist() == [2]


def test_jitter_delays_each_forward_within_its_bound():
    sensors = [[0.0, 0.0, 320.0 - 80.0 * i] for i in range(4)]
    t0 = run(sensors, [[0.0, 0.0, 0.0]], {0: [1.0]}, "flooding", until=60.0)
    t1 = run(sensors, [[0.0, 0.0, 0.0]], {0: [1.0]}, "flooding", {"jitter_max_s": 2.0}, until=60.0)
    d0 = rows(t0, "deliver")["time"].iloc[0]
    d1 = rows(t1, "deliver")["time"].iloc[0]
    assert d0 < d1 < d0 + 3 * 2.0
