"""Obstacle model: obstructed links get exactly the configured extra loss and excess delay,
the random part of the delay is half-normal per packet from the link's own stream, each link
is decided from its own stream, and without obstacles the channel is unchanged."""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

import numpy as np
import pytest
from scipy import stats

from aquasim_py.channel.config import ChannelConfig
from aquasim_py.channel.obstacles import ObstacleConfig, ObstacleField
from aquasim_py.channel.ssp import Constant
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node

PINGS = 3


class _Pinger(Node):
    name = "test_obstacle_pinger"

    def run(self) -> Generator[Any, Any, None]:
        if self.id == 0:
            for _ in range(PINGS):
                yield self.broadcast("ping", bits=100)
                yield self.sleep(1.0)


def _packets(obstacles: ObstacleConfig | None, seed: int = 7):
    sim = Simulation(seed, ssp=Constant(1500.0), channel=ChannelConfig(collision="none", obstacles=obstacles))
    pos = np.array([[0.0, 0, 50], [300, 0, 50], [0, 400, 60], [200, 200, 40]])
    sim.add_group(_Pinger, 4, role="anchor", positions=pos)
    sim.run(3.5)
    pk = sim.trace.frames()["packets"]
    return pk[pk["event"] == "rx"].reset_index(drop=True)


def test_no_obstacles_leaves_the_channel_bit_identical():
    base = _packets(None)
    assert base.equals(_packets(ObstacleConfig()))  # configured but inactive
    assert base.equals(_packets(ObstacleConfig(probability=0.0, extra_loss_db=30.0)))


def test_obstructed_link_gets_exactly_the_excess_delay_and_loss():
    base = _packets(None)
    cfg = ObstacleConfig(links=((2, 0),), extra_loss_db=25.0, excess_delay_s=0.01, excess_delay_ratio=0.2)
    got = _packets(cfg)
    blocked = got["node"] == 2
    b0 = base[base["node"] == 2]
    np.testing.assert_allclose(got.loc[blocked, "tof"], b0["tof"].to_numpy() * 1.2 + 0.01, rtol=1e-15)
    np.testing.assert_allclose(got.loc[blocked, "snr_db"], b0["snr_db"].to_numpy() - 25.0, rtol=1e-15)
    # the other links are untouched, bit for bit
    assert got[~blocked].reset_index(drop=True).equals(base[base["node"] != 2].reset_index(drop=True))


def test_random_excess_delay_varies_per_packet_on_its_own_link_stream():
    base = _packets(None)
    one = _packets(ObstacleConfig(links=((2, 0),), extra_loss_db=25.0, excess_delay_sigma_ratio=0.25))
    two = _packets(ObstacleConfig(links=((2, 0), (3, 0)), extra_loss_db=25.0, excess_delay_sigma_ratio=0.25))
    assert one.equals(_packets(ObstacleConfig(links=((2, 0),), extra_loss_db=25.0, excess_delay_sigma_ratio=0.25)))
    at2 = one["node"] == 2
    late = one.loc[at2, "tof"].to_numpy() - base.loc[base["node"] == 2, "tof"].to_numpy()
    # late, never early, and drawn anew for each of the pings of a static network (no cache)
    assert late.size == PINGS and (late > 0).all() and np.unique(late).size == PINGS
    # node 2's draws do not move when another link is obstructed too; clear links untouched
    np.testing.assert_array_equal(two.loc[two["node"] == 2, "tof"].to_numpy(), one.loc[at2, "tof"].to_numpy())
    assert one[~at2].reset_index(drop=True).equals(base[base["node"] != 2].reset_index(drop=True))


def test_random_excess_delay_is_half_normal_with_the_configured_scale():
    # eq: delay = T (1 + ratio + sigma |g|); KS test of (delay / T - 1 - ratio) / sigma against
    # the half-normal (scipy's halfnorm); a Gaussian (signed) or mis-scaled draw fails at n = 4000
    cfg = ObstacleConfig(links=((0, 1),), excess_delay_ratio=0.1, excess_delay_sigma_ratio=0.25)
    field = ObstacleField(cfg, lambda a, b: 0.0, lambda a, b: np.random.default_rng([5, a, b]))
    T = np.array([0.02, 0.03])
    u = np.array([field.apply(0, np.array([1, 2]), T, np.zeros(2))[0] for _ in range(4000)])
    np.testing.assert_array_equal(u[:, 1], T[1])  # link {0, 2} is clear
    g = (u[:, 0] / T[0] - 1.1) / 0.25
    assert stats.kstest(g, stats.halfnorm.cdf).pvalue > 1e-3
    assert stats.kstest(np.abs(g) * 1.2, stats.halfnorm.cdf).pvalue < 1e-6  # the test can tell the scale


def test_link_decisions_come_from_per_link_streams():
    def uniform(a: int, b: int) -> float:
        return float(np.random.default_rng([11, a, b]).random())

    cfg = ObstacleConfig(probability=0.3)
    f1, f2 = ObstacleField(cfg, uniform), ObstacleField(cfg, uniform)
    ids = np.arange(1, 200)
    m1 = f1.mask(0, ids)
    m2 = f2.mask(0, ids[::-1])[::-1]  # another query order
    np.testing.assert_array_equal(m1, m2)
    assert f1.obstructed(5, 0) == f1.obstructed(0, 5)  # undirected
    # the share is Binomial(199, 0.3): inside its 99.9 % interval
    lo, hi = stats.binom.interval(0.999, ids.size, 0.3)
    assert lo <= m1.sum() <= hi
    only = ObstacleField(ObstacleConfig(probability=1.0, nodes=(7,)), uniform)
    assert only.obstructed(7, 3) and not only.obstructed(2, 3)


@pytest.mark.parametrize(
    "kwargs",
    [
        dict(probability=1.5),
        dict(extra_loss_db=-1.0),
        dict(links=((3, 3),)),
        dict(excess_delay_s=np.inf),
        dict(excess_delay_sigma_ratio=-0.25),
    ],
)
def test_bad_obstacle_config_is_rejected(kwargs):
    with pytest.raises(ValueError, match="obstacles"):
        ObstacleConfig(**kwargs)
