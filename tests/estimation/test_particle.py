"""Particle-filter core: resampling properties, and convergence to the Kalman filter on a
linear-Gaussian model (with a check that broken weighting fails the same tolerance)."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest
from scipy.stats import multivariate_normal

from aquasim_py.estimation import (
    cv_matrices,
    effective_sample_size,
    gaussian_log_likelihood,
    kf_predict,
    kf_update,
    normalize_log_weights,
    propagate,
    resample,
    residual_resample,
    systematic_resample,
    update_log_weights,
    weighted_cov,
    weighted_mean,
)

F, Q = cv_matrices(1, 1.0, 0.5)
H = np.array([[1.0, 0.0]])
R = np.array([[2.0]])
X0, P0 = np.array([0.0, 1.0]), np.diag([4.0, 1.0])
STEPS = 5


def _data():
    rng = np.random.default_rng(2024)
    x = rng.multivariate_normal(X0, P0)
    zs = []
    for _ in range(STEPS):
        x = F @ x + rng.multivariate_normal(np.zeros(2), Q)
        zs.append(H @ x + rng.normal(0.0, np.sqrt(R[0, 0]), 1))
    # a surprising last measurement (about 2 innovation stds off): the Kalman answer is still
    # the exact posterior, and a wrong weighting of the likelihood shows up clearly
    zs[-1] = zs[-1] + 4.0
    return zs


ZS = _data()


def _kalman():
    x, P = X0, P0
    for z in ZS:
        x, P = kf_predict(x, P, F, Q)
        u = kf_update(x, P, z, H, R)
        x, P = u.x, u.P
    return x, P


def _correct(logw, loglik):
    return update_log_weights(logw, loglik)


def _squared(logw, loglik):  # w^2: as if the measurement were twice as precise
    return update_log_weights(logw, 2.0 * loglik)


def _unnormalized(logw, loglik):  # forgets to divide by the sum of the weights
    return np.asarray(logw) + loglik


def _pf(M: int, seed: int, weigh: Callable = _correct) -> np.ndarray:
    rng = np.random.default_rng(seed)
    X = X0 + rng.standard_normal((M, 2)) @ np.linalg.cholesky(P0).T
    logw = np.full(M, -np.log(M))
    for z in ZS:
        X = propagate(X, lambda s: s @ F.T, Q, rng)
        logw = weigh(logw, gaussian_log_likelihood(z, X @ H.T, R))
        est = weighted_mean(X, np.exp(logw))
        X, logw = resample(X, logw, rng, "systematic")
    return est


def _err(M: int, seeds, weigh: Callable = _correct) -> float:
    """RMS over seeds of the PF-KF mean difference, in units of the KF posterior std."""
    xk, Pk = _kalman()
    e = np.array([(_pf(M, s, weigh) - xk) / np.sqrt(np.diag(Pk)) for s in seeds])
    return float(np.sqrt(np.mean(e**2)))


TOL = 0.03  # at 1e5 particles, in posterior standard deviations


def test_particle_mean_converges_to_kalman_like_inverse_sqrt_n() -> None:
    seeds = range(8)
    Ms = np.array([1_000, 10_000, 100_000])
    errs = np.array([_err(int(M), seeds) for M in Ms])
    slope = np.polyfit(np.log(Ms), np.log(errs), 1)[0]
    assert -0.7 < slope < -0.3, (errs, slope)
    assert errs[-1] < TOL, errs
    assert 4.0 < errs[0] / errs[-1] < 25.0, errs


@pytest.mark.parametrize("weigh", [_squared, _unnormalized])
def test_broken_weighting_fails_the_same_tolerance(weigh: Callable) -> None:
    assert _err(100_000, range(2), weigh) > 3 * TOL


def test_systematic_counts_are_floor_or_ceil() -> None:
    rng = np.random.default_rng(0)
    w = rng.dirichlet(np.ones(37))
    for _ in range(20):
        counts = np.bincount(systematic_resample(w, rng), minlength=37)
        assert counts.sum() == 37
        assert np.all((counts == np.floor(37 * w)) | (counts == np.ceil(37 * w)))


def test_residual_resampling_is_unbiased() -> None:
    rng = np.random.default_rng(1)
    w = rng.dirichlet(np.ones(10))
    M, draws = 10, 5_000
    counts = np.zeros(M)
    for _ in range(draws):
        idx = residual_resample(w, rng)
        assert idx.size == M
        c = np.bincount(idx, minlength=M)
        assert np.all(c >= np.floor(M * w))
        counts += c
    # the mean count of each particle is M w_i (binomial std < 0.5 / sqrt(draws) per draw)
    np.testing.assert_allclose(counts / draws, M * w, atol=5 * 0.5 / np.sqrt(draws))


def test_ess_and_moments() -> None:
    assert effective_sample_size(np.full(50, 1 / 50)) == pytest.approx(50)
    assert effective_sample_size(np.eye(1, 50)[0]) == pytest.approx(1)
    rng = np.random.default_rng(2)
    X = rng.normal(size=(200, 3))
    w = rng.dirichlet(np.ones(200))
    np.testing.assert_allclose(weighted_mean(X, w), np.average(X, axis=0, weights=w))
    np.testing.assert_allclose(weighted_cov(X, w), np.cov(X.T, aweights=w, bias=True), atol=1e-14)


def test_log_likelihood_and_underflow() -> None:
    rng = np.random.default_rng(3)
    A = rng.normal(size=(3, 3))
    Rm = A @ A.T + np.eye(3)
    Zp = rng.normal(size=(40, 3))
    z = rng.normal(size=3)
    np.testing.assert_allclose(
        gaussian_log_likelihood(z, Zp, Rm), multivariate_normal(cov=Rm).logpdf(z - Zp), rtol=1e-12
    )
    # likelihoods far below the smallest double still give proper weights
    w, _lw = normalize_log_weights(np.array([-2000.0, -2001.0, -5000.0]))
    np.testing.assert_allclose(w, [1 / (1 + np.exp(-1)), np.exp(-1) / (1 + np.exp(-1)), 0.0], atol=1e-300)
    with pytest.raises(ValueError):
        normalize_log_weights(np.full(3, -np.inf))


def test_propagate_noise_covariance_even_when_singular() -> None:
    rng = np.random.default_rng(4)
    Qs = np.array([[1.0, 1.0], [1.0, 1.0]])  # rank 1
    X = propagate(np.zeros((200_000, 2)), lambda s: s, Qs, rng)
    np.testing.assert_allclose(np.cov(X.T), Qs, atol=0.02)
