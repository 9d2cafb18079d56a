"""Cramér-Rao bounds: Fisher information for independent Gaussian measurements with
distance-independent or distance-dependent variance (Ramezani et al., eqs 30-36), and the
recursive posterior CRB for a linear-Gaussian motion model with a nonlinear measurement
(eqs 41-42; Tichavsky et al. 1998).

Everything broadcasts over leading axes, so a Monte Carlo set of target positions or
trajectories is one call.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ._linalg import spd_inverse, symmetrize
from .errors import DegenerateGeometryError, SingularMatrixError

__all__ = [
    "crb",
    "crb_trace",
    "fisher_information",
    "measurement_information",
    "pcrb_information",
    "pcrb_position",
    "range_crb_trace",
]

Array = NDArray[np.float64]


def fisher_information(J: ArrayLike, var: ArrayLike, dvar: ArrayLike | None = None) -> Array:
    """FIM of z ~ N(f(x), R(x)), R = diag(var) (eq 28), from J = df/dx (..., N, n), the
    variances var (..., N) and, for distance-dependent noise, dvar = d var / dx (..., N, n):

        I_ij = df/dx_i^T R^-1 df/dx_j + 1/2 tr(R^-1 dR/dx_i R^-1 dR/dx_j)   (eqs 30-32)

    With diagonal R the trace is sum_n dvar_ni dvar_nj / var_n^2. For eq 34-35 noise feed
    ``dvar = d sigma_n^2 / d l_n * d l_n / dx`` (eq 36): the variance derivative along the ray
    length times the ray-length gradient. A depth measurement is one more row [0, 0, 1] with
    its variance and zero derivative (eq 37).
    """
    J = np.asarray(J, dtype=float)
    v = np.asarray(var, dtype=float)
    if np.any(~np.isfinite(v)) or np.any(v <= 0):
        raise ValueError("variances must be positive and finite")
    I = np.einsum("...ki,...k,...kj->...ij", J, 1.0 / v, J)
    if dvar is not None:
        D = np.asarray(dvar, dtype=float)
        I = I + 0.5 * np.einsum("...ki,...k,...kj->...ij", D, 1.0 / v**2, D)
    return symmetrize(I)


def crb(J: ArrayLike, var: ArrayLike, dvar: ArrayLike | None = None) -> Array:
    """CRB matrix I^-1 (..., n, n) (eq 33 takes its diagonal). Raises
    :class:`DegenerateGeometryError` when the FIM is singular (the measurements cannot fix x)."""
    try:
        return spd_inverse(fisher_information(J, var, dvar), "Fisher information")
    except SingularMatrixError as exc:
        raise DegenerateGeometryError(f"singular Fisher information: {exc}") from None


def crb_trace(J: ArrayLike, var: ArrayLike, dvar: ArrayLike | None = None) -> Array:
    """CRB = sum_i [I^-1]_ii (eq 33), m^2 for positions: the bound on E||x_hat - x||^2."""
    return np.trace(crb(J, var, dvar), axis1=-2, axis2=-1)


def measurement_information(H: ArrayLike, R: ArrayLike) -> Array:
    """H^T R^-1 H (..., n, n) for H (..., m, n); R (..., m, m) full or (..., m) diagonal."""
    H = np.asarray(H, dtype=float)
    R = np.asarray(R, dtype=float)
    if R.ndim == H.ndim - 1:
        return fisher_information(H, R)
    Ri = spd_inverse(R, "measurement covariance")
    return symmetrize(np.swapaxes(H, -1, -2) @ Ri @ H)


def pcrb_information(
    J0: ArrayLike,
    F: ArrayLike,
    Q: ArrayLike,
    info: ArrayLike,
    *,
    expectation: bool = False,
) -> Array:
    """Posterior FIM sequence J_k = (Q + F J_{k-1}^-1 F^T)^-1 + E[H_k^T R_k^-1 H_k] (eq 41).

    ``J0`` (..., n, n) is the prior information (inverse prior covariance); ``info``
    (..., K, n, n) the measurement information per step, H evaluated at the *true* state
    (use :func:`measurement_information`; steps without a measurement have zeros; a depth
    report every rho steps is an extra row on those steps). Returns J_1..J_K (..., K, n, n).

    With ``expectation=True`` the measurement information is first averaged over the leading
    axis (Monte Carlo trajectories): that is the expectation in the Tichavsky bound, giving one
    sequence (K, n, n). Otherwise each trajectory has its own sequence (the paper averages the
    resulting PCRBs: "mean PCRB").
    """
    Im = np.asarray(info, dtype=float)
    if expectation:
        Im = Im.mean(axis=0)
    Fm = np.asarray(F, dtype=float)
    Qm = np.asarray(Q, dtype=float)
    Jk = np.broadcast_to(np.asarray(J0, dtype=float), Im.shape[:-3] + Im.shape[-2:])
    out = np.empty_like(Im)
    for k in range(Im.shape[-3]):
        Jinv = spd_inverse(Jk, "posterior information J_k")
        Jk = spd_inverse(Qm + Fm @ Jinv @ Fm.T, "predicted covariance Q + F J^-1 F^T") + Im[..., k, :, :]
        out[..., k, :, :] = Jk
    return out


def pcrb_position(Jseq: ArrayLike, index: ArrayLike = (0, 1, 2)) -> Array:
    """PCRB_k = sum over ``index`` of [J_k^-1]_ii (eq 42), m^2: the position part of the bound."""
    C = spd_inverse(np.asarray(Jseq, dtype=float), "posterior information")
    idx = np.asarray(index, dtype=int)
    return np.sum(np.diagonal(C, axis1=-2, axis2=-1)[..., idx], axis=-1)


def range_crb_trace(
    position: ArrayLike,
    anchors: ArrayLike,
    *,
    std: float = 0.0,
    rel_std: float = 0.0,
    mask: ArrayLike | None = None,
    plane: bool = True,
) -> Array:
    """CRB = tr I^-1 (m^2) of a position from ranges r_i = |x - a_i| + e_i to known anchors,
    e_i ~ N(0, std^2 + (rel_std |x - a_i|)^2) independent (distance-dependent when rel_std > 0:
    the variance term of :func:`fisher_information`).

    ``position`` (..., 3), ``anchors`` (..., N, 3) (m); ``mask`` (..., N) True where the anchor
    is present (absent ones carry no information), default all. ``plane``: the depth is known
    (a depth gauge), the bound is on (x, y) only; else on (x, y, z). Broadcasts over leading
    axes (one call for every estimate of a run); NaN where the anchors cannot fix the position
    (singular information: fewer than 2 + 1 anchors, or all on one line).
    """
    x = np.asarray(position, dtype=float)
    a = np.asarray(anchors, dtype=float)
    d = x[..., None, :] - a
    r = np.linalg.norm(d, axis=-1)
    if np.any(r <= 0):
        raise ValueError("an anchor coincides with the position")
    if not (std > 0 or rel_std > 0):
        raise ValueError("std and rel_std cannot both be 0")
    u = d / r[..., None]
    if plane:
        u = u[..., :2]
    var = std**2 + (rel_std * r) ** 2
    dvar = (2.0 * rel_std**2 * r)[..., None] * u
    J = u
    if mask is not None:
        m = np.broadcast_to(np.asarray(mask, dtype=bool), r.shape)
        J = np.where(m[..., None], J, 0.0)
        dvar = np.where(m[..., None], dvar, 0.0)
        var = np.where(m, var, 1.0)
    info = fisher_information(J, var, dvar)
    # singular where the smallest eigenvalue is negligible against the largest (collinear)
    ev = np.linalg.eigvalsh(info)
    ok = ev[..., 0] > 1e-9 * ev[..., -1]
    inv = np.linalg.inv(np.where(ok[..., None, None], info, np.eye(info.shape[-1])))
    return np.where(ok, np.trace(inv, axis1=-2, axis2=-1), np.nan)
