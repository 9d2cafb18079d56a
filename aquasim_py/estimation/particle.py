"""Particle-filter core, vectorized over particles (no Python loop over them): propagation,
log-space weighting, systematic and residual resampling, effective sample size, weighted
moments. Randomness only from the ``numpy.random.Generator`` passed in (reproducible runs).

Particles are (M, n) arrays; weights are kept as normalized log-weights (M,) so that very
informative measurements do not underflow.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._linalg import cho_factor

__all__ = [
    "effective_sample_size",
    "gaussian_log_likelihood",
    "normalize_log_weights",
    "propagate",
    "resample",
    "residual_resample",
    "sir_update",
    "systematic_resample",
    "update_log_weights",
    "weighted_cov",
    "weighted_mean",
]

Array = NDArray[np.float64]


def _psd_sqrt(Q: Array) -> Array:
    """A matrix L with L L^T = Q for a symmetric positive *semi*-definite Q (process noise is
    often singular, e.g. noise on velocities only, where Cholesky fails)."""
    w, V = np.linalg.eigh(0.5 * (Q + Q.T))
    if w.min() < -1e-12 * max(w.max(), 0.0):
        raise ValueError("process noise covariance is not positive semi-definite")
    return V * np.sqrt(np.clip(w, 0.0, None))


def propagate(
    particles: ArrayLike,
    f: Callable[[Array], Array],
    Q: ArrayLike,
    rng: np.random.Generator,
) -> Array:
    """x' = f(x) + w, w ~ N(0, Q), for all particles at once (``f`` maps (M, n) -> (M, n))."""
    X = np.asarray(particles, dtype=float)
    L = _psd_sqrt(np.asarray(Q, dtype=float))
    return np.asarray(f(X), dtype=float) + _rows_times(rng.standard_normal(X.shape), L.T)


def _rows_times(X: Array, A: Array) -> Array:
    """X @ A for tall X (M, n) and small A (n, m): n axpy passes over the particles. BLAS
    GEMM on such shapes is slow (and thread-contended on shared machines)."""
    out = X[:, :1] * A[0]
    for k in range(1, A.shape[0]):
        out += X[:, k : k + 1] * A[k]
    return out


def gaussian_log_likelihood(z: ArrayLike, z_pred: ArrayLike, R: ArrayLike) -> Array:
    """log N(z; z_pred[i], R) per particle: z (m,), z_pred (M, m), R (m, m) -> (M,)."""
    from scipy.linalg import solve_triangular

    z = np.asarray(z, dtype=float).reshape(-1)
    Zp = np.asarray(z_pred, dtype=float).reshape(-1, z.size)
    c, _ = cho_factor(np.atleast_2d(np.asarray(R, dtype=float)), "measurement covariance R")
    # whiten with the Cholesky factor: ||L^-1 (z - z_pred)||^2 for all particles at once
    Linv = solve_triangular(c, np.eye(z.size), lower=True, check_finite=False)
    E = _rows_times(z - Zp, Linv.T)
    logdet = 2.0 * np.sum(np.log(np.diag(c)))
    return -0.5 * (np.einsum("ij,ij->i", E, E) + logdet + z.size * np.log(2.0 * np.pi))


def normalize_log_weights(logw: ArrayLike) -> tuple[Array, Array]:
    """(weights, normalized log-weights): w = exp(logw - logsumexp(logw))."""
    lw = np.asarray(logw, dtype=float)
    if not np.any(np.isfinite(lw)):
        raise ValueError("all particle weights are zero (every log-weight is -inf or NaN)")
    # log-sum-exp shifted by the maximum (scipy's logsumexp does the same with ~10x the
    # overhead, which showed at 1000 particles)
    m = np.max(lw)
    lw = lw - (m + np.log(np.sum(np.exp(lw - m))))
    return np.exp(lw), lw


def update_log_weights(logw: ArrayLike, loglik: ArrayLike) -> Array:
    """Bayes in log space: normalized log(w * likelihood)."""
    return normalize_log_weights(np.asarray(logw, dtype=float) + np.asarray(loglik, dtype=float))[1]


def effective_sample_size(w: ArrayLike) -> float:
    """ESS = 1 / sum w_i^2 for normalized weights (M for uniform weights, 1 for a single one)."""
    w = np.asarray(w, dtype=float)
    return float(1.0 / np.sum(w * w))


def _cumulative(w: Array) -> Array:
    c = np.cumsum(w)
    c /= c[-1]  # exact 1 at the end, so no uniform can fall beyond the last particle
    return c


def systematic_resample(w: ArrayLike, rng: np.random.Generator, size: int | None = None) -> Array:
    """Indices by systematic resampling: one uniform u, points (u + i) / M."""
    w = np.asarray(w, dtype=float)
    M = w.size if size is None else int(size)
    u = (rng.random() + np.arange(M)) / M
    return np.minimum(np.searchsorted(_cumulative(w), u, side="right"), w.size - 1)


def residual_resample(w: ArrayLike, rng: np.random.Generator) -> Array:
    """Indices by residual resampling: floor(M w_i) copies of i, the rest multinomially from
    the residual weights M w_i - floor(M w_i)."""
    w = np.asarray(w, dtype=float)
    M = w.size
    Mw = M * w / w.sum()
    counts = np.floor(Mw).astype(np.int64)
    rest = M - int(counts.sum())
    if rest > 0:
        res = Mw - counts
        counts += rng.multinomial(rest, res / res.sum())
    return np.repeat(np.arange(M), counts)


def resample(
    particles: ArrayLike,
    logw: ArrayLike,
    rng: np.random.Generator,
    method: str = "systematic",
) -> tuple[Array, Array]:
    """Resampled particles and uniform log-weights."""
    X = np.asarray(particles)
    w, _ = normalize_log_weights(logw)
    return X[_resample_indices(w, rng, method)], np.full(X.shape[0], -np.log(X.shape[0]))


def _resample_indices(w: Array, rng: np.random.Generator, method: str) -> Array:
    if method == "systematic":
        return systematic_resample(w, rng)
    if method == "residual":
        return residual_resample(w, rng)
    raise ValueError(f"unknown resampling method {method!r} (systematic, residual)")


def weighted_mean(x: ArrayLike, w: ArrayLike) -> Array:
    """sum_i w_i x_i for normalized w; x (M, n)."""
    return np.asarray(w, dtype=float) @ np.asarray(x, dtype=float)


def weighted_cov(x: ArrayLike, w: ArrayLike) -> Array:
    """sum_i w_i (x_i - m)(x_i - m)^T (the particle approximation's own covariance)."""
    x = np.asarray(x, dtype=float)
    w = np.asarray(w, dtype=float)
    D = x - w @ x
    C = (D * w[:, None]).T @ D
    return 0.5 * (C + C.T)


def sir_update(
    particles: ArrayLike,
    logw: ArrayLike,
    loglik: ArrayLike,
    rng: np.random.Generator,
    method: str = "systematic",
) -> tuple[Array, Array, Array, Array]:
    """One SIR measurement update (transition prior as proposal): weight by the likelihood,
    take the weighted mean and covariance, resample. Returns (particles, log-weights, mean,
    cov); the moments are of the weighted set before resampling (same expectation as after,
    without the resampling noise)."""
    X = np.asarray(particles, dtype=float)
    lw = update_log_weights(logw, loglik)
    w = np.exp(lw)
    mean, cov = weighted_mean(X, w), weighted_cov(X, w)
    Xr = X[_resample_indices(w, rng, method)]  # w is normalized already
    return Xr, np.full(X.shape[0], -np.log(X.shape[0])), mean, cov
