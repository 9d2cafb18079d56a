"""The kernel / channel seam (``aquasim_py.radio``): the channel driven by a stub network with no
kernel, against hand-computed timelines in a 1500 m/s medium (straight rays: delay = d / c)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
import simpy

from aquasim_py.channel import Constant
from aquasim_py.channel.acoustic import AcousticChannel
from aquasim_py.channel.config import ChannelConfig, no_snr
from aquasim_py.packet import Packet, Reception
from aquasim_py.radio import PACKET_FIELDS
from aquasim_py.trace import SCHEMAS

C = 1500.0


class StubNetwork:
    """Static nodes at fixed positions (a NetworkView without a kernel)."""

    def __init__(self, positions: list[list[float]]) -> None:
        self.p = np.asarray(positions, dtype=float)

    def positions(self, t: float) -> np.ndarray:
        return self.p

    def positions_at(self, idx: np.ndarray, times: np.ndarray) -> np.ndarray:
        return self.p[idx]

    def velocities(self, t: float) -> np.ndarray:
        return np.zeros_like(self.p)

    def is_moving(self) -> np.ndarray:
        return np.zeros(len(self.p), dtype=bool)


class StubPort:
    """A RadioPort with an affine clock local = (1 + skew) t + offset."""

    def __init__(self, index: int, skew: float = 0.0, offset: float = 0.0) -> None:
        self.index = index
        self.skew, self.offset = skew, offset
        self.got: list[Reception] = []
        self.jitter_asked = 0

    def clock_stamp(self, t: float) -> float:
        return (1.0 + self.skew) * t + self.offset

    def jitter_stream(self) -> np.random.Generator:
        self.jitter_asked += 1
        return np.random.default_rng(self.index)

    def deliver(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        self.got.append(Reception(packet, rx_local, snr_db, pressure))


class ListLog:
    def __init__(self) -> None:
        self.rows: list[tuple[Any, ...]] = []

    def append(self, values: tuple[Any, ...]) -> None:
        self.rows.append(values)

    def table(self) -> list[dict[str, Any]]:
        return [dict(zip(PACKET_FIELDS, r, strict=True)) for r in self.rows]


def _channel(
    positions: list[list[float]], ports: list[StubPort], **config: Any
) -> tuple[simpy.Environment, Any, ListLog]:
    env = simpy.Environment()
    log = ListLog()
    ch = AcousticChannel(env, StubNetwork(positions), log, Constant(C), ChannelConfig(**config), loss_model=no_snr)
    for p in ports:
        ch.attach(p)
    return env, ch, log


def test_packet_fields_are_the_trace_schema():
    assert tuple(name for name, _ in SCHEMAS["packets"]) == PACKET_FIELDS


def test_stub_network_broadcast_timeline():
    """0 broadcasts 100 bits (0.1 s at 1000 bps) at t = 0.5 to nodes 1500 m and 3000 m away."""
    ports = [StubPort(0, 1e-4, 2.0), StubPort(1, -2e-5, -1.0), StubPort(2, 3e-5, 0.5)]
    env, ch, log = _channel([[0, 0, 10], [1500, 0, 10], [0, 3000, 10]], ports)
    sent: list[tuple[float, Any]] = []

    def sender() -> Any:
        yield env.timeout(0.5)
        stamp = yield ch.transmit(0, None, "ping", {"n": 1}, 100)
        sent.append((env.now, stamp))

    env.process(sender())
    env.run(10.0)
    tx_local = (1 + 1e-4) * 0.5 + 2.0
    ((t_sent, stamp),) = sent
    assert t_sent == pytest.approx(0.6, abs=1e-12) and stamp == pytest.approx(tx_local, abs=1e-12)
    for port, delay in ((ports[1], 1.0), (ports[2], 2.0)):
        (rec,) = port.got
        assert rec.packet.src == 0 and rec.packet.kind == "ping" and rec.packet.payload == {"n": 1}
        assert rec.packet.tx_local == pytest.approx(tx_local, abs=1e-12)
        assert rec.rx_local == pytest.approx(port.clock_stamp(0.5 + delay), abs=1e-9)
    rows = log.table()
    assert [(r["event"], r["node"]) for r in rows] == [("tx", 0), ("rx", 1), ("rx", 2)]
    assert rows[2]["time"] == pytest.approx(2.5, abs=1e-9) and rows[2]["tof"] == pytest.approx(2.0, abs=1e-9)
    assert ports[0].got == [] and all(p.jitter_asked == 0 for p in ports)


class OtherPort(StubPort):
    """A port of another class: its deliver is another function."""

    def deliver(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        self.got.append(("other", packet.kind))


class PlainCallablePort(StubPort):
    """A port whose deliver is a plain callable attribute, not a method."""

    def __init__(self, index: int) -> None:
        super().__init__(index)
        self.deliver = lambda packet, rx_local, snr_db, pressure: self.got.append(("plain", packet.kind))


def test_each_port_gets_its_own_deliver_called():
    """Ports of different kinds on one channel (two classes, and a deliver that is not a
    method): each reception goes to its receiver's own deliver."""
    ports = [StubPort(0), OtherPort(1), PlainCallablePort(2), StubPort(3)]
    env, ch, _ = _channel([[0, 0, 10], [1500, 0, 10], [0, 1500, 10], [-1500, 0, 10]], ports)

    def sender() -> Any:
        yield env.timeout(0.5)
        yield ch.transmit(0, None, "ping", None, 100)

    env.process(sender())
    env.run(10.0)
    assert ports[0].got == []
    assert ports[1].got == [("other", "ping")] and ports[2].got == [("plain", "ping")]
    (rec,) = ports[3].got
    assert rec.packet.kind == "ping" and rec.packet.src == 0


def test_stub_network_half_duplex_and_queue():
    """1 starts a 0.5 s packet at t = 0.8 while 0's packet (sent at 0) arrives over [1.0, 1.5):
    1 drops it (half-duplex). 0 queues a second packet behind its first one."""
    ports = [StubPort(0), StubPort(1)]
    env, ch, log = _channel([[0, 0, 10], [1500, 0, 10]], ports, collision="none")
    done: list[float] = []

    def node0() -> Any:
        ev1 = ch.transmit(0, 1, "a", None, 500)
        ev2 = ch.transmit(0, 1, "b", None, 500)  # modem busy until 0.5: starts then
        yield ev1
        done.append(env.now)
        yield ev2
        done.append(env.now)

    def node1() -> Any:
        yield env.timeout(0.8)
        yield ch.transmit(1, None, "c", None, 500)

    env.process(node0())
    env.process(node1())
    env.run(10.0)
    assert done == [pytest.approx(0.5), pytest.approx(1.0)]
    rows = log.table()
    at1 = [(r["kind"], r["event"], r["reason"]) for r in rows if r["node"] == 1 and r["event"] != "tx"]
    # "a" arrives over [1.0, 1.5) and "b" over [1.5, 2.0); 1 transmits over [0.8, 1.3)
    assert sorted(at1) == [("a", "drop", "half_duplex"), ("b", "rx", None)]
    assert [r.packet.kind for r in ports[1].got] == ["b"]
    # 0 was not transmitting over [1.8, 2.3), so it hears "c"
    assert [r.packet.kind for r in ports[0].got] == ["c"]


def test_jitter_stream_asked_once_per_node():
    ports = [StubPort(0), StubPort(1)]
    env, ch, _ = _channel([[0, 0, 10], [1500, 0, 10]], ports, jitter_std_s=1e-3, collision="none")

    def sender() -> Any:
        for _ in range(5):
            yield ch.transmit(0, None, "x", None, 10)
            yield env.timeout(1.0)

    env.process(sender())
    env.run(20.0)
    assert len(ports[1].got) == 5
    assert ports[0].jitter_asked == 1 and ports[1].jitter_asked == 1
    # receive stamps: the clock's stamp of the arrival (sent at k * 1.01 s, 1 s on the way) plus
    # the receiver's own stream, drawn in order
    jitter = np.random.default_rng(1).normal(0.0, 1e-3, 5)
    arrival = np.arange(5) * 1.01 + 1.0
    got = np.array([r.rx_local for r in ports[1].got])
    assert np.abs(got - arrival - jitter).max() < 1e-9


def test_attach_in_id_order():
    env = simpy.Environment()
    ch = AcousticChannel(env, StubNetwork([[0, 0, 10]]), ListLog(), Constant(C), ChannelConfig())
    with pytest.raises(ValueError, match="node 0"):
        ch.attach(StubPort(1))
