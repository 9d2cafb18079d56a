"""Test trajectories computed in closed form (complex-number arcs), independently of the
motion models under test."""

from __future__ import annotations

import numpy as np


def cv_turn_cv(
    dt: float,
    n_cv1: int,
    n_turn: int,
    n_cv2: int,
    speed: float,
    omega: float,
    vz: float = 0.0,
    heading: float = 0.0,
) -> tuple[np.ndarray, np.ndarray]:
    """Exact positions (K, 3) and the mode per step (K,) (0 = straight, 1 = turning) of a target
    that goes straight, turns at ``omega`` rad/s (counter-clockwise in x-y), then goes straight.
    Step k is the state at time k * dt; z = vz * t."""
    K = 1 + n_cv1 + n_turn + n_cv2
    p = np.zeros(K, dtype=complex)
    v = speed * np.exp(1j * heading)
    mode = np.zeros(K, dtype=int)
    for k in range(1, K):
        turning = n_cv1 < k <= n_cv1 + n_turn
        if turning:
            rot = np.exp(1j * omega * dt)
            # exact arc: p(t) = p0 + v0 (e^{i w t} - 1) / (i w)
            p[k] = p[k - 1] + v * (rot - 1.0) / (1j * omega)
            v = v * rot
            mode[k] = 1
        else:
            p[k] = p[k - 1] + v * dt
    t = np.arange(K) * dt
    return np.column_stack([p.real, p.imag, vz * t]), mode
