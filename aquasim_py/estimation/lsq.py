"""Closed-form linearized least squares: multilateration on ranges and hyperbolic TDOA with a
pivot reference. Both subtract the pivot anchor's equation from the others, which cancels
the quadratic term |x|^2 and leaves a linear system; used as rough positions (e.g. ITMTL
phase 1) or as the start of :func:`~aquasim_py.estimation.gauss_newton.gauss_newton`.

Coordinates are shifted to the pivot before solving (better conditioned for anchors far from
the origin). A rank-deficient system (collinear anchors in 2-D, coplanar in 3-D, too few
anchors) raises :class:`~aquasim_py.estimation.errors.DegenerateGeometryError`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .errors import DegenerateGeometryError, InsufficientMeasurementsError

__all__ = ["TDOAResult", "multilaterate", "multilateration_covariance", "tdoa_ls"]

Array = NDArray[np.float64]

#: relative singular-value threshold for the linear systems (rank test)
_RCOND = 1e-9


def _anchors(anchors: ArrayLike) -> Array:
    A = np.asarray(anchors, dtype=float)
    if A.ndim != 2 or A.shape[1] not in (2, 3):
        raise ValueError(f"anchors must be (N, 2) or (N, 3), got {A.shape}")
    return A


def _solve(M: Array, b: Array, what: str) -> Array:
    if M.shape[0] < M.shape[1]:
        raise InsufficientMeasurementsError(f"{what}: {M.shape[0]} independent equations for {M.shape[1]} unknowns")
    # column scaling so that the rank test is not fooled by mixed units (m vs range)
    scale = np.linalg.norm(M, axis=0)
    scale[scale == 0] = 1.0
    sol, _, rank, sv = np.linalg.lstsq(M / scale, b, rcond=None)
    if rank < M.shape[1] or sv[-1] <= _RCOND * sv[0]:
        raise DegenerateGeometryError(
            f"{what}: the anchor geometry cannot fix the position (linear system of rank "
            f"{int(np.sum(sv > _RCOND * sv[0]))} < {M.shape[1]}: collinear or coplanar anchors?)"
        )
    return sol / scale


def multilaterate(
    anchors: ArrayLike,
    ranges: ArrayLike,
    *,
    depth: float | None = None,
    pivot: int = 0,
    refine: int = 0,
) -> Array:
    """Position from ranges (m) to N anchors (N, d), d = 2 or 3.

    For i != pivot: 2 (a_i - a_p)^T (x - a_p) = |a_i - a_p|^2 - r_i^2 + r_p^2. Needs N >= d + 1
    anchors not all on one line (2-D) / plane (3-D). With ``depth`` (3-D only, m) the depth is
    known and the problem is solved in (x, y) on the horizontal ranges; then 3 anchors not on
    one vertical plane suffice.

    ``refine`` > 0 (without ``depth``) follows the linear solution with up to that many
    Gauss-Newton steps on the range residuals |x - a_i| - r_i (stopping once a step is below
    1 um): the maximum-likelihood fix for equal Gaussian range noise, which the linear
    solution is not once the ranges are noisy.

    Examples:
        Four anchors (x, y, depth in m), three at 10 m and one at 150 m, and a node at 120 m:

        >>> import numpy as np
        >>> from aquasim_py.estimation import multilaterate
        >>> anchors = np.array([[0, 0, 10], [2000, 0, 10], [0, 2000, 10], [2000, 2000, 150]], float)
        >>> truth = np.array([700.0, 1200.0, 120.0])
        >>> ranges = np.linalg.norm(anchors - truth, axis=1)
        >>> multilaterate(anchors, ranges).round(6)
        array([ 700., 1200.,  120.])

        With 1 m of range noise the nearly flat anchor geometry fixes the depth badly; a
        known depth (a pressure gauge) removes that error:

        >>> noisy = ranges + np.random.default_rng(1).normal(0.0, 1.0, 4)
        >>> multilaterate(anchors, noisy).round(2)
        array([ 699.51, 1200.06,  143.69])
        >>> multilaterate(anchors, noisy, depth=120.0).round(2)
        array([ 700.07, 1200.62,  120.  ])
    """
    A = _anchors(anchors)
    r = np.asarray(ranges, dtype=float).reshape(-1)
    if r.size != A.shape[0]:
        raise ValueError(f"{A.shape[0]} anchors but {r.size} ranges")
    if not np.all(np.isfinite(r)):
        raise ValueError("ranges must be finite")
    if depth is not None:
        if A.shape[1] != 3:
            raise ValueError("depth is only meaningful in 3-D")
        # horizontal range^2; may go negative with noise, which the linear system tolerates
        r2 = r**2 - (depth - A[:, 2]) ** 2
        xy = _multi(A[:, :2], r2, pivot)
        return np.array([xy[0], xy[1], float(depth)])
    x = _multi(A, r**2, pivot)
    for _ in range(refine):
        d = x - A
        rho = np.maximum(np.linalg.norm(d, axis=1), 1e-9)
        step = np.linalg.lstsq(d / rho[:, None], r - rho, rcond=None)[0]
        x = x + step
        if np.linalg.norm(step) < 1e-6:
            break
    return x


def multilateration_covariance(anchors: ArrayLike, ranges: ArrayLike, range_std: ArrayLike, *, pivot: int = 0) -> Array:
    """First-order covariance (m^2, (d, d)) of :func:`multilaterate`'s linear fix (no depth, no
    refinement) for independent range errors of std ``range_std`` (m, scalar or (N,)).

    The linear system M y = b has b_i = |a_i - a_p|^2 - r_i^2 + r_p^2, so a range error moves
    b by J dr with J_ii = -2 r_i, J_ip = 2 r_p; the fix moves by pinv(M) J dr. Collinear
    (coplanar) anchors make M singular and this covariance unbounded in the direction across
    the line: the mirror ambiguity of the fix. Raises like :func:`multilaterate` when M is
    rank deficient."""
    A = _anchors(anchors)
    r = np.asarray(ranges, dtype=float).reshape(-1)
    if r.size != A.shape[0]:
        raise ValueError(f"{A.shape[0]} anchors but {r.size} ranges")
    sd = np.broadcast_to(np.asarray(range_std, dtype=float), r.shape)
    M = 2.0 * np.delete(A - A[pivot], pivot, axis=0)
    others = np.delete(np.arange(r.size), pivot)
    J = np.zeros((r.size - 1, r.size))
    J[np.arange(r.size - 1), others] = -2.0 * r[others]
    J[:, pivot] = 2.0 * r[pivot]
    _solve(M, np.zeros(M.shape[0]), "multilateration")  # the fix's checks: too few anchors, rank
    G = np.linalg.pinv(M) @ (J * sd)
    return G @ G.T


def _multi(A: Array, r2: Array, pivot: int) -> Array:
    p = A[pivot]
    B = np.delete(A - p, pivot, axis=0)
    rhs = np.sum(B**2, axis=1) - np.delete(r2, pivot) + r2[pivot]
    y = _solve(2.0 * B, rhs, "multilateration")
    return p + y


@dataclass(frozen=True)
class TDOAResult:
    x: Array  #: position (d,) (3,) when depth was given
    range_pivot: float  #: range to the pivot anchor (m), solved as an extra unknown
    #: every admissible (position, range_pivot) when the geometry leaves two (Chan's quadratic,
    #: one equation short); empty when the linear solve was determined
    candidates: tuple[tuple[Array, float], ...] = ()


def tdoa_ls(
    anchors: ArrayLike,
    arrival_times: ArrayLike,
    speed: float,
    *,
    pivot: int = 0,
    depth: float | None = None,
    hint: ArrayLike | None = None,
) -> TDOAResult:
    """Hyperbolic TDOA: arrival times (s) of one emission at N synchronized anchors, constant
    sound ``speed`` (m/s). With d_i = d_p + c (t_i - t_p), linear in (x, d_p):

        2 (a_i - a_p)^T (x - a_p) + 2 c (t_i - t_p) d_p = |a_i - a_p|^2 - c^2 (t_i - t_p)^2.

    Needs N >= d + 2 anchors (5 in 3-D); with ``depth`` (m) known, 4 in 3-D. The linear
    solution ignores d_p = |x - a_p| (spherical interpolation): exact for exact data.

    One equation short (N = d + 1, or 3 anchors at known depth) the position is affine in d_p
    and d_p = |x - a_p| closes the system as a quadratic (Chan's approach): of two admissible
    roots the one nearer ``hint`` (default: the anchors' centroid) is returned, both are in
    ``candidates``. Fewer anchors raise :class:`InsufficientMeasurementsError`.
    """
    A = _anchors(anchors)
    t = np.asarray(arrival_times, dtype=float).reshape(-1)
    if t.size != A.shape[0]:
        raise ValueError(f"{A.shape[0]} anchors but {t.size} arrival times")
    if not (np.isfinite(speed) and speed > 0):
        raise ValueError("speed must be positive")
    if depth is not None and A.shape[1] != 3:
        raise ValueError("depth is only meaningful in 3-D")
    p = A[pivot]
    B = np.delete(A - p, pivot, axis=0)
    dd = speed * (np.delete(t, pivot) - t[pivot])
    rhs = np.sum(B**2, axis=1) - dd**2
    yz = None if depth is None else float(depth) - p[2]
    if yz is not None:
        rhs = rhs - 2.0 * B[:, 2] * yz
        M = np.column_stack([2.0 * B[:, :2], 2.0 * dd])
    else:
        M = np.column_stack([2.0 * B, 2.0 * dd])
    npos = M.shape[1] - 1

    def full(y: Array) -> Array:
        return p + (np.array([y[0], y[1], yz]) if yz is not None else y)

    try:
        sol = _solve(M, rhs, "TDOA")
        return TDOAResult(full(sol[:npos]), float(sol[npos]))
    except DegenerateGeometryError:
        if M.shape[0] < npos:
            raise
    # Chan: y = y0 + y1 d_p from the first npos rows (square in the position unknowns)
    Mp, md = M[:npos, :npos], M[:npos, npos]
    y0 = _solve(Mp, rhs[:npos], "TDOA")
    y1 = _solve(Mp, -md, "TDOA")
    q0 = full(y0) - p
    q1 = np.append(y1, 0.0) if yz is not None else y1
    # |q0 + q1 d|^2 = d^2
    a2, a1, a0 = q1 @ q1 - 1.0, 2.0 * q0 @ q1, q0 @ q0
    roots = np.roots([a2, a1, a0]) if abs(a2) > 1e-12 else np.array([-a0 / a1])
    roots = np.real(roots[np.abs(np.imag(roots)) < 1e-9 * np.maximum(1.0, np.abs(roots))])
    roots = roots[roots >= 0.0]
    if roots.size == 0:
        raise DegenerateGeometryError("TDOA: no real solution for this geometry")
    cands = tuple((full(y0 + y1 * d), float(d)) for d in roots)
    hint_p = A.mean(axis=0) if hint is None else np.asarray(hint, dtype=float)
    k = int(np.argmin([np.linalg.norm(c - hint_p) for c, _ in cands]))
    return TDOAResult(cands[k][0], cands[k][1], cands)
