"""The truth barrier seen from a probe protocol: the public paths that used to lead to ground
truth (true time through an event's ``env``, the run seed through ``rng``, the exact SNR,
the sender's own payload object) give nothing true any more, and the node API still works."""

from __future__ import annotations

import math
from typing import Any, ClassVar

import numpy as np
import pytest
import simpy
from hypothesis import given, settings
from hypothesis import strategies as st

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node, NodeEnv
from aquasim_py.packet import copy_payload

# every test on both delivery paths (compiled and the Python reference), see tests/conftest.py

C = Constant(1500.0)
P0, P1, P2 = [0.0, 0.0, 20.0], [1500.0, 0.0, 20.0], [0.0, 1500.0, 20.0]  # 1 s from node 0
SKEW = 3e-4


def _env_of_everything(node: Node) -> dict[str, Any]:
    """The ``env`` of every kind of event a node can get back."""

    def child() -> Any:
        yield node.env.timeout(0.0)

    evs: dict[str, simpy.Event] = {
        "env.timeout": node.env.timeout(0.0),
        "sleep": node.sleep(0.0),
        "recv": node.recv(timeout=0.0),
        "broadcast": node.broadcast("probe", None, 8),
        "env.event": node.env.event(),
        "env.process": node.env.process(child()),
    }
    evs["or"] = evs["sleep"] | evs["env.timeout"]
    evs["and"] = evs["sleep"] & evs["env.timeout"]
    evs["all_of"] = node.env.all_of([evs["sleep"], evs["recv"]])
    evs["any_of"] = node.env.any_of([evs["sleep"], evs["recv"]])
    return {k: ev.env for k, ev in evs.items()}


class Probe(Node):
    """Tries every public path to truth it knows of and writes down what it found."""

    name = "probe"
    found: ClassVar[dict[str, Any]] = {}

    def run(self) -> Any:
        f = self.found
        f["envs"] = _env_of_everything(self)
        f["active"] = self.env.active_process
        t0 = self.local_time()
        ev = self.env.timeout(1.0)
        f["delay"] = ev._delay  # private: out of contract, but it holds only the local duration
        yield ev
        f["elapsed"] = self.local_time() - t0
        # a timer built by hand on the node's env is a local timer too
        t0 = self.local_time()
        yield simpy.Timeout(self.env, 2.0)  # type: ignore[arg-type]
        f["hand_timer"] = self.local_time() - t0
        # conditions over the node's events are usable in yield
        res = yield self.sleep(0.5) | self.recv(timeout=5.0)
        f["condition"] = len(res.todict())
        f["seed_seq"] = self.rng.bit_generator.seed_seq
        f["draws"] = self.rng.random(4)


def _probe_sim(seed: int = 11) -> Simulation:
    Probe.found = {}
    sim = Simulation(seed, ssp=C)
    sim.add_group(Probe, 1, positions=[P0], clocks=[Clock(skew=SKEW, offset=2.0)])
    return sim


def test_no_event_a_node_gets_leads_to_true_time() -> None:
    sim = _probe_sim()
    sim.run(10.0)
    f = Probe.found
    node = sim.nodes[0]
    assert len(f["envs"]) == 10
    for what, env in f["envs"].items():
        assert env is node.env, what
        assert not isinstance(env, simpy.Environment), what
        assert not hasattr(env, "now"), what
    assert f["active"].env is node.env  # the node's own run process, on its view
    # local-clock durations, and the timeout holds no true delay: 1/_delay - 1 is no skew
    assert f["delay"] == 1.0
    assert math.isclose(f["elapsed"], 1.0, abs_tol=1e-12)
    assert math.isclose(f["hand_timer"], 2.0, abs_tol=1e-12)
    assert f["condition"] == 1


def test_interrupt_and_processes_on_the_node_view() -> None:
    log: list[Any] = []

    class Interrupter(Node):
        name = "interrupter"

        def run(self) -> Any:
            def sleeper() -> Any:
                try:
                    yield self.sleep(100.0)
                except simpy.Interrupt as e:
                    log.append(("interrupted", e.cause, round(self.local_time(), 9)))

            p = self.env.process(sleeper())
            yield self.sleep(1.0)
            p.interrupt("wake")
            yield p
            log.append("joined")

    sim = Simulation(0, ssp=C)
    sim.add_group(Interrupter, 1, positions=[P0])
    sim.run(5.0)
    assert log == [("interrupted", "wake", 1.0), "joined"]


def test_rng_holds_no_run_seed_and_draws_as_before() -> None:
    seed = 11
    sim = _probe_sim(seed)
    sim.run(10.0)
    ss = Probe.found["seed_seq"]
    assert ss.entropy != seed and ss.spawn_key == ()
    # nothing that the run's own derivation would give: not the node's clock stream, say
    rebuilt = np.random.Generator(np.random.PCG64(np.random.SeedSequence(ss.entropy, spawn_key=(0, 2))))
    assert not np.array_equal(rebuilt.random(4), sim.rng("node", 0, "clock").random(4))
    # the protocol stream itself is unchanged: the same draws as the keyed stream
    assert np.array_equal(Probe.found["draws"], sim.rng("node", 0, "protocol").random(4))
    # and still a function of the run seed only
    draws = Probe.found["draws"]
    sim2 = _probe_sim(seed)
    sim2.run(10.0)
    assert np.array_equal(Probe.found["draws"], draws)
    assert Probe.found["seed_seq"].entropy == ss.entropy


class Talker(Node):
    """Node 0: sends a dict and an array, then changes both right after sending."""

    name = "talker"
    n: ClassVar[int] = 1

    def run(self) -> Any:
        for i in range(self.n):
            d = {"seq": i, "pos": [1.0, 2.0, 3.0]}
            a = np.array([float(i), 0.0, 0.0])
            yield self.broadcast("d", d, 8)
            yield self.broadcast("a", a, 8)
            d["seq"] = -1  # a change after sending reaches nobody
            d["pos"][0] = -1.0
            a[0] = -1.0
            yield self.sleep(0.05)


class Listener(Node):
    name = "listener"
    got: ClassVar[dict[int, list[Any]]] = {}

    def run(self) -> Any:
        while True:
            self.keep((yield self.recv()))

    def keep(self, rec: Any) -> None:
        """Keep (kind, payload, SNR) of ``rec`` and write 99 into its payload (its own copy only)."""
        self.got.setdefault(self.id, []).append((rec.packet.kind, rec.packet.payload, rec.snr_db))
        if rec.packet.kind == "d":
            rec.packet.payload["pos"][1] = 99.0
        else:
            rec.packet.payload[1] = 99.0


def _talk_sim(n: int, std: float | None, seed: int = 5) -> Simulation:
    Listener.got = {}
    cfg = ChannelConfig(collision="none") if std is None else ChannelConfig(collision="none", snr_estimate_std_db=std)
    sim = Simulation(seed, ssp=C, channel=cfg)
    sim.add_group(type("T", (Talker,), {"n": n}), 1, positions=[P0])
    sim.add_group(Listener, 2, positions=[P1, P2])
    return sim


def _assert_own_snapshots() -> None:
    """Each listener (1, 2) got the Talker's three send-time snapshots (its later changes
    unseen) with its own write of 99 in each, in objects of its own."""
    for rid in (1, 2):
        got = Listener.got[rid]
        assert [k for k, _, _ in got] == ["d", "a"] * 3
        for i in range(3):
            (_, d, _), (_, a, _) = got[2 * i], got[2 * i + 1]
            assert d["seq"] == i and d["pos"][0] == 1.0 and d["pos"][1] == 99.0  # its own write only
            assert a[0] == float(i) and a[1] == 99.0
    for (_, x, _), (_, y, _) in zip(Listener.got[1], Listener.got[2], strict=True):
        assert x is not y


def test_payload_is_a_snapshot_and_each_receiver_has_its_own() -> None:
    sim = _talk_sim(3, None)
    sim.run(20.0)
    _assert_own_snapshots()


class LateListener(Listener):
    """Takes its receptions from the modem's inbox after ``delay`` s (they wait there, uncopied),
    then writes into each payload as Listener does."""

    delay: ClassVar[dict[int, float]] = {}

    def run(self) -> Any:
        yield self.sleep(self.delay[self.id])
        yield from super().run()


class LateTaker(Listener):
    """Takes its whole inbox at once (``take_pending``) after ``delay`` s, writing into each."""

    delay: ClassVar[dict[int, float]] = {}

    def run(self) -> Any:
        yield self.sleep(self.delay[self.id])
        for rec in self.take_pending():
            self.keep(rec)


@pytest.mark.parametrize("late", [LateListener, LateTaker], ids=["recv", "take_pending"])
def test_receptions_taken_from_the_inbox_are_own_copies_of_the_snapshot(late: type[LateListener | LateTaker]) -> None:
    """Node 1 takes (and writes into) its receptions first, node 2 later, one by one with recv or
    all at once with take_pending: node 2 still gets the send-time snapshot, in its own objects."""
    Listener.got = {}
    late.delay = {1: 2.0, 2: 4.0}
    sim = Simulation(5, ssp=C, channel=ChannelConfig(collision="none"))
    sim.add_group(type("T", (Talker,), {"n": 3}), 1, positions=[P0])
    sim.add_group(late, 2, positions=[P1, P2])
    sim.run(20.0)
    _assert_own_snapshots()


def test_snr_is_an_estimate_with_the_configured_noise_and_the_trace_keeps_truth() -> None:
    n = 400
    sim = _talk_sim(n // 2, None)  # default: 1 dB
    assert ChannelConfig().snr_estimate_std_db == 1.0
    sim.run(60.0)
    pk = sim.trace.table("packets").frame()
    rx = pk[(pk.event == "rx") & (pk.node == 1)].sort_values("uid")
    est = np.array([s for _, _, s in Listener.got[1]])
    err = est - rx.snr_db.to_numpy()
    assert len(err) == n
    # static nodes: the true SNR is the same every time, so range would follow exactly from it;
    # the estimate's error has the configured std (sample std of n normals: sd ~ 1/sqrt(2n) =
    # 0.035 dB; 5 sigma) and a mean near 0 (sd 1/sqrt(n) = 0.05 dB; 5 sigma)
    assert np.ptp(rx.snr_db.to_numpy()) == 0.0
    assert abs(err.std(ddof=1) - 1.0) < 5 / math.sqrt(2 * n)
    assert abs(err.mean()) < 5 / math.sqrt(n)
    # 0 = exact, and the noise draws come from their own stream: every trace is unchanged
    sim0 = _talk_sim(n // 2, 0.0)
    sim0.run(60.0)
    est0 = np.array([s for _, _, s in Listener.got[1]])
    assert np.array_equal(est0, rx.snr_db.to_numpy())
    assert sim0.trace.table("packets").frame().equals(pk)


def test_snr_estimate_std_validated() -> None:
    with pytest.raises(ValueError, match="snr_estimate_std_db"):
        ChannelConfig(snr_estimate_std_db=-1.0)


def test_node_env_is_a_node_env() -> None:
    sim = _probe_sim()
    assert isinstance(sim.nodes[0].env, NodeEnv)


_leaves = st.none() | st.booleans() | st.integers() | st.floats(allow_nan=False) | st.text(max_size=5)
_payloads = st.recursive(
    _leaves,
    lambda kids: (
        st.lists(kids, max_size=4)
        | st.dictionaries(st.text(max_size=3), kids, max_size=4)
        | st.tuples(kids, kids)
        | st.lists(st.floats(allow_nan=False), max_size=4).map(np.array)
    ),
    max_leaves=8,
)


def _containers(obj: Any) -> list[Any]:
    """Every mutable container (dict, list, array) inside ``obj``, depth first."""
    if isinstance(obj, dict):
        return [obj, *(c for v in obj.values() for c in _containers(v))]
    if isinstance(obj, (list, tuple)):
        inner = [c for v in obj for c in _containers(v)]
        return [obj, *inner] if isinstance(obj, list) else inner
    return [obj] if isinstance(obj, np.ndarray) else []


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray):
        return isinstance(b, np.ndarray) and np.array_equal(a, b)
    if isinstance(a, dict):
        return type(b) is dict and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    return type(a) is type(b) and a == b


@given(_payloads)
@settings(max_examples=50, deadline=None)
def test_copy_payload_is_an_equal_copy_sharing_no_mutable_part(p: Any) -> None:
    q = copy_payload(p)
    assert _same(p, q)
    mine = {id(c) for c in _containers(p)}
    assert not mine & {id(c) for c in _containers(q)}


def _shared_tuples(p: Any, q: Any) -> list[tuple[Any, ...]]:
    """The tuples of ``q`` that are the very objects of ``p`` (walked in parallel)."""
    if isinstance(p, tuple) and p is q:
        return [p]
    if isinstance(p, dict):
        return [t for k in p for t in _shared_tuples(p[k], q[k])]
    if isinstance(p, (list, tuple)):
        return [t for a, b in zip(p, q) for t in _shared_tuples(a, b)]
    return []


@given(_payloads)
@settings(max_examples=50, deadline=None)
def test_copy_payload_shares_a_tuple_only_when_nothing_in_it_is_mutable(p: Any) -> None:
    # A shared tuple cannot be written (no item assignment) and holds no container a receiver
    # could write into; one that holds such a container is rebuilt around its copy.
    q = copy_payload(p)
    for t in _shared_tuples(p, q):
        assert _containers(t) == []
    if isinstance(p, tuple):
        assert (q is p) == (_containers(p) == [])


def test_immutable_tuples_are_shared_and_stay_immutable() -> None:
    xy = (1.5, 2.5)
    p = {"xy": xy, "vel": (np.float64(0.1), 0.2), "tags": frozenset({"a", 3}), "hist": [1.0]}
    q = copy_payload(p)
    assert q is not p and q["hist"] is not p["hist"]
    assert q["xy"] is xy and q["vel"] is p["vel"] and q["tags"] is p["tags"]
    with pytest.raises(TypeError):
        q["xy"][0] = 9.0  # type: ignore[index]
    q["xy"] = (9.0, 9.0)  # a receiver rebinding its own dict's entry
    q["hist"].append(2.0)
    assert p == {"xy": (1.5, 2.5), "vel": (np.float64(0.1), 0.2), "tags": frozenset({"a", 3}), "hist": [1.0]}
    nested = ((1, 2), [3])
    r = copy_payload(nested)
    assert r is not nested and r[0] is nested[0] and r[1] == [3] and r[1] is not nested[1]
