"""PCRLB recursion against the Kalman filter's covariance, and subset selection against a brute
force over det J."""

from __future__ import annotations

import itertools

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from aquasim_py.estimation import ConstantVelocityModel, best_subset, particle_information, pcrlb_step


def test_linear_gaussian_pcrlb_is_the_kalman_covariance() -> None:
    """For a linear-Gaussian model the PCRLB equals the KF posterior covariance (Tichavsky)."""
    m = ConstantVelocityModel(dim=2, dt=1.0, q=1.0)
    F, Q = m.F, m.Q
    H = np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0]])
    R = np.diag([4.0, 9.0])
    P = 10.0 * np.eye(4)
    J = np.linalg.inv(P)
    for _ in range(20):
        Pp = F @ P @ F.T + Q
        K = Pp @ H.T @ np.linalg.inv(H @ Pp @ H.T + R)
        P = (np.eye(4) - K @ H) @ Pp
        J = pcrlb_step(J, F, Q, H.T @ np.linalg.inv(R) @ H)
        np.testing.assert_allclose(np.linalg.inv(J), P, rtol=1e-9, atol=1e-12)


@settings(max_examples=12, deadline=None)
@given(seed=st.integers(0, 2**31), C=st.integers(3, 8), k=st.integers(1, 4))
def test_selection_matches_brute_force_det(seed: int, C: int, k: int) -> None:
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(4, 4))
    J0 = A @ A.T + 0.1 * np.eye(4)
    g = rng.normal(size=(C, 4))
    infos = np.einsum("ci,cj->cij", g, g) * rng.uniform(0.1, 2.0, C)[:, None, None]
    k = min(k, C)
    best, best_det = None, -np.inf
    for sub in itertools.combinations(range(C), k):  # the brute force, one det per subset
        d = np.linalg.det(J0 + sum(infos[i] for i in sub))
        if d > best_det * (1 + 1e-12):
            best, best_det = sub, d
    assert tuple(best_subset(J0, infos, k).tolist()) == best


def test_particle_information_is_the_average_outer_product() -> None:
    rng = np.random.default_rng(3)
    G = rng.normal(size=(50, 2))
    s = rng.uniform(0, 1, 50)
    ref = sum(s[i] * np.outer(G[i], G[i]) for i in range(50)) / 50
    out = particle_information(G, s, [0, 1], 4)
    np.testing.assert_allclose(out[:2, :2], ref, rtol=1e-12)
    assert np.all(out[2:, :] == 0) and np.all(out[:, 2:] == 0)
