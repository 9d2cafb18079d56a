"""Channel access of each MAC against hand-computed timelines: slotted ALOHA's slot starts on
the local clock, CSMA's causal carrier sense, TDMA's own slots, Slotted FAMA's handshake."""

from __future__ import annotations

import numpy as np
import pytest
from macnet import run

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig, no_snr
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation
from aquasim_py.net import mac

# 0 and 1 750 m either side of the sink 2 (0.5 s each), 1500 m apart (1 s); 1 kbps
LINE = [[0.0, 0.0, 10.0], [1500.0, 0.0, 10.0], [750.0, 0.0, 10.0]]


def _rows(packets, event, kind="data"):
    return packets[(packets["event"] == event) & (packets["kind"] == kind)]


# -- slotted ALOHA -----------------------------------------------------------------------------


def test_slotted_aloha_sends_at_the_next_slot_start_of_the_local_clock():
    # slot = 1000 bits at 1 kbps + guard 0.25 s; node 0's clock runs 1 s ahead and 100 ppm fast
    clocks = [Clock(skew=1e-4, offset=1.0), Clock.perfect(), Clock.perfect()]
    plan = {0: [(1.3, 2, 1000)], 1: [(0.3, 2, 1000), (3.75, 2, 1000)]}
    p = {"guard_s": 0.25, "slot_bits": 1000, "queue_length": 4}
    packets, _ = run(LINE, plan, "slotted_aloha", p, clocks=clocks, bitrate_bps=1000.0)
    tx = _rows(packets, "tx")
    t0 = tx[tx["node"] == 0]
    # node 0 offered at local 1.3: its next slot start is local 2.5, true (2.5 - 1) / (1 + 1e-4)
    assert t0["time"].tolist() == [pytest.approx(1.5 / (1 + 1e-4), abs=1e-12)]
    assert t0["local_time"].tolist() == [pytest.approx(2.5, abs=1e-12)]
    # node 1: 0.3 -> 1.25; 3.75 is a slot start, and the next one is 5.0
    assert tx[tx["node"] == 1]["time"].tolist() == pytest.approx([1.25, 5.0], abs=1e-12)


def test_slotted_aloha_default_guard_is_the_largest_delay():
    sim = Simulation(0, channel=ChannelConfig(max_range_m=3000.0, bitrate_bps=500.0), loss_model=no_snr)
    (_node,) = sim.add_group(type("N", (mac_node(),), {}), 1, positions=[[0, 0, 10]], mac="slotted_aloha")
    m = sim._cores[0].mac
    assert m.slot == pytest.approx(256 / 500.0 + 3000.0 / 1500.0)


def mac_node():
    from aquasim_py.node import Node

    return Node


# -- CSMA --------------------------------------------------------------------------------------


def test_modem_busy_at_is_causal_and_end_exclusive():
    # 0 sends 1 s at t = 0; it reaches 1 (1500 m) over [1, 2)
    sim = Simulation(
        0, Constant(1500.0), channel=ChannelConfig(bitrate_bps=1000.0, collision="none"), loss_model=no_snr
    )
    sim.add_group(mac_node(), 2, positions=LINE[:2], mac="csma")
    ch = sim.channel
    seen = {}

    def probe(t):
        def at(_):
            seen[t] = (ch.carrier_busy(0), ch.carrier_busy(1))

        sim.env.timeout(t).callbacks.append(at)

    sim.env.timeout(0.0).callbacks.append(lambda _: ch.transmit(0, None, "x", None, 1000))
    for t in (0.5, 0.999999, 1.0, 1.5, 1.999999, 2.0, 2.5):
        probe(t)
    sim.run(5.0)
    assert [seen[t][1] for t in (0.5, 0.999999, 1.0, 1.5, 1.999999, 2.0, 2.5)] == [
        False,  # recorded at 1 since t = 0, but not arrived yet
        False,
        True,
        True,
        True,
        False,  # the last bit has passed
        False,
    ]
    assert seen[0.5][0] and not seen[1.0][0]  # the sender itself while it transmits


def test_csma_defers_while_a_signal_arrives_and_not_before():
    # 1 hears 0's 2-s frame over [1, 3); an offer at 1.5 is sensed busy, one at 0.5 is not
    plan = {0: [(0.0, 2, 2000)], 1: [(0.5, 2, 500), (1.5, 2, 500)]}
    p = {"backoff_max_s": 0.4, "queue_length": 4}
    packets, _ = run(LINE, plan, "csma", p, bitrate_bps=1000.0, collision="none")
    tx1 = _rows(packets, "tx")
    tx1 = tx1[tx1["node"] == 1]["time"].tolist()
    assert tx1[0] == pytest.approx(0.5)
    assert tx1[1] >= 3.0  # only after the carrier has passed (backoffs of at most 0.4 s)
    assert tx1[1] < 3.4 + 1e-9


def test_csma_gives_up_after_max_attempts():
    plan = {0: [(0.0, 2, 5000)], 1: [(1.5, 2, 500)]}
    p = {"backoff_max_s": 0.1, "max_attempts": 3}
    packets, _ = run(LINE, plan, "csma", p, bitrate_bps=1000.0, collision="none")
    busy = packets[(packets["event"] == "drop") & (packets["reason"] == "busy")]
    assert busy["node"].tolist() == [1]


# -- TDMA --------------------------------------------------------------------------------------


def test_tdma_transmits_in_the_own_slot_only_and_nothing_collides():
    # 3-s slots with a 1-s guard: node i owns [3i, 3i + 3) of each 9-s cycle, and its frames
    # must end by 3i + 2
    plan = {0: [(0.5, 2, 1000), (0.6, 2, 500), (0.7, 2, 1000)], 1: [(0.0, 2, 1000)], 2: [(7.0, 0, 1000)]}
    p = {"slot_s": 3.0, "guard_s": 1.0}
    packets, _ = run(LINE, plan, "tdma", p, until=30.0, bitrate_bps=1000.0)
    tx = _rows(packets, "tx")
    by = {n: g["time"].tolist() for n, g in tx.groupby("node")}
    # node 0: in its slot at once, the second frame back to back (ends at 2.0, the guard's
    # start), the third no longer fits: the next cycle
    assert by[0] == pytest.approx([0.5, 1.5, 9.0])
    assert by[1] == pytest.approx([3.0])
    assert by[2] == pytest.approx([7.0])
    assert not (packets["reason"] == "collision").any()
    assert len(_rows(packets, "rx")) == 5


def test_tdma_gives_up_a_frame_longer_than_its_slot():
    packets, _ = run(LINE, {0: [(0.0, 2, 2000)]}, "tdma", {"slot_bits": 1000}, bitrate_bps=1000.0)
    assert packets[packets["event"] == "drop"]["reason"].tolist() == ["too_long"]


# -- Slotted FAMA ------------------------------------------------------------------------------


def test_sfama_handshake_at_slot_starts():
    # tau_max = 1 s (max_delay_s), control 100 bits = 0.1 s: slot 1.1 s; data 1000 bits = 1 s
    plan = {0: [(0.2, 2, 1000)]}
    p = {"max_delay_s": 1.0}
    packets, tables = run(LINE, plan, "sfama", p, bitrate_bps=1000.0)
    tx = packets[packets["event"] == "tx"].sort_values("time")
    assert tx["kind"].tolist() == [mac.RTS, mac.CTS, "data", mac.ACK]
    assert tx["node"].tolist() == [0, 2, 0, 2]
    # RTS at slot 1, CTS at slot 2, data at slot 3 (its last bit reaches the sink at
    # 3.3 + 1 + 0.5 = 4.8), ACK at the next slot start, 5.5
    assert tx["time"].tolist() == pytest.approx([1.1, 2.2, 3.3, 5.5], abs=1e-9)
    got = tables["got"]
    assert got[got["node"] == 2]["kind"].tolist() == ["data"]  # the control frames stay in the MACs
    # the protocol's event: when the ACK's last bit reached the sender
    assert tables["outcome"]["time"].tolist() == pytest.approx([5.5 + 0.1 + 0.5], abs=1e-9)


def test_sfama_overhearing_nodes_defer_and_contenders_both_deliver():
    # 0 and 1 both want the sink at once; 1 also hears 0's RTS (1500 m)
    plan = {0: [(0.0, 2, 1000)], 1: [(0.0, 2, 1000)]}
    p = {"max_delay_s": 1.0, "retries": 8}
    packets, _ = run(LINE, plan, "sfama", p, until=200.0, bitrate_bps=1000.0, seed=3)
    rx = _rows(packets, "rx")
    assert sorted(rx[rx["node"] == 2]["src"]) == [0, 1]
    # data never collides at the sink: the handshake reserved the channel each time
    lost = packets[(packets["event"] == "drop") & (packets["kind"] == "data") & (packets["node"] == 2)]
    assert lost.empty


def test_every_mac_is_registered_with_its_parameters():
    for name, cls in mac.MACS.items():
        assert cls.name == name
        cls.Params()  # every parameter has a default
    assert np.all([issubclass(c, mac.Mac) for c in mac.MACS.values()])
