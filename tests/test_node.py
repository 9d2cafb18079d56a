"""The Node API: recv/timeout semantics (the SimPy lost-race pitfall), local timers, sensors,
logging with truth columns, and that no public path leads to ground truth."""

from __future__ import annotations

import math
import warnings
from typing import ClassVar

import numpy as np
import pytest
import simpy

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import Box, ConstantVelocity, Mobility
from aquasim_py.node import Node, NodeEnv, Role, Sensors, SensorUnavailable

C = Constant(1500.0)
BOX = Box([-5000.0, -5000.0, 0.0], [5000.0, 5000.0, 500.0])
P0, P1 = [0.0, 0.0, 20.0], [1500.0, 0.0, 20.0]  # 1 s apart


class Sender(Node):
    """Node 0 broadcasts kinds at fixed true-equals-local times (perfect clock)."""

    name = "sender"
    schedule: ClassVar[list[tuple[float, str]]] = []

    def run(self):
        for t, kind in self.schedule:
            yield self.sleep(t - self.local_time())
            yield self.broadcast(kind, None, 10)


def _sim(receiver_cls, schedule, clocks=None, seed=0):
    sim = Simulation(seed, ssp=C, channel=ChannelConfig(collision="none"))
    sim.add_group(type("S", (Sender,), {"schedule": schedule}), 1, positions=[P0])
    sim.add_group(receiver_cls, 1, positions=[P1], clocks=clocks)
    return sim


def test_recv_timeout_does_not_eat_the_next_packet():
    """A recv that times out must leave no pending getter behind (DESIGN.md pitfall)."""
    results = []

    class R(Node):
        name = "r"

        def run(self):
            results.append((yield self.recv(timeout=0.5)))  # nothing arrives before 1.0 + 0.5
            results.append((yield self.recv(timeout=0.5)))
            results.append((yield self.recv(timeout=10.0)))  # the packet arriving at t = 3
            results.append((yield self.recv(timeout=10.0)))  # the one arriving at t = 4

    sim = _sim(R, [(2.0, "a"), (3.0, "b")])
    sim.run(20.0)
    assert results[0] is None and results[1] is None
    assert [r.packet.kind for r in results[2:]] == ["a", "b"]


def test_naive_simpy_race_loses_a_packet():
    """The pitfall itself, on a bare simpy Store: shows why recv() handles its own timeout."""
    env = simpy.Environment()
    store = simpy.Store(env)
    got = []

    def naive():
        get = store.get()
        yield get | env.timeout(1.0)  # the timeout wins; `get` stays queued
        second = store.get()
        res = yield second | env.timeout(10.0)
        got.append(res[second] if second in res else None)  # noqa: SIM401 (ConditionValue has no .get)

    def producer():
        yield env.timeout(2.0)
        yield store.put("p1")

    env.process(naive())
    env.process(producer())
    env.run(20.0)
    assert got == [None]  # p1 went to the stale getter


def test_recv_kinds_filter_keeps_other_packets():
    results = []

    class R(Node):
        name = "r"

        def run(self):
            yield self.sleep(10.0)  # both packets are buffered by then
            results.append((yield self.recv(kinds="b")))
            results.append((yield self.recv(timeout=0.0, kinds=["a", "c"])))
            results.append((yield self.recv(timeout=0.0)))
            results.append(self.pending())

    sim = _sim(R, [(1.0, "a"), (2.0, "b")])
    sim.run(20.0)
    assert results[0].packet.kind == "b" and results[1].packet.kind == "a"
    assert results[2] is None and results[3] == 0


def test_several_waiting_recvs_are_served_in_line():
    """With several processes waiting at once, a reception goes to the first waiting recv (in
    the order they were made) that takes its kind; a recv that times out leaves the line, first
    or not, and the others keep their places; what none takes stays in the inbox."""
    got = []

    class R(Node):
        name = "r"

        def waiter(self, label, **kw):
            rec = yield self.recv(**kw)
            got.append((label, None if rec is None else rec.packet.kind, self.local_time()))

        def run(self):
            # the line at t = 0: a (kind a), any (times out at 1.5), any, b (kind b)
            self.env.process(self.waiter("p1", kinds="a"))
            self.env.process(self.waiter("p2", timeout=1.5))
            self.env.process(self.waiter("p3"))
            self.env.process(self.waiter("p4", kinds="b", timeout=100.0))
            yield self.sleep(6.0)
            # the first in line times out with another behind it
            self.env.process(self.waiter("q1", kinds="z", timeout=1.0))
            self.env.process(self.waiter("q2", kinds="z"))
            yield self.sleep(10.0)
            got.append(("pending", self.pending(), self.local_time()))

    # sent at t, heard at t + 1 (1500 m at 1500 m/s), plus 10 bits at 1 kbit/s (default bitrate)
    sim = _sim(R, [(2.0, "b"), (2.5, "a"), (3.0, "c"), (4.0, "b"), (7.5, "z")])
    sim.run(30.0)
    labels = [(label, kind) for label, kind, _ in got]
    assert labels == [
        ("p2", None),  # 1.5: times out second in line
        ("p3", "b"),  # 3: p1 wants "a", p3 is the first that takes "b"
        ("p1", "a"),
        ("p4", "b"),  # "c" (4) went to the inbox: p4 takes only "b"
        ("q1", None),  # 7: the first in line times out, q2 moves up
        ("q2", "z"),
        ("pending", 1),  # the "c"
    ]
    times = [t for _, _, t in got]
    assert times[0] == pytest.approx(1.5) and times[4] == pytest.approx(7.0)
    assert times[1] < times[2] < times[3] < times[5]


def test_sleep_and_timeouts_run_on_the_local_clock():
    """sleep / recv timeout / env.timeout take local seconds: with skew 1e-3 and offset 5 the
    true duration is dt / (1 + skew)."""
    skew = 1e-3
    seen = {}

    class R(Node):
        name = "r"

        def run(self):
            t0 = self.local_time()
            yield self.sleep(100.0)
            seen["sleep"] = self.local_time() - t0
            t1 = self.local_time()
            yield self.env.timeout(50.0)
            seen["env"] = self.local_time() - t1
            t2 = self.local_time()
            r = yield self.recv(timeout=25.0)
            seen["recv"] = (r, self.local_time() - t2)

    sim = _sim(R, [], clocks=[Clock(skew=skew, offset=5.0)])
    sim.run(200.0)
    assert math.isclose(seen["sleep"], 100.0, abs_tol=1e-9)
    assert math.isclose(seen["env"], 50.0, abs_tol=1e-9)
    assert seen["recv"][0] is None and math.isclose(seen["recv"][1], 25.0, abs_tol=1e-9)
    # and in true time: local advanced 175 s, i.e. 175 / (1 + skew) s of simulation
    assert math.isclose(sim.clock_of(1).to_local(175.0 / (1 + skew)) - 5.0, 175.0, abs_tol=1e-9)


def test_env_facade_has_no_true_time():
    class R(Node):
        name = "r"

    sim = _sim(R, [])
    node = sim.nodes[1]
    assert isinstance(node.env, NodeEnv)
    with pytest.raises(AttributeError, match="local_time"):
        node.env.now  # noqa: B018


def test_depth_and_velocity_sensors():
    std_z, std_v = 0.5, 0.05
    v = np.array([0.3, -0.4, 0.1])
    sim = Simulation(11, ssp=C, volume=BOX)
    ordinary = sim.add_group(
        Node,
        1,
        role="ordinary",
        mobility=ConstantVelocity([[0, 0, 100.0]], BOX, velocity=v),
        sensors=Sensors(depth_std=std_z, velocity_std=std_v),
    )[0]
    target = sim.add_group(Node, 1, role=Role.TARGET, positions=[[10.0, 0.0, 50.0]])[0]
    sim.run(10.0)  # true depth of the ordinary node is now 100 + 0.1 * 10 = 101 m
    z = np.array([ordinary.depth() for _ in range(4000)])
    assert abs(z.mean() - 101.0) < 4 * std_z / math.sqrt(z.size)
    assert 0.95 * std_z < z.std() < 1.05 * std_z
    vs = np.array([ordinary.velocity() for _ in range(4000)])
    assert np.all(np.abs(vs.mean(axis=0) - v) < 4 * std_v / math.sqrt(4000))
    assert np.all((0.95 * std_v < vs.std(axis=0)) & (vs.std(axis=0) < 1.05 * std_v))
    assert target.depth() == 50.0  # default: no depth noise
    with pytest.raises(SensorUnavailable, match="velocity"):
        target.velocity()


def test_position_fix_only_where_a_node_could_know_it():
    """Buoys and anchors have a GPS / survey fix by default; ordinary nodes and targets do not."""
    std = 0.8
    sim = Simulation(12, ssp=C, volume=BOX)
    anchor = sim.add_group(
        Node, 1, role=Role.ANCHOR, positions=[[100.0, -200.0, 30.0]], sensors=Sensors(position_std=std)
    )[0]
    buoy = sim.add_group(Node, 1, role=Role.BUOY, positions=[[0.0, 0.0, 0.0]])[0]
    ordinary = sim.add_group(Node, 1, role=Role.ORDINARY, positions=[[5.0, 5.0, 50.0]])[0]
    rov = sim.add_group(Node, 1, role=Role.ORDINARY, positions=[[9.0, 9.0, 90.0]], sensors=Sensors(position=True))[0]
    sim.run(1.0)
    fixes = np.array([anchor.known_position() for _ in range(4000)])
    assert np.all(np.abs(fixes.mean(axis=0) - [100.0, -200.0, 30.0]) < 4 * std / math.sqrt(4000))
    assert np.all((0.95 * std < fixes.std(axis=0)) & (fixes.std(axis=0) < 1.05 * std))
    assert buoy.known_position().tolist() == [0.0, 0.0, 0.0]  # default: noise-free fix
    assert rov.known_position().tolist() == [9.0, 9.0, 90.0]  # opted in explicitly
    with pytest.raises(SensorUnavailable, match="position"):
        ordinary.known_position()


def test_log_estimate_and_clock_truth_columns():
    skew, offset = 30e-6, 0.8

    class R(Node):
        name = "proto"

        def run(self):
            yield self.sleep(10.0)
            self.log_estimate(1503.0, 4.0, 20.0, confidence=0.7, round=1)
            self.log_clock(skew, offset)  # exactly right: error 0
            self.log_clock(0.0, 0.0)  # believes it is on true time
            self.log("custom", value=42)

    sim = _sim(R, [], clocks=[Clock(skew=skew, offset=offset)])
    sim.run(20.0)
    f = sim.trace.frames()
    e = f["estimates"].iloc[0]
    assert list(f["estimates"].columns[:12]) == [
        "time",
        "node",
        "protocol",
        "x",
        "y",
        "z",
        "true_x",
        "true_y",
        "true_z",
        "error",
        "confidence",
        "is_reference",
    ]
    assert (e.node, e.protocol, e.true_x, e.true_y, e.true_z) == (1, "proto", 1500.0, 0.0, 20.0)
    assert math.isclose(e.error, 5.0) and e.confidence == 0.7 and e["round"] == 1
    c = f["clocks"]
    t = c.time.iloc[0]
    assert math.isclose(t, 10.0 / (1 + skew), rel_tol=1e-12)
    assert np.allclose(c.true_skew, skew, rtol=0, atol=0) and np.allclose(c.true_offset, offset)
    assert abs(c.error.iloc[0]) < 1e-12
    # believing local == true: its estimate of true time is the local reading, off by skew t + offset
    assert math.isclose(c.error.iloc[1], skew * t + offset, rel_tol=1e-9)
    assert f["custom"].iloc[0].to_dict() == {"time": t, "node": 1, "protocol": "proto", "value": 42}


def test_params_validated_by_the_protocol_model():
    from pydantic import BaseModel, ValidationError

    class P(Node):
        name = "p"

        class Params(BaseModel):
            period_s: float = 2.0

    sim = Simulation(0, ssp=C)
    (n,) = sim.add_group(P, 1, positions=[P0], params={"period_s": 3.5})
    assert n.params.period_s == 3.5
    with pytest.raises(ValidationError):
        sim.add_group(P, 1, positions=[P1], params={"period_s": "soon"})


def _walk_public(node, sim):
    """Assert that no public attribute of ``node``, nor of those attributes, is ground truth."""
    true_pos = sim.positions()
    forbidden_types = (Simulation, simpy.Environment, Mobility, Clock)

    def public(obj):
        for name in dir(obj):
            if name.startswith("_"):
                continue
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    yield name, getattr(obj, name)
            except Exception:
                continue

    def check(path, val):
        assert not isinstance(val, forbidden_types), f"{path} exposes {type(val).__name__}"
        if isinstance(val, (float, np.floating)):
            assert val != sim.now, f"{path} equals the true time"
        if isinstance(val, (np.ndarray, list, tuple)):
            arr = np.asarray(val)
            if arr.dtype.kind == "f" and arr.size and arr.size % 3 == 0:
                rows = arr.reshape(-1, 3)
                near = np.isclose(rows[:, None, :], true_pos[None, :, :], atol=1e-6).all(axis=-1)
                assert not near.any(), f"{path} holds a true position"

    n_checked = 0
    for name, val in public(node):
        check(f"node.{name}", val)
        n_checked += 1
        for sub, sval in public(val):
            check(f"node.{name}.{sub}", sval)
            n_checked += 1
    return n_checked


def _moving_sim():
    sim = Simulation(3, ssp=C, volume=BOX)
    sim.add_group(
        Node,
        2,
        mobility=ConstantVelocity([P0, P1], BOX, velocity=[1.0, 0.5, 0.0]),
        clocks=[Clock(skew=1e-4, offset=0.25), Clock(skew=-2e-4, offset=3.0)],
    )
    sim.run(7.3)
    return sim


def test_public_api_reaches_no_ground_truth():
    """Walk a node's public attributes two levels deep: no Simulation, Environment, Mobility,
    Clock, true position or true time may be among them."""
    sim = _moving_sim()
    node = sim.nodes[1]
    assert _walk_public(node, sim) > 20
    # the observables themselves are local: the clock reading is not true time
    assert node.local_time() != sim.now


@pytest.mark.parametrize("leak", ["sim", "clock", "position", "time", "nested"])
def test_ground_truth_walk_detects_leaks(leak):
    """The walk above is not vacuous: each kind of leak, planted by hand, is caught."""
    sim = _moving_sim()
    node = sim.nodes[1]
    value = {
        "sim": sim,
        "clock": sim.clock_of(1),
        "position": sim.positions()[1].copy(),
        "time": float(sim.now),
        "nested": type("Box", (), {"inner": sim.env})(),
    }[leak]
    node.leaked = value
    with pytest.raises(AssertionError):
        _walk_public(node, sim)


def test_local_durations_with_a_drifting_clock():
    """With skew drift (no closed form for the true duration), sleep and recv timeouts still
    advance the node's own clock by exactly the requested local time."""
    seen = []

    class R(Node):
        name = "r"

        def run(self):
            for dt in (3.7, 55.0, 120.25):
                t0 = self.local_time()
                yield self.sleep(dt)
                seen.append(self.local_time() - t0 - dt)
            t0 = self.local_time()
            assert (yield self.recv(timeout=42.0)) is None
            seen.append(self.local_time() - t0 - 42.0)

    sim = Simulation(0, ssp=C)
    clock = Clock(skew=2e-4, offset=1.0, drift_std=1e-5, drift_interval=5.0, rng=sim.rng("test", "clock"))
    sim.add_group(R, 1, positions=[P0], clocks=[clock])
    sim.run(400.0)
    assert len(seen) == 4
    assert max(abs(e) for e in seen) < 1e-9
    # and the drift is real: the true durations differ from the local ones by more than that
    assert abs(clock.to_true(clock.to_local(100.0) + 55.0) - 100.0 - 55.0 / 1.0002) > 1e-7


def test_a_guessed_truth_attribute_says_what_a_node_can_use() -> None:
    sim = Simulation(1, ssp=C, volume=BOX)
    node = sim.add_group(Node, 1, positions=[[1.0, 2.0, 3.0]])[0]
    with pytest.raises(AttributeError, match=r"no attribute 'position'.*known_position\(\)"):
        node.position()  # type: ignore[attr-defined]
    assert not hasattr(node, "now")  # still an AttributeError, so hasattr() keeps working


def test_a_protocol_may_use_a_guessed_truth_name_for_its_own() -> None:
    """The hints do not reserve the names: a protocol's own attribute or method named like a
    guessed truth attribute is its own."""

    class Own(Node):
        name = "own"

        def setup(self):
            self.time = 3.0  # its own (local) bookkeeping

        def position(self):  # its own estimate
            return (1.0, 2.0, 3.0)

    sim = Simulation(1, ssp=C, volume=BOX)
    node = sim.add_group(Own, 1, positions=[[1.0, 2.0, 3.0]])[0]
    node.setup()
    assert node.time == 3.0 and node.position() == (1.0, 2.0, 3.0)
    with pytest.raises(AttributeError, match=r"no attribute 'now'.*local_time\(\)"):
        node.now  # noqa: B018
    assert not hasattr(node, "sim")


def test_at_instant_end_runs_after_every_other_event_of_its_instant():
    """The hook comes after the events of its instant scheduled after it (zero timeouts made
    later in the same instant), and before the next instant."""
    log = []

    class R(Node):
        name = "r"

        def run(self):
            yield self.sleep(1.0)
            self.env.at_instant_end(lambda _ev: log.append(("end", self.local_time())))
            for step in "abc":
                log.append((step, self.local_time()))
                yield self.env.timeout(0.0)
            yield self.sleep(1e-9)
            log.append(("d", self.local_time()))

    sim = _sim(R, [])
    sim.run(5.0)
    assert [k for k, _ in log] == ["a", "b", "c", "end", "d"]
    assert [t for _, t in log[:4]] == [1.0] * 4 and log[4][1] > 1.0


# -- events made and never waited on (a missing `yield`) --------------------------------------------


class _Forgetful(Node):
    """Listens, and after each reception means to pause but forgets the ``yield``; also
    broadcasts once without waiting for the send to finish."""

    name = "forgetful"

    def run(self):
        if self.id == 0:
            self.broadcast("hello", None, 10)  # not waited on
            yield self.sleep(1e6)
        while True:
            rec = yield self.recv(timeout=5.0)
            if rec is None:
                return
            self.sleep(0.5)  # the bug: no yield


class _Careful(Node):
    """Waits on everything it makes, also through conditions (the loser of ``a | b`` counts as
    waited on: its condition dropped its callback when the other won)."""

    name = "careful"

    def run(self):
        if self.id == 0:
            for _ in range(3):
                yield self.broadcast("hello", None, 10) | self.sleep(100.0)
                yield self.sleep(1.0)
            return
        while True:
            rec = yield self.recv(timeout=5.0)
            if rec is None:
                return
            yield self.sleep(0.2) & self.sleep(0.1)


def _unawaited_run(cls: type[Node]) -> tuple[Simulation, list[warnings.WarningMessage]]:
    from aquasim_py.kernel import UnawaitedEventsWarning

    sim = Simulation(0, ssp=C, channel=ChannelConfig(collision="none"))
    sim.add_group(cls, 2, positions=[P0, P1])
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sim.run(20.0)
    return sim, [w for w in caught if issubclass(w.category, UnawaitedEventsWarning)]


def test_events_never_waited_on_are_counted_and_warned_once_per_protocol() -> None:
    sim, caught = _unawaited_run(_Forgetful)
    assert sim.unawaited == {"forgetful": {"broadcast": 1, "sleep": 1}}
    assert len(caught) == 1
    text = str(caught[0].message)
    assert "'forgetful'" in text and "1 broadcast, 1 sleep" in text and "yield" in text


def test_events_waited_on_directly_or_through_conditions_are_not_reported() -> None:
    sim, caught = _unawaited_run(_Careful)
    assert sim.unawaited == {} and caught == []
    rows = sim.trace.frames()["packets"]
    assert (rows["event"] == "rx").sum() == 3  # the run did what it was meant to


def test_the_cli_prints_one_warning_line_for_a_protocol_that_forgets_yield(tmp_path, capsys, monkeypatch) -> None:
    from aquasim_py import registry
    from aquasim_py.cli import main

    registry.available()  # loaded, so that the test's protocol is added to a complete registry
    monkeypatch.setitem(registry._registry, "forgetful", _Forgetful)
    (tmp_path / "s.toml").write_text(
        'description = "t"\n[simulation]\nduration_s = 20.0\n'
        "[environment]\nvolume = { lo = [-5000.0, -5000.0, 0.0], hi = [5000.0, 5000.0, 500.0] }\n"
        'sound_speed = { model = "constant", speed_mps = 1500.0 }\n[channel]\ncollision = "none"\n'
        '[[nodes]]\nname = "n"\nrole = "ordinary"\ncount = 2\nprotocol = "forgetful"\n'
        'placement = { kind = "explicit", positions = [[0.0, 0.0, 20.0], [1500.0, 0.0, 20.0]] }\n'
    )
    assert main([str(tmp_path / "s.toml"), "--quiet", "--out", str(tmp_path / "out")]) == 0
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "never waited on" in line]
    assert len(lines) == 1 and lines[0].startswith("warning: protocol 'forgetful'"), err
