"""The SINR receiver (``reception = "sinr"``) in the channel: its verdicts against a brute force
over every signal, its packet-error draws against the PER they were drawn from, and weak
signals interfering.

The brute force: networks on a line in a 1024 m/s medium (nodes 64 m apart or more, 1024
bit/s, 64- or 128-bit broadcasts on a 1/16 s grid: every arrival and end is an exact binary
fraction, so equal arrivals and signals that only touch occur), with a PER table that is a step
(PER 1 below X dB, 0 above), so every verdict is deterministic. It re-decides each reception
from the rules as docs/network.md states them, by testing every pair of signals: acquisition at
the first bit (awake, not transmitting, SINR >= threshold, and the lock), then the SINR at every
piece between the instants where an interferer starts or ends.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scripted import Plan, planned

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.channel.phy import ErrorModel, packet_error
from aquasim_py.kernel import Simulation

C = 1024.0  # m/s
BITRATE = 1024.0  # bit/s
GRID = 1.0 / 16.0  # s
THR = 10.0  # dB: acquisition
FLOOR = 0.0  # dB: weaker signals are not recorded
STEP = 14.0  # dB: the PER table's step


def _config(lock: str, **kw: object) -> ChannelConfig:
    # spherical spreading and a 140 dB source: SNR from 37 dB at 64 m to 8 dB at 1536 m, so
    # that weak signals (below THR, above FLOOR) and the PER step's both sides occur
    base = dict(
        max_range_m=1e6,
        bitrate_bps=BITRATE,
        source_level_db=140.0,
        spreading=2.0,
        snr_threshold_db=THR,
        reception="sinr",
        lock=lock,
        interference_floor_db=FLOOR,
        modulation="table",
        per_table=((STEP - 1e-3, 1.0), (STEP, 0.0)),
        per_table_bits=64,
    )
    base.update(kw)
    return ChannelConfig(**base)  # type: ignore[arg-type]


def _run(xs: list[int], plan: Plan, lock: str) -> pd.DataFrame:
    sim = Simulation(1, ssp=Constant(C), channel=_config(lock))
    sim.add_group(planned(plan), len(xs), positions=[[64.0 * x, 0.0, 10.0] for x in xs])
    sim.run(20.0)
    return sim.trace.frames()["packets"]


def _brute_force(xs: list[int], p: pd.DataFrame, lock: str) -> list[tuple[int, int, str, str | None]]:
    """(uid, node, event, reason) of every reception decided from the rules by brute force."""
    tx = p[p.event == "tx"]
    snr = {(int(u), int(n)): float(s) for u, n, s in zip(p.uid, p.node, p.snr_db, strict=True) if s == s}
    own = {
        r: [(t0, t0 + b / BITRATE) for t0, s, b in zip(tx.time, tx.src, tx.bits, strict=True) if s == r]
        for r in range(len(xs))
    }
    thr, step = 10.0 ** (THR / 10.0), 10.0 ** (STEP / 10.0)
    out = []
    for r in range(len(xs)):
        sig = []  # (arrival, end, power, uid) of every recorded signal at r
        for t0, src, uid, bits in zip(tx.time, tx.src, tx.uid, tx.bits, strict=True):
            if src != r and snr[(int(uid), r)] >= FLOOR:
                arr = t0 + abs(xs[r] - xs[src]) * 64.0 / C
                sig.append((arr, arr + bits / BITRATE, 10.0 ** (snr[(int(uid), r)] / 10.0), int(uid)))
        sig.sort(key=lambda s: s[0])

        def transmitting(t: float) -> bool:
            return any(a <= t < b for a, b in own[r])

        def level(t: float, me: int) -> float:  # noise + every other signal present at t
            return 1.0 + sum(q for a, b, q, u in sig if u != me and a <= t < b)

        state: dict[int, str] = {}
        held = None  # the signal the receiver is locked on
        for arr, end, q, uid in sig:
            if held is not None and (held[1] <= arr or any(held[0] < a <= arr for a, _ in own[r])):
                held = None  # it ended, or a transmission of r's own abandoned it
            ok = q >= thr and not transmitting(arr) and q >= thr * level(arr, uid)
            if ok and (lock != "first" or held is None):
                if held is not None and lock == "relock":
                    state[held[3]] = "lost"
                state[uid] = "acquired"
                if lock != "none":
                    held = (arr, end, q, uid)
            else:
                state[uid] = "not"
        for arr, end, q, uid in sig:
            if snr[(uid, r)] < THR:
                continue  # its row is the channel's "snr" drop
            if any(a < end and b > arr for a, b in own[r]):
                out.append((uid, r, "drop", "half_duplex"))
                continue
            if state[uid] != "acquired":
                out.append((uid, r, "drop", "collision"))
                continue
            cuts = sorted({arr, end} | {t for a, b, *_ in sig for t in (a, b) if arr < t < end})
            worst = min(q / level((a + b) / 2, uid) for a, b in itertools.pairwise(cuts))
            if worst >= step:
                out.append((uid, r, "rx", None))
            else:
                out.append((uid, r, "drop", "per" if q < step else "collision"))
    return sorted(out)


def _observed(p: pd.DataFrame) -> list[tuple[int, int, str, str | None]]:
    rec = p[(p.event != "tx") & (p.reason.astype(str) != "snr")]
    reasons = [r if isinstance(r, str) else None for r in rec.reason]
    return sorted(zip(rec.uid.astype(int), rec.node.astype(int), rec.event, reasons, strict=True))


@st.composite
def networks(draw: st.DrawFn) -> tuple[list[int], Plan]:
    n = draw(st.integers(2, 6))
    xs = draw(st.lists(st.integers(0, 24), min_size=n, max_size=n, unique=True))
    plan: Plan = {
        i: [
            (GRID * k, None, draw(st.sampled_from([64, 128])))
            for k in sorted(draw(st.lists(st.integers(0, 40), max_size=4, unique=True)))
        ]
        for i in range(n)
    }
    return xs, plan


@pytest.mark.parametrize("lock", ["first", "relock", "none"])
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(networks())
def test_sinr_verdicts_match_a_brute_force_over_every_signal(lock: str, net) -> None:
    xs, plan = net
    p = _run(xs, plan, lock)
    assert _observed(p) == _brute_force(xs, p, lock)


def _line(lock: str, plan: Plan, xs: list[float], until: float = 20.0, **kw: object) -> pd.DataFrame:
    sim = Simulation(1, ssp=Constant(C), channel=_config(lock, **kw))
    sim.add_group(planned(plan), len(xs), positions=[[x, 0.0, 10.0] for x in xs])
    sim.run(until)
    return sim.trace.frames()["packets"]


def test_lock_rules_on_a_hand_case() -> None:
    """R at 0; A (768 m, SNR ~15 dB) starts first, B (128 m, ~31 dB) arrives during A.
    "first": R keeps A, which B's interference then destroys, and B is lost to the lock;
    "relock": B takes R over (delivered), A is lost; "none": B is delivered on its own SINR,
    A lost to the interference. Every loss here is the interference's ("collision")."""
    xs = [0.0, 768.0, 128.0]  # delays 0.75 s and 0.125 s
    plan = {1: [(0.0, None, 1024)], 2: [(1.0, None, 512)]}  # at R: A [0.75, 1.75), B [1.125, 1.625)

    def at_r(lock: str) -> dict[int, str]:
        p = _line(lock, plan, xs)
        r = p[(p.node == 0) & (p.event != "tx")]
        assert (r.snr_db >= STEP).all()  # each would be delivered alone
        return {int(s): (x if isinstance(x, str) else "rx") for s, x in zip(r.src, r.reason, strict=True)}

    assert at_r("first") == {1: "collision", 2: "collision"}
    assert at_r("relock") == {1: "collision", 2: "rx"}
    assert at_r("none") == {1: "collision", 2: "rx"}
    # B outlasting A ([1.125, 2.125)): A's verdict now comes before B's
    plan[2] = [(1.0, None, 1024)]
    assert at_r("relock") == {1: "collision", 2: "rx"}
    assert at_r("first") == {1: "collision", 2: "collision"}


def test_weak_signals_interfere_under_sinr_not_under_the_threshold_model() -> None:
    """A signal below the detection threshold (never decoded) but above the floor still lowers
    the SINR of a decodable one it overlaps: lost under "sinr"; the threshold model never
    records it, so the same packet is delivered there even with destructive collisions."""
    xs = [0.0, 700.0, 1300.0]  # R, a decodable sender (~15.7 dB), a weak one (~9.6 dB)
    plan = {1: [(1.0, None, 512)], 2: [(0.5, None, 512)]}  # at R: [1.684, 2.184) and [1.770, 2.270)
    sinr = _line("first", plan, xs)
    at_r = sinr[(sinr.node == 0) & (sinr.event != "tx")].set_index("src")
    assert FLOOR <= at_r.loc[2, "snr_db"] < THR and at_r.loc[1, "snr_db"] >= STEP  # weak; decodable alone
    assert at_r.loc[2, "reason"] == "snr" and at_r.loc[1, "reason"] == "collision"
    sim = Simulation(1, ssp=Constant(C), channel=_config("first", reception="threshold", collision="destructive"))
    sim.add_group(planned(plan), 3, positions=[[x, 0.0, 10.0] for x in xs])
    sim.run(20.0)
    p = sim.trace.frames()["packets"]
    assert p[(p.node == 0) & (p.src == 1)].event.tolist() == ["rx"]


def test_per_draws_deliver_at_the_rate_the_modulation_gives() -> None:
    """One sender, one receiver at a fixed SNR where non-coherent BFSK loses a 256-bit packet
    with probability PER (phy.packet_error): the fraction delivered over 2000 packets is within
    4.5 binomial standard deviations of 1 - PER, and every loss is "per" (noise alone)."""
    x = 2000.0
    n = 2000
    plan = {1: [(0.5 * k, 0, 256) for k in range(n)]}
    cfg = dict(modulation="bfsk", per_table=None, source_level_db=138.2, bitrate_bps=1000.0, snr_threshold_db=0.0)
    p = _line("first", plan, [0.0, x], 0.5 * n + 5.0, **cfg)
    rec = p[(p.node == 0) & (p.event != "tx")]
    assert len(rec) == n
    snr = float(rec.snr_db.iloc[0])
    per = packet_error(ErrorModel("bfsk", 2, 5000.0, 1000.0), ((10.0 ** (snr / 10.0), 256.0),))
    assert 0.2 < per < 0.8, per  # the test is informative where the draw matters
    got = float((rec.event == "rx").mean())
    sd = math.sqrt(per * (1.0 - per) / n)
    assert abs(got - (1.0 - per)) < 4.5 * sd
    assert set(rec.reason.dropna()) == {"per"}
    # the draws are the receiver's own stream: the same run again gives the same verdicts
    again = _line("first", plan, [0.0, x], 0.5 * n + 5.0, **cfg)
    assert again.equals(p)


def test_sinr_with_no_loss_model_is_refused() -> None:
    with pytest.raises(ValueError, match="table"):
        ChannelConfig(reception="sinr", modulation="table")
    assert np.isfinite(ChannelConfig(reception="sinr").error_model().ebn0_per_sinr)
