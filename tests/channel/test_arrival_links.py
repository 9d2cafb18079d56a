"""The channel in a range-dependent environment (aquasim_py.channel.arrival_links): the modem's
stamp at the first detectable arrival, against independent calculations."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq
from scripted import planned
from test_acoustic import Listener

from aquasim_py.channel import ssp
from aquasim_py.channel.arrival_cache import ArrivalCache
from aquasim_py.channel.arrival_links import ARRIVAL_FIELDS
from aquasim_py.channel.arrivals import arrivals
from aquasim_py.channel.bathymetry import FluidBottom, GriddedBathymetry, Seamount
from aquasim_py.channel.config import ChannelConfig, _snr_constants
from aquasim_py.channel.environment import Environment
from aquasim_py.channel.fields import DepthProfile
from aquasim_py.channel.raytrace import eigenray, reflected_eigenray
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import Box, ConstantVelocity
from aquasim_py.radio import PACKET_FIELDS

C = 1500.0
_POST_INIT = ArrivalCache.__post_init__
#: a constant speed over a flat 1000 m floor with a seamount whose crest (100 m) stands between
#: two nodes at 500 m, 6 km apart: no direct path, the surface reflection passes over the crest
SEAMOUNT = Environment(DepthProfile(ssp.Constant(C)), Seamount(1000.0, 900.0, 800.0, x0=3000.0), FluidBottom())
SRC, DST = np.array([0.0, 0.0, 500.0]), np.array([6000.0, 0.0, 500.0])
BOX = Box([-10_000.0, -10_000.0, 0.0], [10_000.0, 10_000.0, 1000.0])


def _surface_image_time(src: np.ndarray, dst: np.ndarray) -> float:
    """Constant speed: the surface-reflected path is the straight line to the receiver's image
    above the surface (closed form, no ray tracer)."""
    return float(np.linalg.norm(np.array([dst[0], dst[1], -dst[2]]) - src)) / C


def _run(env: Environment, cfg: ChannelConfig, src, dst_group: dict, until: float, seed: int = 1):
    sim = Simulation(seed, ssp=ssp.Constant(C), volume=BOX, channel=cfg, environment=env)
    sim.add_group(planned({0: [(1.0, None, 64), (20.0, None, 64)]}), 1, positions=[src])
    sim.add_group(Listener, 1, **dst_group)
    sim.run(until)
    return sim.trace.frames()["packets"]


def test_blocked_direct_path_stamps_the_surface_reflection() -> None:
    """Behind the seamount the stamp is the surface-reflected arrival: its delay equals the
    image-source closed form to 1e-9 s, later than the straight line by the range bias of a
    blocked path; the extra columns say why (no direct arrival)."""
    p = _run(SEAMOUNT, ChannelConfig(collision="none", max_range_m=8000.0), SRC, {"positions": [DST]}, 30.0)
    rx = p[p.event == "rx"]
    assert len(rx) == 2
    expected = _surface_image_time(SRC, DST)
    np.testing.assert_allclose(rx.tof, expected, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rx.time - p[p.event == "tx"].time.to_numpy(), expected, rtol=0, atol=1e-9)
    assert (rx.path == "surface").all()
    assert rx.direct_tof.isna().all()  # blocked
    np.testing.assert_allclose(rx.first_tof, expected, rtol=0, atol=1e-9)
    straight = float(np.linalg.norm(DST - SRC)) / C
    assert (rx.tof - straight > 0.05).all()  # 82 m of range bias
    assert list(p.columns) == [*PACKET_FIELDS, *ARRIVAL_FIELDS]
    assert p[p.event == "tx"][list(ARRIVAL_FIELDS)].isna().all().all()


# a warm surface layer over a sharp thermocline (a summer profile, downward refracting) over a
# floor that is flat at 100 m where the link lies and deepens beyond 1 km (range-dependent)
SUMMER = ssp.Layered([0, 20, 40, 100], [1525, 1520, 1486, 1490], bottom=100.0)
SHELF = Environment(
    DepthProfile(ssp.Layered(SUMMER.depths, SUMMER.speeds)),
    GriddedBathymetry([-5000.0, 1000.0, 5000.0], [-5000.0, 5000.0], [[100.0, 100.0], [100.0, 100.0], [200.0, 200.0]]),
    FluidBottom(1650.0, 1.9, 0.8),
)
WEAK_SRC, WEAK_DST = np.array([0.0, 0.0, 21.19517557]), np.array([541.62134934, 0.0, 54.72617385])


def test_weak_direct_path_stamps_a_later_arrival() -> None:
    """The refracted direct ray spreads so much below the thermocline that it arrives 6.7 dB
    weaker than the surface reflection: with the detection threshold between the two the stamp
    is the surface-reflected arrival, whose delay equals the exact layered solver's (an
    independent solver: the mirrored profile) to 1e-9 s; with a threshold below both it is the
    direct one. The SNR is the stamped arrival's."""
    a = arrivals(SHELF, WEAK_SRC, WEAK_DST, max_bounces=2)
    assert list(a.path_class[:2]) == [1, 2] and a.level_db[1] - a.level_db[0] > 6.0
    noise, band, _, _ = _snr_constants(ChannelConfig())
    snr = 170.0 + a.level_db - float(noise + band)
    threshold = 0.5 * (snr[0] + snr[1])
    cfg = ChannelConfig(collision="none", detection_threshold_db=threshold, snr_threshold_db=threshold - 20.0)
    p = _run(SHELF, cfg, WEAK_SRC, {"positions": [WEAK_DST]}, 30.0)
    rx = p[p.event == "rx"]
    surface = float(reflected_eigenray(SUMMER, WEAK_SRC, WEAK_DST, "surface").time)
    np.testing.assert_allclose(rx.tof, surface, rtol=0, atol=1e-9)
    assert (rx.path == "surface").all()
    np.testing.assert_allclose(rx.snr_db, snr[1], rtol=0, atol=1e-9)
    direct = float(eigenray(SUMMER, WEAK_SRC, WEAK_DST).time)
    np.testing.assert_allclose(rx.first_tof, direct, rtol=0, atol=1e-9)
    np.testing.assert_allclose(rx.direct_tof, direct, rtol=0, atol=1e-9)
    # below both: the direct (refracted) arrival
    low = ChannelConfig(collision="none", detection_threshold_db=snr[0] - 1.0, snr_threshold_db=snr[0] - 1.0)
    p_low = _run(SHELF, low, WEAK_SRC, {"positions": [WEAK_DST]}, 30.0)
    rx = p_low[p_low.event == "rx"]
    np.testing.assert_allclose(rx.tof, direct, rtol=0, atol=1e-9)
    assert (rx.path == "refracted").all()
    # above every arrival: lost, "undetected"
    high = ChannelConfig(collision="none", detection_threshold_db=float(snr.max()) + 1.0)
    p_high = _run(SHELF, high, WEAK_SRC, {"positions": [WEAK_DST]}, 30.0)
    assert not (p_high.event == "rx").any()
    assert (p_high[p_high.event == "drop"].reason == "undetected").all()


def test_moving_receiver_against_brentq() -> None:
    """A receiver drifting at 2 m/s behind the seamount: the stamp solves t_a = t0 +
    T_surface(p_src, p_rx(t_a)) on its true trajectory; checked against brentq on the
    closed-form image time to 1e-9 s (the motion moves it by far more)."""
    v = np.array([1.2, -1.6, 0.0])
    p = _run(
        SEAMOUNT,
        ChannelConfig(collision="none", max_range_m=8000.0),
        SRC,
        {"mobility": ConstantVelocity([DST], BOX, velocity=v)},
        30.0,
    )
    tx = p[p.event == "tx"].sort_values("uid")
    rx = p[p.event == "rx"].sort_values("uid")
    assert len(rx) == 2
    for t0, (_, r) in zip(tx.time, rx.iterrows()):
        t_arr = brentq(
            lambda ta: ta - t0 - _surface_image_time(SRC, DST + v * ta), t0, t0 + 10.0, xtol=1e-13, rtol=1e-15
        )
        assert abs(r.time - t_arr) < 1e-9
        assert abs(r.tof - (t_arr - t0)) < 1e-9
        assert r.path == "surface"
        # the delay to the receiver's send-time position is off by far more
        assert abs(r.tof - _surface_image_time(SRC, DST + v * t0)) > 1e-4


def test_turning_receiver_converges_after_the_newton_step(monkeypatch: pytest.MonkeyPatch) -> None:
    """A receiver 2 km from the source, clear of the seamount, turning on a circle (2 m/s, 0.02
    rad/s: 0.04 m/s^2): the stamp equals brentq's on the direct path's closed-form time to
    1e-9 s, and the Newton step from the first iterate (~2e-3 s off) lands within the fixed
    point's 1e-10 s: two requests of the link per transmission. Its slope takes the velocity at
    the first iterate's instant; the velocity at t0 would leave the step off by about |a| T / c
    times the first iterate's error, 6e-8 s here (a third request)."""
    from aquasim_py.channel import arrival_cache
    from aquasim_py.mobility import CoordinatedTurn

    requests: list[int] = []
    get = arrival_cache.ArrivalCache.get

    def counted(self: arrival_cache.ArrivalCache, links, src, dst):  # type: ignore[no-untyped-def]
        requests.append(int(np.size(links)))
        return get(self, links, src, dst)

    monkeypatch.setattr(arrival_cache.ArrivalCache, "get", counted)
    mob = CoordinatedTurn([[2000.0, 0.0, 500.0]], BOX, speed=2.0, turn_rate=0.02, heading=0.3)
    p = _run(SEAMOUNT, ChannelConfig(collision="none", max_range_m=8000.0), SRC, {"mobility": mob}, 30.0)
    tx = p[p.event == "tx"].sort_values("uid")
    rx = p[p.event == "rx"].sort_values("uid")
    assert len(rx) == 2 and requests == [1, 1, 1, 1]  # two transmissions, two requests each
    for t0, (_, r) in zip(tx.time, rx.iterrows()):

        def fixed_point(ta: float) -> float:
            return ta - t0 - float(np.linalg.norm(mob.position_at([0], ta)[0] - SRC)) / C

        t_arr = brentq(fixed_point, t0, t0 + 10.0, xtol=1e-13, rtol=1e-15)
        assert abs(r.time - t_arr) < 1e-9 and r.path == "direct"


def _network(seed: int, **channel: float) -> Simulation:
    env = SHELF
    sim = Simulation(
        seed,
        ssp=ssp.Constant(C),
        volume=BOX,
        channel=ChannelConfig(collision="destructive", **channel),
        environment=env,
    )
    rng = np.random.default_rng(seed)
    pos = np.c_[rng.uniform(-800, 800, 5), rng.uniform(-800, 800, 5), rng.uniform(5, 90, 5)]
    vel = rng.normal(size=(5, 3)) * np.array([0.5, 0.5, 0.0])
    plan = {i: [(1.0 + 3.0 * k + 0.4 * i, None, 64) for k in range(4)] for i in range(5)}
    sim.add_group(planned(plan), 5, mobility=ConstantVelocity(pos, BOX, velocity=vel))
    sim.run(20.0)
    return sim


def test_deterministic() -> None:
    """Same network and seed: identical packets (every column, every arrival number)."""
    sim = _network(3)
    a = sim.trace.frames()["packets"]
    b = _network(3).trace.frames()["packets"]
    assert len(a) > 40 and (a.event == "rx").any()
    assert a.equals(b)
    # every row names the same columns, so the table keeps its one-list-append path
    assert sim.trace.table("packets")._fast_keys == (*PACKET_FIELDS, *ARRIVAL_FIELDS)


def test_range_independent_environment_takes_the_profile_path() -> None:
    """An Environment without range dependence is its profile: the same packets table as with the
    profile itself (schema columns only)."""
    flat = Environment.from_profile(SUMMER)
    cfg = ChannelConfig(collision="none")
    p_env = _run(flat, cfg, WEAK_SRC, {"positions": [WEAK_DST]}, 30.0)
    sim = Simulation(1, ssp=SUMMER, volume=BOX, channel=cfg)
    sim.add_group(planned({0: [(1.0, None, 64), (20.0, None, 64)]}), 1, positions=[WEAK_SRC])
    sim.add_group(Listener, 1, positions=[WEAK_DST])
    sim.run(30.0)
    p_ssp = sim.trace.frames()["packets"]
    assert list(p_env.columns) == list(PACKET_FIELDS)
    assert p_env.equals(p_ssp)


def test_custom_loss_model_refused() -> None:
    with pytest.raises(ValueError, match="loss_model must be"):
        Simulation(1, channel=ChannelConfig(), environment=SEAMOUNT, loss_model=lambda ray, cfg: ray.time * 0.0)


def test_no_snr_stamps_the_first_arrival() -> None:
    """loss_model none: no SNR, every arrival detectable, the stamp is the first one."""
    from aquasim_py.channel.config import no_snr

    sim = Simulation(1, ssp=ssp.Constant(C), volume=BOX, channel=ChannelConfig(), environment=SHELF, loss_model=no_snr)
    sim.add_group(planned({0: [(1.0, None, 64)]}), 1, positions=[WEAK_SRC])
    sim.add_group(Listener, 1, positions=[WEAK_DST])
    sim.run(10.0)
    rx = sim.trace.frames()["packets"].query("event == 'rx'")
    assert len(rx) == 1 and math.isnan(rx.snr_db.iloc[0])
    np.testing.assert_allclose(rx.tof, float(eigenray(SUMMER, WEAK_SRC, WEAK_DST).time), rtol=0, atol=1e-9)


def test_direct_only_loses_reflected_stamps() -> None:
    """The analysis switch: behind the seamount every reception is stamped on the surface
    reflection, so with direct_only every one is lost, "indirect"; a link with a direct path
    is not touched."""
    cfg = ChannelConfig(collision="none", max_range_m=8000.0, direct_only=True)
    p = _run(SEAMOUNT, cfg, SRC, {"positions": [DST]}, 30.0)
    drops = p[p.event == "drop"]
    assert not (p.event == "rx").any() and len(drops) == 2 and (drops.reason == "indirect").all()
    assert (drops.path == "surface").all()
    low = ChannelConfig(collision="none", direct_only=True, snr_threshold_db=-50.0, detection_threshold_db=-50.0)
    p = _run(SHELF, low, WEAK_SRC, {"positions": [WEAK_DST]}, 30.0)
    assert (p[p.event == "rx"].path == "refracted").sum() == 2


def test_reception_carries_the_stamp_only() -> None:
    """A protocol's Reception behind the seamount holds the packet, the MAC stamp (the late
    surface-reflected arrival, as the receiver's clock reads it), the SNR and the hydrophone
    pressure, and nothing of the arrival structure: no delay, class, count or spread, neither
    on the Reception nor on the Packet."""
    from dataclasses import fields

    from aquasim_py.node import Node
    from aquasim_py.packet import Packet, Reception

    got: list[Reception] = []

    class Keeper(Node):
        name = "keeper"

        def run(self):
            while True:
                got.append((yield self.recv()))

    sim = Simulation(
        1,
        ssp=ssp.Constant(C),
        volume=BOX,
        channel=ChannelConfig(collision="none", max_range_m=8000.0),
        environment=SEAMOUNT,
    )
    sim.add_group(planned({0: [(1.0, None, 64)]}), 1, positions=[SRC])
    sim.add_group(Keeper, 1, positions=[DST])
    sim.run(10.0)
    assert len(got) == 1
    rec = got[0]
    assert type(rec) is Reception and type(rec.packet) is Packet
    assert [f.name for f in fields(Reception)] == ["packet", "rx_local", "snr_db", "pressure"]
    assert [f.name for f in fields(Packet)] == ["uid", "src", "dst", "kind", "payload", "bits", "tx_local"]
    assert not hasattr(rec, "__dict__") and not hasattr(rec.packet, "__dict__")  # slots: nothing added later
    assert rec.packet.payload == {"from": 0}  # what the sender put in, nothing more
    # the stamp is the surface reflection's (the clocks are ideal by default)
    np.testing.assert_allclose(rec.rx_local - rec.packet.tx_local, _surface_image_time(SRC, DST), rtol=0, atol=1e-9)


def _caches(monkeypatch: pytest.MonkeyPatch, **setting: int) -> list[ArrivalCache]:
    """The arrival caches the channel makes from now on, each with ``setting`` applied first."""
    made: list[ArrivalCache] = []

    def keep(self: ArrivalCache) -> None:
        for k, v in setting.items():
            setattr(self, k, v)
        _POST_INIT(self)
        made.append(self)

    monkeypatch.setattr(ArrivalCache, "__post_init__", keep)
    return made


def test_links_followed_from_their_reverse_keep_the_stamps(monkeypatch: pytest.MonkeyPatch) -> None:
    """The channel numbers its links so that the cache follows a link from its reverse's search
    (nodes transmitting 0.4 s apart, drifting 0.5 m/s): some links are served so, and the packets
    equal those of the cache without that tier (the same events; stamps to 1e-9 s, the search's
    own accuracy)."""
    caches = _caches(monkeypatch)
    a = _network(4).trace.frames()["packets"]
    assert sum(c.stats.reversed for c in caches) >= 5
    caches = _caches(monkeypatch, n_nodes=0)  # without the reverse tier
    b = _network(4).trace.frames()["packets"]
    assert sum(c.stats.reversed for c in caches) == 0
    assert (a.event == "rx").sum() > 20
    assert a[["event", "reason", "node", "src", "uid"]].equals(b[["event", "reason", "node", "src", "uid"]])
    for col in ("time", "tof"):
        np.testing.assert_allclose(a[col].to_numpy(float), b[col].to_numpy(float), rtol=0, atol=1e-9)


def test_follow_radius_sets_what_the_cache_follows(monkeypatch: pytest.MonkeyPatch) -> None:
    """``follow_radius_m`` is the cache's following radius: 0 searches every moved link, 3 m
    follows more of them than the default 1 m; the receptions are the same (nodes drifting 0.5 m/s,
    1.5 m between a link's requests: no path appears there), stamps to 1e-9 s."""
    runs, follows = {}, {}
    for radius in (0.0, 1.0, 3.0):
        caches = _caches(monkeypatch)
        runs[radius] = _network(4, follow_radius_m=radius).trace.frames()["packets"]
        assert {c.follow_m for c in caches} == {radius}
        follows[radius] = sum(c.stats.follows for c in caches)
    assert follows[0.0] == 0 < follows[1.0] < follows[3.0]
    a = runs[0.0]
    assert (a.event == "rx").sum() > 20
    for b in (runs[1.0], runs[3.0]):
        assert a[["event", "reason", "node", "src", "uid", "n_arrivals"]].equals(
            b[["event", "reason", "node", "src", "uid", "n_arrivals"]]
        )
        for col in ("time", "tof"):
            np.testing.assert_allclose(a[col].to_numpy(float), b[col].to_numpy(float), rtol=0, atol=1e-9)
