"""Mobi-Sync: the spatial-correlation velocity estimate, and where it beats MU-Sync."""

import tomllib
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from aquasim_protocols.itmtl.metrics import protocol_metrics
from aquasim_protocols.itmtl.mobi_sync import correlation_weights
from aquasim_py import scenario
from aquasim_py.estimation.sync import neighbour_velocity

SCEN = Path(__file__).resolve().parents[2] / "scenarios" / "itmtl.toml"


@given(st.lists(st.floats(0.0, 5000.0), min_size=2, max_size=8), st.floats(10.0, 5000.0))
def test_weights_fall_with_distance(d, length):
    d = np.sort(np.asarray(d))
    w = correlation_weights(d, length)
    assert np.all(np.diff(w) <= 0.0)
    assert np.all((w > 0.0) & (w <= 1.0))


def test_velocity_is_the_correlation_weighted_mean():
    v = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    w = correlation_weights(np.array([0.0, 1000.0]), 1000.0)  # 1 and 1/e
    got = neighbour_velocity(v, w)
    e = np.exp(-1.0)
    np.testing.assert_allclose(got, [1.0 / (1.0 + e), e / (1.0 + e), 0.0], rtol=1e-12)


def _drifting(protocol: str, seed: int) -> dict:
    """Buoys (GPS + velocity sensor) and sensors drifting in the same current at full tide
    (~1 m/s, spatially correlated): Mobi-Sync's assumption holds."""
    raw = tomllib.loads(SCEN.read_text())
    raw.pop("variants", None)
    raw["simulation"].update(seed=seed, duration_s=300.0)
    raw["environment"]["sound_speed"] = {"model": "constant", "speed_mps": 1500.0}
    cur = {"model": "kinematic", "phase": 0.0}
    raw["nodes"] = [
        {
            "name": "buoys",
            "role": "buoy",
            "protocol": protocol,
            "placement": {
                "kind": "explicit",
                "positions": [[500.0, 500.0, 5.0], [1500.0, 500.0, 5.0], [500.0, 1500.0, 5.0], [1500.0, 1500.0, 5.0]],
            },
            "mobility": cur,
            "sensors": {"velocity_noise_std_mps": 0.02},
        },
        {
            "name": "sensors",
            "role": "ordinary",
            "protocol": protocol,
            "placement": {"kind": "explicit", "positions": [[900.0, 900.0, 100.0], [1100.0, 1000.0, 200.0]]},
            "mobility": cur,
            "clock": {"skew_ppm": 40.0, "skew_std_ppm": 10.0, "offset_s": 0.5, "offset_std_s": 0.2},
            "sensors": {"depth_noise_std_m": 0.1},
            "params": {"mean_speed_mps": 1500.0},
        },
    ]
    return raw


def _sync_error(protocol: str, seed: int) -> float:
    raw = _drifting(protocol, seed)
    sim = scenario.build(scenario.load_dict(raw, SCEN))
    sim.run(raw["simulation"]["duration_s"])
    return protocol_metrics(sim.trace.frames(), protocol)["sync_final_mean_all_s"]


def test_mobi_sync_beats_mu_sync_with_drifting_references():
    """With references drifting alike, the half round trip of MU-Sync is biased by the
    motion (~2 d v / c^2 per exchange); Mobi-Sync's correlated velocity removes most of it."""
    mobi, mu = _sync_error("mobi_sync", 1), _sync_error("mu_sync", 1)
    assert mobi < 0.8 * mu


@pytest.mark.slow
def test_mobi_sync_beats_mu_sync_over_seeds():
    seeds = range(1, 6)
    mobi = [_sync_error("mobi_sync", s) for s in seeds]
    mu = [_sync_error("mu_sync", s) for s in seeds]
    assert np.mean(mobi) < 0.8 * np.mean(mu)
    assert sum(a < b for a, b in zip(mobi, mu, strict=True)) >= 4
