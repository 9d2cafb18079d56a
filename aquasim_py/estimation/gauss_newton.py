"""Gauss-Newton time-of-flight localization (Ramezani et al., Algorithm 1, eq 29) with a
Levenberg-Marquardt fallback, plus a batched Algorithm 1 for Monte Carlo studies.

The solvers work on a generic *whitened* residual function ``fun(x) -> (r, J)``:
r = (f(x) - z) / sigma (m,), J = dr/dx (m, n). Minimizing ||r||^2 is the maximum-likelihood
problem (29) for independent Gaussian noise; with equal sigmas the iterates are exactly those
of Algorithm 1. :func:`tof_model` builds ``fun`` from any travel-time function and its
gradient w.r.t. the receiver (e.g. ``aquasim_py.channel.travel_time`` / ``travel_time_gradient``
with the anchors as sources), optionally with a depth measurement as an extra residual (eq 37).
Estimation does not import the channel: the caller passes the functions in.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DegenerateGeometryError, EstimationError, InsufficientMeasurementsError

__all__ = ["GNResult", "constant_speed_tof", "gauss_newton", "gauss_newton_batch", "tof_model"]

Array = NDArray[np.float64]
ResidualFn = Callable[[Array], tuple[Array, Array]]

#: default bound on cond(J) (the normal matrix J^T J has its square): above it a step is not
#: trusted (LM fallback) and at the solution the position is declared not identifiable.
COND_MAX = 1e7


@dataclass(frozen=True)
class GNResult:
    """Outcome of :func:`gauss_newton`."""

    x: Array  #: estimate (n,)
    cov: Array  #: (J^T J)^-1 at the estimate: the Gauss-Newton covariance (whitened residuals)
    cost: float  #: 0.5 ||r||^2 at the estimate
    iterations: int  #: Gauss-Newton steps taken (LM function evaluations when method is LM)
    converged: bool  #: step norm fell below tol (GN) / scipy reported success (LM)
    method: str  #: "gauss-newton" or "levenberg-marquardt"


def _eval(fun: ResidualFn, x: Array) -> tuple[Array, Array]:
    r, J = fun(x)
    r = np.asarray(r, dtype=float).reshape(-1)
    J = np.asarray(J, dtype=float).reshape(r.size, x.size)
    return r, J


def _svd(J: Array) -> tuple[Array, Array, Array, float]:
    U, s, Vt = np.linalg.svd(J, full_matrices=False)
    cond = np.inf if s[-1] <= 0 else s[0] / s[-1]
    return U, s, Vt, cond


def gauss_newton(
    fun: ResidualFn,
    x0: ArrayLike,
    max_iter: int = 7,
    tol: float = 1e-3,
    *,
    fallback: bool = True,
    cond_max: float = COND_MAX,
) -> GNResult:
    """Solve min ||r(x)||^2 by Gauss-Newton (Algorithm 1: at most ``max_iter`` steps, stop when
    the step norm ||x_{k+1} - x_k|| < ``tol``; units of x, e.g. m).

    Falls back to Levenberg-Marquardt (``scipy.optimize.least_squares(method="lm")``), started
    from the best Gauss-Newton iterate, when a step leaves the model's domain (residuals still
    non-finite after halving the step 12 times), increases the cost, the Jacobian is
    ill-conditioned (cond(J) > ``cond_max``), or GN has not converged within ``max_iter``. The
    LM answer is kept only if its cost is not higher. ``fallback=False`` is the paper's plain
    algorithm (plus the step halving, which never triggers while the model is defined).

    Raises :class:`InsufficientMeasurementsError` if there are fewer residuals than unknowns,
    :class:`DegenerateGeometryError` if the Jacobian at the answer is rank-deficient (the
    measurements cannot fix x there, e.g. collinear anchors), :class:`EstimationError` if the
    residuals are not finite at the start.
    """
    x = np.asarray(x0, dtype=float).reshape(-1).copy()
    r, J = _eval(fun, x)
    if r.size < x.size:
        raise InsufficientMeasurementsError(f"{r.size} measurements for {x.size} unknowns")
    if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
        raise EstimationError("residuals or Jacobian not finite at the initial point (no path?)")
    cost = 0.5 * float(r @ r)
    best = (x.copy(), cost)
    trouble = False
    converged = False
    k = 0
    while k < max_iter:
        U, s, Vt, cond = _svd(J)
        if cond > cond_max:
            trouble = True
            break
        # the Gauss-Newton step -(J^T J)^-1 J^T r via the SVD (same maths, better conditioned)
        step = -Vt.T @ ((U.T @ r) / s)
        k += 1
        # a full step may leave the model's domain (e.g. above the sea surface, or into a
        # shadow zone where there is no direct ray): shorten it until the model is defined
        for _ in range(12):
            x_new = x + step
            r_new, J_new = _eval(fun, x_new)
            if np.all(np.isfinite(r_new)) and np.all(np.isfinite(J_new)):
                break
            step = 0.5 * step
        else:
            trouble = True
            break
        cost_new = 0.5 * float(r_new @ r_new)
        small = bool(np.linalg.norm(step) < tol)
        # a rising cost on a large step means GN overshoots; on a tiny step it is round-off
        rising = cost_new > cost * (1 + 1e-9) and not small
        x, r, J, cost = x_new, r_new, J_new, cost_new
        if cost < best[1]:
            best = (x.copy(), cost)
        if rising:
            trouble = True
            break
        if small:
            converged = True
            break
    method = "gauss-newton"
    if fallback and (trouble or not converged):
        import scipy.optimize as sopt  # only the fallback needs it

        xb = best[0]
        cache: dict[str, tuple[Array, Array]] = {}

        def res(z: Array) -> Array:
            rr, JJ = _eval(fun, z)
            # outside the model's domain: a huge finite residual makes LM shrink its step
            ok = np.all(np.isfinite(rr)) and np.all(np.isfinite(JJ))
            if not ok:
                rr, JJ = np.full(rr.shape, 1e100), np.zeros(JJ.shape)
            cache["last"] = (z.copy(), JJ)
            return rr

        def jac(z: Array) -> Array:
            last = cache.get("last")
            if last is not None and np.array_equal(last[0], z):
                return last[1]
            res(z)
            return cache["last"][1]

        try:
            sol = sopt.least_squares(
                res, xb, jac=jac, method="lm", xtol=1e-12, ftol=1e-12, gtol=1e-12, max_nfev=200 * (x.size + 1)
            )
            lm_ok = bool(np.all(np.isfinite(sol.x)))
        except (ValueError, np.linalg.LinAlgError):
            lm_ok = False
        if lm_ok and 0.5 * float(sol.fun @ sol.fun) <= best[1]:
            x = sol.x
            r, J = _eval(fun, x)
            cost = 0.5 * float(r @ r)
            converged, method, k = bool(sol.success), "levenberg-marquardt", int(sol.nfev)
        elif cost > best[1]:
            x = best[0]
            r, J = _eval(fun, x)
            cost = best[1]
    U, s, Vt, cond = _svd(J)
    if not np.isfinite(cond) or cond > cond_max:
        raise DegenerateGeometryError(
            f"Jacobian rank-deficient at the estimate (cond {cond:.3g}): the measurements cannot "
            "fix the position (collinear/coplanar anchors, or target on their plane?)"
        )
    cov = (Vt.T / s**2) @ Vt
    return GNResult(x, cov, cost, k, converged, method)


def gauss_newton_batch(
    fun: Callable[[Array], tuple[Array, Array]],
    X0: ArrayLike,
    max_iter: int = 7,
    tol: float = 1e-3,
    *,
    cond_max: float = COND_MAX,
) -> tuple[Array, NDArray[np.int_], NDArray[np.bool_]]:
    """Algorithm 1 on B independent problems at once (Monte Carlo draws): ``fun(X (B, n))``
    returns ``(r (B, m), J (B, m, n))``. Each row stops on its own (step < ``tol``) or after
    ``max_iter`` steps. No fallback: this is the paper's plain algorithm.

    Returns ``(X (B, n), iterations (B,), ok (B,))``; ``ok`` is False where a row stopped on an
    ill-conditioned Jacobian or a non-finite step (its last finite iterate is kept), or did
    not reach ``tol`` within ``max_iter``.
    """
    X = np.array(X0, dtype=float, ndmin=2)
    B, _n = X.shape
    active = np.ones(B, dtype=bool)
    failed = np.zeros(B, dtype=bool)
    done = np.zeros(B, dtype=bool)
    iters = np.zeros(B, dtype=int)
    for _ in range(max_iter):
        if not active.any():
            break
        ia = np.flatnonzero(active)
        # evaluate every row (keeps fun free of row bookkeeping; at most max_iter calls)
        r, J = fun(X)
        r, J = np.asarray(r, dtype=float)[ia], np.asarray(J, dtype=float)[ia]
        # rows with no path (NaN time/gradient) stop; zeros keep the batched SVD defined
        bad = ~(np.all(np.isfinite(r), axis=-1) & np.all(np.isfinite(J), axis=(-2, -1)))
        J = np.where(bad[:, None, None], 0.0, J)
        U, s, Vt = np.linalg.svd(J, full_matrices=False)
        bad |= ~(s[:, -1] * cond_max > s[:, 0])
        s_safe = np.where(bad[:, None], 1.0, s)
        coef = np.einsum("bmk,bm->bk", U, np.where(np.isfinite(r), r, 0.0)) / s_safe
        step = -np.einsum("bkn,bk->bn", Vt, coef)
        bad |= ~np.all(np.isfinite(step), axis=-1)
        step[bad] = 0.0
        X[ia] += step
        iters[ia[~bad]] += 1
        small = np.linalg.norm(step, axis=-1) < tol
        done[ia[small & ~bad]] = True
        failed[ia[bad]] = True
        active[ia[bad | small]] = False
    return X, iters, done & ~failed


def tof_model(
    anchors: ArrayLike,
    measured: ArrayLike,
    time_fn: Callable[[Array, Array], Array],
    grad_fn: Callable[[Array, Array], Array],
    *,
    sigma: ArrayLike = 1.0,
    depth: ArrayLike | None = None,
    sigma_depth: float | None = None,
) -> Callable[[Array], tuple[Array, Array]]:
    """Whitened residual function of the ToF model (eq 27; with depth, eq 37).

    ``anchors`` (N, 3) are the ray sources, the unknown x the receiver. ``measured`` ToFs (s),
    shape (N,) or (B, N) for a batch; ``sigma`` (s) broadcasting to ``measured`` (scalar, per
    anchor, or per draw and anchor for distance-dependent noise); ``depth`` (m, z
    positive down) scalar or (B,) with its std ``sigma_depth`` (m). ``time_fn(src, dst)`` (s)
    and ``grad_fn(src, dst)`` (s/m, d time / d dst) broadcast over leading axes.

    The returned ``fun(x)`` accepts x (3,) or (B, 3) and returns r (..., M) and J (..., M, 3)
    with M = N (+1 with depth): usable by :func:`gauss_newton` and :func:`gauss_newton_batch`.
    """
    A = np.asarray(anchors, dtype=float)
    if A.ndim != 2 or A.shape[1] != 3:
        raise ValueError(f"anchors must be (N, 3), got {A.shape}")
    t = np.asarray(measured, dtype=float)
    if t.shape[-1] != A.shape[0]:
        raise ValueError(f"measured ToFs must end with N = {A.shape[0]}, got {t.shape}")
    sig = np.broadcast_to(np.asarray(sigma, dtype=float), t.shape)
    if np.any(~np.isfinite(sig)) or np.any(sig <= 0):
        raise ValueError("sigma must be positive")
    depth_meas: tuple[Array, float] | None = None  # (depth (m), its std (m))
    if depth is not None:
        if sigma_depth is None or not sigma_depth > 0:
            raise ValueError("a depth measurement needs a positive sigma_depth")
        depth_meas = (np.asarray(depth, dtype=float), sigma_depth)

    def fun(x: Array) -> tuple[Array, Array]:
        x = np.asarray(x, dtype=float)
        dst = x[..., None, :]
        r = (time_fn(A, dst) - t) / sig
        J = np.asarray(grad_fn(A, dst), dtype=float) / sig[..., None]
        if depth_meas is not None:
            zd, sd = depth_meas
            rz = ((x[..., 2] - zd) / sd)[..., None]
            Jz = np.broadcast_to(np.array([0.0, 0.0, 1.0 / sd]), J.shape[:-2] + (1, 3))
            r = np.concatenate([r, rz], axis=-1)
            J = np.concatenate([J, Jz], axis=-2)
        return r, J

    return fun


def constant_speed_tof(speed: float) -> tuple[Callable[[Array, Array], Array], Callable[[Array, Array], Array]]:
    """(time_fn, grad_fn) of the straight-ray, one-speed model t = |dst - src| / speed: the
    "without stratification compensation" baseline (Ramezani's GNA-ASSP with speed = v_bar,
    footnote 1; ITMTL-wsc). Pass them to :func:`tof_model`."""
    if not (np.isfinite(speed) and speed > 0):
        raise ValueError("speed must be positive")

    def time_fn(src: Array, dst: Array) -> Array:
        return np.linalg.norm(np.asarray(dst, dtype=float) - src, axis=-1) / speed

    def grad_fn(src: Array, dst: Array) -> Array:
        diff = np.asarray(dst, dtype=float) - src
        return diff / (np.linalg.norm(diff, axis=-1, keepdims=True) * speed)

    return time_fn, grad_fn
