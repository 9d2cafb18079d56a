"""Who hears a transmission, and when, in a network of fast nodes on box-folded straight lines,
against brute force: the range test against every node's distance at the send time, and each
delay against brentq on the receiver's true (folded) trajectory.

The networks are small boxes with fast nodes, a sea floor above the box's bottom and a few
nodes faster than c / 2, so that wall bounces during a flight, receivers out of the water,
shadowed links and out-of-range nodes all occur (the test checks that they do)."""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.channel.fixed_point import FIXED_POINT_TOL_S
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


def _network(seed: int, n: int, speed: float, groups: int) -> Simulation:
    """n nodes in a 800 m x 800 m x 120 m box (sea floor at 116 m), random headings at up to
    ``speed`` m/s (vertical component a fifth), 1 % at 800 m/s (faster than c / 2), split into
    ``groups`` groups (the last with its own smaller box)."""
    rng = np.random.default_rng(seed)
    boxes = [Box([0.0, 0.0, 0.0], [800.0, 800.0, 120.0]), Box([50.0, 20.0, 0.0], [650.0, 780.0, 90.0])]
    sim = Simulation(
        seed,
        ssp=Constant(C, bottom=116.0),
        volume=boxes[0],
        channel=ChannelConfig(max_range_m=RANGE, collision="none"),
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


def test_links_against_brute_force():
    seen = {"heard": 0, "lost": 0, "out_of_range": 0}
    for seed in range(4):
        sim = _network(seed, 60, 60.0, 1 + seed % 2)
        ch = sim.channel
        for t0 in (0.0, 1.3, 7.77):
            pos = sim.positions(t0)
            for src in range(0, 60, 3):
                ids, heard, lost = ch.links.links(src, t0, 60)
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
    assert min(seen.values()) > 10, seen


def test_a_fixed_point_without_convergence_keeps_the_last_iterate(monkeypatch):
    """Where the arrival-time iteration does not settle (no fixed point: the first eigenray
    switching paths across the receiver's track), the link keeps the last iterate's stamp and
    the transmission is counted in ``unconverged``; the run goes on (no iteration at all here)."""
    import aquasim_py.channel.links as links_mod
    from aquasim_py.channel import Layered

    sim = Simulation(
        1,
        ssp=Layered([0.0, 50.0, 120.0], [1520.0, 1490.0, 1495.0], bottom=120.0),
        volume=Box([0.0, 0.0, 0.0], [800.0, 800.0, 120.0]),
        channel=ChannelConfig(max_range_m=RANGE, collision="none"),
    )
    p0 = np.array([[100.0, 100.0, 30.0], [200.0, 150.0, 60.0], [150.0, 250.0, 40.0]])
    v = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [-1.0, 1.0, 0.0]])
    sim.add_group(Idle, 3, mobility=ConstantVelocity(p0, Box([0.0, 0.0, 0.0], [800.0, 800.0, 120.0]), velocity=v))
    monkeypatch.setattr(links_mod, "MAX_ITER", 0)
    ids, heard, _lost = sim.channel.links.links(0, 0.5, 3)
    assert sorted(ids) == [1, 2] and len(heard) == 2
    assert all(np.isfinite(tof) for _j, tof, _p, _s in heard)
    assert sim.channel.links.unconverged == 1
