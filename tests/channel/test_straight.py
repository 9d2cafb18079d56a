"""The compiled links (channel/straight.py) of a constant profile with every node on a
box-folded straight line: bit for bit the numpy path's answer, and against brute force (every
node's distance at the send time; the arrival time by brentq on the true, folded trajectory).

The networks are small boxes with fast nodes, a sea floor above the box's bottom and a few
nodes faster than c / 2, so that wall bounces during a flight, receivers out of the water,
shadowed links and out-of-range nodes all occur (the test checks that they do)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
import textwrap

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.optimize import brentq

from aquasim_py.channel import Constant, acoustic
from aquasim_py.channel.acoustic import FIXED_POINT_TOL_S, ChannelConfig, no_snr
from aquasim_py.channel.rays import Eigenray
from aquasim_py.channel.straight import FALLBACK, OK, _fold, _root, by_arrival, straight_links
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import Box, ConstantVelocity
from aquasim_py.node import Node

C = 1500.0
RANGE = 250.0


class Idle(Node):
    """Never transmits: the test calls the channel's link computation itself."""

    name = "idle"

    def run(self):
        yield self.sleep(1e9)


def _network(seed: int, n: int, speed: float, groups: int, loss: str = "physical") -> Simulation:
    """n nodes in a 800 m x 800 m x 120 m box (sea floor at 116 m), random headings at up to
    ``speed`` m/s (vertical component a fifth), 1 % at 800 m/s (faster than c / 2), split into
    ``groups`` groups (the last with its own smaller box)."""
    rng = np.random.default_rng(seed)
    boxes = [Box([0.0, 0.0, 0.0], [800.0, 800.0, 120.0]), Box([50.0, 20.0, 0.0], [650.0, 780.0, 90.0])]
    model = None
    if loss == "none":
        model = no_snr
    elif loss == "angles":  # a model reading the whole ray (angles): the compiled path builds it

        def model(ray: Eigenray, config: ChannelConfig) -> np.ndarray:
            return 60.0 + 10.0 * np.sin(ray.arrival_angle) - ray.length / 50.0

    sim = Simulation(
        seed,
        ssp=Constant(C, bottom=116.0),
        volume=boxes[0],
        channel=ChannelConfig(max_range_m=RANGE, collision="none"),
        loss_model=model,
    )
    sizes = np.diff(np.linspace(0, n, groups + 1).astype(int))
    for g, size in enumerate(sizes):
        box = boxes[1] if (g == groups - 1 and groups > 1) else boxes[0]
        p0 = rng.uniform(box.lo, box.hi, (size, 3))
        head = rng.normal(size=(size, 3)) * [1.0, 1.0, 0.2]
        v = head / np.linalg.norm(head, axis=1)[:, None] * rng.uniform(0.0, speed, (size, 1))
        v[rng.random(size) < 0.01] *= 800.0 / speed
        sim.add_group(Idle, int(size), mobility=ConstantVelocity(p0, box, velocity=v))
    return sim


def _plain(links):
    ids, heard, lost = links  # ids: the set in range (the channel only tests membership)
    return sorted(ids), heard, lost


def _same(a, b) -> bool:
    """Equal, with NaN equal to NaN (an SNR or a lost link's delay)."""
    return json.dumps(a, default=str) == json.dumps(b, default=str)


@settings(max_examples=10)
@given(
    seed=st.integers(0, 2**31 - 1),
    speed=st.sampled_from([0.5, 20.0, 60.0]),
    groups=st.integers(1, 2),
    loss=st.sampled_from(["physical", "none", "angles"]),
)
def test_compiled_links_are_the_numpy_links_bit_for_bit(seed, speed, groups, loss):
    sim = _network(seed, 60, speed, groups, loss)
    ch = sim.channel
    ch._links(0, 0.0)  # the layout
    compiled = ch._lines
    assert compiled is not None
    for t0 in (0.0, 3.9):
        for src in range(0, 60, 2):
            ch._lines = compiled
            got = _plain(ch._links(src, t0))
            ch._lines = None
            ref = _plain(ch._links(src, t0))
            assert _same(got, ref), (src, t0)


def test_compiled_links_against_brute_force():
    """Range test against every node's distance, delays against brentq on the true trajectory
    (to the fixed point's tolerance), and every unusual case actually met."""
    statuses = {OK: 0, FALLBACK: 0}
    seen = {"heard": 0, "lost": 0, "out_of_range": 0}
    for seed in range(4):
        sim = _network(seed, 60, 60.0, 1 + seed % 2)
        ch = sim.channel
        ch._links(0, 0.0)
        assert ch._lines is not None and ch._index is not None
        records, kernel = ch._lines[:2]
        for t0 in (0.0, 1.3, 7.77):
            pos = sim.positions(t0)
            for src in range(0, 60, 3):
                near = ch._index.neighbourhood(src, t0, 60, sim.positions)
                bottom = ch.ssp.bottom
                statuses[kernel(records, near, t0, C, bottom, RANGE**2, FIXED_POINT_TOL_S)[0]] += 1
                ids, heard, lost = ch._links(src, t0)
                d = np.linalg.norm(pos - pos[src], axis=1)
                d[src] = np.inf
                assert sorted(ids) == np.flatnonzero(d <= RANGE).tolist()
                seen["out_of_range"] += int((d > RANGE).sum() - 1)
                seen["lost"] += len(lost)
                for j, tof, _path, _snr in heard:
                    seen["heard"] += 1

                    def gap(tau, j=j):
                        here = sim.positions_at(np.array([j]), np.array([t0 + tau]))[0]
                        return C * tau - np.linalg.norm(here - pos[src])

                    tau = brentq(gap, 0.0, 2.0 * RANGE / C + 1.0, xtol=1e-15, rtol=1e-15)
                    assert abs(tof - tau) <= FIXED_POINT_TOL_S
    assert statuses[OK] > 100 and statuses[FALLBACK] > 10, statuses
    assert min(seen.values()) > 10, seen


@settings(max_examples=30)
@given(seed=st.integers(0, 2**31 - 1), scale=st.sampled_from([1.0, 1e3, 1e6]))
def test_kernel_pieces_are_numpy_bit_for_bit(seed, scale):
    """The fold (positions and velocities, any number of bounces) against ``Box.fold`` through
    the model, and the closed-form root against ``acoustic._constant_moving_root``."""
    rng = np.random.default_rng(seed)
    box = Box(rng.uniform(-50.0, 0.0, 3) * [1, 1, 0], rng.uniform(10.0, 300.0, 3))
    n = 64
    model = ConstantVelocity(rng.uniform(box.lo, box.hi, (n, 3)), box, velocity=rng.normal(0.0, 3.0, (n, 3)))
    rec = np.ascontiguousarray(model.line_records())
    t = rng.uniform(0.0, scale, n)
    pos, vel = model.state_at(np.arange(n), t)
    got = np.array([[_fold(rec[i], t[i], j) for j in range(3)] for i in range(n)])
    assert np.array_equal(got[:, :, 0], pos) and np.array_equal(got[:, :, 1], vel)
    d = rng.normal(0.0, scale, (n, 3))
    v = rng.normal(0.0, 1.0, (n, 3))
    v *= rng.uniform(0.0, 0.5 * C, (n, 1)) / np.linalg.norm(v, axis=1)[:, None]
    mine = np.array([_root(C, *d[i], *v[i]) for i in range(n)])
    assert np.array_equal(mine, acoustic._constant_moving_root(C, d, v))
    assert math.isnan(_root(C, *d[0], *(v[0] * (0.51 * C / np.linalg.norm(v[0])))))  # faster than c / 2


@settings(max_examples=30)
@given(seed=st.integers(0, 2**31 - 1), m=st.integers(0, 40))
def test_by_arrival_is_physical_snr_and_a_stable_sort(seed, m):
    rng = np.random.default_rng(seed)
    cfg = ChannelConfig(frequency_khz=float(rng.uniform(5.0, 30.0)), spreading=float(rng.choice([1.0, 1.5, 2.0])))
    length = rng.uniform(0.0, 3000.0, m)
    length[: m // 4] = rng.uniform(0.0, 1.0, m // 4)  # under the loss model's 1 m reference
    time = np.round(length / C, 3)  # ties, for the stability of the sort
    cand = rng.permutation(1000)[:m]
    noise, band, alpha, k10 = acoustic._snr_constants(cfg)
    terms = np.array([k10, alpha, cfg.source_level_db, noise, band], dtype=float)
    thr = float(rng.uniform(0.0, 60.0))
    snr, lost, ids, t_s, snr_s = by_arrival(cand, time, length, np.log10(np.maximum(length, 1.0)), terms, thr)
    ref = acoustic._snr_of_length(length, cfg)
    assert np.array_equal(snr, ref) and lost == int((ref < thr).sum())
    heard = sorted(zip(cand.tolist(), time.tolist(), ref.tolist()), key=lambda h: h[1])
    assert list(zip(ids.tolist(), t_s.tolist(), snr_s.tolist())) == heard


def test_kernel_matches_the_fold_of_the_model():
    """The sender's and receivers' folded positions the kernel uses are the model's: a lone
    receiver with a wall bounce mid-flight falls back, one far from the walls does not."""
    box = Box([0.0, 0.0, 0.0], [1000.0, 1000.0, 200.0])
    p0 = np.array([[500.0, 500.0, 100.0], [700.0, 500.0, 100.0], [999.9, 500.0, 100.0]])
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    rec = np.ascontiguousarray(ConstantVelocity(p0, box, velocity=v).line_records())
    status, cand, t, length, diff = straight_links(rec, np.array([0, 1]), 0.0, C, np.inf, 300.0**2, 1e-10)
    assert status == OK and cand.tolist() == [1]
    tau = brentq(lambda s: C * s - (200.0 + s), 0.0, 1.0, xtol=1e-15)
    assert abs(t[0] - tau) < 1e-12 and length[0] == C * t[0] and diff[0, 1:].tolist() == [0.0, 0.0]
    # node 2 reaches the wall at x = 1000 m 0.1 s after the send, while the sound is under way
    assert straight_links(rec, np.array([0, 2]), 0.0, C, np.inf, 600.0**2, 1e-10)[0] == FALLBACK


def test_numba_is_imported_only_by_runs_that_take_the_compiled_path():
    code = textwrap.dedent(
        """
        import json, sys
        from aquasim_py.channel import Constant
        from aquasim_py.kernel import Simulation
        from aquasim_py.mobility import Box, ConstantVelocity, RandomWalk
        from aquasim_py.node import Node

        class Ping(Node):
            name = "ping"

            def run(self):
                while True:
                    yield self.broadcast("ping", None, 64)
                    yield self.sleep(0.5)

        box = Box([0, 0, 0], [2000, 2000, 200])
        p = [[100.0 * i, 50.0, 50.0] for i in range(5)]
        out = []
        for kind in ("static", "walk", "line"):
            sim = Simulation(1, ssp=Constant(1500.0), volume=box)
            if kind == "static":
                sim.add_group(Ping, 5, positions=p)
            elif kind == "walk":
                sim.add_group(Ping, 5, mobility=lambda r: RandomWalk(p, box, r))
            else:
                sim.add_group(Ping, 5, mobility=ConstantVelocity(p, box, velocity=[1.0, 0.0, 0.0]))
            sim.run(3.0)
            out.append("numba" in sys.modules)
        print(json.dumps(out))
        """
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, check=False)
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout) == [False, False, True]
