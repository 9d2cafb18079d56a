"""The SimPy acoustic channel: delays, moving receivers, MAC stamps, losses, hand timelines.

References are independent of the channel code: the ray tracer's own ``travel_time`` for a
single pair (tested in its own module), a scipy root of the arrival-time equation written
from the receiver's closed-form trajectory, and hand-computed timelines in a 1500 m/s medium.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st
from scipy.optimize import brentq
from scripted import Script, planned

from aquasim_py.channel import Constant, Isogradient, config, eigenray, fixed_point, links, travel_time
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.channel.rays import Eigenray, PathKind
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import Box, ConstantVelocity
from aquasim_py.node import Node

# every test on both delivery paths (compiled and the Python reference), see tests/conftest.py

# Use the isogradient profile as soon as the ray tracer supports it; Constant only until then.
_ISO = Isogradient(1480.0, 0.1)
try:
    travel_time(_ISO, [0.0, 0.0, 50.0], [800.0, 300.0, 120.0])
    PROFILE = _ISO
except NotImplementedError:
    PROFILE = Constant(1500.0)

BOX = Box([-10_000.0, -10_000.0, 0.0], [10_000.0, 10_000.0, 1000.0])


class Listener(Node):
    name = "listener"

    def run(self):
        while True:
            rec = yield self.recv()
            self.log("got", src=rec.packet.src, uid=rec.packet.uid, tx_local=rec.packet.tx_local, rx_local=rec.rx_local)


def _packets(sim: Simulation):
    return sim.trace.frames()["packets"]


def test_static_delay_equals_travel_time():
    src, dst = [0.0, 0.0, 50.0], [800.0, 300.0, 120.0]
    sim = Simulation(1, ssp=PROFILE, channel=ChannelConfig(collision="none"))
    sim.add_group(planned({0: [(0.3, None, 64)]}), 1, positions=[src])
    sim.add_group(Listener, 1, positions=[dst])
    sim.run(5.0)
    p = _packets(sim)
    tx = p[p.event == "tx"].iloc[0]
    rx = p[p.event == "rx"].iloc[0]
    expected = float(travel_time(PROFILE, src, dst))
    assert abs((rx.time - tx.time) - expected) < 1e-9
    assert abs(rx.tof - expected) < 1e-9
    assert rx.path == "direct"


def test_moving_receiver_delay_at_arrival_position():
    """Receiver at 2 m/s, sender at 1.5 m/s: tof = T(p_src(t0), p_rx(t_arr)) to 1e-9 s."""
    p_s0, v_s = np.array([0.0, 0.0, 100.0]), np.array([1.5, 0.0, 0.0])
    p_r0, v_r = np.array([1200.0, 400.0, 160.0]), np.array([-1.2, 1.6, 0.0])  # |v| = 2 m/s
    assert math.isclose(np.linalg.norm(v_r), 2.0)
    sim = Simulation(2, ssp=PROFILE, volume=BOX, channel=ChannelConfig(collision="none"))
    sim.add_group(
        planned({0: [(5.0, None, 64), (40.0, None, 64)]}), 1, mobility=ConstantVelocity([p_s0], BOX, velocity=v_s)
    )
    sim.add_group(Listener, 1, mobility=ConstantVelocity([p_r0], BOX, velocity=v_r))
    sim.run(60.0)
    p = _packets(sim)
    tx = p[p.event == "tx"].sort_values("uid")
    rx = p[p.event == "rx"].sort_values("uid")
    assert len(tx) == 2 and len(rx) == 2
    for (_, t), (_, r) in zip(tx.iterrows(), rx.iterrows()):
        t0 = t.time
        ps = p_s0 + v_s * t0
        # independent root of t = t0 + T(ps, p_r0 + v_r t) (scipy, not the channel's iteration)
        f = lambda ta: ta - t0 - float(travel_time(PROFILE, ps, p_r0 + v_r * ta))  # noqa: E731
        t_arr = brentq(f, t0, t0 + 10.0, xtol=1e-13, rtol=1e-15)
        assert abs(r.time - t_arr) < 1e-9
        assert abs(r.tof - float(travel_time(PROFILE, ps, p_r0 + v_r * r.time))) < 1e-9
        # and the motion matters at this scale: the delay to the send-time position is off
        assert abs(r.tof - float(travel_time(PROFILE, ps, p_r0 + v_r * t0))) > 1e-4


def test_mac_timestamps_follow_local_clocks():
    """Every stamp (trace and what the protocols saw) = (1 + skew) t + offset of its true time."""
    skews, offsets = [40e-6, -25e-6, 0.0], [0.37, -1.25, 0.0]
    clocks = [Clock(skew=s, offset=o) for s, o in zip(skews, offsets)]
    positions = [[0.0, 0.0, 30.0], [1000.0, 0.0, 30.0], [0.0, 900.0, 60.0]]
    cls = planned({0: [(2.0, None, 100), (9.0, 1, 100)], 1: [(4.0, None, 80)]})

    class Both(cls):  # sends its plan and logs what it receives
        def run(self):
            self.env.process(Script.run(self))
            while True:
                rec = yield self.recv()
                self.log(
                    "got", src=rec.packet.src, tx_local=rec.packet.tx_local, rx_local=rec.rx_local, uid=rec.packet.uid
                )

    sim = Simulation(3, ssp=PROFILE, channel=ChannelConfig(collision="none", jitter_std_s=0.0))
    sim.add_group(Both, 3, positions=positions, clocks=clocks)
    sim.run(20.0)
    f = sim.trace.frames()
    p = f["packets"]
    stamped = p[p.event.isin(["tx", "rx"])]
    assert len(stamped) >= 6
    for _, r in stamped.iterrows():
        n = int(r.node)
        assert abs(r.local_time - ((1 + skews[n]) * r.time + offsets[n])) < 1e-12 * max(1, r.time)
    got = f["got"]
    tx_time = p[p.event == "tx"].set_index("uid")["time"]
    rx = p[p.event == "rx"].set_index(["uid", "node"])["time"]
    for _, g in got.iterrows():
        s, n = int(g.src), int(g.node)
        assert abs(g.tx_local - ((1 + skews[s]) * tx_time[g.uid] + offsets[s])) < 1e-12
        assert abs(g.rx_local - ((1 + skews[n]) * rx[(g.uid, n)] + offsets[n])) < 1e-12
    # the protocol's own notion of the transmit stamp (value of the send event) agrees too
    sent = f["sent"]
    assert np.allclose(sorted(sent.stamp), sorted(p[p.event == "tx"].local_time), rtol=0, atol=0)


# ---------------------------------------------------------------------------------------------
# Hand-computed timelines in c = 1500 m/s, bitrate 1000 bps: 200 bits = 0.2 s on the air.

C = Constant(1500.0)
A, R, B_FAR = [-1500.0, 0.0, 10.0], [0.0, 0.0, 10.0], [1500.0, 0.0, 10.0]  # T(A,R) = T(B,R) = 1 s


def _run_three(plan, positions, **cfg) -> tuple[Simulation, object]:
    kw = dict(max_range_m=2000.0, snr_threshold_db=-1e9)
    kw.update(cfg)
    sim = Simulation(4, ssp=C, channel=ChannelConfig(**kw))
    sim.add_group(planned(plan), len(positions), positions=positions)
    sim.run(10.0)
    return sim, _packets(sim)


def _at(p, node, event=None):
    q = p[p.node == node]
    return q if event is None else q[q.event == event]


@pytest.mark.parametrize("t_b, collide", [(0.1, True), (0.25, False)])
def test_destructive_collision_timeline(t_b, collide):
    # A -> R occupies [1.0, 1.2]; B -> R occupies [t_b + 1, t_b + 1.2]; A and B are 3000 m apart
    # (out of range), so only R sees both.
    _sim, p = _run_three({0: [(0.0, None, 200)], 2: [(t_b, None, 200)]}, [A, R, B_FAR], collision="destructive")
    at_r = _at(p, 1)
    if collide:
        assert list(at_r.event) == ["drop", "drop"]
        assert set(at_r.reason) == {"collision"}
        assert np.allclose(sorted(at_r.time), [1.0, 1.0 + t_b])
    else:
        assert list(at_r.event) == ["rx", "rx"]
        assert np.allclose(sorted(at_r.time), [1.0, 1.25])
    assert len(_at(p, 0, "rx")) == 0 and len(_at(p, 2, "rx")) == 0  # out of each other's range


def _spherical(ray: Eigenray, cfg: ChannelConfig):
    """Test loss model: SNR = 100 dB - 20 log10(path length / 1 m)."""
    return 100.0 - 20.0 * np.log10(ray.length)


@pytest.mark.parametrize("threshold, b_survives", [(6.0, True), (6.1, False)])
def test_capture_timeline(threshold, b_survives):
    # R at 0; A 1500 m away (T = 1 s, SNR 100 - 20 log10 1500), B 750 m away (T = 0.5 s,
    # SNR 100 - 20 log10 750): B is 20 log10 2 = 6.0206 dB stronger. A at R: [1.0, 1.2],
    # B sent at 0.55: [1.05, 1.25]. A never survives; B survives iff threshold <= 6.0206 dB.
    B_NEAR = [750.0, 0.0, 10.0]
    kw = dict(max_range_m=2000.0, snr_threshold_db=-1e9, collision="capture", capture_threshold_db=threshold)
    sim = Simulation(5, ssp=C, channel=ChannelConfig(**kw), loss_model=_spherical)
    sim.add_group(planned({0: [(0.0, None, 200)], 2: [(0.55, None, 200)]}), 3, positions=[A, R, B_NEAR])
    sim.run(10.0)
    at_r = _at(_packets(sim), 1).set_index("src")
    assert at_r.loc[0, "event"] == "drop" and at_r.loc[0, "reason"] == "collision"
    assert at_r.loc[2, "event"] == ("rx" if b_survives else "drop")
    assert math.isclose(at_r.loc[2, "snr_db"] - at_r.loc[0, "snr_db"], 20 * math.log10(2), abs_tol=1e-9)
    assert math.isclose(at_r.loc[0, "time"], 1.0) and math.isclose(at_r.loc[2, "time"], 1.05)


@pytest.mark.parametrize("t_r, lost", [(1.1, True), (0.9, True), (0.7, False), (1.25, False)])
def test_half_duplex_timeline(t_r, lost):
    # A -> R occupies [1.0, 1.2] at R; R transmits 200 bits over [t_r, t_r + 0.2].
    _sim, p = _run_three({0: [(0.0, None, 200)], 1: [(t_r, None, 200)]}, [A, R], collision="none")
    rec = _at(p, 1).query("src == 0").iloc[0]
    if lost:
        assert rec.event == "drop" and rec.reason == "half_duplex"
    else:
        assert rec.event == "rx"
    # R's own packet reaches A at t_r + 1 while A is silent
    back = _at(p, 0, "rx").iloc[0]
    assert math.isclose(back.time, t_r + 1.0)


def test_modem_queues_back_to_back_packets():
    class Burst(Node):
        name = "burst"

        def run(self):
            if self.id == 0:
                e1 = self.broadcast("a", None, 200)
                e2 = self.broadcast("b", None, 300)
                yield e1 & e2
                self.log("stamps", s1=e1.value, s2=e2.value)

    sim = Simulation(6, ssp=C, channel=ChannelConfig(collision="none"))
    sim.add_group(Burst, 2, positions=[A, R])
    sim.run(5.0)
    p = _packets(sim)
    tx = p[p.event == "tx"]
    assert np.allclose(tx.time, [0.0, 0.2])  # the second waits for the first to leave
    assert np.allclose(_at(p, 1, "rx").time, [1.0, 1.2])
    st = sim.trace.frames()["stamps"].iloc[0]
    assert st.s1 == 0.0 and math.isclose(st.s2, 0.2)


def test_unicast_range_and_overhearing():
    # 0 sends to 1 (in range) and to 2 (2500 m away: out of range -> "range" drop). Node 3
    # overhears the unicast to 1 but must not deliver it.
    pos = [[0.0, 0.0, 10.0], [1000.0, 0.0, 10.0], [2500.0, 0.0, 10.0], [0.0, 1000.0, 10.0]]

    class Uni(Node):
        name = "uni"

        def run(self):
            if self.id == 0:
                yield self.send(1, "x", None, 100)
                yield self.send(2, "x", None, 100)
            else:
                while True:
                    rec = yield self.recv()
                    self.log("got", uid=rec.packet.uid)

    sim = Simulation(7, ssp=C, channel=ChannelConfig(max_range_m=2000.0, collision="none"))
    sim.add_group(Uni, 4, positions=pos)
    sim.run(5.0)
    p = _packets(sim)
    assert list(_at(p, 1, "rx").uid) == [0]
    drop = _at(p, 2, "drop")
    assert list(drop.reason) == ["range"] and list(drop.uid) == [1]
    assert len(_at(p, 3)) == 0
    assert list(sim.trace.frames()["got"].node) == [1]


def test_unicast_overheard_signal_still_collides():
    # 0 -> 1 unicast arrives at node 2 too (same distance): it destroys a broadcast from 3 at 2.
    pos = [[0.0, 0.0, 10.0], [0.0, 1500.0, 10.0], [1500.0, 0.0, 10.0], [3000.0, 0.0, 10.0]]
    _sim, p = _run_three({0: [(0.0, 1, 200)], 3: [(0.1, None, 200)]}, pos, collision="destructive")
    at2 = _at(p, 2)
    assert list(at2.event) == ["drop"] and list(at2.reason) == ["collision"] and list(at2.src) == [3]


def test_snr_and_no_path_drops(monkeypatch):
    weak = lambda ray, cfg: np.full(np.shape(ray.time), 3.0)  # noqa: E731
    sim = Simulation(8, ssp=C, channel=ChannelConfig(snr_threshold_db=5.0), loss_model=weak)
    sim.add_group(planned({0: [(0.0, None, 100)]}), 2, positions=[A, R])
    sim.run(3.0)
    d = _at(_packets(sim), 1, "drop").iloc[0]
    assert d.reason == "snr" and d.snr_db == 3.0 and math.isclose(d.time, 1.0)

    real = links.eigenray

    def shadow(ssp, s, d, reflections="fallback"):
        r = real(ssp, s, d, reflections=reflections)
        nan = np.full(np.shape(r.time), np.nan)
        return Eigenray(nan, nan, nan, nan, nan, np.full(np.shape(r.time), PathKind.NONE, dtype=np.int8))

    monkeypatch.setattr(links, "eigenray", shadow)
    sim = Simulation(8, ssp=C)
    sim.add_group(planned({0: [(0.0, None, 100)]}), 2, positions=[A, R])
    sim.run(3.0)
    d = _at(_packets(sim), 1, "drop").iloc[0]
    assert d.reason == "no_path" and d.path == "none"


def test_mac_jitter_statistics():
    """Jitter: rx stamp - true local stamp ~ N(0, sigma) (sample std within 10 % for 400 draws)."""
    sigma = 1e-4

    class Beacon(Node):
        name = "beacon"

        def run(self):
            if self.id == 0:
                while True:
                    yield self.broadcast("b", None, 50)
                    yield self.sleep(0.95)

    sim = Simulation(9, ssp=C, channel=ChannelConfig(jitter_std_s=sigma, collision="none"))
    sim.add_group(Beacon, 2, positions=[A, R])
    sim.run(400.0)
    p = _packets(sim)
    rx = p[p.event == "rx"]
    err = rx.local_time.to_numpy() - rx.time.to_numpy()  # perfect clocks: local = true + jitter
    assert len(err) > 350
    assert abs(err.mean()) < 4 * sigma / math.sqrt(len(err))
    assert 0.9 * sigma < err.std() < 1.1 * sigma


def test_real_shadow_zone_and_reflected_path():
    """c(z) = 1500 - 0.05 z: arcs between shallow nodes 6 km apart would leave the water. With
    reflections="none" the packet is lost ("no_path"); with "fallback" it arrives by the
    bottom-reflected path, with that path's travel time."""
    ssp = Isogradient(1500.0, -0.05, bottom=1000.0)
    src, dst = [0.0, 0.0, 2.0], [6000.0, 0.0, 2.0]
    assert np.isnan(travel_time(ssp, src, dst, reflections="none"))
    for refl in ("none", "fallback"):
        sim = Simulation(10, ssp=ssp, channel=ChannelConfig(max_range_m=7000.0, reflections=refl))
        sim.add_group(planned({0: [(0.0, None, 100)]}), 2, positions=[src, dst])
        sim.run(10.0)
        r = _at(_packets(sim), 1).iloc[0]
        if refl == "none":
            assert (r.event, r.reason, r.path) == ("drop", "no_path", "none")
        else:
            assert (r.event, r.path) == ("rx", "bottom")
            assert abs(r.tof - float(travel_time(ssp, src, dst, reflections="fallback"))) < 1e-9


def test_default_loss_model_wires_the_config():
    """The default SNR follows the sonar equation's dependencies: +10 dB of source level gives
    +10 dB; 10x the bandwidth gives -10 dB (flat noise PSD); 4x the range with spreading k = 2
    costs 20 log10 4 dB plus the absorption over the extra path; and a threshold above the
    SNR drops the packet."""

    def snr(**cfg):
        sim = Simulation(12, ssp=C, channel=ChannelConfig(collision="none", snr_threshold_db=-1e9, **cfg))
        sim.add_group(planned({0: [(0.0, None, 64)]}), 3, positions=[R, [500.0, 0.0, 10.0], [0.0, 2000.0, 10.0]])
        sim.run(5.0)
        p = _packets(sim)
        return p[p.event == "rx"].set_index("node")["snr_db"]

    base = snr(spreading=2.0)
    assert np.isfinite(base).all()
    assert math.isclose(snr(spreading=2.0, source_level_db=180.0)[1] - base[1], 10.0, abs_tol=1e-9)
    assert math.isclose(snr(spreading=2.0, bandwidth_khz=50.0)[1] - base[1], -10.0, abs_tol=1e-9)
    from aquasim_py.channel.loss import thorp_absorption_db_per_km

    expected = 20 * math.log10(4.0) + 1.5 * float(thorp_absorption_db_per_km(10.0))  # 1.5 km more
    assert math.isclose(base[1] - base[2], expected, abs_tol=1e-9)
    sim = Simulation(12, ssp=C, channel=ChannelConfig(snr_threshold_db=float(base[2]) + 0.5, spreading=2.0))
    sim.add_group(planned({0: [(0.0, None, 64)]}), 3, positions=[R, [500.0, 0.0, 10.0], [0.0, 2000.0, 10.0]])
    sim.run(5.0)
    p = _packets(sim)
    assert list(p[p.node == 1].event) == ["rx"] and list(p[p.node == 2].reason) == ["snr"]


def test_signal_logs_stay_short_at_overhearing_nodes():
    """A node that only overhears unicasts keeps no unbounded record of past signals."""
    pos = [[0.0, 0.0, 10.0], [300.0, 0.0, 10.0], [0.0, 300.0, 10.0]]

    class Chat(Node):
        name = "chat"

        def run(self):
            if self.id == 0:
                while True:
                    yield self.send(1, "u", None, 50)
                    yield self.sleep(0.3)

    sim = Simulation(13, ssp=C)
    sim.add_group(Chat, 3, positions=pos)
    sim.run(300.0)
    p = _packets(sim)
    assert (p.event == "tx").sum() > 800 and (p.event == "rx").sum() >= (p.event == "tx").sum() - 1
    assert sim.channel.signals_at(2) <= 3 and sim.channel.signals_at(1) <= 3


def test_turning_receiver_delay_at_arrival_position():
    """A receiver on a tight circle (3 m/s, 0.2 rad/s): the straight-line start is not exact,
    yet the delay still matches an independent root on the closed-form circle to 1e-9 s."""
    from aquasim_py.mobility import CoordinatedTurn

    speed, w, h0 = 3.0, 0.2, 0.4
    p_r0 = np.array([900.0, -300.0, 140.0])
    src = [0.0, 0.0, 60.0]

    def circle(t):  # written here from the geometry, not taken from the mobility module
        return p_r0 + (speed / w) * np.array([np.sin(h0 + w * t) - np.sin(h0), np.cos(h0) - np.cos(h0 + w * t), 0.0])

    sim = Simulation(14, ssp=PROFILE, volume=BOX, channel=ChannelConfig(collision="none"))
    sim.add_group(planned({0: [(3.0, None, 64), (17.5, None, 64)]}), 1, positions=[src])
    sim.add_group(Listener, 1, mobility=CoordinatedTurn([p_r0], BOX, speed=speed, turn_rate=w, heading=h0))
    sim.run(30.0)
    p = _packets(sim)
    for t0, r_time, tof in zip(p[p.event == "tx"].time, p[p.event == "rx"].time, p[p.event == "rx"].tof):
        f = lambda ta: ta - t0 - float(travel_time(PROFILE, src, circle(ta)))  # noqa: E731
        t_arr = brentq(f, t0, t0 + 10.0, xtol=1e-13, rtol=1e-15)
        assert abs(r_time - t_arr) < 1e-9 and abs(tof - (t_arr - t0)) < 1e-9


# -- straight-line start of the moving-receiver fixed point (performance path) ------------------------


def _brentq_linear(T, p0, v):
    """Independent root of t = T(p0 + v t) for one receiver (scipy bracketing, not the channel)."""
    t_s = T(p0)
    return brentq(lambda t: t - T(p0 + v * t), 0.5 * t_s, 2.0 * t_s, xtol=1e-14, rtol=1e-15)


def test_constant_moving_root_matches_brentq():
    """Closed-form root of |d + v t| = c t against a bracketing root of the distance equation,
    for receivers approaching (d.v < 0), receding and crossing, at speeds up to 20 m/s."""
    rng = np.random.default_rng(5)
    c = 1500.0
    d = rng.uniform(-3000.0, 3000.0, (40, 3))
    v = rng.normal(0.0, 8.0, (40, 3))
    t = fixed_point.constant_moving_root(c, d, v)
    dv = np.einsum("ij,ij->i", d, v)
    assert (dv < 0).any() and (dv > 0).any()
    for i in range(len(d)):
        ref = brentq(lambda s: np.linalg.norm(d[i] + v[i] * s) - c * s, 0.0, 10.0, xtol=1e-15, rtol=1e-15)
        assert abs(t[i] - ref) <= 4e-15 * ref
    # a receiver as fast as sound has no root: NaN, so the caller falls back to iteration
    assert np.isnan(fixed_point.constant_moving_root(c, d[:1], np.array([[c, 0.0, 0.0]])))[0]


@pytest.mark.parametrize("reflections", ["fallback", "all"])
def test_linear_fixed_point_isogradient_matches_brentq(reflections):
    """Secant start on the isogradient closed form (and on the full eigenray with
    reflections="all") against brentq on t - T(p0 + v t), to 1e-12 s, in few evaluations."""
    ssp = Isogradient(1480.0, 0.1, bottom=400.0)
    rng = np.random.default_rng(9)
    src = np.array([0.0, 0.0, 80.0])
    p0 = np.column_stack([rng.uniform(-2500, 2500, 12), rng.uniform(-2500, 2500, 12), rng.uniform(20, 300, 12)])
    v = rng.normal(0.0, 3.0, (12, 3))
    ray = eigenray(ssp, src, p0, reflections=reflections)
    assert np.isfinite(ray.time).all()
    calls = []
    fn = fixed_point.travel_time_fn(ssp, reflections, src, ray.path)

    def counted(dst):
        calls.append(len(dst))
        return fn(dst)

    slope = fixed_point.slope_along(ssp, src, p0, v, ray.arrival_angle)
    t = fixed_point.secant_fixed_point(counted, p0, v, ray.time, slope)
    T = lambda q: float(travel_time(ssp, src, q, reflections=reflections))  # noqa: E731
    for i in range(len(p0)):
        assert abs(t[i] - _brentq_linear(T, p0[i], v[i])) < 1e-12
    # plain iteration needs ~4 evaluations at these speeds; the seeded secant at most 3
    assert len(calls) <= 3
    # the seed slope is the exact derivative d/dt T(p0 + v t) at t = 0 (central difference)
    h = 1e-3
    fd = [(T(p0[i] + v[i] * h) - T(p0[i] - v[i] * h)) / (2 * h) for i in range(len(p0))]
    assert np.allclose(slope, fd, rtol=1e-6, atol=1e-12)


def test_moving_receiver_delay_constant_profile():
    """The closed-form straight-line start (Constant profile) through the kernel: delay of a
    receiver at 4 m/s against brentq on the distance equation, to 1e-9 s."""
    c = 1500.0
    p_s, p_r0, v_r = np.array([0.0, 0.0, 100.0]), np.array([-900.0, 1300.0, 60.0]), np.array([3.2, -2.4, 0.0])
    sim = Simulation(4, ssp=Constant(c), volume=BOX, channel=ChannelConfig(collision="none"))
    sim.add_group(planned({0: [(2.0, None, 64), (31.0, None, 64)]}), 1, positions=[p_s])
    sim.add_group(Listener, 1, mobility=ConstantVelocity([p_r0], BOX, velocity=v_r))
    sim.run(40.0)
    p = _packets(sim)
    tx, rx = p[p.event == "tx"].sort_values("uid"), p[p.event == "rx"].sort_values("uid")
    assert len(tx) == 2 and len(rx) == 2
    for t0, r_time, tof in zip(tx.time, rx.time, rx.tof):
        t_arr = brentq(
            lambda ta: (ta - t0) * c - np.linalg.norm(p_r0 + v_r * ta - p_s), t0, t0 + 10.0, xtol=1e-13, rtol=1e-15
        )
        assert abs(r_time - t_arr) < 1e-9 and abs(tof - (t_arr - t0)) < 1e-9


def test_physical_snr_is_loss_snr_db_bit_for_bit():
    """The per-config cached noise and band terms change nothing: identical to loss.snr_db."""
    from aquasim_py.channel import loss

    lengths = np.array([1.0, 2.5, 80.0, 1234.5, 4999.0, np.nan])
    ray = Eigenray(
        time=lengths / 1500.0,
        length=lengths,
        launch_angle=np.zeros(6),
        arrival_angle=np.zeros(6),
        turning_depth=np.full(6, np.nan),
        path=np.zeros(6, np.int8),
    )
    for cfg in (
        ChannelConfig(),
        ChannelConfig(
            frequency_khz=25.0, bandwidth_khz=8.0, spreading=2.0, shipping=0.9, wind_mps=7.0, source_level_db=180.0
        ),
    ):
        got = config.physical_snr(ray, cfg)
        ref = loss.snr_db(
            cfg.source_level_db,
            lengths,
            cfg.frequency_khz,
            cfg.bandwidth_khz * 1e3,
            k=cfg.spreading,
            shipping=cfg.shipping,
            wind_mps=cfg.wind_mps,
        )
        assert np.array_equal(got, ref, equal_nan=True)
        assert np.isfinite(got[:5]).all() and np.all(np.diff(got[:5]) < 0)


def test_accelerated_root_matches_brentq():
    """One Newton step from the straight-line root: the root of |d + v t + a t^2 / 2| = c t to
    well under the fixed point's tolerance, for current-like accelerations."""
    rng = np.random.default_rng(5)
    c = 1500.0
    d = rng.normal(0.0, 60.0, (200, 3))
    v = rng.normal(0.0, 1.0, (200, 3))
    a = rng.normal(0.0, 1e-3, (200, 3))
    a[:20] = 0.0  # rows without an acceleration keep the straight-line root, bit for bit
    t_lin = fixed_point.constant_moving_root(c, d, v)
    t = fixed_point.accelerated_root(c, d, v, a, t_lin)
    assert np.array_equal(t[:20], t_lin[:20])
    for i in range(20, 200):
        ref = brentq(
            lambda s, i=i: np.linalg.norm(d[i] + v[i] * s + 0.5 * a[i] * s * s) - c * s,
            0.0,
            1.0,
            xtol=1e-16,
            rtol=1e-15,
        )
        assert abs(t[i] - ref) < 1e-13
        assert abs(t_lin[i] - ref) > abs(t[i] - ref)  # the straight line misses by |a| t^2 / 2c


def test_current_driven_receivers_one_exact_step_and_exact():
    """Receivers on the kinematic current (no speed bound, so the channel tests every node):
    after the first transmissions the start uses each receiver's estimated acceleration and the
    exact fixed point needs one trajectory evaluation per transmission (two from the
    straight-line start), and every delay still matches brentq on the true trajectory."""
    from aquasim_py.mobility import Kinematic

    box = Box([0.0, 0.0, 0.0], [20_000.0, 20_000.0, 200.0])
    rng = np.random.default_rng(3)
    p0 = np.column_stack([rng.uniform(5000, 5400, 30), rng.uniform(5000, 5400, 30), rng.uniform(20, 180, 30)])
    sim = Simulation(3, ssp=Constant(1500.0), volume=box, channel=ChannelConfig(max_range_m=300.0))
    sim.add_group(Listener, 30, mobility=lambda r: Kinematic(p0, box, r))
    ch = sim.channel
    evaluations = []
    positions_at = sim.positions_at

    def counted(idx, times):
        evaluations[-1] += 1
        return positions_at(idx, times)

    sim.positions_at = counted  # type: ignore[method-assign]
    for k, t0 in enumerate(np.arange(0.0, 20.0, 0.37)):
        src = k % 30
        evaluations.append(0)
        _, heard, lost = ch.links.links(src, float(t0), 30)
        assert heard and not lost
        if k % 9 == 0:
            p_src = positions_at(np.array([src]), np.array([t0]))[0]
            for rid, tof, _, _ in heard:
                j = np.array([rid])
                ref = brentq(
                    lambda s, j=j: 1500.0 * s - np.linalg.norm(positions_at(j, np.array([t0 + s]))[0] - p_src),
                    0.0,
                    1.0,
                    xtol=1e-15,
                    rtol=1e-15,
                )
                assert abs(tof - ref) <= fixed_point.FIXED_POINT_TOL_S
    assert ch.links._index is None  # the path under test: no speed bound
    assert evaluations[0] == 2 and np.mean(evaluations[10:]) <= 1.1, evaluations


@given(
    now=st.floats(0.0, 1e7, allow_subnormal=False),
    at=st.floats(0.0, 1e7, allow_subnormal=False),
)
def test_a_timeout_of_the_difference_fires_at_the_instant_whenever_any_can(now: float, at: float) -> None:
    """The channel schedules a delivery at true time ``at`` as a Timeout of ``at - now``, which
    SimPy fires at ``now + (at - now)``: that is ``at`` bit for bit unless no delay gives it
    (brute force over the delays around ``at - now``), and then an ulp from it."""
    now, at = min(now, at), max(now, at)
    if now + (at - now) != at:
        around = []
        for step in (math.inf, -math.inf):
            x = at - now
            for _ in range(16):
                x = math.nextafter(x, step)
                around.append(x)
        assert all(now + x != at for x in around)
        assert abs(now + (at - now) - at) <= math.ulp(at)
