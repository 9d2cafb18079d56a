"""Clock synchronization maths for two-way (Req/Res) exchanges with moving nodes (no SimPy).

Clock model: a node's local clock reads ``T = alpha * t + beta`` at true time ``t`` (``alpha``
skew factor, ``beta`` offset, s). One exchange with reference ``j``: the node sends Req at
local ``T1``; ``j`` receives it at ``t2`` and answers at ``t3`` (reference time); the node
receives the answer at local ``T4``. With ``tau_f`` / ``tau_b`` the forward / backward
propagation delays (s)::

    T1 = alpha (t2 - tau_f) + beta,        T4 = alpha (t3 + tau_b) + beta.

ITMTL (Gao, Qiao, Zhang, Xu: "mobile target localization based on iterative tracing", the
seed 004; its equations were lost in extraction, this follows the reconstruction in
``notes/papers.md``):

- eq 29 (round trip):  ``S = tau_f + tau_b = (T4 - T1) / alpha - (t3 - t2)``;
- eqs 19-23 (relative motion): ``tau_b - tau_f = Delta``; with the relative line-of-sight
  speed ``v_r`` and sound speed ``c``, ``Delta = v_r (t3 - t2 + S) / c``; here written as
  ``Delta = k_node (t3 - t2 + S) + k_ref (t3 - t2)`` with ``k = d tau / d position . velocity``
  (dimensionless), which is the same thing for ``k_node = v_r / c, k_ref = 0`` and also lets a
  ray-traced gradient replace ``1 / c``;
- eqs 24-28 (linear regression): weighted least squares of ``T`` on ``t`` over the points
  ``(t2 - tau_f, T1)`` and ``(t3 + tau_b, T4)`` of all exchanges so far;
- phase 2c: recompute ``S`` with the new ``alpha`` and iterate.

Baselines (their essentials only):

- TSHL: A. A. Syed and J. Heidemann, "Time synchronization for high latency acoustic
  networks", IEEE INFOCOM 2006: one-way beacons, skew from a regression of receive time on
  send time assuming a constant delay, then one two-way exchange for the offset.
- MU-Sync: N. Chirdchoo, W.-S. Soh, K. C. Chua, "MU-Sync: a time synchronization protocol for
  underwater mobile networks", ACM WUWNet 2008: two-way exchanges, one-way delay = half the
  round trip, a first regression for skew, then the delays recomputed with it and a second
  regression.
- Mobi-Sync: J. Liu, Z. Zhou, J.-H. Cui et al., "Mobi-Sync: efficient time synchronization
  for mobile underwater sensor networks" (as cited by ITMTL, INFOCOM 2010): the node's own velocity from its neighbours' velocities (spatial correlation),
  the delay change over an exchange from that velocity, then regression.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "ClockFit",
    "Exchanges",
    "fit_clock",
    "half_round_trip_sync",
    "itmtl_sync",
    "mu_sync",
    "neighbour_velocity",
    "regression_points",
    "round_trip",
    "split_delays",
    "sync_error",
    "to_true",
    "tshl_offset",
    "tshl_skew",
    "tshl_sync",
]

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class ClockFit:
    """Estimated clock ``T = alpha t + beta`` and how it was reached."""

    alpha: float  #: skew factor (1 + skew)
    beta: float  #: offset, s
    iterations: int = 1
    converged: bool = True

    @property
    def skew(self) -> float:
        """alpha - 1 (the convention of :class:`aquasim_py.clock.Clock`)."""
        return self.alpha - 1.0

    def to_true(self, local: ArrayLike) -> FloatArray:
        """True time (s) of local reading(s) ``local`` according to this fit."""
        return to_true(local, self.alpha, self.beta)


@dataclass(frozen=True)
class Exchanges:
    """A set of two-way exchanges (all arrays shape (n,)).

    ``k_node`` / ``k_ref`` are the first-order rates of change of the one-way delay with
    the node's / the reference's motion (dimensionless, ``grad tau . v``); zero means "no
    motion correction" (half the round trip).
    """

    T1: FloatArray  #: node's local Req send stamps, s
    t2: FloatArray  #: reference's Req receive stamps (reference time), s
    t3: FloatArray  #: reference's Res send stamps (reference time), s
    T4: FloatArray  #: node's local Res receive stamps, s
    k_node: FloatArray
    k_ref: FloatArray
    weight: FloatArray  #: regression weight of both points of the exchange

    @classmethod
    def build(
        cls,
        T1: ArrayLike,
        t2: ArrayLike,
        t3: ArrayLike,
        T4: ArrayLike,
        k_node: ArrayLike = 0.0,
        k_ref: ArrayLike = 0.0,
        weight: ArrayLike = 1.0,
    ) -> Exchanges:
        a = [np.atleast_1d(np.asarray(v, dtype=float)) for v in (T1, t2, t3, T4, k_node, k_ref, weight)]
        b = np.broadcast_arrays(*a)
        return cls(*[np.array(v, dtype=float) for v in b])

    def __len__(self) -> int:
        return int(self.T1.shape[0])


def to_true(local: ArrayLike, alpha: float, beta: float) -> FloatArray:
    """Invert ``T = alpha t + beta``: true time (s) of local reading(s)."""
    return (np.asarray(local, dtype=float) - beta) / alpha


def sync_error(local: ArrayLike, true: ArrayLike, alpha: float, beta: float) -> FloatArray:
    """Error (s) of the synchronized time of local reading(s) whose true time is ``true``."""
    return to_true(local, alpha, beta) - np.asarray(true, dtype=float)


def fit_clock(
    t: ArrayLike, T: ArrayLike, w: ArrayLike | None = None, alpha_fixed: float | None = None
) -> tuple[float, float]:
    """Weighted least-squares line ``T = alpha t + beta`` (ITMTL eqs 24-28).

    Centred sums avoid the cancellation of the normal equations at large ``t``. With one
    distinct abscissa the slope is unidentifiable: ``alpha = 1`` is returned and only the
    offset is fitted. ``alpha_fixed``: fit the offset only, with that slope (a short data
    span cannot tell a skew from timestamp noise).
    """
    t = np.asarray(t, dtype=float)
    T = np.asarray(T, dtype=float)
    w = np.ones_like(t) if w is None else np.broadcast_to(np.asarray(w, dtype=float), t.shape)
    sw = w.sum()
    if t.size == 0 or sw <= 0.0:
        raise ValueError("fit_clock needs at least one point with positive weight")
    tm = (w * t).sum() / sw
    Tm = (w * T).sum() / sw
    if alpha_fixed is not None:
        return float(alpha_fixed), float(Tm - alpha_fixed * tm)
    dt = t - tm
    sxx = (w * dt * dt).sum()
    # Slope needs abscissae spread over more than rounding noise.
    if sxx <= (1e-9 * max(1.0, abs(tm))) ** 2 * sw:
        return 1.0, float(Tm - tm)
    alpha = (w * dt * (T - Tm)).sum() / sxx
    return float(alpha), float(Tm - alpha * tm)


def round_trip(ex: Exchanges, alpha: float) -> FloatArray:
    """``S = tau_f + tau_b`` (s) of each exchange given the skew factor (ITMTL eq 29)."""
    return (ex.T4 - ex.T1) / alpha - (ex.t3 - ex.t2)


def split_delays(ex: Exchanges, alpha: float) -> tuple[FloatArray, FloatArray]:
    """Forward and backward delays (s) from the round trip and the motion term (eqs 19-23).

    ``Delta = tau_b - tau_f = k_node (t3 - t2 + S) + k_ref (t3 - t2)``: the node moves
    during the whole exchange (t1 to t4), the reference only between its stamps.
    """
    S = round_trip(ex, alpha)
    hold = ex.t3 - ex.t2
    delta = ex.k_node * (hold + S) + ex.k_ref * hold
    return 0.5 * (S - delta), 0.5 * (S + delta)


def regression_points(ex: Exchanges, tau_f: FloatArray, tau_b: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Abscissae (true s), ordinates (local s) and weights of the regression points."""
    t = np.concatenate([ex.t2 - tau_f, ex.t3 + tau_b])
    T = np.concatenate([ex.T1, ex.T4])
    w = np.concatenate([ex.weight, ex.weight])
    return t, T, w


def itmtl_sync(
    ex: Exchanges,
    alpha0: float = 1.0,
    *,
    tol_skew: float = 1e-12,
    tol_offset: float = 1e-10,
    max_iter: int = 20,
    fix_skew: bool = False,
) -> ClockFit:
    """ITMTL phase 2: split delays with the current skew, regress, repeat until stable.

    ``alpha0`` is the starting skew factor (1 in the first round, the previous estimate
    later). Stops when both the skew factor and the offset move less than the tolerances.
    ``fix_skew``: keep ``alpha0`` and fit the offset only.
    """
    alpha, beta = float(alpha0), np.nan
    for it in range(1, max_iter + 1):
        tau_f, tau_b = split_delays(ex, alpha)
        a_new, b_new = fit_clock(*regression_points(ex, tau_f, tau_b), alpha_fixed=alpha0 if fix_skew else None)
        done = abs(a_new - alpha) < tol_skew and np.isfinite(beta) and abs(b_new - beta) < tol_offset
        alpha, beta = a_new, b_new
        if done:
            return ClockFit(alpha, beta, it, True)
    return ClockFit(alpha, beta, max_iter, False)


def half_round_trip_sync(ex: Exchanges, alpha0: float = 1.0, **kw: Any) -> ClockFit:
    """Same iteration with ``tau_f = tau_b = S / 2`` (no motion correction)."""
    still = Exchanges.build(ex.T1, ex.t2, ex.t3, ex.T4, 0.0, 0.0, ex.weight)
    return itmtl_sync(still, alpha0, **kw)


def mu_sync(ex: Exchanges) -> ClockFit:
    """MU-Sync (Chirdchoo, Soh, Chua, WUWNet 2008): two regressions with half round trips.

    First regression with ``S`` computed at ``alpha = 1``; the delays are then recomputed
    with the fitted skew and the line fitted again.
    """
    still = Exchanges.build(ex.T1, ex.t2, ex.t3, ex.T4, 0.0, 0.0, ex.weight)
    fit1 = itmtl_sync(still, 1.0, max_iter=1)
    fit2 = itmtl_sync(still, fit1.alpha, max_iter=1)
    return ClockFit(fit2.alpha, fit2.beta, 2, True)


def tshl_skew(send_true: ArrayLike, recv_local: ArrayLike, group: ArrayLike | None = None) -> float:
    """TSHL phase 1 (Syed & Heidemann, INFOCOM 2006): skew factor from one-way beacons.

    Receive stamps ``T = alpha (t_send + tau) + beta`` with ``tau`` assumed constant per
    sender, so the slope of ``T`` on ``t_send`` is ``alpha``. Several senders (``group``
    labels) share the slope but each has its own intercept (its own delay): a pooled
    within-group regression.
    """
    t = np.asarray(send_true, dtype=float)
    T = np.asarray(recv_local, dtype=float)
    g = np.zeros(t.shape, dtype=int) if group is None else np.unique(np.asarray(group), return_inverse=True)[1]
    n = np.bincount(g)
    tm = (np.bincount(g, t) / n)[g]
    Tm = (np.bincount(g, T) / n)[g]
    sxx = ((t - tm) ** 2).sum()
    if sxx <= 0.0:
        return 1.0
    return float(((t - tm) * (T - Tm)).sum() / sxx)


def tshl_offset(alpha: float, T1: ArrayLike, t2: ArrayLike, t3: ArrayLike, T4: ArrayLike) -> float:
    """TSHL phase 2: offset from two-way exchange(s) with the skew known, symmetric delay.

    ``T1 + T4 = alpha (t2 + t3) + 2 beta`` when ``tau_f = tau_b``; averaged over exchanges.
    """
    T1, t2, t3, T4 = (np.asarray(v, dtype=float) for v in (T1, t2, t3, T4))
    return float(np.mean(0.5 * ((T1 + T4) - alpha * (t2 + t3))))


def tshl_sync(
    beacon_send_true: ArrayLike,
    beacon_recv_local: ArrayLike,
    beacon_group: ArrayLike | None,
    T1: ArrayLike,
    t2: ArrayLike,
    t3: ArrayLike,
    T4: ArrayLike,
) -> ClockFit:
    """TSHL: skew from the one-way beacons, then offset from the two-way exchange(s)."""
    alpha = tshl_skew(beacon_send_true, beacon_recv_local, beacon_group)
    return ClockFit(alpha, tshl_offset(alpha, T1, t2, t3, T4), 1, True)


def neighbour_velocity(velocities: ArrayLike, weights: ArrayLike | None = None) -> FloatArray:
    """Mobi-Sync's spatial-correlation estimate of a node's velocity (m/s), shape (3,).

    Nearby nodes drift with the same current, so the node's velocity is taken as the
    (weighted) mean of its neighbours' reported velocities (Liu et al., INFOCOM 2010).
    """
    v = np.asarray(velocities, dtype=float).reshape(-1, 3)
    w = np.ones(v.shape[0]) if weights is None else np.asarray(weights, dtype=float)
    return (w[:, None] * v).sum(axis=0) / w.sum()
