"""Energy by modem state (aquasim_py.energy) in scripted exchanges against the hand computation,
sleep, battery depletion (a dead node neither sends nor receives), the meter's bookkeeping, and
the energy.* metrics."""

from __future__ import annotations

import math
from typing import ClassVar

import pandas as pd
import pytest

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.energy import EnergyMeter
from aquasim_py.kernel import Simulation
from aquasim_py.metrics import energy_metrics
from aquasim_py.node import Node

#: (tx, rx, idle, sleep) W
POWER = dict(tx_power_w=10.0, rx_power_w=1.0, idle_power_w=0.1, sleep_power_w=0.01)


class Scripted(Node):
    """Follows ``actions[id]``: (local time, "send" bits | "sleep" | "wake"); logs each send's
    stamp (or what the modem said) to ``did``."""

    name = "scripted_energy"
    actions: ClassVar[dict[int, list[tuple[float, str, int]]]] = {}

    def run(self):
        for t, what, bits in self.actions.get(self.id, []):
            if t > self.local_time():
                yield self.sleep(t - self.local_time())
            if what == "send":
                stamp = yield self.broadcast("data", None, bits)
                self.log("did", what=what, stamp=stamp, asleep=self.modem_asleep())
            elif what == "sleep":
                self.modem_sleep()
            else:
                self.modem_wake()


def _run(actions, xs, until=10.0, battery=None, **cfg):
    cls = type("S", (Scripted,), {"actions": actions})
    config = ChannelConfig(max_range_m=1e6, bitrate_bps=1000.0, snr_threshold_db=-1e9, collision="destructive", **cfg)
    sim = Simulation(1, ssp=Constant(1500.0), channel=config)
    sim.add_group(cls, len(xs), positions=[[x, 0.0, 10.0] for x in xs], battery_j=battery)
    sim.run(until)
    f = sim.trace.frames()
    return f["packets"], f["energy"].set_index("node")


def test_a_scripted_exchange_costs_what_the_hand_computation_says() -> None:
    """A (0 m) sends 1000 bits at 1 s, B (1500 m) 500 bits at 5 s, C (3000 m) sleeps over
    [2.5, 3.5). Delays 1 s per 1500 m, 1 s per 1000 bits.
    A: tx [1, 2) 10 J, rx [6, 6.5) 0.5 J, idle 8.5 s 0.85 J.
    B: rx [2, 3) 1 J, tx [5, 5.5) 5 J, idle 8.5 s 0.85 J.
    C: A's packet at [3, 4): asleep until 3.5 (lost, "sleep"), then receiving; B's at [6, 6.5):
    sleep 1 s 0.01 J, rx 1 s 1 J, idle 8 s 0.8 J."""
    actions = {0: [(1.0, "send", 1000)], 1: [(5.0, "send", 500)], 2: [(2.5, "sleep", 0), (3.5, "wake", 0)]}
    packets, e = _run(actions, [0.0, 1500.0, 3000.0], **POWER)
    hand = {
        0: dict(tx_j=10.0, rx_j=0.5, idle_j=0.85, sleep_j=0.0, tx_s=1.0, rx_s=0.5, idle_s=8.5, sleep_s=0.0),
        1: dict(tx_j=5.0, rx_j=1.0, idle_j=0.85, sleep_j=0.0, tx_s=0.5, rx_s=1.0, idle_s=8.5, sleep_s=0.0),
        2: dict(tx_j=0.0, rx_j=1.0, idle_j=0.8, sleep_j=0.01, tx_s=0.0, rx_s=1.0, idle_s=8.0, sleep_s=1.0),
    }
    for node, want in hand.items():
        for col, v in want.items():
            assert e.loc[node, col] == pytest.approx(v, abs=1e-12), (node, col)
        assert e.loc[node, "energy_j"] == pytest.approx(sum(want[k] for k in ("tx_j", "rx_j", "idle_j", "sleep_j")))
    at_c = packets[(packets.node == 2) & (packets.event != "tx")].set_index("src")
    assert at_c.loc[0, "reason"] == "sleep" and at_c.loc[1, "event"] == "rx"
    assert e["capacity_j"].isna().all() and e["depleted_at"].isna().all()


def test_a_modem_that_sleeps_draws_sleep_power_and_sends_nothing() -> None:
    """A sleeps from 1 s to 9 s and tries to send at 4 s: the packet is dropped ("sleep"), its
    event still fires after its airtime, and the 8 s asleep cost 8 x 0.01 J."""
    actions = {0: [(1.0, "sleep", 0), (4.0, "send", 1000), (9.0, "wake", 0)]}
    packets, e = _run(actions, [0.0, 1500.0], **POWER)
    assert packets.event.tolist() == ["drop"] and packets.reason.tolist() == ["sleep"]
    assert e.loc[0, "sleep_s"] == pytest.approx(8.0) and e.loc[0, "sleep_j"] == pytest.approx(0.08)
    assert e.loc[0, "tx_j"] == 0.0 and e.loc[0, "idle_s"] == pytest.approx(2.0)


def test_sleep_waits_for_the_transmit_queue() -> None:
    """A modem put to sleep while it transmits sleeps once the queue has emptied: the packet
    goes out whole, and the sleep starts at its last bit."""

    class Busy(Node):
        name = "busy"

        def run(self):
            if self.id == 0:
                yield self.sleep(1.0)
                ev = self.broadcast("data", None, 2000)  # [1, 3)
                self.modem_sleep()
                yield ev

    config = ChannelConfig(max_range_m=1e6, bitrate_bps=1000.0, snr_threshold_db=-1e9, **POWER)
    sim = Simulation(1, ssp=Constant(1500.0), channel=config)
    sim.add_group(Busy, 2, positions=[[0.0, 0.0, 10.0], [1500.0, 0.0, 10.0]])
    sim.run(10.0)
    f = sim.trace.frames()
    assert f["packets"].event.tolist() == ["tx", "rx"]
    e = f["energy"].set_index("node")
    assert e.loc[0, "tx_s"] == pytest.approx(2.0) and e.loc[0, "sleep_s"] == pytest.approx(7.0)


def test_a_dead_node_neither_sends_nor_receives() -> None:
    """A's battery holds 5 J: idle 0.1 W over [0, 1), then 10 W from its transmission at 1 s: empty
    at 1 + 4.9 / 10 = 1.49 s. That transmission still reaches B (its signal is in the water);
    B's packet to A at 5 s is lost ("energy") and A's second packet at 8 s never leaves. B's
    own 5 J last: 0.1 x 8.9 s idle + 1 J receiving + 1 J sending (100 bits) = 2.89 J."""
    actions = {0: [(1.0, "send", 1000), (8.0, "send", 100)], 1: [(5.0, "send", 100)]}
    packets, e = _run(actions, [0.0, 1500.0], battery=5.0, **POWER)
    assert e.loc[0, "depleted_at"] == pytest.approx(1.49, abs=1e-12)
    assert e.loc[0, "energy_j"] == pytest.approx(5.0, abs=1e-12)
    assert e.loc[0, "tx_s"] == pytest.approx(0.49) and e.loc[0, "idle_s"] == pytest.approx(1.0)
    assert e.loc[1, "capacity_j"] == 5.0 and math.isnan(e.loc[1, "depleted_at"])
    assert e.loc[1, "energy_j"] == pytest.approx(2.89, abs=1e-12)
    rows = list(zip(packets.time, packets.event, packets.reason.fillna(""), packets.node, strict=True))
    assert (2.0, "rx", "", 1) in rows  # A's first packet, sent before it died, arrives
    assert (6.0, "drop", "energy", 0) in rows  # A is dead when B's packet arrives
    assert (8.0, "drop", "energy", 0) in rows  # A's second packet never leaves
    assert not any(ev == "tx" and t >= 1.49 and n == 0 for t, ev, _, n in rows)


def test_the_meter_counts_overlapping_signals_once_and_by_precedence() -> None:
    m = EnergyMeter((10.0, 1.0, 0.1, 0.01))
    m.receive(1.0, 3.0, 0.0)
    m.receive(2.0, 4.0, 0.0)  # overlaps: rx [1, 4)
    m.transmit(3.5, 4.5)  # tx wins over rx
    m.sleep(6.0)
    m.receive(6.5, 7.0, 6.0)  # asleep: not receiving
    m.wake(8.0)
    row = dict(zip(("energy_j", "tx_j", "rx_j", "idle_j", "sleep_j", "tx_s", "rx_s", "idle_s", "sleep_s"), m.row(10.0)))
    assert row["tx_s"] == pytest.approx(1.0) and row["rx_s"] == pytest.approx(2.5)
    assert row["sleep_s"] == pytest.approx(2.0) and row["idle_s"] == pytest.approx(4.5)
    assert row["energy_j"] == pytest.approx(10.0 + 2.5 + 0.45 + 0.02)
    with pytest.raises(ValueError, match="capacity"):
        EnergyMeter((1.0, 1.0, 1.0, 1.0), capacity_j=0.0)


def test_energy_metrics_from_a_table() -> None:
    e = pd.DataFrame(
        {
            "time": [5.0, 10.0, 10.0, 10.0, 10.0],
            "node": [0, 0, 1, 2, 3],
            "energy_j": [1.0, 4.0, 2.0, 6.0, 8.0],
            **{c: [0.0, 1.0, 0.5, 1.5, 2.0] for c in ("tx_j", "rx_j", "idle_j", "sleep_j")},
            "capacity_j": [4.0, 4.0, 4.0, 6.0, math.nan],
            "depleted_at": [math.nan, 7.0, math.nan, 9.0, math.nan],
        }
    )
    est = pd.DataFrame({"node": [0, 1, 1, 3], "time": [1.0, 2.0, 3.0, 4.0]})
    nodes = pd.DataFrame({"node": [0, 1, 2, 3], "role": ["anchor", "ordinary", "ordinary", "ordinary"]})
    m = energy_metrics(e, received=10, estimates=est, nodes=nodes)
    assert m["total_j"] == 20.0 and m["per_node_j"] == 5.0 and m["max_node_j"] == 8.0
    assert m["tx_j"] == 5.0 and m["per_delivered_packet_j"] == 2.0
    assert m["per_localized_node_j"] == 10.0  # nodes 1 and 3 (node 0 is an anchor)
    assert m["depleted_nodes"] == 2 and m["first_depleted_s"] == 7.0
    assert m["half_depleted_s"] == 9.0  # 3 batteries: the second to empty
    assert energy_metrics(None) == {}
