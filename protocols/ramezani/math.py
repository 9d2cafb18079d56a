"""Ramezani et al. (IEEE TSP 2013) localization and tracking maths, vectorized over Monte
Carlo draws (numpy only, no SimPy): the ToF models of GNA/EKF-ESSP and -ASSP, the paper's
tracking model (eqs 38-40), a batched EKF (Algorithm 2), the PCRB along true trajectories
(eqs 41-42) and the CRB of a fix (eqs 30-33, 37).

Shared by the network protocol (:mod:`aquasim_protocols.ramezani.node`), its metrics, the
acceptance tests and the paper-figure drivers in ``tools/`` (the Monte Carlo study of Sec. V is
``tools/ramezani_mc.py``). The generic pieces (Gauss-Newton, CRB / PCRB recursions,
closed-form isogradient eigenrays) come from :mod:`aquasim_py.estimation` and
:mod:`aquasim_py.channel`; only what is specific to the paper lives here.

Conventions: metres, seconds, z = depth positive down. The ToF of anchor n is the travel time
of the ray from the anchor (source) to the target (receiver), so d t / d x is the gradient of
:func:`aquasim_py.channel.travel_time` with respect to its ``dst``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np
from numpy.typing import ArrayLike, NDArray

from aquasim_py.channel import Isogradient, travel_time, travel_time_gradient
from aquasim_py.estimation import (
    DegenerateGeometryError,
    EstimationError,
    constant_speed_tof,
    crb_trace,
    gauss_newton,
    gauss_newton_batch,
    pcrb_information,
    pcrb_position,
    tof_model,
)

__all__ = [
    "CUBE_VERTICES",
    "PAPER_A",
    "PAPER_B",
    "TETRAHEDRON",
    "EKFRun",
    "assp_model",
    "batched_ekf",
    "ddn_variance",
    "essp_model",
    "fix_crb",
    "fix_crb_ddn",
    "localize_batch",
    "paper_transition",
    "pcrb_along",
    "tof_functions",
    "v_bar",
]

Array = NDArray[np.float64]
TofFn = Callable[[Array, Array], Array]

#: the paper's isogradient profile c(z) = b + a z (Section V)
PAPER_B, PAPER_A = 1480.0, 0.1
#: the eight vertices of the paper's 100 m cube; the first four form the regular tetrahedron
#: (the non-coplanar choice of four whose centroid is the paper's [50, 50, 50]); Fig. 14 adds
#: the others one by one
CUBE_VERTICES = np.array(
    [
        [0.0, 0.0, 0.0],
        [100.0, 100.0, 0.0],
        [100.0, 0.0, 100.0],
        [0.0, 100.0, 100.0],
        [100.0, 0.0, 0.0],
        [0.0, 100.0, 0.0],
        [0.0, 0.0, 100.0],
        [100.0, 100.0, 100.0],
    ]
)
TETRAHEDRON = CUBE_VERTICES[:4]


def v_bar(b: float, a: float, anchors: ArrayLike) -> float:
    """GNA/EKF-ASSP speed (m/s): [C(max_n z_n) + C(min_n z_n)] / 2 over the anchor depths (Sec. V)."""
    z = np.asarray(anchors, dtype=float)[..., 2]
    return float(b + a * 0.5 * (z.max() + z.min()))


def essp_model(b: float, a: float, *, continued: bool = False) -> tuple[TofFn, TofFn]:
    """(time_fn, grad_fn) of the exact isogradient ray model (eqs 13, 15-18), direct arc only:
    the model a node with profile knowledge (b, a) fits.

    ``continued=False``: the channel's closed forms, NaN where the arc leaves the water (a
    Gauss-Newton iterate above the surface then has no model value). ``continued=True``: the
    same closed forms evaluated without the water-column check, i.e. eq 13 analytically
    continued to any point with c > 0 (what an estimator coded from the paper's formulas
    does); identical in the water (tested against the channel).
    """
    if continued:
        return partial(_continued_time, b, a), partial(_continued_grad, b, a)
    ssp = Isogradient(b, a)
    return (partial(travel_time, ssp, reflections="none"), partial(travel_time_gradient, ssp, reflections="none"))


def _continued_parts(b: float, a: float, src: Array, dst: Array) -> tuple[Array, ...]:
    s = np.asarray(src, dtype=float)
    d = np.asarray(dst, dtype=float)
    diff = d - s
    D = np.linalg.norm(diff, axis=-1)
    c1 = b + a * s[..., 2]
    c2 = b + a * d[..., 2]
    with np.errstate(invalid="ignore"):
        g = np.sqrt(c1 * c2)  # NaN where a speed is not positive: no model there
    y = abs(a) * D / (2.0 * g)
    return diff, D, c2, g, y


def _continued_time(b: float, a: float, src: Array, dst: Array) -> Array:
    """Eq 13 as t = (D / g) asinh(y) / y, g = sqrt(c1 c2), y = |a| D / (2 g): no 1/a, exact at a = 0."""
    _, D, _, g, y = _continued_parts(b, a, src, dst)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(y < 1e-6, 1.0 - y * y / 6.0, np.arcsinh(y) / np.where(y < 1e-6, 1.0, y))
    return D / g * ratio


def _continued_grad(b: float, a: float, src: Array, dst: Array) -> Array:
    """d t / d dst of :func:`_continued_time`: ((dx, dy, dz) / D - (0, 0, a D / (2 c2))) / (g sqrt(1 + y^2))."""
    diff, D, c2, g, y = _continued_parts(b, a, src, dst)
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(D[..., None] > 0.0, diff / np.where(D > 0.0, D, 1.0)[..., None], 0.0)
        u[..., 2] -= a * D / (2.0 * c2)
        return u / (g * np.sqrt(1.0 + y * y))[..., None]


def assp_model(b: float, a: float, anchors: ArrayLike) -> tuple[TofFn, TofFn]:
    """(time_fn, grad_fn) of the straight-ray model at the one speed v_bar (footnote 1)."""
    return constant_speed_tof(v_bar(b, a, anchors))


def tof_functions(
    model: str, b: float, a: float, anchors: ArrayLike, *, continued: bool = False
) -> tuple[TofFn, TofFn]:
    """The ToF model by name: ``"essp"`` (exact SSP; ``continued`` as in :func:`essp_model`) or
    ``"assp"`` (average speed)."""
    if model == "essp":
        return essp_model(b, a, continued=continued)
    if model == "assp":
        return assp_model(b, a, anchors)
    raise ValueError(f"model must be 'essp' or 'assp', got {model!r}")


# --------------------------------------------------------------------------- localization
def fix_crb(
    anchors: ArrayLike, x: ArrayLike, b: float, a: float, sigma_t: float, sigma_z: float | None = None
) -> Array:
    """CRB (m^2, trace of I^-1, eqs 30-33) of one fix at true positions x (..., 3) with
    distance-independent ToF noise ``sigma_t`` (s) and, if given, a depth measurement of std
    ``sigma_z`` (m, eq 37). The gradient is the exact isogradient one (eqs 15-18)."""
    A = np.asarray(anchors, dtype=float)
    x = np.asarray(x, dtype=float)
    _, grad = essp_model(b, a)
    J = grad(A, x[..., None, :])
    var = np.full(J.shape[:-1], sigma_t**2)
    if sigma_z is not None:
        J = np.concatenate([J, np.broadcast_to([0.0, 0.0, 1.0], J.shape[:-2] + (1, 3))], axis=-2)
        var = np.concatenate([var, np.full(var.shape[:-1] + (1,), sigma_z**2)], axis=-1)
    return crb_trace(J, var)


def ddn_variance(
    anchors: ArrayLike,
    x: ArrayLike,
    b: float,
    a: float,
    k_e_s2: float,
    *,
    l0_m: float = 1000.0,
    beta: float = 2.0,
    absorption_db_per_km: float = 1.0,
    step_m: float = 1e-3,
) -> tuple[Array, Array]:
    """Distance-dependent ToF noise (eqs 34-36) at true positions x (..., 3): the variance
    (..., N) s^2 of each anchor's ToF from the direct arc's length l (eq 19), and its gradient
    d sigma^2 / dx (..., N, 3) = d sigma^2 / dl * dl / dx (eq 36). dl/dx by central differences
    of the closed-form arc length (step ``step_m``): the channel has no closed-form arc-length
    gradient, and the term it feeds is small next to the ToF term of the FIM."""
    from aquasim_py.channel.isogradient import arc_length
    from aquasim_py.channel.loss import tof_noise_variance_derivative_s2_per_m, tof_noise_variance_s2

    A = np.asarray(anchors, dtype=float)
    x = np.asarray(x, dtype=float)[..., None, :]
    length = arc_length(b, a, A, x)
    kw = dict(k=beta, l0_m=l0_m, absorption_db_per_km=absorption_db_per_km)
    var = tof_noise_variance_s2(length, k_e_s2, **kw)
    e = np.eye(3) * step_m
    dl = np.stack(
        [(arc_length(b, a, A, x + e[i]) - arc_length(b, a, A, x - e[i])) / (2 * step_m) for i in range(3)], axis=-1
    )
    dvar = tof_noise_variance_derivative_s2_per_m(length, k_e_s2, **kw)[..., None] * dl
    return var, dvar


def fix_crb_ddn(anchors: ArrayLike, x: ArrayLike, b: float, a: float, k_e_s2: float, **kw: float) -> Array:
    """CRB (m^2) of one fix with distance-dependent noise: both terms of eq 30 (eqs 34-36)."""
    A = np.asarray(anchors, dtype=float)
    x = np.asarray(x, dtype=float)
    _, grad = essp_model(b, a)
    var, dvar = ddn_variance(A, x, b, a, k_e_s2, **kw)
    return crb_trace(grad(A, x[..., None, :]), var, dvar)


def localize_batch(
    anchors: ArrayLike,
    tofs: ArrayLike,
    time_fn: TofFn,
    grad_fn: TofFn,
    sigma_t: float,
    x0: ArrayLike,
    *,
    depth: ArrayLike | None = None,
    sigma_z: float | None = None,
    max_iter: int = 7,
    tol: float = 1e-3,
    rescue: bool = True,
) -> tuple[Array, NDArray[np.bool_], NDArray[np.bool_]]:
    """Algorithm 1 (K = ``max_iter``, eps = ``tol``) on B draws at once, ToFs (B, N) in s.

    Rows where the plain algorithm fails (an iterate leaves the model's domain, e.g. above the
    sea surface where there is no ray, or the Jacobian is singular) or does not stop within K
    steps are, with ``rescue``, solved again one by one by :func:`gauss_newton` (step halving
    plus Levenberg-Marquardt fallback) from the same start. Returns (X (B, 3), plain_ok (B,),
    rescued (B,)); rows that could not be solved at all are NaN.
    """
    t = np.asarray(tofs, dtype=float)
    B = t.shape[0]
    X0 = np.broadcast_to(np.asarray(x0, dtype=float), (B, 3))
    fun = tof_model(anchors, t, time_fn, grad_fn, sigma=sigma_t, depth=depth, sigma_depth=sigma_z)
    X, _, ok = gauss_newton_batch(fun, X0, max_iter, tol)
    rescued = np.zeros(B, dtype=bool)
    if rescue and not ok.all():
        zd = None if depth is None else np.broadcast_to(np.asarray(depth, dtype=float), (B,))
        # a loop only over the failed rows (a few per cent): the robust solver is sequential
        for i in np.flatnonzero(~ok):
            f1 = tof_model(
                anchors, t[i], time_fn, grad_fn, sigma=sigma_t, depth=None if zd is None else zd[i], sigma_depth=sigma_z
            )
            try:
                X[i] = gauss_newton(f1, X0[i], max_iter, tol).x
                rescued[i] = True
            except (DegenerateGeometryError, EstimationError):
                X[i] = np.nan
    return X, ok, rescued


# --------------------------------------------------------------------------- tracking
def paper_transition(Ts: float, q_xy: float = 1e-2, q_z: float = 1e-3) -> tuple[Array, Array]:
    """(Phi, Q) of Section V: Phi = [[I, Ts I], [0, I]] (eq 38), Q = blockdiag(0, diag(q_xy^2,
    q_xy^2, q_z^2)): the process noise moves the velocity only (std per frame, m/s)."""
    Phi = np.eye(6)
    Phi[:3, 3:] = Ts * np.eye(3)
    Q = np.zeros((6, 6))
    Q[3:, 3:] = np.diag([q_xy**2, q_xy**2, q_z**2])
    return Phi, Q


@dataclass(frozen=True)
class EKFRun:
    """Output of :func:`batched_ekf`."""

    x: Array  #: posterior states (B, K+1, 6), index 0 = the prior
    P_pos: Array  #: trace of the position block of P (B, K+1), m^2
    clipped: int  #: linearizations evaluated at z = 0 because the prediction was above the surface


def batched_ekf(
    tofs: ArrayLike,
    depths: ArrayLike | None,
    anchors: ArrayLike,
    time_fn: TofFn,
    grad_fn: TofFn,
    x0: ArrayLike,
    P0: ArrayLike,
    Phi: ArrayLike,
    Q: ArrayLike,
    sigma_t: float,
    sigma_z: float = 1.0,
    rho: int = 10,
) -> EKFRun:
    """Algorithm 2 on B independent runs at once (Joseph-form update, as
    :func:`aquasim_py.estimation.ekf_update`, batched).

    tofs (B, K, N) s: measured ToFs of frames k = 1..K; depths (B, K) m or None: depth readings,
    used when mod(k, rho) == 0 (eq 40, H and R extended by a depth row); x0 (B, 6) or (6,) and
    P0 (6, 6): the prior s_0. A prediction above the surface (no ray there) is linearized at
    z = 0 (counted in ``clipped``).
    """
    T = np.asarray(tofs, dtype=float)
    B, K, N = T.shape
    A = np.asarray(anchors, dtype=float)
    Phi = np.asarray(Phi, dtype=float)
    Q = np.asarray(Q, dtype=float)
    x = np.array(np.broadcast_to(np.asarray(x0, dtype=float), (B, 6)))
    P = np.array(np.broadcast_to(np.asarray(P0, dtype=float), (B, 6, 6)))
    xs = np.empty((B, K + 1, 6))
    pp = np.empty((B, K + 1))
    xs[:, 0], pp[:, 0] = x, np.trace(P[:, :3, :3], axis1=1, axis2=2)
    Z = None if depths is None else np.asarray(depths, dtype=float)
    clipped = 0
    eye = np.eye(6)
    for k in range(1, K + 1):  # the recursion is sequential in k; vectorized over runs
        x = x @ Phi.T
        P = Phi @ P @ Phi.T + Q
        pos = x[:, :3].copy()
        above = pos[:, 2] < 0.0
        clipped += int(above.sum())
        pos[above, 2] = 0.0
        h = time_fn(A, pos[:, None, :])  # (B, N)
        G = grad_fn(A, pos[:, None, :])  # (B, N, 3)
        H = np.zeros((B, N, 6))
        H[:, :, :3] = G
        y = T[:, k - 1] - h
        r = np.full(N, sigma_t**2)
        if Z is not None and rho > 0 and k % rho == 0:
            Hz = np.zeros((B, 1, 6))
            Hz[:, 0, 2] = 1.0
            H = np.concatenate([H, Hz], axis=1)
            y = np.concatenate([y, (Z[:, k - 1] - x[:, 2])[:, None]], axis=1)
            r = np.append(r, sigma_z**2)
        PHt = P @ np.swapaxes(H, 1, 2)  # (B, 6, M)
        S = H @ PHt + np.diag(r)
        Kg = np.swapaxes(np.linalg.solve(S, np.swapaxes(PHt, 1, 2)), 1, 2)  # P H^T S^-1 (S symmetric)
        x = x + np.einsum("bnm,bm->bn", Kg, y)
        IKH = eye - Kg @ H
        P = IKH @ P @ np.swapaxes(IKH, 1, 2) + (Kg * r) @ np.swapaxes(Kg, 1, 2)
        P = 0.5 * (P + np.swapaxes(P, 1, 2))
        xs[:, k], pp[:, k] = x, np.trace(P[:, :3, :3], axis1=1, axis2=2)
    return EKFRun(xs, pp, clipped)


def pcrb_along(
    positions: ArrayLike,
    anchors: ArrayLike,
    b: float,
    a: float,
    sigma_t: float,
    P0: ArrayLike,
    Phi: ArrayLike,
    Q: ArrayLike,
    *,
    sigma_z: float | None = None,
    depth_steps: ArrayLike | None = None,
    mask: ArrayLike | None = None,
) -> Array:
    """PCRB_k (m^2, eq 42) along true positions (..., K, 3) of frames 1..K (eq 41, J0 = P0^-1).

    The ToF rows use the exact isogradient gradient at the true position (H-bar of eq 41);
    ``depth_steps`` (K,) or (..., K) bool adds the depth row [0, 0, 1] of std ``sigma_z`` on those
    frames; ``mask`` (..., K, N) bool keeps only the anchors actually heard in a frame.
    """
    X = np.asarray(positions, dtype=float)
    A = np.asarray(anchors, dtype=float)
    _, grad = essp_model(b, a)
    G = grad(A, X[..., None, :])  # (..., K, N, 3)
    var = np.full(G.shape[:-1], sigma_t**2)
    if mask is not None:
        # an anchor not heard carries no information: infinite variance
        var = np.where(np.asarray(mask, bool), var, np.inf)
    G = np.where(np.isfinite(var)[..., None], G, 0.0)
    H = np.zeros(G.shape[:-1] + (6,))
    H[..., :3] = G
    info = np.einsum("...ki,...k,...kj->...ij", H, 1.0 / var, H)
    if depth_steps is not None and sigma_z is not None:
        d = np.broadcast_to(np.asarray(depth_steps, bool), info.shape[:-2])
        info = info.copy()
        info[..., 2, 2] += np.where(d, 1.0 / sigma_z**2, 0.0)
    J0 = np.linalg.inv(np.asarray(P0, dtype=float))
    Jseq = pcrb_information(J0, Phi, Q, info)
    return pcrb_position(Jseq)
