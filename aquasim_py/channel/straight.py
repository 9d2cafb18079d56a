"""Compiled links of one transmission: constant sound speed, every node on a box-folded
straight line (issue 19 item 1).

:func:`straight_links` does in one compiled call what ``AcousticChannel._links`` and
``_straight_moving`` do with about 60 small numpy calls per transmission: the sender's and its
neighbourhood's positions and velocities at the send time t0 (``ConstantVelocity`` folded into
its box by ``Box.fold``), the exact range test, the closed-form start of the moving-receiver
fixed point (``_constant_moving_root``), one exact step on the true (folded) trajectories and
the straight ray's length and time. Every operation is the numpy path's own, in its order, so
the results have the same bits (checked by tests/channel/test_straight.py against that path):

- the fold is elementwise (+, -, *, floor, abs, copysign, max): IEEE, no fused multiply-add
  (numba contracts nothing without ``fastmath``);
- ``np.einsum("ij,ij->i", a, b)`` on contiguous (k, 3) rows sums (p0 + p2) + p1 (its
  two-lane SIMD loop, numpy's baseline on x86-64 and arm64), written out below;
- ``np.add.reduce(x * x, axis=-1)`` sums (p0 + p1) + p2;
- sqrt is correctly rounded in both.

Transcendental functions (the SNR's log10, the ray angles) stay in numpy: numpy may use its
own SIMD versions (SVML on AVX-512), whose bits libm's need not share.

Imported lazily by the channel, only for a network it applies to: ``import numba`` costs about
64 MiB of RSS and 0.15 s, which runs that never take this path must not pay.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from numpy.typing import NDArray

__all__ = ["FALLBACK", "OK", "by_arrival", "straight_links"]

#: status codes of :func:`straight_links`
OK = 0
FALLBACK = 1  # something unusual (out of the water, a wall bounce during the flight, ...)

# rows of a node's record in the table (n, 7, 3): start position (m), velocity (m/s), and its
# box's lo, hi, size, period = 2 size, 1 / period (m, m, m, m, 1/m; Box's own constants)
_P0, _V, _LO, _HI, _SIZE, _PERIOD, _INV = range(7)


@njit(cache=True)
def _fold(rec: NDArray[np.float64], t: float, j: int) -> tuple[float, float]:
    """Coordinate j (m) and velocity component (m/s) at true time t (s) of the node whose record
    is ``rec`` (7, 3): ``Box.fold`` of p0 + v t, operation for operation."""
    d = (rec[_P0, j] + rec[_V, j] * t) - rec[_LO, j]
    q = math.floor(d * rec[_INV, j]) * rec[_PERIOD, j]
    d = (d - q) - rec[_SIZE, j]
    sign = -math.copysign(1.0, d)
    out = rec[_HI, j] - abs(d)
    lo = rec[_LO, j]
    if not (out >= lo or out != out):  # np.maximum(out, lo): NaN propagates
        out = lo
    return out, rec[_V, j] * sign


@njit(cache=True)
def _root(c: float, d0: float, d1: float, d2: float, v0: float, v1: float, v2: float) -> float:
    """``acoustic._constant_moving_root`` of one receiver: the positive root t (s) of
    |d + v t| = c t (offset d in m, velocity v in m/s); NaN when |v| > c / 2."""
    dv = (d0 * v0 + d2 * v2) + d1 * v1
    vv = (v0 * v0 + v2 * v2) + v1 * v1
    if not vv <= 0.25 * c * c:
        return math.nan
    a = c * c - vv
    return (dv + math.sqrt(dv * dv + a * ((d0 * d0 + d2 * d2) + d1 * d1))) / a


@njit(cache=True)
def straight_links(
    table: NDArray[np.float64],
    near: NDArray[np.intp],
    t0: float,
    c: float,
    bottom: float,
    range2: float,
    tol: float,
) -> tuple[int, NDArray[np.intp], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Receivers in range of a transmission and their exact arrivals on straight rays.

    table: (n, 7, 3) every node's record (see ``_P0``...). near: the sender's id, then the
    ids that may be in range (the neighbour index's superset). t0: send time (s). c: sound
    speed (m/s). bottom: sea-floor depth (m; inf for none). range2: squared range (m^2).
    tol: the fixed point's tolerance (s).

    Returns (status, cand, time, length, diff): the ids within range at t0 in the order of
    ``near``, their delays (s) and ray lengths (m), and the ray vectors (m, (m, 3)) from the
    sender at t0 to each receiver at its arrival. status FALLBACK when the answer needs the
    general path (the source or a receiver out of the water, a receiver faster than c / 2, or
    one exact step moving a delay by more than ``tol``: e.g. a wall bounce during the flight);
    the arrays are then meaningless."""
    k = near.size - 1
    src = table[near[0]]
    ps0, _ = _fold(src, t0, 0)
    ps1, _ = _fold(src, t0, 1)
    ps2, _ = _fold(src, t0, 2)
    # positions and velocities at t0, the range test: einsum's (x0 x0 + x2 x2) + x1 x1
    pos = np.empty((k, 3))
    vel = np.empty((k, 3))
    keep = np.empty(k, dtype=np.intp)
    m = 0
    for i in range(k):
        rec = table[near[i + 1]]
        x0, v0 = _fold(rec, t0, 0)
        x1, v1 = _fold(rec, t0, 1)
        x2, v2 = _fold(rec, t0, 2)
        d0, d1, d2 = x0 - ps0, x1 - ps1, x2 - ps2
        if (d0 * d0 + d2 * d2) + d1 * d1 <= range2:
            pos[m, 0], pos[m, 1], pos[m, 2] = x0, x1, x2
            vel[m, 0], vel[m, 1], vel[m, 2] = v0, v1, v2
            keep[m] = i + 1
            m += 1
    cand = np.empty(m, dtype=np.intp)
    time = np.empty(m)
    length = np.empty(m)
    diff = np.empty((m, 3))
    if m == 0:
        return OK, cand, time, length, diff
    if not (ps2 >= 0.0 and ps2 <= bottom and math.isfinite(ps0 + ps1 + ps2)):
        return FALLBACK, cand, time, length, diff
    for i in range(m):
        z = pos[i, 2]
        if not (z >= 0.0 and z <= bottom):  # NaN fails too
            return FALLBACK, cand, time, length, diff
        # the closed-form start (NaN for a receiver faster than c / 2)
        t = _root(c, pos[i, 0] - ps0, pos[i, 1] - ps1, pos[i, 2] - ps2, vel[i, 0], vel[i, 1], vel[i, 2])
        if not math.isfinite(t):
            return FALLBACK, cand, time, length, diff
        # one exact step: the receiver on its true trajectory at t0 + t
        node = near[keep[i]]
        rec = table[node]
        ta = t0 + t
        y0, _ = _fold(rec, ta, 0)
        y1, _ = _fold(rec, ta, 1)
        y2, _ = _fold(rec, ta, 2)
        e0, e1, e2 = y0 - ps0, y1 - ps1, y2 - ps2
        dist = math.sqrt((e0 * e0 + e1 * e1) + e2 * e2)
        if not (math.isfinite(dist) and y2 >= 0.0 and y2 <= bottom):
            return FALLBACK, cand, time, length, diff
        tt = dist / c
        if not abs(tt - t) <= tol:
            return FALLBACK, cand, time, length, diff
        cand[i] = node
        time[i] = tt
        length[i] = dist
        diff[i, 0], diff[i, 1], diff[i, 2] = e0, e1, e2
    return OK, cand, time, length, diff


@njit(cache=True)
def by_arrival(
    cand: NDArray[np.intp],
    time: NDArray[np.float64],
    length: NDArray[np.float64],
    log_length: NDArray[np.float64],
    snr_terms: NDArray[np.float64],
    threshold: float,
) -> tuple[NDArray[np.float64], int, NDArray[np.intp], NDArray[np.float64], NDArray[np.float64]]:
    """``acoustic.physical_snr`` of the rays and the receivers in order of arrival.

    log_length: numpy's log10(max(length, 1)) (numpy's own log10: its bits may differ from
    libm's). snr_terms: (10 k, Thorp's alpha in dB/km, source level, ambient noise N(f),
    10 log10 B), the constants of ``acoustic._snr_constants``; threshold: the SNR (dB) below
    which a reception is lost. Returns (snr in the candidates' order, how many are below the
    threshold, and the ids, delays and SNR sorted by delay, stably: equal delays keep the
    candidates' order, as ``list.sort`` does)."""
    k10, alpha, level, noise, band = snr_terms[0], snr_terms[1], snr_terms[2], snr_terms[3], snr_terms[4]
    m = cand.size
    snr = np.empty(m)
    lost = 0
    for i in range(m):
        ell = length[i]
        if not (ell >= 1.0 or ell != ell):  # np.maximum(length, 1.0)
            ell = 1.0
        loss = k10 * log_length[i] + ((ell - 1.0) * 1e-3) * alpha
        snr[i] = ((level - loss) - noise) - band
        if snr[i] < threshold:
            lost += 1
    order = np.arange(m)
    for i in range(1, m):  # insertion sort (a neighbourhood is small), stable
        o = order[i]
        j = i
        while j > 0 and time[order[j - 1]] > time[o]:
            order[j] = order[j - 1]
            j -= 1
        order[j] = o
    return snr, lost, cand[order], time[order], snr[order]
