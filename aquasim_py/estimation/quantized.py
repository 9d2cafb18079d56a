"""Quantized Gaussian measurements: z = h(x) + v, v ~ N(0, sigma^2), reported only as the level
l in {0..L-1} with z in [gamma_l, gamma_{l+1}) (gamma_0 = -inf, gamma_L = +inf).

Level probabilities (MSWPF eq 12), their log-likelihood, the mutual information between the
level and the state from (predicted) particles (eqs 19-23), and the Fisher information of the
level about h (the quantized-measurement FIM of Ozdemir et al. 2009 / Masazade et al. 2012).
Vectorized over leading axes (sensors, particles); pure numpy/scipy.

Inside, the level (or edge) axis comes *first*, so that every elementwise pass runs over long
contiguous particle rows: with the level axis last (length L <= ~9 innermost) numpy's strided
inner loops were 10x slower. Gaussian tails are capped at ``_A_MAX`` sigma so that no pass
touches subnormal numbers (another 10-100x).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = [
    "level_probabilities",
    "mutual_information",
    "quantize",
    "quantized_fisher_scale",
    "quantized_log_likelihood",
    "quantized_mutual_information",
]

Array = NDArray[np.float64]

#: floor of a level probability: keeps log-likelihoods finite for particles deep in a tail
_P_FLOOR = 1e-300

#: |a| (sigmas) beyond which a Gaussian tail (and density) is taken as 0, as at an infinite
#: edge. Inside, tails are >= Phi(-36) = 4.2e-284 and their differences land on normal doubles
#: (ulp ~1e-300); further out erfc, exp and their differences produce subnormals, on which the
#: CPU is 10-100x slower. A bin of probability below ~1e-284 then gets 0, i.e. the 1e-300 floor.
_A_MAX = 36.0

#: the cap for the information measures (MI, Fisher): a bin of probability below Phi(-12) =
#: 1.8e-33 adds under 1e-30 nats to an entropy and ~12 phi(12) = 1e-31 to a Fisher scale, and
#: skipping such edges skips most erfc calls (the costly part) when bins are many sigmas wide
_A_INFO = 12.0

_SQRT1_2 = 1.0 / np.sqrt(2.0)
_INV_SQRT_2PI = 1.0 / np.sqrt(2.0 * np.pi)


def _interior(thresholds: ArrayLike) -> Array:
    """The L-1 finite thresholds, checked strictly increasing."""
    g = np.asarray(thresholds, dtype=float).reshape(-1)
    if g.size and not np.all(np.diff(g) > 0):
        raise ValueError("quantizer thresholds must be strictly increasing")
    return g


def quantize(z: ArrayLike, thresholds: ArrayLike) -> NDArray[np.int64]:
    """Level of each raw value z (eq 11): the number of thresholds <= z."""
    g = np.asarray(thresholds, dtype=float).reshape(-1)
    return np.searchsorted(g, np.asarray(z, dtype=float), side="right").astype(np.int64)


def _tails(e: Array, h: Array, s: Array, cap: float = _A_MAX) -> tuple[Array, Array]:
    """a = (edge - h)/sigma and the smaller Gaussian tail Phi(-|a|) = erfc(|a|/sqrt 2)/2 (erfc
    of a non-negative argument: no cancellation); 0 beyond ``cap`` sigmas (erfc not called)."""
    from scipy.special import erfc

    a = (e - h) / s
    m = np.abs(a)
    inside = m <= cap
    t = np.zeros(a.shape)
    t[inside] = 0.5 * erfc(m[inside] * _SQRT1_2)
    return a, t


def _shifted_cdf(a: Array, t: Array) -> tuple[Array, NDArray[np.bool_]]:
    """u = Phi(a) - [a >= +0] (= t below 0, -t above) and [a >= +0] (by sign bit, so that -0.0
    and +0.0 agree with u): the CDF without its integer part. A difference of two edges' u
    keeps the tails' relative accuracy (no 1 - Phi cancellation)."""
    return np.copysign(t, -a), ~np.signbit(a)


def _bin_probabilities(a_lo: Array, t_lo: Array, a_hi: Array, t_hi: Array) -> Array:
    """P(a_lo <= Z < a_hi) = (u_hi - u_lo) + ([a_hi >= 0] - [a_lo >= 0]): t_lo - t_hi above 0,
    t_hi - t_lo below, 1 - t_lo - t_hi straddling."""
    u_lo, up_lo = _shifted_cdf(a_lo, t_lo)
    u_hi, up_hi = _shifted_cdf(a_hi, t_hi)
    return np.asarray(np.maximum((u_hi - u_lo) + (up_hi > up_lo), 0.0))


def _edge_terms(
    h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike, cap: float = _A_MAX
) -> tuple[Array, Array, Array]:
    """a and tails at the L-1 interior edges, edge axis first: (L-1, ...); and sigma."""
    h = np.asarray(h, dtype=float)
    s = np.asarray(sigma, dtype=float)
    g = _interior(thresholds).reshape((-1,) + (1,) * max(h.ndim, s.ndim))
    a, t = _tails(g, h, s, cap)
    return a, t, s


def _probabilities_first(a: Array, t: Array) -> Array:
    """Bin probabilities (L, ...) from the interior edges (L-1, ...); the open edges have u = 0
    (no tail) and [a >= 0] = 0 at -inf, 1 at +inf."""
    u, up = _shifted_cdf(a, t)
    P = np.empty((a.shape[0] + 1,) + a.shape[1:])
    P[0] = u[0] + up[0]
    np.add(u[1:] - u[:-1], up[1:] > up[:-1], out=P[1:-1])
    P[-1] = ~up[-1] - u[-1]
    return np.asarray(np.maximum(P, 0.0, out=P))


def level_probabilities(h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike) -> Array:
    """P(level = l | h) = Q((gamma_l - h)/sigma) - Q((gamma_{l+1} - h)/sigma) (eq 12), shape
    (..., L) for h, sigma broadcasting to (...), with tail probabilities kept accurate."""
    a, t, _ = _edge_terms(h, sigma, thresholds)
    return np.moveaxis(_probabilities_first(a, t), 0, -1)


def quantized_log_likelihood(level: ArrayLike, h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike) -> Array:
    """log P(level | h) for h, sigma broadcasting with level (e.g. particles (S, N), level (S, 1));
    only the reported bin's two edges are evaluated."""
    e = np.concatenate(([-np.inf], _interior(thresholds), [np.inf]))
    h = np.asarray(h, dtype=float)
    s = np.asarray(sigma, dtype=float)
    lv = np.asarray(level, dtype=np.int64)
    lo, ts_lo = _tails(e[lv], h, s)
    hi, ts_hi = _tails(e[lv + 1], h, s)
    return np.asarray(np.log(np.maximum(_bin_probabilities(lo, ts_lo, hi, ts_hi), _P_FLOOR)))


def _plogp(P: Array) -> Array:
    """p log p with 0 log 0 = 0 (p >= 0; a p below the floor contributes ~0 either way)."""
    return np.asarray(P * np.log(np.maximum(P, _P_FLOOR)))


def _mi_first(P: Array) -> Array:
    """MI (eq 23) from level probabilities (L, ..., N) of N equally weighted particles."""
    pm = P.mean(axis=-1)
    h_marg = -_plogp(pm).sum(axis=0)
    h_cond = -_plogp(P).sum(axis=0).mean(axis=-1)
    return np.asarray(np.maximum(h_marg - h_cond, 0.0))


def mutual_information(P: ArrayLike) -> Array:
    """I(x; m) in nats from per-particle level probabilities P (..., N, L) of equally weighted
    particles (eq 23): H(mean_i P_i) - mean_i H(P_i). 0 when every particle gives the same
    distribution (the level cannot depend on the state); at most log L."""
    return _mi_first(np.moveaxis(np.asarray(P, dtype=float), -1, 0))


def quantized_mutual_information(h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike) -> Array:
    """MI (nats) between the level and the state from the noise-free values h (..., N) and noise
    stds of N equally weighted particles (eqs 12, 19-23): ``mutual_information`` of
    ``level_probabilities`` without the level-last copy. Shape (...)."""
    a, t, _ = _edge_terms(h, sigma, thresholds, _A_INFO)
    return _mi_first(_probabilities_first(a, t))


def quantized_fisher_scale(h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike) -> Array:
    """Fisher information of the level about h: sum_l (phi(a_l) - phi(a_{l+1}))^2 / (sigma^2 P_l)
    with a_l = (gamma_l - h)/sigma; the FIM about x is this times grad h grad h^T. It tends to
    1/sigma^2 (the unquantized value) as the thresholds get dense."""
    a, t, s = _edge_terms(h, sigma, thresholds, _A_INFO)
    P = _probabilities_first(a, t)
    # exponent capped (no subnormals); phi = 0 where the tail was skipped, as at an open edge
    phi = np.exp(-0.5 * np.minimum(a * a, _A_MAX**2)) * (_INV_SQRT_2PI * (t > 0.0))
    d = np.empty_like(P)  # phi(a_l) - phi(a_{l+1}), with phi(+-inf) = 0
    d[0] = -phi[0]
    np.subtract(phi[:-1], phi[1:], out=d[1:-1])
    d[-1] = phi[-1]
    # a bin below the floor has both edges deep in one tail: its term is ~0 (and d ~ 0 there)
    terms = d * d / np.maximum(P, _P_FLOOR)
    return np.asarray(terms.sum(axis=0) / s**2)
