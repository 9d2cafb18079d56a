"""The traffic protocol: Poisson and constant-rate sources, their destinations, sinks."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_protocols.traffic import TrafficNode
from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig, no_snr
from aquasim_py.kernel import Simulation


def _sim(params, n_sources=3, sinks=2, until=2000.0, mac="direct"):
    sim = Simulation(
        4, Constant(1500.0), channel=ChannelConfig(max_range_m=3000.0, collision="none"), loss_model=no_snr
    )
    sim.add_group(TrafficNode, sinks, role="sink", positions=[[100.0 * k, 0.0, 10.0] for k in range(sinks)], mac=mac)
    sim.add_group(
        TrafficNode,
        n_sources,
        positions=[[0.0, 500.0 + 10 * k, 10.0] for k in range(n_sources)],
        params=params,
        mac=mac,
    )
    sim.run(until)
    pk = sim.trace.frames()["packets"]
    return pk, sim


def test_poisson_sources_offer_at_their_rate_to_the_sinks():
    pk, sim = _sim({"rate_pps": 0.5, "bits": 100}, n_sources=3, until=2000.0)
    tx = pk[pk["event"] == "tx"]
    assert set(tx["node"]) == {2, 3, 4} and set(tx["dst"]) == {0, 1}  # sinks only receive
    # 3 x 0.5 x 2000 = 3000 frames, Poisson: within 4 std
    assert abs(len(tx) - 3000) < 4 * np.sqrt(3000)
    gaps = np.diff(np.sort(tx[tx["node"] == 2]["time"].to_numpy()))
    # exponential gaps: mean 2 s, coefficient of variation 1
    assert gaps.mean() == pytest.approx(2.0, rel=0.12)
    assert gaps.std() / gaps.mean() == pytest.approx(1.0, rel=0.15)
    assert not sim.unawaited  # the open loop is not mistaken for a missing yield


def test_constant_rate_and_a_fixed_destination():
    pk, _ = _sim({"rate_pps": 0.1, "process": "constant", "destination": 1, "start_s": 50.0, "stop_s": 150.0})
    tx = pk[pk["event"] == "tx"]
    for _, g in tx.groupby("node"):
        t = g["time"].to_numpy()
        assert len(t) == 10 and np.allclose(np.diff(t), 10.0)
        assert 50.0 <= t[0] < 60.0
    assert set(tx["dst"]) == {1}


def test_broadcast_traffic_through_a_mac():
    pk, _ = _sim({"rate_pps": 0.01, "destination": "broadcast"}, mac="aloha")
    assert set(pk[pk["event"] == "tx"]["dst"]) == {-1}
    assert (pk["event"] == "offer").sum() == (pk["event"] == "tx").sum() + (pk["reason"] == "queue_full").sum()
