"""Motion models against ODE integration, numerical integrals and finite differences."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import fixed_quad, solve_ivp
from scipy.linalg import expm

from aquasim_py.estimation import ConstantVelocityModel, CoordinatedTurnModel, cwna_noise
from aquasim_py.estimation.motion import _SERIES_BELOW


def _ct_ode(_t, s, dim):
    d = dim
    out = np.zeros_like(s)
    out[:d] = s[d : 2 * d]
    w = s[-1]
    out[d] = -w * s[d + 1]
    out[d + 1] = w * s[d]
    return out


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize("omega", [0.0, 1e-7, 0.02, 0.3, -0.8])
def test_ct_transition_matches_ode_integration(dim: int, omega: float) -> None:
    dt = 2.5
    x = np.array([1.0, -2.0, 3.0, 4.0, -1.5, 0.7, omega]) if dim == 3 else np.array([1.0, -2.0, 4.0, -1.5, omega])
    sol = solve_ivp(_ct_ode, (0, dt), x, args=(dim,), rtol=1e-12, atol=1e-12, method="DOP853")
    got = CoordinatedTurnModel(dim, dt).transition(x)
    np.testing.assert_allclose(got, sol.y[:, -1], rtol=1e-9, atol=1e-9)


def test_ct_transition_vectorized() -> None:
    ct = CoordinatedTurnModel(3, 1.0)
    X = np.random.default_rng(0).normal(size=(50, 7))
    np.testing.assert_allclose(ct.transition(X), np.stack([ct.transition(x) for x in X]), rtol=0, atol=0)


@pytest.mark.parametrize("dim", [2, 3])
@pytest.mark.parametrize(
    "omega",
    [0.0, 1e-9, 3e-4, 0.999 * _SERIES_BELOW / 2.0, 1.001 * _SERIES_BELOW / 2.0, 0.4, -1.3],
)
def test_ct_jacobian_matches_finite_differences(dim: int, omega: float) -> None:
    ct = CoordinatedTurnModel(dim, 2.0)
    x = np.array([5.0, 1.0, -3.0, 2.0, -1.0, 0.3, omega]) if dim == 3 else np.array([5.0, 1.0, 2.0, -1.0, omega])
    J = ct.jacobian(x)
    h = 1e-6
    Jfd = np.column_stack([(ct.transition(x + h * e) - ct.transition(x - h * e)) / (2 * h) for e in np.eye(ct.n)])
    np.testing.assert_allclose(J, Jfd, rtol=1e-7, atol=1e-8)


def test_ct_coefficients_continuous_at_series_switch() -> None:
    ct = CoordinatedTurnModel(2, 1.0)
    x = np.array([0.0, 0.0, 3.0, -2.0, 0.0])
    w = _SERIES_BELOW
    lo, hi = x.copy(), x.copy()
    lo[-1], hi[-1] = np.nextafter(w, 0), w
    np.testing.assert_allclose(ct.transition(lo), ct.transition(hi), rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(ct.jacobian(lo), ct.jacobian(hi), rtol=1e-12, atol=1e-13)


@pytest.mark.parametrize("dim", [2, 3])
def test_ct_at_zero_turn_rate_is_cv(dim: int) -> None:
    cv, ct = ConstantVelocityModel(dim, 1.5, q=0.2), CoordinatedTurnModel(dim, 1.5, q=0.2)
    x = np.arange(1.0, 2 * dim + 1)
    np.testing.assert_allclose(ct.transition(np.append(x, 0.0))[:-1], cv.transition(x), rtol=1e-15)
    np.testing.assert_allclose(ct.jacobian(np.append(x, 0.0))[:-1, :-1], cv.F, rtol=1e-15)
    np.testing.assert_allclose(ct.Q[:-1, :-1], cv.Q)


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_cwna_noise_is_the_integral_of_white_acceleration(dim: int) -> None:
    dt, q = 1.7, 0.3
    n = 2 * dim
    A = np.zeros((n, n))
    A[:dim, dim:] = np.eye(dim)
    G = np.vstack([np.zeros((dim, dim)), np.eye(dim)])

    # Q = int_0^dt e^{A s} G q G^T e^{A^T s} ds; the integrand is a degree-2 polynomial in s,
    # so 5-point Gauss-Legendre quadrature is exact
    def integrand(ss):
        return np.stack([expm(A * s) @ G @ G.T @ expm(A * s).T * q for s in ss], axis=-1)

    Q_num, _ = fixed_quad(integrand, 0.0, dt, n=5)
    np.testing.assert_allclose(cwna_noise(dim, dt, q), Q_num, rtol=1e-10, atol=1e-13)


def test_bad_dimension_rejected() -> None:
    with pytest.raises(ValueError):
        ConstantVelocityModel(4, 1.0)
