"""Delivery verdicts (half duplex, collisions) against a brute force over every signal, and the
order of deliveries whether or not they are decided in the channel's queue loop.

Networks on a line in a 1024 m/s medium, nodes 64 m apart or more, 1024 bit/s, packets of 64 or
128 bits and transmit times on a 1/16 s grid: every delay, duration, arrival and end is an exact
binary fraction, so equal arrivals, equal ends and signals that only touch (one ends exactly as
the other arrives: no overlap, the strict inequalities) occur in most examples. Every node hears
every other (range and SNR threshold out of the way), a unicast interferes at every node and only
its addressee gets a row.
"""

from __future__ import annotations

import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scripted import Plan, planned

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.kernel import Simulation

# every test on both delivery paths (compiled and the Python reference), see tests/conftest.py

C = 1024.0  # m/s
BITRATE = 1024.0  # bit/s
GRID = 1.0 / 16.0  # s


def _run(xs: list[int], plan: Plan, collision: str) -> pd.DataFrame:
    cls = planned(plan)
    cfg = ChannelConfig(max_range_m=1e6, bitrate_bps=BITRATE, snr_threshold_db=-1e9, collision=collision)
    sim = Simulation(1, ssp=Constant(C), channel=cfg)
    sim.add_group(cls, len(xs), positions=[[64.0 * x, 0.0, 10.0] for x in xs])
    sim.run(20.0)
    return sim.trace.frames()["packets"]


def _brute_force(xs: list[int], p: pd.DataFrame) -> list[tuple[int, int, float, str, str | None]]:
    """(uid, node, arrival, event, reason) of every reception, from the transmissions alone: a reception
    at r is cut by r's own transmission [s, e) if s < end and e > arr ("half_duplex", first),
    else by any other signal at r with arrival < end and end > arr ("collision")."""
    tx = p[p.event == "tx"]
    sig = []  # (receiver, arrival, end, uid, dst, src)
    for t0, src, uid, dst, bits in zip(tx.time, tx.src, tx.uid, tx.dst, tx.bits, strict=True):
        for r in range(len(xs)):
            if r != src:
                arr = t0 + abs(xs[r] - xs[src]) * 64.0 / C
                sig.append((r, arr, arr + bits / BITRATE, uid, dst, src))
    own = [(src, t0, t0 + bits / BITRATE) for t0, src, bits in zip(tx.time, tx.src, tx.bits, strict=True)]
    out = []
    for r, arr, end, uid, dst, _src in sig:
        if dst not in (-1, r):
            continue  # a unicast: heard (and interfering) here, delivered only at its addressee
        reason = None
        if any(n == r and s < end and e > arr for n, s, e in own):
            reason = "half_duplex"
        elif any(o[0] == r and o[3] != uid and o[1] < end and o[2] > arr for o in sig):
            reason = "collision"
        out.append((int(uid), r, arr, "rx" if reason is None else "drop", reason))
    return sorted(out, key=lambda x: (x[0], x[1]))


def _observed(p: pd.DataFrame) -> list[tuple[int, int, float, str, str | None]]:
    rec = p[p.event != "tx"]
    reasons = [None if not isinstance(r, str) else r for r in rec.reason]
    rows = zip(rec.uid.astype(int), rec.node.astype(int), rec.time, rec.event, reasons, strict=True)
    return sorted(rows, key=lambda x: (x[0], x[1]))


@st.composite
def networks(draw: st.DrawFn) -> tuple[list[int], Plan]:
    n = draw(st.integers(2, 6))
    xs = draw(st.lists(st.integers(0, 24), min_size=n, max_size=n, unique=True))
    plan: Plan = {}
    for i in range(n):
        slots = draw(st.lists(st.integers(0, 40), max_size=4, unique=True))
        plan[i] = [
            (
                GRID * k,
                draw(st.one_of(st.none(), st.sampled_from([j for j in range(n) if j != i]))),
                draw(st.sampled_from([64, 128])),
            )
            for k in sorted(slots)
        ]
    return xs, plan


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(networks())
def test_destructive_verdicts_match_a_brute_force_over_every_signal(net) -> None:
    """The destructive model's verdicts (the channel's bisected scans of the receiver's logs at
    each delivery) are those of testing every pair of signals and every own transmission."""
    xs, plan = net
    p = _run(xs, plan, "destructive")
    assert _observed(p) == _brute_force(xs, p)


def test_the_brute_force_sees_touching_and_equal_signals() -> None:
    """Hand case: R at 0, A 64 m and B 128 m away (1/16 and 1/8 s). A sends 64 bits at 0 (at R
    [1/16, 1/8)), B at 0 (at R [1/8, 3/16)): they only touch, both received. Then A and B send
    at 1 + 1/16 and 1: both arrive at R at 1 + 1/8 exactly, both lost. R itself transmits at
    2 for 1/8 s; A's packet sent at 2 - 1/16 arrives at 2 exactly: half duplex; B's sent at
    2 arrives as R's transmission ends: received."""
    xs = [0, 1, 2]
    plan = {
        0: [(2.0, None, 128)],
        1: [(0.0, None, 64), (1.0 + GRID, None, 64), (2.0 - GRID, None, 64)],
        2: [(0.0, None, 64), (1.0, None, 64), (2.0, None, 64)],
    }
    p = _run(xs, plan, "destructive")
    at_r = p[(p.node == 0) & (p.event != "tx")].sort_values("time")
    got = [
        (t, e, r if isinstance(r, str) else None) for t, e, r in zip(at_r.time, at_r.event, at_r.reason, strict=True)
    ]
    assert got[:4] == [
        (1 / 16, "rx", None),
        (1 / 8, "rx", None),
        (1.125, "drop", "collision"),
        (1.125, "drop", "collision"),
    ]
    assert got[4:] == [(2.0, "drop", "half_duplex"), (2.125, "rx", None)]
    assert _observed(p) == _brute_force(xs, p)
