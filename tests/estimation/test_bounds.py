"""CRB (eqs 30-33) and recursive PCRB (eqs 41-42) against closed forms, Monte Carlo Fisher
information and the Kalman filter's own covariance."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import norm

from aquasim_py.estimation import (
    DegenerateGeometryError,
    crb,
    crb_trace,
    cv_matrices,
    fisher_information,
    kf_predict,
    kf_update,
    measurement_information,
    pcrb_information,
    pcrb_position,
)


def test_din_crb_closed_form_symmetric_geometry() -> None:
    """Six anchors at +-L on the axes, target at the centre, straight rays at speed c: each
    gradient is -+e_i / c, so I = 2 / (c sigma)^2 * Id and CRB = 3 (c sigma)^2 / 2."""
    c, sig, L = 1500.0, 1e-3, 100.0
    A = np.vstack([L * np.eye(3), -L * np.eye(3)])
    J = (0.0 - A) / (L * c)
    assert crb_trace(J, np.full(6, sig**2)) == pytest.approx(1.5 * (c * sig) ** 2, rel=1e-12)


def _gaussian_model(x):
    """Mean and variance of 3 measurements of a 2-D parameter, both depending on x."""
    A = np.array([[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]])
    d = np.linalg.norm(x[..., None, :] - A, axis=-1)
    return d, 0.2 * d**2 + 0.1  # strongly distance-dependent variance


def test_ddn_fisher_information_matches_monte_carlo_score() -> None:
    """E[score score^T] with the score from finite differences of the exact log-density."""
    x = np.array([3.0, 4.0])
    mu, var = _gaussian_model(x)
    h = 1e-5
    J = np.empty((3, 2))
    dvar = np.empty((3, 2))
    for i, e in enumerate(np.eye(2)):
        (mp, vp), (mm, vm) = _gaussian_model(x + h * e), _gaussian_model(x - h * e)
        J[:, i], dvar[:, i] = (mp - mm) / (2 * h), (vp - vm) / (2 * h)
    I = fisher_information(J, var, dvar)
    rng = np.random.default_rng(0)
    Z = mu + np.sqrt(var) * rng.standard_normal((400_000, 3))

    def logp(xx):
        m, v = _gaussian_model(xx)
        return norm.logpdf(Z, m, np.sqrt(v)).sum(axis=1)

    score = np.column_stack([(logp(x + h * e) - logp(x - h * e)) / (2 * h) for e in np.eye(2)])
    I_mc = score.T @ score / len(Z)
    np.testing.assert_allclose(I, I_mc, rtol=0.02, atol=0.02 * np.abs(I).max())
    # and the second term matters here: without it the bound is visibly different
    assert not np.allclose(fisher_information(J, var), I_mc, rtol=0.05)


def test_crb_vectorized_and_singular() -> None:
    rng = np.random.default_rng(1)
    J = rng.normal(size=(10, 5, 3))
    v = rng.uniform(0.5, 2, (10, 5))
    batch = crb(J, v)
    for k in range(10):
        np.testing.assert_allclose(batch[k], np.linalg.inv(J[k].T @ np.diag(1 / v[k]) @ J[k]), rtol=1e-10)
    Jdeg = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0], [2.0, 1.0, 0.0]])
    with pytest.raises(DegenerateGeometryError):
        crb(Jdeg, np.ones(4))


def test_pcrb_of_linear_gaussian_model_is_the_kalman_covariance() -> None:
    """For a linear measurement the PCRB recursion (eq 41) is the information form of the KF,
    so J_k^-1 must equal the KF posterior covariance at every step; measurements vary over time
    (depth row every 3rd step, as with rho = 3)."""
    F, Q = cv_matrices(3, 10.0, 1e-3)
    P0 = np.diag([100.0] * 3 + [1.0] * 3)
    rng = np.random.default_rng(2)
    K = 30
    info = np.zeros((K, 6, 6))
    P = P0
    x = np.zeros(6)
    covs = []
    for k in range(K):
        H = np.hstack([rng.normal(size=(4, 3)), np.zeros((4, 3))])
        R = np.diag(rng.uniform(1, 3, 4))
        if (k + 1) % 3 == 0:
            H = np.vstack([H, [0, 0, 1, 0, 0, 0]])
            R = np.diag(np.append(np.diag(R), 0.5))
        info[k] = measurement_information(H, R)
        x, P = kf_predict(x, P, F, Q)
        u = kf_update(x, P, H @ x, H, R)
        x, P = u.x, u.P
        covs.append(P)
    Jseq = pcrb_information(np.linalg.inv(P0), F, Q, info)
    np.testing.assert_allclose(np.linalg.inv(Jseq), np.array(covs), rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(pcrb_position(Jseq), np.trace(np.array(covs)[:, :3, :3], axis1=1, axis2=2), rtol=1e-8)


def test_pcrb_expectation_averages_information_over_trajectories() -> None:
    F, Q = cv_matrices(2, 1.0, 0.1)
    rng = np.random.default_rng(3)
    info = np.einsum("mkai,mkaj->mkij", *(2 * [rng.normal(size=(5, 8, 3, 4))]))
    J0 = np.eye(4)
    per = pcrb_information(J0, F, Q, info)
    assert per.shape == (5, 8, 4, 4)
    for m in range(5):
        np.testing.assert_allclose(per[m], pcrb_information(J0, F, Q, info[m]), rtol=1e-12)
    avg = pcrb_information(J0, F, Q, info, expectation=True)
    np.testing.assert_allclose(avg, pcrb_information(J0, F, Q, info.mean(axis=0)), rtol=1e-12)


def test_information_with_mixed_units_is_not_called_singular() -> None:
    """A FIM whose entries span 20 orders of magnitude (units, not rank) still inverts; a
    rank-deficient one raises."""
    from aquasim_py.estimation import SingularMatrixError
    from aquasim_py.estimation._linalg import spd_inverse

    s = np.array([1e-10, 1.0, 1e10])
    C = np.array([[1.0, 0.5, 0.2], [0.5, 1.0, 0.3], [0.2, 0.3, 1.0]])
    A = C * np.outer(s, s)
    np.testing.assert_allclose(spd_inverse(A) * np.outer(s, s), np.linalg.inv(C), rtol=1e-12)
    with pytest.raises(SingularMatrixError):
        spd_inverse(np.outer([1.0, 2.0, 3.0], [1.0, 2.0, 3.0]))


class TestRangeCRB:
    """range_crb_trace against closed forms: N anchors evenly spaced on a circle of radius R
    around the position give I = (N / 2) (1 / sigma^2 + var'^2 / (2 sigma^4)) per axis."""

    @pytest.mark.parametrize("n", [3, 4, 7])
    def test_circle_constant_noise(self, n):
        from aquasim_py.estimation.bounds import range_crb_trace

        ang = 2 * np.pi * np.arange(n) / n + 0.3
        R, sigma = 40.0, 1.5
        a = np.stack([R * np.cos(ang), R * np.sin(ang), np.full(n, 12.0)], axis=1)
        x = np.array([0.0, 0.0, 12.0])
        assert range_crb_trace(x, a, std=sigma) == pytest.approx(4 * sigma**2 / n, rel=1e-12)

    @pytest.mark.parametrize("rho", [0.02, 0.1])
    def test_circle_distance_dependent_noise(self, rho):
        from aquasim_py.estimation.bounds import range_crb_trace

        n, R = 5, 60.0
        ang = 2 * np.pi * np.arange(n) / n
        a = np.stack([R * np.cos(ang), R * np.sin(ang), np.zeros(n)], axis=1)
        # var = rho^2 R^2, d var / dx = 2 rho^2 R u: I = (n / 2) (1 + 2 rho^2) / (rho^2 R^2) per axis
        expect = 4 * rho**2 * R**2 / (n * (1 + 2 * rho**2))
        assert range_crb_trace(np.zeros(3), a, rel_std=rho) == pytest.approx(expect, rel=1e-12)

    def test_mask_and_degenerate_rows(self):
        from aquasim_py.estimation.bounds import range_crb_trace

        a = np.array([[[10.0, 0, 0], [0, 10.0, 0], [-10.0, 0, 0], [0, -10.0, 0]]] * 2)
        mask = np.array([[True, True, True, True], [True, False, True, False]])  # row 2: one line
        out = range_crb_trace(np.zeros((2, 3)), a, std=1.0, mask=mask)
        assert out[0] == pytest.approx(1.0) and np.isnan(out[1])
        # an absent anchor changes nothing: 3 present of 4 = the 3 alone
        three = range_crb_trace(np.zeros(3), a[0, :3], std=1.0)
        assert range_crb_trace(np.zeros(3), a[0], std=1.0, mask=[True, True, True, False]) == pytest.approx(three)

    def test_monte_carlo_ml_reaches_the_bound(self):
        """Gauss-Newton ML on many noisy draws: its MSE approaches the CRB (small noise)."""
        from aquasim_py.estimation.bounds import range_crb_trace
        from aquasim_py.estimation.lsq import multilaterate

        rng = np.random.default_rng(3)
        a = np.array([[0.0, 0, 20], [70.0, 10, 25], [20.0, 60, 22], [60.0, 70, 18]])
        x = np.array([35.0, 30.0, 21.0])
        rho = 0.01
        d = np.linalg.norm(x - a, axis=1)
        errs = []
        for _ in range(4000):
            r = d * (1 + rho * rng.standard_normal(4))
            rh = np.sqrt(np.maximum(r**2 - (a[:, 2] - x[2]) ** 2, 0))
            est = multilaterate(a[:, :2], rh, refine=5)
            errs.append(np.sum((est - x[:2]) ** 2))
        mse = float(np.mean(errs))
        crb = float(range_crb_trace(x, a, rel_std=rho))
        # ML is efficient to first order; 4000 draws: the MSE's standard error is ~3 %
        assert mse == pytest.approx(crb, rel=0.1)
