"""IMM (CV Kalman + coordinated-turn EKF) on a straight -> turn -> straight trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py.estimation import (
    IMM,
    ConstantVelocityModel,
    CoordinatedTurnModel,
    ekf_predict,
    kf_predict,
    kf_update,
)

from ._trajectories import cv_turn_cv

DT, SIG, SPEED, OMEGA = 1.0, 5.0, 10.0, 0.1
N1, NT, N2 = 50, 30, 50


def _run(seed: int, dim: int):
    truth, mode = cv_turn_cv(DT, N1, NT, N2, SPEED, OMEGA, vz=0.5 if dim == 3 else 0.0, heading=0.3)
    truth = truth[:, :dim]
    rng = np.random.default_rng(seed)
    z = truth + SIG * rng.standard_normal(truth.shape)
    R = SIG**2 * np.eye(dim)
    cv = ConstantVelocityModel(dim, DT, q=0.01)
    ct = CoordinatedTurnModel(dim, DT, q=0.01, q_turn=1e-4)
    n = ct.n
    x0 = np.zeros(n)
    x0[:dim] = z[0]
    P0 = np.diag([SIG**2] * dim + [SPEED**2] * dim + [0.01])
    H = np.zeros((dim, n))
    H[:, :dim] = np.eye(dim)
    imm = IMM([cv, ct], [[0.95, 0.05], [0.05, 0.95]], x0, P0, [0.9, 0.1])
    xc, Pc = x0[: 2 * dim].copy(), P0[: 2 * dim, : 2 * dim].copy()
    xt, Pt = x0.copy(), P0.copy()
    K = len(z)
    se = np.zeros((3, K))
    mu_turn = np.zeros(K)
    for k in range(1, K):
        imm.predict()
        imm.update(z[k], R, H=H)
        xc, Pc = kf_predict(xc, Pc, cv.F, cv.Q)
        u = kf_update(xc, Pc, z[k], H[:, : 2 * dim], R)
        xc, Pc = u.x, u.P
        xt, Pt = ekf_predict(xt, Pt, ct.transition, ct.jacobian, ct.Q)
        u = kf_update(xt, Pt, z[k], H, R)
        xt, Pt = u.x, u.P
        for i, est in enumerate((imm.x, xc, xt)):
            se[i, k] = np.sum((est[:dim] - truth[k]) ** 2)
        mu_turn[k] = imm.mu[1]
        assert np.isclose(imm.mu.sum(), 1.0)
    return se, mu_turn, mode


@pytest.mark.parametrize("dim, seeds", [(2, range(5)), (3, range(3))])
def test_imm_beats_single_models_and_follows_the_turn(dim: int, seeds) -> None:
    runs = [_run(s, dim) for s in seeds]
    se = np.stack([r[0] for r in runs])[:, :, 5:]  # skip the initial transient
    rmse = np.sqrt(se.mean(axis=(0, 2)))
    imm_rmse, cv_rmse, ct_rmse = rmse
    assert imm_rmse < cv_rmse, rmse
    assert imm_rmse < ct_rmse, rmse
    mu = np.stack([r[1] for r in runs])
    mode = runs[0][2]
    on = np.flatnonzero(mode == 1)
    # windows: before the turn, inside it (after a short reaction delay), after it (settled)
    before = mu[:, 10 : on[0]].mean()
    during = mu[:, on[0] + 6 : on[-1] + 1].mean()
    after = mu[:, on[-1] + 10 :].mean()
    assert during > 0.6 and before < 0.45 and after < 0.45, (before, during, after)
    assert during - max(before, after) > 0.3


def test_imm_predict_only_keeps_probabilities_on_markov_chain() -> None:
    cv = ConstantVelocityModel(2, 1.0, q=0.1)
    ct = CoordinatedTurnModel(2, 1.0, q=0.1, q_turn=1e-3)
    Pi = np.array([[0.9, 0.1], [0.2, 0.8]])
    imm = IMM([cv, ct], Pi, np.zeros(5), np.eye(5), [1.0, 0.0])
    for _ in range(200):
        imm.predict()
    # stationary distribution of the chain: pi Pi = pi -> (2/3, 1/3)
    np.testing.assert_allclose(imm.mu, [2 / 3, 1 / 3], atol=1e-12)


def test_imm_single_model_equals_kalman_filter() -> None:
    """One CV model with a trivial chain is the plain Kalman filter."""
    rng = np.random.default_rng(1)
    cv = ConstantVelocityModel(2, 0.5, q=0.2)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = 4.0 * np.eye(2)
    x, P = np.zeros(4), 10 * np.eye(4)
    imm = IMM([cv], [[1.0]], x, P)
    for _ in range(20):
        z = rng.normal(size=2)
        x, P = kf_predict(x, P, cv.F, cv.Q)
        u = kf_update(x, P, z, H, R)
        x, P = u.x, u.P
        imm.predict()
        imm.update(z, R, H=H)
    np.testing.assert_allclose(imm.x, x, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(imm.P, P, rtol=1e-12, atol=1e-12)


def test_imm_rejects_bad_transition() -> None:
    cv = ConstantVelocityModel(2, 1.0)
    with pytest.raises(ValueError):
        IMM([cv, cv], [[0.5, 0.6], [0.5, 0.5]], np.zeros(4), np.eye(4))


def test_imm_nonlinear_measurement_path_matches_direct_ekf() -> None:
    """Range measurements to three anchors (h, H_jac on the joint state): each model-matched
    update must be the EKF update of that model seen through its embedding."""
    from aquasim_py.estimation import ekf_update

    anchors = np.array([[0.0, 0.0], [100.0, 0.0], [0.0, 100.0]])

    def h(s):
        return np.linalg.norm(s[:2] - anchors, axis=1)

    def H_jac(s):
        J = np.zeros((3, s.size))
        J[:, :2] = (s[:2] - anchors) / h(s)[:, None]
        return J

    cv = ConstantVelocityModel(2, 1.0, q=0.1)
    ct = CoordinatedTurnModel(2, 1.0, q=0.1, q_turn=1e-3)
    x0 = np.array([40.0, 30.0, 1.0, -0.5, 0.02])
    P0 = np.diag([25.0, 25.0, 1.0, 1.0, 1e-3])
    Pi = np.array([[0.9, 0.1], [0.1, 0.9]])
    imm = IMM([cv, ct], Pi, x0, P0, [0.6, 0.4])
    imm.predict()
    xs_pred = [x.copy() for x in imm.xs]
    Ps_pred = [P.copy() for P in imm.Ps]
    z = np.array([52.0, 70.0, 76.0])
    R = 0.5 * np.eye(3)
    imm.update(z, R, h=h, H_jac=H_jac)

    # CV: the joint state with omega = 0; CT: the joint state itself
    def pad(s):
        return np.append(s, 0.0)

    u_cv = ekf_update(xs_pred[0], Ps_pred[0], z, lambda s: h(pad(s)), lambda s: H_jac(pad(s))[:, :4], R)
    u_ct = ekf_update(xs_pred[1], Ps_pred[1], z, h, H_jac, R)
    np.testing.assert_allclose(imm.xs[0], u_cv.x, rtol=1e-13)
    np.testing.assert_allclose(imm.xs[1], u_ct.x, rtol=1e-13)
    np.testing.assert_allclose(imm.log_likelihoods, [u_cv.log_likelihood, u_ct.log_likelihood], rtol=1e-13)
    # mode probabilities: Bayes with the predicted probabilities c_j = sum_i mu_i Pi_ij
    c = np.array([0.6, 0.4]) @ Pi
    post = c * np.exp(imm.log_likelihoods)
    np.testing.assert_allclose(imm.mu, post / post.sum(), rtol=1e-12)


def test_imm_mixing_matches_textbook_formulas() -> None:
    """Two CV models (different q): the mixed initial condition of model j is
    x0j = sum_i w_ij x_i, P0j = sum_i w_ij (P_i + (x_i - x0j)(x_i - x0j)^T),
    w_ij = mu_i Pi_ij / c_j (Bar-Shalom et al. 11.6.6)."""
    rng = np.random.default_rng(9)
    m1, m2 = ConstantVelocityModel(2, 1.0, q=0.01), ConstantVelocityModel(2, 1.0, q=1.0)
    Pi = np.array([[0.8, 0.2], [0.3, 0.7]])
    imm = IMM([m1, m2], Pi, np.zeros(4), np.eye(4), [0.35, 0.65])
    xs = [rng.normal(size=4), rng.normal(size=4)]
    Ps = []
    for _ in range(2):
        A = rng.normal(size=(4, 4))
        Ps.append(A @ A.T + np.eye(4))
    imm.xs, imm.Ps = [x.copy() for x in xs], [P.copy() for P in Ps]
    mu = imm.mu.copy()
    imm.predict()
    c = mu @ Pi
    for j, m in enumerate((m1, m2)):
        w = mu * Pi[:, j] / c[j]
        x0 = w[0] * xs[0] + w[1] * xs[1]
        P0 = sum(w[i] * (Ps[i] + np.outer(xs[i] - x0, xs[i] - x0)) for i in range(2))
        np.testing.assert_allclose(imm.xs[j], m.F @ x0, rtol=1e-12)
        np.testing.assert_allclose(imm.Ps[j], m.F @ P0 @ m.F.T + m.Q, rtol=1e-12)
    np.testing.assert_allclose(imm.mu, c, rtol=1e-12)
