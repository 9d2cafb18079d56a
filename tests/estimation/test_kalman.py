"""Kalman / extended Kalman filter against closed forms and independent formulas."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.linalg as sla
from scipy.stats import multivariate_normal

from aquasim_py.estimation import (
    SingularMatrixError,
    cv_matrices,
    ekf_predict,
    ekf_update,
    kf_predict,
    kf_update,
)


def _iterate_covariance(F, Q, H, R, P0, steps):
    x = np.zeros(F.shape[0])
    P = P0
    for _ in range(steps):
        x, P_prior = kf_predict(x, P, F, Q)
        P = kf_update(x, P_prior, H @ x, H, R).P
    return P_prior, P


def test_scalar_random_walk_steady_state_closed_form() -> None:
    q, r = 0.3, 2.0
    P_prior, P_post = _iterate_covariance(np.eye(1), q * np.eye(1), np.eye(1), r * np.eye(1), 50 * np.eye(1), 200)
    # steady prior variance solves P = P r / (P + r) + q  ->  P^2 - q P - q r = 0
    p_inf = (q + np.sqrt(q * q + 4 * q * r)) / 2
    assert P_prior[0, 0] == pytest.approx(p_inf, rel=1e-12)
    assert P_post[0, 0] == pytest.approx(p_inf * r / (p_inf + r), rel=1e-12)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_cv_steady_state_matches_discrete_riccati(dim: int) -> None:
    F, Q = cv_matrices(dim, 2.0, 0.05)
    n = F.shape[0]
    H = np.hstack([np.eye(n // 2), np.zeros((n // 2, n // 2))])
    R = 3.0 * np.eye(n // 2)
    P_prior, _ = _iterate_covariance(F, Q, H, R, 100 * np.eye(n), 400)
    # the a-priori steady state is the stabilizing DARE solution (filter form: A = F^T, B = H^T)
    P_dare = sla.solve_discrete_are(F.T, H.T, Q, R)
    np.testing.assert_allclose(P_prior, P_dare, rtol=1e-9, atol=1e-12)


def test_update_matches_information_form_and_likelihood() -> None:
    rng = np.random.default_rng(3)
    n, m = 4, 3
    A = rng.normal(size=(n, n))
    P = A @ A.T + n * np.eye(n)
    B = rng.normal(size=(m, m))
    R = B @ B.T + np.eye(m)
    H = rng.normal(size=(m, n))
    x = rng.normal(size=n)
    z = rng.normal(size=m)
    u = kf_update(x, P, z, H, R)
    # independent: information form P+ = (P^-1 + H^T R^-1 H)^-1, x+ = P+ (P^-1 x + H^T R^-1 z)
    Pi = np.linalg.inv(np.linalg.inv(P) + H.T @ np.linalg.solve(R, H))
    xi = Pi @ (np.linalg.solve(P, x) + H.T @ np.linalg.solve(R, z))
    np.testing.assert_allclose(u.P, Pi, rtol=1e-10)
    np.testing.assert_allclose(u.x, xi, rtol=1e-10)
    assert u.log_likelihood == pytest.approx(multivariate_normal(H @ x, H @ P @ H.T + R).logpdf(z), rel=1e-12)


def test_ekf_on_linear_model_equals_kf_exactly() -> None:
    rng = np.random.default_rng(7)
    F, Q = cv_matrices(3, 0.7, 0.4)
    H = rng.normal(size=(4, 6))
    R = np.diag(rng.uniform(0.5, 2.0, 4))
    xk, Pk = rng.normal(size=6), 5 * np.eye(6)
    xe, Pe = xk.copy(), Pk.copy()
    for _ in range(30):
        z = rng.normal(size=4)
        xk, Pk = kf_predict(xk, Pk, F, Q)
        xe, Pe = ekf_predict(xe, Pe, lambda s: F @ s, lambda s: F, Q)
        uk = kf_update(xk, Pk, z, H, R)
        ue = ekf_update(xe, Pe, z, lambda s: H @ s, lambda s: H, R)
        xk, Pk, xe, Pe = uk.x, uk.P, ue.x, ue.P
        assert uk.log_likelihood == ue.log_likelihood
    assert np.array_equal(xk, xe)
    assert np.array_equal(Pk, Pe)


def test_ekf_range_update_matches_linearization_by_finite_differences() -> None:
    """A nonlinear (range) update uses the Jacobian at the prior mean: compare with a linear
    update built from a numerically differentiated h."""
    anchor = np.array([10.0, -5.0])

    def h(s):
        return np.array([np.hypot(*(s[:2] - anchor))])

    def Hj(s):
        return np.concatenate([(s[:2] - anchor) / np.hypot(*(s[:2] - anchor)), [0.0, 0.0]])[None, :]

    x, P = np.array([1.0, 2.0, 0.5, 0.0]), np.diag([4.0, 4.0, 1.0, 1.0])
    z = np.array([14.0])
    u = ekf_update(x, P, z, h, Hj, [[0.25]])
    eps = 1e-6
    Hfd = np.array([[(h(x + eps * e) - h(x - eps * e))[0] / (2 * eps) for e in np.eye(4)]])
    ul = kf_update(x, P, z - h(x) + Hfd @ x, Hfd, [[0.25]])
    np.testing.assert_allclose(u.x, ul.x, rtol=1e-8)
    np.testing.assert_allclose(u.P, ul.P, rtol=1e-8)


def test_singular_innovation_covariance_raises() -> None:
    with pytest.raises(SingularMatrixError):
        kf_update(np.zeros(2), np.zeros((2, 2)), [1.0], [[1.0, 0.0]], [[0.0]])
    with pytest.raises(ValueError):
        kf_update(np.zeros(2), np.eye(3), [1.0], [[1.0, 0.0]], [[1.0]])
