"""Ramezani et al. (IEEE TSP 2013), Sec. V: the tracking Monte Carlo study behind Figs 10-11
(an experiment driver, kept out of the importable library).

``tracking_monte_carlo(n, ...)`` draws n random-walk trajectories of the paper's model (eq 38),
exact isogradient ToFs plus noise, depth reports every rho frames, runs EKF-ESSP / EKF-ASSP
(:func:`aquasim_protocols.ramezani.math.batched_ekf`) and the PCRB along the trajectories.
Used by ``tools/ramezani_figures.py`` and the slow test ``tests/estimation/test_ramezani_tracking.py``.

    python tools/ramezani_mc.py --runs 200 --sigma-t-ms 1
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from aquasim_protocols.ramezani.math import (
    PAPER_A,
    PAPER_B,
    TETRAHEDRON,
    batched_ekf,
    essp_model,
    paper_transition,
    pcrb_along,
    tof_functions,
)

__all__ = ["TrackingMC", "simulate_trajectories", "tracking_monte_carlo"]

Array = NDArray[np.float64]


def simulate_trajectories(
    rng: np.random.Generator,
    n: int,
    K: int,
    x0: ArrayLike,
    v0: ArrayLike = (0.0, 0.0, 0.0),
    *,
    Ts: float = 10.0,
    q_xy: float = 1e-2,
    q_z: float = 1e-3,
    z_max: float | None = None,
) -> tuple[Array, float]:
    """n true state sequences s_0..s_K (n, K+1, 6) of s_k = Phi s_{k-1} + w_k (eq 38).

    The linear model lets a depth random walk leave the water (its std after 500 frames is
    about 65 m at q_z = 1e-3); such trajectories (any z < 0, or z > ``z_max``) are redrawn, so
    every kept one is an exact sample of the model conditioned on staying in the water.
    Returns (states, fraction of draws rejected).
    """
    out = np.empty((0, K + 1, 6))
    drawn = kept = 0
    std = np.array([q_xy, q_xy, q_z])
    while out.shape[0] < n:
        m = max(2 * (n - out.shape[0]), 16)
        w = rng.standard_normal((m, K, 3)) * std
        v = np.concatenate(
            [np.broadcast_to(np.asarray(v0, float), (m, 1, 3)), np.asarray(v0, float) + np.cumsum(w, axis=1)], axis=1
        )
        # x_k = x_{k-1} + Ts v_{k-1}
        x = np.asarray(x0, float) + Ts * np.concatenate([np.zeros((m, 1, 3)), np.cumsum(v[:, :-1], axis=1)], axis=1)
        keep = np.all(x[..., 2] >= 0.0, axis=1)
        if z_max is not None:
            keep &= np.all(x[..., 2] <= z_max, axis=1)
        # count draws up to the n-th kept one, so the rejected fraction does not depend on m
        need = n - out.shape[0]
        used = int(np.searchsorted(np.cumsum(keep), need) + 1) if keep.sum() >= need else m
        drawn += used
        kept += int(keep[:used].sum())
        out = np.concatenate([out, np.concatenate([x, v], axis=-1)[:used][keep[:used]]])
    return out[:n], 1.0 - kept / drawn if drawn else 0.0


@dataclass(frozen=True)
class TrackingMC:
    """Per-frame Monte Carlo statistics of :func:`tracking_monte_carlo` (arrays (K,), k = 1..K)."""

    mse: dict[str, Array]  #: E||x_hat_k - x_k||^2 per model (m^2)
    bias: dict[str, Array]  #: ||E[x_hat_k - x_k]|| per model (m): the offset of Fig. 10
    pcrb: Array  #: mean PCRB_k over the trajectories (m^2, eq 42)
    distance: Array  #: mean distance of the target from the anchors' centroid (m)
    rejected: float  #: fraction of drawn trajectories that left the water (redrawn)
    clipped: dict[str, int]  #: EKF linearizations moved to the surface, per model

    def rmse(self, model: str, k1: int = 300, k2: int | None = None) -> float:
        """RMSE over frames k1..k2 (eq 45, 1-based, inclusive; k2 default K)."""
        return float(np.sqrt(self.mse[model][k1 - 1 : k2].mean()))

    def sqrt_pcrb(self, k1: int = 300, k2: int | None = None) -> float:
        return float(np.sqrt(self.pcrb[k1 - 1 : k2].mean()))


def tracking_monte_carlo(
    n: int,
    *,
    seed: int = 0,
    K: int = 500,
    x0: ArrayLike = (500.0, 50.0, 50.0),
    anchors: ArrayLike = TETRAHEDRON,
    sigma_t: float = 1e-3,
    sigma_z: float = 1.0,
    rho: int = 10,
    Ts: float = 10.0,
    q_xy: float = 1e-2,
    q_z: float = 1e-3,
    b: float = PAPER_B,
    a: float = PAPER_A,
    guess_offset: float = 30.0,
    p0_vel_std: float = 0.01,
    models: tuple[str, ...] = ("essp", "assp"),
    pcrb_runs: int | None = None,
) -> TrackingMC:
    """The paper's tracking study (Sec. V): n random-walk trajectories from rest at ``x0``
    (:func:`simulate_trajectories`), exact isogradient ToFs plus N(0, sigma_t^2), depth
    readings N(z, sigma_z^2) every ``rho`` frames, EKF-ESSP / EKF-ASSP from the initial guess
    x0 + ``guess_offset`` on every axis with P0 = diag(guess_offset^2 I, p0_vel_std^2 I), and
    the PCRB with J0 = P0^-1 along the first ``pcrb_runs`` (default all) trajectories.
    """
    rng = np.random.default_rng(seed)
    A = np.asarray(anchors, dtype=float)
    S, rejected = simulate_trajectories(rng, n, K, x0, Ts=Ts, q_xy=q_xy, q_z=q_z)
    X = S[:, 1:, :3]
    tt, _ = essp_model(b, a)
    tofs = tt(A, X[:, :, None, :]) + sigma_t * rng.standard_normal((n, K, len(A)))
    depths = X[..., 2] + sigma_z * rng.standard_normal((n, K))
    Phi, Q = paper_transition(Ts, q_xy, q_z)
    P0 = np.diag([guess_offset**2] * 3 + [p0_vel_std**2] * 3)
    prior = S[:, 0].copy()
    prior[:, :3] += guess_offset
    prior[:, 3:] = 0.0
    mse, bias, clipped = {}, {}, {}
    for m in models:
        tf, gf = tof_functions(m, b, a, A)
        r = batched_ekf(tofs, depths, A, tf, gf, prior, P0, Phi, Q, sigma_t, sigma_z, rho)
        err = r.x[:, 1:, :3] - X
        mse[m] = np.mean(np.sum(err**2, axis=-1), axis=0)
        bias[m] = np.linalg.norm(err.mean(axis=0), axis=-1)
        clipped[m] = r.clipped
    steps = np.arange(1, K + 1)
    depth_steps = (steps % rho == 0) if rho > 0 else np.zeros(K, bool)
    npc = n if pcrb_runs is None else min(n, pcrb_runs)
    pc = pcrb_along(X[:npc], A, b, a, sigma_t, P0, Phi, Q, sigma_z=sigma_z, depth_steps=depth_steps)
    dist = np.linalg.norm(X - A.mean(axis=0), axis=-1).mean(axis=0)
    return TrackingMC(mse, bias, pc.mean(axis=0), dist, rejected, clipped)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--runs", type=int, default=200, help="Monte Carlo trajectories")
    ap.add_argument("--sigma-t-ms", type=float, default=1.0, help="ToF noise std (ms)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    r = tracking_monte_carlo(args.runs, seed=args.seed, sigma_t=args.sigma_t_ms * 1e-3, pcrb_runs=min(args.runs, 200))
    pc = r.sqrt_pcrb()
    for m in ("essp", "assp"):
        print(
            f"EKF-{m.upper()}: RMSE over frames 300-500 {r.rmse(m):.4g} m, sqrt(PCRB) {pc:.4g} m, ratio {r.rmse(m) / pc:.3f}"
        )


if __name__ == "__main__":
    main()
