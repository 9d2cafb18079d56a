"""ITMTL maths as pure functions (numpy/scipy, no SimPy): phases 1, 2a, 3 and the confidence.

ITMTL: R. Gao, D. Qiao, M. Zhang, G. Xu et al., "Mobile target localization based on
iterative tracing for underwater wireless sensor networks" (seed 004). The paper's equations
were lost in extraction; this module follows the reconstruction in ``notes/papers.md``:

- phase 1 (eqs 1-6): hyperbolic TDOA with reference 1 as the pivot, linearized least squares
  in ``(x, y[, z], d_1)``; initial clock ``alpha = 1``, ``beta = T1 - (t2_1 - d_1 / c)``;
- phase 2a (eqs 7-18): the one-way delay of the rough position is the eigenray time of the
  channel's ray tracer (stratification compensation) or, for ITMTL-wsc, distance / c;
- phase 2a' (eqs 19-23): the delay's rate of change with the node's and the reference's motion,
  ``k = grad tau . v`` (the ray-traced gradient, or the line of sight / c for wsc), which
  :func:`aquasim_py.estimation.sync.split_delays` turns into the forward/backward split;
- phase 3: position fix from the one-way delays (nonlinear least squares through the delay
  model: Gauss-Newton / trust region on ``travel_time``; multilateration on ``c tau`` for wsc);
- network-wide construction: confidence of a fix and the promotion rule (the paper's formula
  is lost; this one is in the spirit of STVF's: mean reference confidence times one minus the
  normalized residual).

The clock, regression and baseline maths (generic) live in :mod:`aquasim_py.estimation.sync`.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.optimize import least_squares

from aquasim_py.channel import straight_line_time, travel_time, travel_time_gradient
from aquasim_py.channel.ssp import SoundSpeedProfile

__all__ = [
    "DelayModel",
    "Fix",
    "TdoaResult",
    "fix_confidence",
    "initial_clock",
    "multilaterate",
    "position_fix",
    "promote",
    "reference_variance",
    "tdoa_pivot",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class TdoaResult:
    """Rough position (m, (3,)) and range to the pivot reference (m); ``candidates`` holds
    every admissible (position, d1) when the geometry leaves two (3 references at known depth)."""

    position: FloatArray
    d1: float
    candidates: tuple[tuple[FloatArray, float], ...] = ()


def _pivot_system(ref: FloatArray, rng_diff: FloatArray, depth: float | None) -> tuple[FloatArray, FloatArray]:
    """Rows ``2 (p_j - p_1) . p + 2 r_j d_1 = |p_j|^2 - |p_1|^2 - r_j^2`` for j >= 2."""
    dp = ref[1:] - ref[0]
    rhs = (ref[1:] ** 2).sum(axis=1) - (ref[0] ** 2).sum() - rng_diff[1:] ** 2
    if depth is not None:
        rhs = rhs - 2.0 * dp[:, 2] * depth
        A = np.column_stack([2.0 * dp[:, :2], 2.0 * rng_diff[1:]])
    else:
        A = np.column_stack([2.0 * dp, 2.0 * rng_diff[1:]])
    return A, rhs


def tdoa_pivot(
    ref_pos: ArrayLike,
    t_rx: ArrayLike,
    speed: float,
    depth: float | None = None,
    hint: ArrayLike | None = None,
) -> TdoaResult:
    """Phase 1: position from the arrival times of one broadcast at synchronized references.

    ``t_rx[j] - t_rx[0] = (d_j - d_1) / c``. Squaring ``d_j = d_1 + r_j`` and subtracting the
    pivot's equation gives equations linear in ``(x, y[, z], d_1)``, solved by least squares.
    With a known ``depth`` the unknowns are ``(x, y, d_1)``. When there is exactly one
    equation too few for the linear solve (3 references at known depth, 4 in 3-D), the
    position is affine in ``d_1`` and ``|p - p_1| = d_1`` gives a quadratic (Chan's
    approach); of two admissible roots the one nearer ``hint`` (default: the references'
    centroid) is kept.
    """
    ref = np.asarray(ref_pos, dtype=float).reshape(-1, 3)
    t = np.asarray(t_rx, dtype=float).reshape(-1)
    if ref.shape[0] != t.shape[0]:
        raise ValueError("ref_pos and t_rx must describe the same references")
    r = speed * (t - t[0])
    A, b = _pivot_system(ref, r, depth)
    m = A.shape[1]
    npos = m - 1
    hint_p = ref.mean(axis=0) if hint is None else np.asarray(hint, dtype=float)

    def full(pxy: FloatArray) -> FloatArray:
        return np.array([pxy[0], pxy[1], depth]) if depth is not None else pxy

    if A.shape[0] >= m and np.linalg.matrix_rank(A) == m:
        sol = np.linalg.lstsq(A, b, rcond=None)[0]
        return TdoaResult(full(sol[:npos]), float(sol[npos]))
    if A.shape[0] < npos:
        raise ValueError(f"TDOA needs at least {npos + 1} references, got {ref.shape[0]}")
    # p = p0 + p1 d1 from the first npos rows (square in the position unknowns)
    Ap, ad = A[:npos, :npos], A[:npos, npos]
    p0 = np.linalg.lstsq(Ap, b[:npos], rcond=None)[0]
    p1 = np.linalg.lstsq(Ap, -ad, rcond=None)[0]
    q0 = full(p0) - ref[0]
    q1 = np.append(p1, 0.0) if depth is not None else p1
    # |q0 + q1 d1|^2 = d1^2
    a2 = q1 @ q1 - 1.0
    a1 = 2.0 * q0 @ q1
    a0 = q0 @ q0
    roots = np.roots([a2, a1, a0]) if abs(a2) > 1e-12 else np.array([-a0 / a1])
    roots = np.real(roots[np.abs(np.imag(roots)) < 1e-9 * np.maximum(1.0, np.abs(roots))])
    roots = roots[roots >= 0.0]
    if roots.size == 0:
        raise ValueError("TDOA: no real solution for this geometry")
    cands = [full(p0 + p1 * d) for d in roots]
    k = int(np.argmin([np.linalg.norm(c - hint_p) for c in cands]))
    return TdoaResult(cands[k], float(roots[k]), tuple((c, float(d)) for c, d in zip(cands, roots)))


def initial_clock(T1: float, t2_pivot: float, d1: float, speed: float) -> tuple[float, float]:
    """Phase 1 clock guess: ``alpha = 1``, ``beta = T1 - (t2_1 - d_1 / c)`` (eq 6)."""
    return 1.0, float(T1 - (t2_pivot - d1 / speed))


@dataclass(frozen=True)
class DelayModel:
    """One-way delay between a reference and the node, with or without stratification.

    ``compensate=True``: the channel's first-arrival eigenray time (ITMTL); where no eigenray
    exists (shadow zone) the straight-ray time stands in. ``compensate=False`` (ITMTL-wsc):
    Euclidean distance / ``mean_speed``.
    """

    ssp: SoundSpeedProfile
    compensate: bool = True
    mean_speed: float = 1500.0

    def delay(self, ref: ArrayLike, p: ArrayLike) -> FloatArray:
        """One-way delay (s) between reference position(s) and node position(s), (..., 3)."""
        ref = np.asarray(ref, dtype=float)
        p = np.asarray(p, dtype=float)
        if not self.compensate:
            return np.linalg.norm(p - ref, axis=-1) / self.mean_speed
        tt = travel_time(self.ssp, ref, p)
        bad = ~np.isfinite(tt)
        if np.any(bad):
            tt = np.where(bad, straight_line_time(self.ssp, ref, p), tt)
        return tt

    def gradients(self, ref: ArrayLike, p: ArrayLike) -> tuple[FloatArray, FloatArray]:
        """(d tau / d p, d tau / d ref), s/m, each (..., 3).

        The eigenray time is reciprocal (the same path both ways), so the gradient with
        respect to the reference is the tracer's destination gradient with the ends swapped.
        """
        ref = np.asarray(ref, dtype=float)
        p = np.asarray(p, dtype=float)
        if self.compensate:
            gp = travel_time_gradient(self.ssp, ref, p)
            gr = travel_time_gradient(self.ssp, p, ref)
            bad = ~np.all(np.isfinite(gp) & np.isfinite(gr), axis=-1, keepdims=True)
            if not np.any(bad):
                return gp, gr
            u = (p - ref) / (np.linalg.norm(p - ref, axis=-1, keepdims=True) * self.mean_speed)
            return np.where(bad, u, gp), np.where(bad, -u, gr)
        diff = p - ref
        u = diff / (np.linalg.norm(diff, axis=-1, keepdims=True) * self.mean_speed)
        return u, -u

    def motion_rates(
        self,
        ref: ArrayLike,
        p: ArrayLike,
        v_node: ArrayLike,
        v_ref: ArrayLike,
        mode: str = "relative",
    ) -> tuple[FloatArray, FloatArray]:
        """(k_node, k_ref) for :func:`aquasim_py.estimation.sync.split_delays` (eqs 19-23).

        ``mode="relative"`` is the paper's form: the relative line-of-sight speed over the
        whole exchange, ``Delta = v_r (t3 - t2 + S) / c`` (``k_ref = 0``).
        ``mode="separate"``: the node moves during the whole exchange, the reference only
        between its stamps (exact to first order when references drift too).
        """
        gp, gr = self.gradients(ref, p)
        vn = np.asarray(v_node, dtype=float)
        vr = np.asarray(v_ref, dtype=float)
        if mode == "relative":
            return (gp * (vn - vr)).sum(axis=-1), np.zeros(gp.shape[:-1])
        if mode == "separate":
            return (gp * vn).sum(axis=-1), (gr * vr).sum(axis=-1)
        raise ValueError(f"unknown motion mode {mode!r} (relative | separate)")


def multilaterate(ref_pos: ArrayLike, ranges: ArrayLike, depth: float | None = None) -> FloatArray:
    """Linear multilateration (m): subtract the first sphere from the others, least squares.

    With a known ``depth`` the unknowns are ``(x, y)`` (needs 3 references), else
    ``(x, y, z)`` (needs 4).
    """
    ref = np.asarray(ref_pos, dtype=float).reshape(-1, 3)
    d = np.asarray(ranges, dtype=float).reshape(-1)
    dp = ref[1:] - ref[0]
    rhs = (ref[1:] ** 2).sum(axis=1) - (ref[0] ** 2).sum() - d[1:] ** 2 + d[0] ** 2
    if depth is not None:
        rhs = rhs - 2.0 * dp[:, 2] * depth
        sol = np.linalg.lstsq(2.0 * dp[:, :2], rhs, rcond=None)[0]
        return np.array([sol[0], sol[1], depth])
    return np.linalg.lstsq(2.0 * dp, rhs, rcond=None)[0]


@dataclass(frozen=True)
class Fix:
    """A phase-3 position fix."""

    position: FloatArray  #: m, (3,)
    cov_unit: FloatArray  #: (J^T J)^-1 in m^2 per s^2 of delay noise, (k, k) over solved axes
    rms_residual: float  #: s, root mean square delay residual
    success: bool


def position_fix(
    model: DelayModel,
    ref_pos: ArrayLike,
    tau: ArrayLike,
    p0: ArrayLike,
    depth: float | None = None,
    weights: ArrayLike | None = None,
) -> Fix:
    """Phase 3: position whose modelled delays to the references best match ``tau`` (s).

    Nonlinear least squares (scipy's trust-region reflective, Gauss-Newton steps with the
    analytic Jacobian from the delay model's gradient) started at ``p0``; with a known
    ``depth`` only ``(x, y)`` are solved. For ITMTL-wsc the start is the linear
    multilateration on ``c tau`` and the model is straight; for ITMTL the model is the
    eigenray time (Ramezani et al.'s GNA on the ToF equations). ``weights`` (one per
    reference, e.g. inverse variances) make it a weighted least squares.
    """
    ref = np.asarray(ref_pos, dtype=float).reshape(-1, 3)
    tau = np.asarray(tau, dtype=float).reshape(-1)
    p0 = np.asarray(p0, dtype=float).reshape(3).copy()
    if depth is not None:
        p0[2] = depth
    axes = [0, 1] if depth is not None else [0, 1, 2]
    if not model.compensate:
        with contextlib.suppress(np.linalg.LinAlgError):
            p0 = multilaterate(ref, model.mean_speed * tau, depth)

    def full(u: FloatArray) -> FloatArray:
        p = p0.copy()
        p[axes] = u
        return p

    sw = np.ones(ref.shape[0]) if weights is None else np.sqrt(np.asarray(weights, dtype=float) / np.mean(weights))

    def res(u: FloatArray) -> FloatArray:
        return sw * (model.delay(ref, full(u)) - tau)

    def jac(u: FloatArray) -> FloatArray:
        return sw[:, None] * model.gradients(ref, full(u))[0][:, axes]

    # scale: residuals in s, unknowns in m; x_scale keeps the trust region in metres
    sol = least_squares(
        res, p0[axes], jac=jac, method="trf", x_scale=1.0, xtol=1e-12, ftol=1e-15, gtol=1e-15, max_nfev=50
    )
    J = jac(sol.x)
    try:
        cov = np.linalg.inv(J.T @ J)
    except np.linalg.LinAlgError:
        cov = np.full((len(axes), len(axes)), np.inf)
    rms = float(np.sqrt(np.mean(sol.fun**2)))
    return Fix(full(sol.x), cov, rms, bool(sol.success) and np.all(np.isfinite(sol.x)))


def reference_variance(confidence: ArrayLike, floor_m: float, residual_scale_m: float) -> FloatArray:
    """Position variance (m^2) a reference's confidence stands for: the confidence formula
    inverted, ``(1 - c) * residual_scale`` of range doubt, on top of a floor."""
    c = np.clip(np.asarray(confidence, dtype=float), 0.0, 1.0)
    return floor_m**2 + ((1.0 - c) * residual_scale_m) ** 2


def fix_confidence(ref_confidence: ArrayLike, rms_residual_m: float, residual_scale_m: float) -> float:
    """Confidence in [0, 1] of a fix: mean reference confidence x (1 - normalized residual).

    The normalized residual is the fix's RMS range residual (m) over ``residual_scale_m``,
    clipped to [0, 1]; a fix through imperfect (promoted) references inherits their doubt.
    """
    rc = float(np.mean(np.asarray(ref_confidence, dtype=float)))
    return rc * float(np.clip(1.0 - rms_residual_m / residual_scale_m, 0.0, 1.0))


def promote(confidences: ArrayLike, threshold: float, min_rounds: int) -> bool:
    """Promotion rule: the last ``min_rounds`` confidences all reach ``threshold``."""
    c = np.asarray(confidences, dtype=float)
    return c.size >= min_rounds and bool(np.all(c[-min_rounds:] >= threshold))
