"""Speed bounds of the current-driven models (Kinematic, MeanderingJet): never below a dense
brute-force sampling of the field, of its acceleration along a path, and of the interpolated
trajectories' speeds and displacements; and the channel's packets on a kinematic network are
the same whether or not the bound gives it a neighbour index."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
import pytest

from aquasim_py.channel import Constant
from aquasim_py.channel.acoustic import ChannelConfig
from aquasim_py.kernel import Simulation
from aquasim_py.mobility import _ETA_SECH2, Box, Kinematic, MeanderingJet
from aquasim_py.node import Node

BOX = Box((0.0, 0.0, 20.0), (500.0, 500.0, 30.0))
HUGE = Box((-1e7, -1e7, 0.0), (1e7, 1e7, 1e7))


def _nodes(n: int, seed: int) -> np.ndarray:
    return np.random.default_rng(seed).uniform(BOX.lo, BOX.hi, (n, 3))


def _kinematic(n: int = 12, seed: int = 3, **kw: Any) -> Kinematic:
    # rel_std 0.3: parameters far from the means, some with other signs' magnitudes
    return Kinematic(_nodes(n, seed), kw.pop("box", BOX), np.random.default_rng(seed + 1), rel_std=0.3, **kw)


def _field_grid(count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """Random dimensionless (x', y') and t' covering many periods of the field."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-20.0, 20.0, (count, 2)), rng.uniform(0.0, 100.0, count)


def _kinematic_node_field(m: Kinematic, j: int, x: np.ndarray, y: np.ndarray, tp: np.ndarray) -> np.ndarray:
    """Node j's dimensionless field, written out independently of the model's code."""
    k1, k2, k3, io, om, k4, k5 = (float(getattr(m, a)[j]) for a in ("k1", "k2", "k3", "iota", "omega", "k4", "k5"))
    vx = k1 * io * om * np.sin(k2 * x) * np.cos(k3 * y) + k1 * io * np.cos(2 * k1 * tp) + k4
    vy = -io * om * np.cos(k2 * x) * np.sin(k3 * y) + k5
    return np.stack([vx, vy], axis=-1)


def test_kinematic_field_bounds_hold_on_dense_samples() -> None:
    m = _kinematic()
    v_bound, a_bound = m._field_bounds()
    for j in range(m.n):
        xy, tp = _field_grid(200_000, j)
        v = _kinematic_node_field(m, j, xy[:, 0], xy[:, 1], tp)
        speed = np.hypot(v[:, 0], v[:, 1])
        assert speed.max() <= v_bound[j]
        # the bound is not loose: sin, cos and the tide line up at some point of the plane
        assert speed.max() >= 0.9 * v_bound[j]
        # acceleration along the path, D v / D t' = (v(p + v d, t' + d) - v(p, t')) / d
        d = 1e-7
        ahead = _kinematic_node_field(m, j, xy[:, 0] + v[:, 0] * d, xy[:, 1] + v[:, 1] * d, tp + d)
        acc = np.hypot(*((ahead - v) / d).T)
        assert acc.max() <= a_bound[j] * (1.0 + 1e-6)


def test_jet_field_bound_holds_on_dense_samples() -> None:
    eta = np.linspace(0.0, 10.0, 2_000_001)
    assert (eta / np.cosh(eta) ** 2).max() <= _ETA_SECH2 < (eta / np.cosh(eta) ** 2).max() + 1e-4
    for amplitude, wavelength, epsilon in ((1.2, 7.5, 0.3), (2.5, 3.0, 0.8)):  # Caruso's defaults, another
        m = MeanderingJet(_nodes(3, 0), BOX, None, amplitude=amplitude, wavelength=wavelength, epsilon=epsilon)
        v_bound, a_bound = m._field_bounds()
        assert np.isinf(a_bound).all()
        rng = np.random.default_rng(1)
        x, y = rng.uniform(-20.0, 20.0, (2, 400_000))
        y[::2] = rng.uniform(-4.0, 4.0, 200_000)  # half of the samples near the jet's axis
        tp = rng.uniform(0.0, 200.0, 400_000)
        u, v = m._dimensionless(x, y, tp)
        assert np.hypot(u, v).max() <= v_bound[0]


@pytest.mark.parametrize(
    "make",
    [
        _kinematic,
        lambda: _kinematic(box=HUGE, steps_per_unit=16),  # coarse table: the 2 V fallback
        lambda: MeanderingJet(_nodes(12, 5), BOX, None, origin=(250.0, 250.0), length_scale=300.0, time_scale=200.0),
    ],
)
def test_trajectory_speeds_and_displacements_stay_under_max_speed(make: Any) -> None:
    m = make()
    vmax = m.max_speed()
    assert 0.0 < vmax < np.inf
    # dense in time over several table steps and a long stretch of the run
    times = np.concatenate([np.linspace(0.0, 40.0 * m._h, 4001), np.linspace(0.0, 3000.0, 3001)])
    idx = np.repeat(np.arange(m.n), times.size)
    ts = np.tile(times, m.n)
    pos, vel = m.state_at(idx, ts)
    speed = np.linalg.norm(vel, axis=1)
    assert speed.max() <= vmax
    # what the neighbour index relies on: |q(t) - q(s)| <= vmax |t - s|
    for j in range(m.n):
        p = pos[j * times.size : (j + 1) * times.size]
        step = np.linalg.norm(np.diff(p, axis=0), axis=1)
        dt = np.diff(times)
        ok = dt > 0
        assert np.all(step[ok] <= vmax * dt[ok] + 1e-9)


def test_kinematic_bound_beats_the_generic_factor_two() -> None:
    """At the scenario's table resolution V + A h / 2 is within 2 % of V (not the 2 V fallback)."""
    m = Kinematic(_nodes(200, 1), BOX, np.random.default_rng(2))  # the Table-1 defaults
    v_bound, _ = m._field_bounds()
    assert m.max_speed() <= 1.02 * float(v_bound.max()) * m._speed_scale


class _Chatter(Node):
    """Broadcasts every 0.5 s from a random phase and drains its inbox."""

    name = "test_current_speed_bound_chatter"

    def run(self) -> Any:
        self.env.process(self._drain())
        yield self.sleep(float(self.rng.uniform(0.0, 0.5)))
        while True:
            yield self.broadcast("hello", None, 32)
            yield self.sleep(0.5)

    def _drain(self) -> Any:
        while True:
            yield self.recv()


def _packets(bounded: bool, monkeypatch: pytest.MonkeyPatch) -> tuple[pd.DataFrame, float]:
    if not bounded:  # no speed bound: the channel tests every node on every transmission
        monkeypatch.setattr(Simulation, "max_speed", lambda self: float("inf"))
    sim = Simulation(7, ssp=Constant(1500.0), volume=BOX, channel=ChannelConfig(max_range_m=80.0, bitrate_bps=10000.0))
    # a fast current (about 10 m/s): the index is rebuilt every 0.1-0.2 s and nodes cross it
    mob = Kinematic(_nodes(60, 11), BOX, np.random.default_rng(12), length_scale=447.12)
    sim.add_group(_Chatter, 60, mobility=mob)
    sim.run(6.0)
    vmax = sim.max_speed()
    monkeypatch.undo()
    return sim.trace.frames()["packets"], vmax


def test_channel_packets_identical_with_and_without_the_index(monkeypatch: pytest.MonkeyPatch) -> None:
    with_index, vmax = _packets(True, monkeypatch)
    without, inf = _packets(False, monkeypatch)
    assert np.isfinite(vmax) and np.isinf(inf)
    assert (with_index["event"] == "rx").sum() > 1000
    pd.testing.assert_frame_equal(with_index, without)
