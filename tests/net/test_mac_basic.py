"""Behaviour every MAC shares, and pure ALOHA's: refusals fire the protocol's event and write a
drop row, a queue sends back to back, ARQ retransmits under one uid and hands a frame up once,
``direct`` is the path of before."""

from __future__ import annotations

import pytest
from macnet import run

from aquasim_py.net import mac

# a line: 0 and 1 750 m either side of the sink 2 (0.5 s each way), 1 s frames at 1 kbps
LINE = [[0.0, 0.0, 10.0], [1500.0, 0.0, 10.0], [750.0, 0.0, 10.0]]


def _rows(packets, event, kind="data"):
    return packets[(packets["event"] == event) & (packets["kind"] == kind)]


def test_direct_is_the_modem_fifo_unchanged():
    plan = {0: [(0.0, 2, 1000), (0.2, 2, 1000)], 1: [(0.1, None, 500)]}
    a, _ = run(LINE, plan, "direct", bitrate_bps=1000.0)
    assert not (a["event"] == "offer").any()  # direct writes no offer rows
    tx = _rows(a, "tx")
    # node 0's second frame waited in the modem's queue for the first's last bit
    assert tx[tx["node"] == 0]["time"].tolist() == [0.0, 1.0]
    assert sorted(tx["uid"]) == [0, 1, 2]


def test_a_busy_aloha_node_refuses_and_the_protocol_still_gets_its_event():
    plan = {0: [(0.0, 2, 1000), (0.5, 2, 1000), (1.5, 2, 1000)]}
    packets, tables = run(LINE, plan, "aloha", bitrate_bps=1000.0)
    offers = packets[packets["event"] == "offer"]
    assert len(offers) == 3 and offers["uid"].is_unique
    refused = packets[(packets["event"] == "drop") & (packets["reason"] == "queue_full")]
    assert refused["time"].tolist() == [0.5] and refused["node"].tolist() == [0]
    out = tables["outcome"].sort_values("k")
    # the refused frame's event fired at once with None; the others at their last bit
    assert out["value"].iloc[1] is None
    assert out["time"].tolist() == [1.0, 0.5, 2.5]
    assert _rows(packets, "tx")["time"].tolist() == [0.0, 1.5]


def test_an_aloha_queue_sends_back_to_back():
    plan = {0: [(0.0, 2, 1000), (0.1, 2, 1000), (0.2, 2, 1000)]}
    packets, _ = run(LINE, plan, "aloha", {"queue_length": 3}, bitrate_bps=1000.0)
    assert _rows(packets, "tx")["time"].tolist() == [0.0, 1.0, 2.0]
    # each transmission carries the uid its offer got
    offers = packets[packets["event"] == "offer"]
    assert _rows(packets, "tx")["uid"].tolist() == offers["uid"].tolist()


def test_arq_retransmits_under_one_uid_and_hands_a_frame_up_once():
    # 0 and 1 collide at the sink; with ACKs each retries after its own random backoff
    plan = {0: [(0.0, 2, 1000)], 1: [(0.0, 2, 1000)]}
    p = {"ack": True, "retries": 10, "backoff_max_s": 8.0}
    packets, tables = run(LINE, plan, "aloha", p, until=200.0, bitrate_bps=1000.0)
    tx = _rows(packets, "tx")
    assert (tx.groupby("uid").size() >= 2).all()  # the first attempts collided
    rx = _rows(packets, "rx")
    assert set(rx["uid"]) == set(tx["uid"])  # both delivered in the end
    got = tables["got"]
    assert len(got[(got["node"] == 2) & (got["kind"] == "data")]) == 2  # each handed up once
    acks = _rows(packets, "tx", mac.ACK)
    assert len(acks) >= 2 and set(acks["node"]) == {2}
    assert not tables["outcome"]["value"].isna().any()  # both frames went out


def test_arq_gives_up_after_its_retries():
    # the sink is out of range: no ACK ever comes
    far = [[0.0, 0.0, 10.0], [1.0, 0.0, 10.0], [9000.0, 0.0, 10.0]]
    plan = {0: [(0.0, 2, 1000)]}
    packets, _ = run(far, plan, "aloha", {"ack": True, "retries": 2}, until=200.0, bitrate_bps=1000.0)
    assert len(_rows(packets, "tx")) == 3
    gave_up = packets[(packets["event"] == "drop") & (packets["reason"] == "retries")]
    assert gave_up["node"].tolist() == [0]


def test_unknown_mac_and_bad_parameters():
    with pytest.raises(mac.UnknownMacError, match="unknown MAC 'alhoa'"):
        mac.get("alhoa")
    with pytest.raises(ValueError, match="queue_length"):
        run(LINE, {}, "aloha", {"queue_length": 0})
