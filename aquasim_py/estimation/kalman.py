"""Kalman filter and extended Kalman filter as pure functions on a Gaussian (x, P).

The linear and the extended update share one code path (:func:`_update`), so an EKF whose
measurement function is linear gives bit-for-bit the Kalman answer. Every update returns the
innovation log-likelihood, which the IMM uses as its model likelihood.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._linalg import cho_factor, cho_solve, symmetrize

__all__ = ["UpdateResult", "ekf_predict", "ekf_update", "kf_predict", "kf_update"]

Array = NDArray[np.float64]
_LOG_2PI = float(np.log(2.0 * np.pi))


@dataclass(frozen=True)
class UpdateResult:
    """Posterior of one measurement update."""

    x: Array  #: posterior mean (n,)
    P: Array  #: posterior covariance (n, n)
    innovation: Array  #: z - predicted z (m,)
    S: Array  #: innovation covariance (m, m)
    log_likelihood: float  #: log N(innovation; 0, S)


def _as_state(x: ArrayLike, P: ArrayLike) -> tuple[Array, Array]:
    x = np.asarray(x, dtype=float).reshape(-1)
    P = np.asarray(P, dtype=float)
    if P.shape != (x.size, x.size):
        raise ValueError(f"P must be ({x.size}, {x.size}), got {P.shape}")
    return x, P


def kf_predict(x: ArrayLike, P: ArrayLike, F: ArrayLike, Q: ArrayLike) -> tuple[Array, Array]:
    """Linear prediction x' = F x, P' = F P F^T + Q."""
    x, P = _as_state(x, P)
    F = np.asarray(F, dtype=float)
    return F @ x, symmetrize(F @ P @ F.T + np.asarray(Q, dtype=float))


def ekf_predict(
    x: ArrayLike,
    P: ArrayLike,
    f: Callable[[Array], Array],
    F_jac: Callable[[Array], Array],
    Q: ArrayLike,
) -> tuple[Array, Array]:
    """Extended prediction x' = f(x), P' = F P F^T + Q with F = df/dx at the prior mean."""
    x, P = _as_state(x, P)
    F = np.asarray(F_jac(x), dtype=float)
    return np.asarray(f(x), dtype=float), symmetrize(F @ P @ F.T + np.asarray(Q, dtype=float))


def _update(x: Array, P: Array, y: Array, H: Array, R: Array) -> UpdateResult:
    S = symmetrize(H @ P @ H.T + R)
    c = cho_factor(S, "innovation covariance S")
    # K^T = S^-1 H P (S and P symmetric), so no explicit inverse is formed
    K = cho_solve(c, H @ P).T
    x_new = x + K @ y
    IKH = np.eye(x.size) - K @ H
    # Joseph form: stays symmetric positive semi-definite under round-off, and is exact for any gain
    P_new = symmetrize(IKH @ P @ IKH.T + K @ R @ K.T)
    maha = float(y @ cho_solve(c, y))
    logdet = 2.0 * float(np.sum(np.log(np.diag(c[0]))))
    ll = -0.5 * (maha + logdet + y.size * _LOG_2PI)
    return UpdateResult(x_new, P_new, y, S, ll)


def _meas(z: ArrayLike, R: ArrayLike) -> tuple[Array, Array]:
    z = np.asarray(z, dtype=float).reshape(-1)
    R = np.atleast_2d(np.asarray(R, dtype=float))
    if R.shape != (z.size, z.size):
        raise ValueError(f"R must be ({z.size}, {z.size}), got {R.shape}")
    return z, R


def kf_update(x: ArrayLike, P: ArrayLike, z: ArrayLike, H: ArrayLike, R: ArrayLike) -> UpdateResult:
    """Linear update with z = H x + v, v ~ N(0, R)."""
    x, P = _as_state(x, P)
    z, R = _meas(z, R)
    H = np.atleast_2d(np.asarray(H, dtype=float))
    return _update(x, P, z - H @ x, H, R)


def ekf_update(
    x: ArrayLike,
    P: ArrayLike,
    z: ArrayLike,
    h: Callable[[Array], Array],
    H_jac: Callable[[Array], Array],
    R: ArrayLike,
    residual: Callable[[Array, Array], Array] | None = None,
) -> UpdateResult:
    """Extended update with z = h(x) + v, linearized at the prior mean (H = dh/dx there).

    ``residual(z, h(x))`` replaces the plain difference where the measurement wraps (angles).
    """
    x, P = _as_state(x, P)
    z, R = _meas(z, R)
    zp = np.asarray(h(x), dtype=float).reshape(-1)
    y = z - zp if residual is None else np.asarray(residual(z, zp), dtype=float).reshape(-1)
    H = np.atleast_2d(np.asarray(H_jac(x), dtype=float))
    return _update(x, P, y, H, R)
