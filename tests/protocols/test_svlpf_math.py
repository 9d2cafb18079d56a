"""SVL-PF maths against independent references: the bordered KKT system, a smooth function,
the propagation-loss model, brute-force likelihoods, noiseless multilateration, Table 1."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import linalg, stats

from aquasim_protocols.svlpf import math as sv

ROOT = Path(__file__).resolve().parents[2]


def _geometry():
    spec = importlib.util.spec_from_file_location("svlpf_geometry", ROOT / "tools" / "svlpf_geometry.py")
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    return mod


# ------------------------------------------------------------------------- LSSVR
def test_lssvr_block_elimination_solves_the_bordered_kkt_system():
    rng = np.random.default_rng(1)
    X = rng.uniform(0, 50, (80, 4))
    Y = rng.normal(size=(80, 3))
    m = sv.lssvr_fit(X, Y, c=50.0, width=15.0)
    # eq 17 as printed, solved directly
    J = len(X)
    A = np.zeros((J + 1, J + 1))
    A[0, 1:] = A[1:, 0] = 1.0
    A[1:, 1:] = sv.rbf_kernel(X, X, 15.0) + np.eye(J) / 50.0
    ref = linalg.solve(A, np.vstack([np.zeros((1, 3)), Y]))
    # both are backward-stable solves of a system with condition number ~ C J: agree to ~1e-10
    np.testing.assert_allclose(m.b, ref[0], atol=1e-9)
    np.testing.assert_allclose(m.alpha, ref[1:], atol=1e-9)


def test_lssvr_recovers_a_smooth_function_on_noiseless_data():
    rng = np.random.default_rng(2)

    def f(x):
        return np.column_stack([np.sin(x[:, 0]) + 0.5 * np.cos(2 * x[:, 1]), x[:, 0] * x[:, 1] / 4])

    X = rng.uniform(-2, 2, (400, 2))
    m = sv.lssvr_fit(X, f(X), c=1e7, width=0.6)
    Xt = rng.uniform(-1.8, 1.8, (200, 2))
    # RBF interpolation of an analytic function at this density (~0.2 spacing, width 0.6)
    # converges spectrally; 1e-3 is far above its error and far below the function's scale (1)
    err = np.abs(sv.lssvr_predict(m, Xt) - f(Xt)).max()
    assert err < 1e-3
    # and it is a regression, not a constant: far from the data it returns the bias b
    np.testing.assert_allclose(sv.lssvr_predict(m, np.array([100.0, 100.0])), m.b, atol=1e-12)


# ------------------------------------------------------------------------- diagnosis, eqs 23-26
@settings(max_examples=60, deadline=None)
@given(
    r=st.lists(st.floats(5.0, 150.0), min_size=3, max_size=12),
    flags=st.lists(st.booleans(), min_size=12, max_size=12),
    noise=st.lists(st.floats(-0.3, 0.3), min_size=12, max_size=12),
)
def test_diagnosis_flags_exactly_the_links_given_excess_loss(r, flags, noise):
    r = np.array(r)
    m = np.array(flags[: len(r)])
    R = r * (1.0 + np.array(noise[: len(r)]))  # measured distances up to 30 % off
    beta = 1.187
    # observed loss TIL - RIL: the true path's eq-24 loss plus 30 dB on the obstructed links
    loss = sv.propagation_loss_db(r, beta) + 30.0 * m
    # |20 log10(r / R)| <= 3.1 dB << p tau(R) >= 0.5 * 20 log10(3.5) = 5.4 dB <= 30 - 3.1 dB
    np.testing.assert_array_equal(sv.diagnose(loss, R, p_hat=0.5, beta_db_per_km=beta, excess=True), m)
    # as printed, TIL - RIL >= p tau(R) holds on every link (the loss is about tau itself)
    assert sv.diagnose(loss, R, p_hat=0.5, beta_db_per_km=beta).all()


def test_delta_weights_eq26():
    R = np.array([40.0, 20.0, 30.0])
    flags = np.array([True, True, False])
    d = sv.delta_weights(R, np.array([50.0, 50.0, 50.0]), flags, clip=True)
    np.testing.assert_allclose(d, [10 / 40, 1.0, 1.0])  # 30/20 > 1 is clipped; unflagged = 1
    printed = sv.delta_weights(R, np.array([50.0, 50.0, 50.0]), flags)
    np.testing.assert_allclose(printed, [10 / 40, 30 / 20, 1.0])


# ------------------------------------------------------------------------- iterative regression
def _subset_model():
    S = np.array([[10.0, 10, 10], [60, 20, 30], [20, 70, 40], [50, 50, 80], [80, 80, 20]])
    X, Y = sv.lssvr_training_set(S, [0, 0, 0], [100, 100, 100], 400, np.random.default_rng(3))
    return S, sv.lssvr_fit(X, Y, c=1e3, width=25.0)


def test_iterative_regression_stops_at_the_first_iterate_meeting_eq27():
    S, m = _subset_model()
    x = np.array([55.0, 45.0, 50.0])
    R = np.linalg.norm(S - x, axis=1)
    R[1] *= 1.6  # a distorted link
    delta = sv.delta_weights(R, m.mean_input, np.array([False, True, False, False, False]))
    res = sv.iterative_regression(m, R, S, delta, eps_b=1.0, eps_step=0.2, max_iter=200, repaired=True)
    assert res.converged and res.iterations == len(res.steps)
    meets = (res.dist_b >= 1.0) & (res.steps <= 0.2)
    assert meets[-1] and not meets[:-1].any()
    # the repaired observation is closer to the truth than the plain LSSVR one (eq 20)
    assert np.linalg.norm(res.z - x) < np.linalg.norm(sv.lssvr_predict(m, R) - x)


def test_iterative_regression_as_printed_is_the_observation_at_delta_r():
    """Eq 21 as printed: Z^(nu+1) = f(delta R) whatever nu; eq 27 stops it once a step is 0."""
    S, m = _subset_model()
    R = np.linalg.norm(S - np.array([55.0, 45.0, 50.0]), axis=1)
    delta = np.array([1.0, 0.4, 1.0, 1.0, 1.0])
    res = sv.iterative_regression(m, R, S, delta, eps_b=1.0, eps_step=0.2, max_iter=50)
    np.testing.assert_array_equal(res.z, sv.lssvr_predict(m, delta * R))
    assert res.converged and res.iterations <= 2 and res.steps[-1] == 0.0


def test_iterative_regression_does_not_stop_near_b_eq27_guard():
    S, m = _subset_model()
    flat = sv.LssvrModel(m.X, np.zeros_like(m.alpha), m.b, m.width, m.mean_input)  # Z = b always
    R = np.linalg.norm(S - 50.0, axis=1)
    res = sv.iterative_regression(flat, R, S, np.ones(5), eps_b=1.0, eps_step=0.2, max_iter=7)
    # every step is 0 (<= eps_step) but Z never leaves b: the plain rule would stop at once
    assert not res.converged and res.iterations == 7 and np.all(res.steps == 0.0)


def test_iterative_regression_without_flags_is_the_lssvr_observation():
    S, m = _subset_model()
    R = np.linalg.norm(S - np.array([30.0, 60.0, 40.0]), axis=1)
    res = sv.iterative_regression(m, R, S, np.ones(5))
    assert res.iterations == 1 and res.converged
    np.testing.assert_array_equal(res.z, sv.lssvr_predict(m, R))


# ------------------------------------------------------------------------- likelihoods
def test_likelihoods_match_gaussian_log_densities_up_to_a_constant():
    rng = np.random.default_rng(4)
    X = rng.uniform(0, 100, (50, 6))
    S = rng.uniform(0, 100, (4, 3))
    R = rng.uniform(10, 80, 4)
    d = np.linalg.norm(X[:, None, :3] - S[None], axis=2)
    ref = stats.norm.logpdf(R[None, :], loc=d, scale=3.0).sum(axis=1)
    got = sv.range_loglik(X, S, R, 3.0)
    np.testing.assert_allclose(got - got[0], ref - ref[0], atol=1e-9)
    z = np.array([40.0, 50, 60])
    ref = stats.multivariate_normal.logpdf(X[:, :3], mean=z, cov=9.0 * np.eye(3))
    got = sv.observation_loglik(X, z, 3.0)
    np.testing.assert_allclose(got - got[0], ref - ref[0], atol=1e-9)


# ------------------------------------------------------------------------- consensus
def test_consensus_estimate_is_exact_on_noiseless_ranges():
    S = np.array([[10.0, 10, 10], [60, 20, 30], [20, 70, 40], [50, 50, 80], [80, 80, 20], [30, 40, 90]])
    x = np.array([45.0, 35.0, 55.0])
    R = np.linalg.norm(S - x, axis=1)
    est = sv.consensus_estimate(S, R, [0, 0, 0], [100, 100, 100])
    np.testing.assert_allclose(est, x, atol=1e-5)  # least_squares' default tolerances


def test_consensus_estimate_stays_in_the_region():
    S = np.array([[10.0, 10, 10], [60, 20, 30], [20, 70, 40]])
    est = sv.consensus_estimate(S, np.array([300.0, 1.0, 250.0]), [0, 0, 0], [100, 100, 100])
    assert np.all(est >= 0) and np.all(est <= 100)


# ------------------------------------------------------------------------- node selection
def test_node_selection_reproduces_table1():
    geo = _geometry()
    P = geo.layout()
    d = np.linalg.norm(P - geo.TARGET, axis=1)
    ranges = (10, 40, 50, 60, 70, 80, 90, 100)
    paper_within = (0, 2, 8, 14, 18, 20, 20, 20)
    paper_discriminant = (0, 2, 8, 14, 18, 19, 19, 19)
    for rng_m, within, disc in zip(ranges, paper_within, paper_discriminant):
        assert int((d < rng_m).sum()) == within  # the layout is built from Table 1's first row
        count = 0
        for j, s in enumerate(P):
            key = f"table1-{j}-{rng_m}"
            dd, y = sv.svm_training_set(s, [0, 0, 0], [100, 100, 100], 400, 180.0, rng_m, sv.training_rng(0, key))
            m = sv.svm_train(dd, y, c=10.0, gamma=50.0, scale=180.0)
            count += bool(sv.svm_discriminant(m, d[j]) > 0)
        assert abs(count - disc) <= 1, (rng_m, count, disc)


# ------------------------------------------------------------------------- cache
def test_training_cache_returns_the_trained_arrays_and_keys_on_geometry(tmp_path, monkeypatch):
    monkeypatch.setattr(sv.TrainingCache, "_memo", {})
    calls = []

    def train(seed=0):
        calls.append(seed)
        rng = sv.training_rng(0, "k")
        return {"a": rng.normal(size=5)}

    parts = {"sensor": np.array([1.0, 2.0, 3.0]), "seed": 0}
    k1 = sv.cache_key("svm", parts)
    first = sv.TrainingCache(tmp_path).get(k1, train)
    monkeypatch.setattr(sv.TrainingCache, "_memo", {})  # a new process: only the disk remains
    again = sv.TrainingCache(tmp_path).get(k1, train)
    assert len(calls) == 1
    np.testing.assert_array_equal(first["a"], again["a"])
    moved = {"sensor": np.array([1.0, 2.0, 3.0 + 1e-9]), "seed": 0}
    assert sv.cache_key("svm", moved) != k1
    assert sv.cache_key("svm", {**parts, "seed": 1}) != k1


def test_training_rng_depends_only_on_seed_and_key():
    a = sv.training_rng(0, "x").normal(size=3)
    sv.training_rng(0, "y").normal(size=3)
    np.testing.assert_array_equal(a, sv.training_rng(0, "x").normal(size=3))
    assert not np.array_equal(a, sv.training_rng(1, "x").normal(size=3))


@pytest.mark.parametrize("r", [1.0, 10.0, 1000.0])
def test_propagation_loss_eq24(r):
    assert sv.propagation_loss_db(r, 2.0) == pytest.approx(20 * np.log10(r) + 2.0 * r / 1000)


def test_fusion_defaults_match_the_channel_defaults():
    """TIL - RIL is read from the SNR with the receiver's known noise level: the defaults must be
    the channel's (10 kHz, 5 kHz band, shipping 0.5, no wind; Thorp absorption at 10 kHz)."""
    from aquasim_protocols.svlpf import SvlpfParams
    from aquasim_py.channel import loss
    from aquasim_py.channel.config import ChannelConfig

    c, p = ChannelConfig(), SvlpfParams()
    noise = loss.noise_psd_db(c.frequency_khz, c.shipping, c.wind_mps) + 10 * np.log10(c.bandwidth_khz * 1e3)
    assert p.noise_band_db == pytest.approx(float(noise), abs=0.005)  # given to 2 decimals
    assert p.beta_db_per_km == pytest.approx(float(loss.thorp_absorption_db_per_km(c.frequency_khz)), abs=5e-4)
    assert p.source_level_db == c.source_level_db
