"""The end-to-end metrics on a routes table written by hand, and the layer's plumbing: ANY_SINK
needs a router, a packet to a node that is not a sink goes one hop."""

from __future__ import annotations

import math

import pandas as pd
import pytest
from routenet import rows, run

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig, no_snr
from aquasim_py.kernel import Simulation
from aquasim_py.net.routing.metrics import route_metrics
from aquasim_py.node import ANY_SINK, Node


def _routes(records: list[tuple]) -> dict[str, pd.DataFrame]:
    cols = ["time", "node", "event", "reason", "origin", "seq", "dst", "hops", "prev", "value"]
    return {"routes": pd.DataFrame([(*r[:3], None, *r[3:], -1, math.nan) for r in records], columns=cols)}


def test_each_definition_on_a_table_by_hand():
    t = _routes(
        [
            # packet (1, 0): 3 transmissions, delivered at 5 s over 3 hops, one later copy at a sink
            (1.0, 1, "originate", 1, 0, -2, 0),
            (1.0, 1, "forward", 1, 0, -2, 1),
            (2.0, 2, "forward", 1, 0, -2, 2),
            (2.5, 3, "forward", 1, 0, -2, 2),
            (4.0, 4, "forward", 1, 0, -2, 3),
            (5.0, 9, "deliver", 1, 0, -2, 3),
            (5.5, 8, "sink_copy", 1, 0, -2, 3),
            # packet (2, 0): sent once, lost
            (3.0, 2, "originate", 2, 0, -2, 0),
            (3.0, 2, "forward", 2, 0, -2, 1),
            # packet (1, 1): delivered at 11 s in one hop
            (10.0, 1, "originate", 1, 1, 9, 0),
            (10.0, 1, "forward", 1, 1, 9, 1),
            (11.0, 9, "deliver", 1, 1, 9, 1),
            # packet (3, 0): originated before the window, delivered in it: not counted
            (0.5, 3, "originate", 3, 0, -2, 0),
            (0.5, 3, "forward", 3, 0, -2, 1),
            (1.5, 9, "deliver", 3, 0, -2, 1),
        ]
    )
    m = route_metrics(t, 0.9, 100.0)
    assert m["packets_originated"] == 3 and m["packets_delivered"] == 2
    assert m["pdr"] == pytest.approx(2 / 3)
    assert m["delay_s"] == pytest.approx(((5.0 - 1.0) + (11.0 - 10.0)) / 2)
    assert m["hops_mean"] == pytest.approx((3 + 1) / 2)
    assert m["copies_per_delivered"] == pytest.approx((4 + 1 + 1) / 2)
    assert m["sink_copies_per_delivered"] == pytest.approx(3 / 2)
    assert route_metrics({}, 0.0, 1.0) == {}
    none = route_metrics(_routes([(1.0, 1, "originate", 1, 0, -2, 0)]), 0.0, 10.0)
    assert none["pdr"] == 0.0 and math.isnan(none["delay_s"]) and math.isnan(none["copies_per_delivered"])


class _Once(Node):
    name = "once"
    dst = ANY_SINK

    def run(self):
        if self.id == 0:
            yield self.send(self.dst, "data", None, 100)


def test_any_sink_needs_a_routing_layer():
    sim = Simulation(1, Constant(1500.0), channel=ChannelConfig(max_range_m=100.0), loss_model=no_snr)
    sim.add_group(_Once, 2, positions=[[0.0, 0.0, 10.0], [50.0, 0.0, 10.0]])
    with pytest.raises(ValueError, match="ANY_SINK needs a routing layer"):
        sim.run(1.0)


def test_a_unicast_to_a_node_that_is_not_a_sink_goes_one_hop():
    class ToOne(_Once):
        dst = 1

    sim = Simulation(1, Constant(1500.0), channel=ChannelConfig(max_range_m=100.0, collision="none"), loss_model=no_snr)
    sim.add_group(ToOne, 2, positions=[[0.0, 0.0, 10.0], [50.0, 0.0, 10.0]], routing="flooding")
    sim.add_group(ToOne, 1, positions=[[0.0, 0.0, 0.0]], role="sink", routing="flooding", name="sink")
    sim.run(2.0)
    t = sim.trace.frames()
    assert "routes" not in t or t["routes"].empty
    rx = t["packets"].query("event == 'rx'")
    assert rx["dst"].tolist() == [1] and rx["node"].tolist() == [1] and rx["kind"].tolist() == ["data"]


def test_a_packet_addressed_to_one_sink_is_delivered_to_it_from_the_first_sink_reached():
    from routenet import Planned

    class ToFar(Planned):
        def run(self):
            if self.id == 0:
                self.send(3, "data", "x", 100).callbacks.append(lambda _e: None)
            yield from super().run()

    sensors = [[0.0, 0.0, 80.0], [0.0, 0.0, 160.0]]
    # sink 2 above node 0; sink 3 far away (only the radio link reaches it)
    t = run(sensors, [[0.0, 0.0, 0.0], [900.0, 0.0, 0.0]], {}, "flooding", until=10.0, cls=ToFar)
    got = t["got"]
    assert got["node"].tolist() == [3] and got["src"].tolist() == [0]
    assert rows(t, "deliver")["node"].tolist() == [2]


def test_a_node_whose_battery_is_empty_routes_nothing():
    from routenet import Planned

    from aquasim_py.node import Sensors

    cls = type("P", (Planned,), {"plan": {0: [1.0, 2.0], 1: [1.5]}})
    cfg = ChannelConfig(
        max_range_m=100.0, collision="none", bitrate_bps=10_000.0,
        tx_power_w=2.0, rx_power_w=0.5, idle_power_w=0.1, sleep_power_w=0.0,
    )  # fmt: skip
    sim = Simulation(1, Constant(1500.0), channel=cfg, loss_model=no_snr)
    chain = [[0.0, 0.0, 160.0], [0.0, 0.0, 80.0]]
    sim.add_group(cls, 1, positions=chain[:1], routing="flooding", sensors=Sensors(position=True), name="a")
    # node 1 idles its 0.05 J away in half a second: dead before anything reaches it
    sim.add_group(cls, 1, positions=chain[1:], routing="flooding", battery_j=0.05, name="b")
    sim.add_group(cls, 1, positions=[[0.0, 0.0, 0.0]], role="sink", routing="flooding", name="sink")
    sim.run(10.0)
    t = sim.trace.frames()
    r = t["routes"]
    assert set(r.loc[r["node"] == 1, "event"]) == set()  # no originate (its own plan), no forward
    assert r.loc[r["event"] == "originate", "node"].tolist() == [0, 0]
    assert rows(t, "deliver").empty
    tx = t["packets"].query("event == 'tx'")
    assert set(tx["node"]) == {0}
