"""IMM (CV Kalman + coordinated-turn EKF) on a straight -> turn -> straight trajectory."""

from __future__ import annotations

import numpy as np
import pytest

from aquasim_py.estimation import (
    IMM,
    ConstantVelocity,
    CoordinatedTurn,
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
    cv = ConstantVelocity(dim, DT, q=0.01)
    ct = CoordinatedTurn(dim, DT, q=0.01, q_turn=1e-4)
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
    cv = ConstantVelocity(2, 1.0, q=0.1)
    ct = CoordinatedTurn(2, 1.0, q=0.1, q_turn=1e-3)
    Pi = np.array([[0.9, 0.1], [0.2, 0.8]])
    imm = IMM([cv, ct], Pi, np.zeros(5), np.eye(5), [1.0, 0.0])
    for _ in range(200):
        imm.predict()
    # stationary distribution of the chain: pi Pi = pi -> (2/3, 1/3)
    np.testing.assert_allclose(imm.mu, [2 / 3, 1 / 3], atol=1e-12)


def test_imm_single_model_equals_kalman_filter() -> None:
    """One CV model with a trivial chain is the plain Kalman filter."""
    rng = np.random.default_rng(1)
    cv = ConstantVelocity(2, 0.5, q=0.2)
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
    cv = ConstantVelocity(2, 1.0)
    with pytest.raises(ValueError):
        IMM([cv, cv], [[0.5, 0.6], [0.5, 0.5]], np.zeros(4), np.eye(4))
