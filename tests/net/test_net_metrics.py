"""The network metrics (net.*) against a packets table computed by hand, and pure and slotted
ALOHA against their throughput formulas on a short run (the full check: docs/mac.md)."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from aquasim_py import run_scenario
from aquasim_py.net.metrics import NetWindow, net_metrics

NAN = math.nan


def _table(rows):
    cols = ["time", "event", "reason", "node", "dst", "uid", "kind", "bits"]
    return pd.DataFrame(rows, columns=cols)


def test_definitions_by_hand():
    # 1 bit = 1 ms; window [10, 110): 100 s
    rows = [
        (5.0, "offer", None, 0, 9, 0, "data", 1000),  # before the window: not counted
        (5.0, "tx", None, 0, 9, 0, "data", 1000),
        (5.5, "rx", None, 9, 9, 0, "data", 1000),
        # uid 1: unicast 0 -> 9, offered at 20, collides, retransmitted, delivered at 30.5
        (20.0, "offer", None, 0, 9, 1, "data", 2000),
        (21.0, "tx", None, 0, 9, 1, "data", 2000),
        (21.5, "drop", "collision", 9, 9, 1, "data", 2000),
        (21.5, "drop", "collision", 4, 9, 1, "data", 2000),  # not an addressee: not counted
        (30.0, "tx", None, 0, 9, 1, "data", 2000),
        (30.5, "rx", None, 9, 9, 1, "data", 2000),
        (30.5, "rx", None, 9, 9, 1, "data", 2000),  # a duplicate reception counts once
        (32.6, "tx", None, 9, 0, 7, "mac.ack", 100),  # control frames are not frames
        # uid 2: broadcast by 3 under direct (no offer row) at 40, heard by 4 and 5, lost at 6
        (40.0, "tx", None, 3, -1, 2, "data", 1000),
        (40.2, "rx", None, 4, -1, 2, "data", 1000),
        (40.3, "rx", None, 5, -1, 2, "data", 1000),
        (40.4, "drop", "collision", 6, -1, 2, "data", 1000),
        # uid 3: unicast refused by its MAC
        (50.0, "offer", None, 1, 9, 3, "data", 1000),
        (50.0, "drop", "queue_full", 1, 9, 3, "data", 1000),
    ]
    m = net_metrics({"packets": _table(rows)}, NetWindow(10.0, 110.0, lambda b: b / 1000.0))
    assert m["frames"] == 3  # uids 1, 2, 3
    assert m["delivered"] == 3  # (1, 9), (2, 4), (2, 5)
    assert m["offered_load"] == pytest.approx((2.0 + 1.0 + 1.0) / 100.0)
    assert m["channel_load"] == pytest.approx((2.0 + 2.0 + 1.0) / 100.0)
    assert m["throughput"] == pytest.approx((2.0 + 1.0 + 1.0) / 100.0)
    assert m["delivery_ratio"] == pytest.approx(1 / 2)  # unicast: uid 1 of uids 1 and 3
    # delays: 30.5 + 2 - 20; 40.2 + 1 - 40; 40.3 + 1 - 40
    assert m["delay_s"] == pytest.approx(np.mean([12.5, 1.2, 1.3]))
    assert m["collisions_per_packet"] == pytest.approx(2 / 3)  # at 9 (uid 1) and 6 (uid 2), 3 tx


def test_no_frames_gives_nan_not_an_error():
    m = net_metrics({"packets": _table([])}, NetWindow(0.0, 10.0, lambda b: b / 1000.0))
    assert m["frames"] == 0 and math.isnan(m["throughput"])


@pytest.mark.parametrize(
    "variant, g, theory",
    [("pure", 0.5, 0.5 * math.exp(-1.0)), ("slotted", 1.0, math.exp(-1.001))],
)
def test_aloha_follows_its_theory_on_a_short_run(variant, g, theory):
    """150 nodes at one distance from a sink, Poisson traffic, no capture. The tolerance is 4
    standard deviations of the delivered share, plus the finite population's bias (< 2 G / 150,
    docs/mac.md), so that a lost factor (S = G e^(-G) for pure ALOHA) fails it."""
    rate = g / 150.0
    res = run_scenario(
        "scenarios/mac_aloha.toml",
        variant=variant,
        overrides=[
            "simulation.duration_s=3000",
            "nodes.1.count=150",
            f"nodes.1.params.rate_pps={rate}",
            "trace.tables=[]",
        ],
    )
    m = res.metrics
    n = m["net.frames"]
    p = m["net.throughput"] / m["net.offered_load"]  # delivered share of the offered frames
    expected = theory / g
    sigma = math.sqrt(expected * (1.0 - expected) / n)
    assert abs(p - expected) < 4.0 * sigma + expected * 2.0 * g / 150.0, (p, expected, sigma)
    assert m["net.offered_load"] == pytest.approx(g, rel=0.1)
