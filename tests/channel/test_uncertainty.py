"""Sound-speed uncertainty (aquasim_py/channel/uncertainty.py) and its hook in the channel.

References: the delay through water of speed c + dc is L / (c + dc) for the ray length
L = c T (written out here, not the module's formula); the Ornstein-Uhlenbeck transition's
variance and lag correlation exp(-dt / tau) in closed form; the range error of a one-way ToA
converted at the nominal speed, R (c / (c + dc) - 1), whose std is R sigma / c to first order
(relative error ~ sigma^2 / c^2 = 4e-5, far below the sampling tolerances used)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from aquasim_py.channel import Constant
from aquasim_py.channel.config import ChannelConfig
from aquasim_py.channel.uncertainty import SoundSpeedUncertainty, ou_step, perturbed_delay
from aquasim_py.kernel import Simulation
from aquasim_py.node import Node

C = 1500.0


@given(
    t=st.floats(1e-4, 10.0),
    c=st.floats(1400.0, 1600.0),
    dc=st.floats(-50.0, 50.0),
)
@settings(max_examples=50, deadline=None)
def test_perturbed_delay_is_length_over_speed(t, c, dc):
    length = t * c
    assert perturbed_delay(t, c, dc) == pytest.approx(length / (c + dc), rel=1e-12)


def test_zero_deviation_and_no_path_are_untouched():
    t = np.array([0.01, np.nan, 0.3333333333333333])
    out = perturbed_delay(t, 1500.0, np.zeros(3))
    assert np.array_equal(out, t, equal_nan=True)  # bit for bit
    assert np.isnan(perturbed_delay(np.nan, 1500.0, 5.0))


def test_ou_transition_variance_and_correlation():
    """Stationary start, one step of dt: variance std^2 and correlation exp(-dt/tau) (closed
    forms); tolerances are 5 standard errors of the estimates for n = 200 000."""
    rng = np.random.default_rng(1)
    n, std, tau, dt = 200_000, 10.0, 30.0, 12.0
    x0 = std * rng.standard_normal(n)
    x1 = ou_step(x0, dt, tau, std, rng.standard_normal(n))
    assert np.var(x1) == pytest.approx(std**2, rel=5 * np.sqrt(2 / n))
    rho = np.exp(-dt / tau)
    assert np.corrcoef(x0, x1)[0, 1] == pytest.approx(rho, abs=5 * (1 - rho**2) / np.sqrt(n))
    # tau = 0: independent draws, exactly std * xi
    xi = rng.standard_normal(5)
    assert np.array_equal(ou_step(x0[:5], dt, 0.0, std, xi), std * xi)


def test_links_share_state_in_both_directions():
    u = SoundSpeedUncertainty(10.0, 1e9, np.random.default_rng(2))
    a = u.deviations(0.0, 3, np.array([5]))
    b = u.deviations(1.0, 5, np.array([3]))  # same link, reverse direction, tau >> dt
    assert b == pytest.approx(a, abs=1e-3)
    with pytest.raises(ValueError):
        SoundSpeedUncertainty(-1.0, 0.0, np.random.default_rng(0))


# -- the channel hook --------------------------------------------------------------------------

R = 1000.0
N_RX = 200
SENDS = 10


class Pinger(Node):
    name = "pinger_ssu"

    def run(self):
        for _ in range(SENDS):
            yield self.sleep(2.0)
            yield self.broadcast("ping", {}, 64)


class Ear(Node):
    name = "ear_ssu"

    def run(self):
        while True:
            yield self.recv()


def _packets(**cfg):
    sim = Simulation(7, ssp=Constant(C), channel=ChannelConfig(collision="none", max_range_m=2 * R, **cfg))
    ang = np.linspace(0.0, 2 * np.pi, N_RX, endpoint=False)
    ring = np.c_[R * np.cos(ang), R * np.sin(ang), np.full(N_RX, 50.0)]
    sim.add_group(Pinger, 1, positions=[[0.0, 0.0, 50.0]])
    sim.add_group(Ear, N_RX, positions=ring)
    sim.run(SENDS * 2.0 + 3.0)
    return sim.trace.frames()["packets"]


def test_std_zero_is_bit_identical():
    base = _packets()
    same = _packets(sound_speed_std_mps=0.0, sound_speed_corr_s=30.0)
    pd.testing.assert_frame_equal(base, same)
    rx = base[base.event == "rx"]
    assert np.allclose(rx.tof, R / C, rtol=0, atol=1e-12)


def test_one_way_toa_range_error_spread():
    """std of (tof x 1500 - R) over 2000 receptions ~ R x 10 / 1500; tolerance 4 standard
    errors of a sample std (relative SE 1/sqrt(2(n-1)))."""
    base = _packets()
    p = _packets(sound_speed_std_mps=10.0)
    # no other random stream moved: same transmissions, same receptions
    pd.testing.assert_frame_equal(
        p[p.event == "tx"].reset_index(drop=True), base[base.event == "tx"].reset_index(drop=True)
    )
    rx = p[p.event == "rx"]
    assert len(rx) == SENDS * N_RX
    key = ["uid", "node"]
    got = rx[key].sort_values(key).to_numpy()
    assert (got == base[base.event == "rx"][key].sort_values(key).to_numpy()).all()
    err = rx.tof.to_numpy() * C - R
    n = err.size
    want = R * 10.0 / C
    assert err.std(ddof=1) == pytest.approx(want, rel=4 / np.sqrt(2 * (n - 1)))
    assert abs(err.mean()) < 4 * want / np.sqrt(n)


def test_correlated_links_repeat_their_error():
    """tau >> the 2 s between pings: each link's error repeats (correlation ~ exp(-2/1e6))."""
    p = _packets(sound_speed_std_mps=10.0, sound_speed_corr_s=1e6)
    rx = p[p.event == "rx"].sort_values(["node", "time"])
    err = (rx.tof.to_numpy() * C - R).reshape(N_RX, SENDS)
    assert np.corrcoef(err[:, 0], err[:, -1])[0, 1] > 0.99
