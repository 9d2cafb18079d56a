"""Simulation: random streams, groups, position sampling, progress, reproducible traces."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.clock import Clock
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import Box, ConstantVelocity, RandomWalk
from aquasim_py.node import Node, Sensors
from aquasim_py.trace import TraceConfig

# every test on both delivery paths (compiled and the Python reference), see tests/conftest.py

C = Constant(1500.0)
BOX = Box([0.0, 0.0, 0.0], [3000.0, 3000.0, 300.0])


def test_rng_streams_are_keyed_and_stable():
    a, b = Simulation(7), Simulation(7)
    assert np.array_equal(a.rng("node", 3, "depth").random(5), b.rng("node", 3, "depth").random(5))
    # creating other streams first changes nothing
    _ = [a.rng("node", i, "x") for i in range(10)]
    assert np.array_equal(a.rng("node", 3, "depth").random(5), b.rng("node", 3, "depth").random(5))
    draws = {
        key: Simulation(7).rng(*key).random()
        for key in [
            ("node", 3, "depth"),
            ("node", 4, "depth"),
            ("node", "3", "depth"),
            ("node", 3, "velocity"),
            ("group", "a", "mobility"),
        ]
    }
    assert len(set(draws.values())) == len(draws)
    assert Simulation(8).rng("node", 3, "depth").random() != draws[("node", 3, "depth")]
    with pytest.raises(ValueError):
        a.rng()


def _noisy_world(n_extra: int, seed: int = 5) -> list[float]:
    """Depth readings of nodes 0 and 1 in a world with n_extra more nodes (and their noise)."""
    out: list[float] = []

    class Reader(Node):
        name = "reader"

        def run(self):
            yield self.sleep(1.0)
            if self.id < 2:
                out.extend(self.depth() for _ in range(3))
                out.append(float(self.rng.random()))

    sim = Simulation(seed, ssp=C, channel=ChannelConfig(collision="none"))
    sim.add_group(
        Reader,
        2 + n_extra,
        positions=[[10.0 * i, 0.0, 50.0] for i in range(2 + n_extra)],
        sensors=Sensors(depth_std=1.0),
    )
    sim.run(2.0)
    return out


def test_adding_a_node_changes_no_other_stream():
    base = _noisy_world(0)
    assert len(base) == 8 and len(set(base)) == 8
    assert _noisy_world(1) == base
    assert _noisy_world(5) == base
    assert _noisy_world(0, seed=6) != base


def test_positions_table_sampled_on_grid():
    p0 = np.array([[100.0, 200.0, 50.0], [1000.0, 1000.0, 100.0]])
    v = np.array([[1.0, 0.0, 0.25], [0.0, -2.0, 0.0]])
    sim = Simulation(1, ssp=C, volume=BOX, trace=TraceConfig(position_interval=2.5))
    sim.add_group(Node, 2, mobility=ConstantVelocity(p0, BOX, velocity=v))
    sim.add_group(Node, 1, positions=[[5.0, 5.0, 5.0]])
    sim.run(10.0)
    pos = sim.trace.frames()["positions"]
    assert list(pos.columns[:8]) == ["time", "node", "x", "y", "z", "vx", "vy", "vz"]
    assert sorted(set(pos.time)) == [0.0, 2.5, 5.0, 7.5]
    for _, r in pos.iterrows():
        n = int(r.node)
        if n < 2:
            expect_p, expect_v = p0[n] + v[n] * r.time, v[n]
        else:
            expect_p, expect_v = np.array([5.0, 5.0, 5.0]), np.zeros(3)
        assert np.allclose([r.x, r.y, r.z], expect_p, atol=1e-12)
        assert np.allclose([r.vx, r.vy, r.vz], expect_v, atol=1e-12)
    off = Simulation(1, trace=TraceConfig(position_interval=None))
    off.add_group(Node, 1, positions=[[0.0, 0.0, 1.0]])
    off.run(5.0)
    assert len(off.trace.frames()["positions"]) == 0


def test_progress_callback():
    calls = []
    sim = Simulation(0)
    sim.add_group(Node, 1, positions=[[0.0, 0.0, 1.0]])
    sim.run(250.0, progress=lambda t, until: calls.append((t, until)))
    times = [t for t, _ in calls]
    assert 95 <= len(calls) <= 101
    assert times == sorted(times) and times[-1] == 250.0
    assert all(u == 250.0 for _, u in calls)
    assert max(np.diff(times)) <= 2.5 + 1e-9


def test_add_group_validation():
    sim = Simulation(0, ssp=C, volume=BOX)
    with pytest.raises(TypeError):
        sim.add_group(object, 1, positions=[[0, 0, 1]])
    with pytest.raises(ValueError, match="mobility"):
        sim.add_group(Node, 1)
    with pytest.raises(ValueError, match="shape"):
        sim.add_group(Node, 3, mobility=ConstantVelocity([[1.0, 1.0, 1.0]], BOX))
    with pytest.raises(ValueError, match="clocks"):
        sim.add_group(Node, 2, positions=[[1, 1, 1], [2, 2, 2]], clocks=[Clock()])

    class NotGen(Node):
        name = "notgen"

        def run(self):
            return None

    with pytest.raises(TypeError, match="generator"):
        sim.add_group(NotGen, 1, positions=[[1, 1, 1]])
    with pytest.raises(ValueError):
        sim.run(0.0)


def test_clock_factory_gets_node_id_and_own_stream():
    made = []

    def factory(node_id, rng):
        skew = float(rng.normal(0.0, 20e-6))
        made.append((node_id, skew))
        return Clock(skew=skew)

    a, b = Simulation(4), Simulation(4)
    a.add_group(Node, 3, positions=[[float(i), 0.0, 1.0] for i in range(3)], clocks=factory)
    b.add_group(Node, 1, positions=[[9.0, 0.0, 1.0]])  # shifts ids: node 1 of b is node 0 of a's group
    b.add_group(Node, 3, positions=[[float(i), 0.0, 1.0] for i in range(3)], clocks=factory)
    ids = [m[0] for m in made]
    assert ids == [0, 1, 2, 1, 2, 3]
    skews = dict(made[:3])
    assert skews[1] == made[3][1] and skews[2] == made[4][1]  # same id -> same stream


class Chatter(Node):
    """Random broadcasts and replies, with noisy sensors logged: exercises every table."""

    name = "chatter"

    def run(self):
        while True:
            rec = yield self.recv(timeout=float(self.rng.uniform(0.5, 3.0)))
            if rec is None:
                yield self.broadcast("hello", {"d": self.depth()}, int(self.rng.integers(50, 300)))
            elif rec.packet.kind == "hello":
                yield self.send(rec.packet.src, "reply", None, 80)
            self.log_estimate(*(self.rng.normal(500.0, 100.0, 3)), confidence=float(self.rng.random()))
            self.log_clock(float(self.rng.normal(0, 1e-5)), float(self.rng.normal(0, 1e-3)))


def _traces(tmp_path, seed, name):
    sim = Simulation(
        seed,
        ssp=C,
        volume=BOX,
        channel=ChannelConfig(collision="capture", jitter_std_s=1e-5, max_range_m=2500.0),
        loss_model=lambda ray, cfg: 120.0 - 15.0 * np.log10(ray.length),
    )

    def clocks(i, rng):
        return Clock(
            skew=rng.normal(0, 3e-5),
            offset=rng.normal(0, 0.1),
            drift_std=1e-7,
            jitter_std=1e-6,
            rng=rng,
        )

    sim.add_group(
        Chatter,
        6,
        mobility=lambda rng: RandomWalk(rng.uniform([0, 0, 0], [3000, 3000, 300], (6, 3)), BOX, rng),
        clocks=clocks,
        sensors=Sensors(depth_std=0.3),
    )
    sim.add_group(Chatter, 2, role="anchor", positions=[[1500.0, 1500.0, 10.0], [100.0, 2900.0, 200.0]])
    sim.run(120.0)
    out = tmp_path / name
    sim.trace.write(out)
    return {p.name: p.read_bytes() for p in sorted(out.iterdir())}, sim


def test_same_seed_gives_byte_identical_csv(tmp_path):
    a, sim = _traces(tmp_path, 11, "a")
    b, _ = _traces(tmp_path, 11, "b")
    c, _ = _traces(tmp_path, 12, "c")
    f = sim.trace.frames()
    p = f["packets"]
    assert (p.event == "rx").sum() > 50 and (p.event == "drop").sum() > 0  # a busy, lossy run
    assert len(f["estimates"]) > 50 and len(f["clocks"]) > 50
    assert set(a) >= {"packets.csv", "positions.csv", "estimates.csv", "clocks.csv", "nodes.csv"}
    assert a == b
    assert a["packets.csv"] != c["packets.csv"]


def test_quiet_gc_restores_the_collector_even_on_error() -> None:
    import gc

    from aquasim_py.kernel import RUN_GC_THRESHOLD, quiet_gc

    before = gc.get_threshold()
    frozen = gc.get_freeze_count()
    with pytest.raises(RuntimeError), quiet_gc():
        assert gc.get_threshold()[0] >= RUN_GC_THRESHOLD
        assert gc.get_freeze_count() >= frozen
        raise RuntimeError("boom")
    assert gc.get_threshold() == before
    assert gc.get_freeze_count() == frozen


def test_positions_and_velocities_of_one_instant_are_each_groups_own() -> None:
    # Simulation.positions(t) keeps the velocities of the same evaluation for velocities(t);
    # both must be what each group's model gives for t alone, whichever is asked first.
    from aquasim_py.mobility import Kinematic

    rng = np.random.default_rng(3)
    drift = Kinematic(rng.uniform(100.0, 290.0, (4, 3)), BOX, np.random.default_rng(4))
    walk = RandomWalk(rng.uniform(100.0, 290.0, (3, 3)), BOX, np.random.default_rng(5), speed_max=2.0)
    sim = Simulation(1, ssp=C, volume=BOX)
    sim.add_group(Node, 4, mobility=drift)
    sim.add_group(Node, 3, mobility=walk)
    sim.add_group(Node, 1, positions=[[5.0, 5.0, 5.0]])
    for t in (0.0, 3.7, 3.7, 120.25, 0.5):
        for first in ("positions", "velocities"):
            if first == "velocities":
                sim._pos_t = sim._vel_t = np.nan  # forget the instant: velocities asked first
                v, p = sim.velocities(t), sim.positions(t)
            else:
                p, v = sim.positions(t), sim.velocities(t)
            want_p = np.concatenate([drift.position(t), walk.position(t), [[5.0, 5.0, 5.0]]])
            want_v = np.concatenate([drift.velocity(t), walk.velocity(t), np.zeros((1, 3))])
            assert np.array_equal(p, want_p) and np.array_equal(v, want_v)
