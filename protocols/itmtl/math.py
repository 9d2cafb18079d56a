"""ITMTL maths as pure functions (numpy/scipy, no SimPy): phases 1, 2a, 3 and the confidence.

ITMTL: R. Gao, D. Qiao, M. Zhang, G. Xu et al., "Mobile target localization based on
iterative tracing for underwater wireless sensor networks". The paper's equations
were lost in extraction; this module follows the reconstruction in docs/itmtl.md ("What the extracted text lost"):

- phase 1 (eqs 1-6): hyperbolic TDOA with reference 1 as the pivot, linearized least squares
  in ``(x, y[, z], d_1)`` (:func:`aquasim_py.estimation.lsq.tdoa_ls`); initial clock ``alpha = 1``, ``beta = T1 - (t2_1 - d_1 / c)``;
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

from aquasim_py.channel import straight_line_time, travel_time, travel_time_gradient
from aquasim_py.channel.ssp import SoundSpeedProfile
from aquasim_py.estimation.errors import EstimationError
from aquasim_py.estimation.lsq import multilaterate

__all__ = [
    "DelayModel",
    "Fix",
    "fix_confidence",
    "initial_clock",
    "position_fix",
    "reference_variance",
]

FloatArray = NDArray[np.float64]


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
    from scipy.optimize import least_squares

    ref = np.asarray(ref_pos, dtype=float).reshape(-1, 3)
    tau = np.asarray(tau, dtype=float).reshape(-1)
    p0 = np.asarray(p0, dtype=float).reshape(3).copy()
    if depth is not None:
        p0[2] = depth
    axes = [0, 1] if depth is not None else [0, 1, 2]
    if not model.compensate:
        with contextlib.suppress(EstimationError):  # degenerate geometry: keep p0
            p0 = multilaterate(ref, model.mean_speed * tau, depth=depth)

    def full(u: FloatArray) -> FloatArray:
        p = p0.copy()
        p[axes] = u
        return p

    if weights is None:
        sw = np.ones(ref.shape[0])
    else:
        w = np.asarray(weights, dtype=float)
        sw = np.sqrt(w / w.mean())

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
    return Fix(full(sol.x), np.asarray(cov, dtype=np.float64), rms, bool(sol.success and np.all(np.isfinite(sol.x))))


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
