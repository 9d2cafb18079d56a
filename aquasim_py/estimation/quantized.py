"""Quantized Gaussian measurements: z = h(x) + v, v ~ N(0, sigma^2), reported only as the level
l in {0..L-1} with z in [gamma_l, gamma_{l+1}) (gamma_0 = -inf, gamma_L = +inf).

Level probabilities (MSWPF eq 12), their log-likelihood, the mutual information between the
level and the state from (predicted) particles (eqs 19-23), and the Fisher information of the
level about h (the quantized-measurement FIM of Ozdemir et al. 2009 / Masazade et al. 2012).
Vectorized over leading axes (sensors, particles); pure numpy/scipy.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import ndtr, xlogy

__all__ = [
    "level_probabilities",
    "mutual_information",
    "quantize",
    "quantized_fisher_scale",
    "quantized_log_likelihood",
]

Array = NDArray[np.float64]

#: floor of a level probability: keeps log-likelihoods finite for particles deep in a tail
_P_FLOOR = 1e-300


def _edges(thresholds: ArrayLike) -> Array:
    g = np.asarray(thresholds, dtype=float).reshape(-1)
    if g.size and not np.all(np.diff(g) > 0):
        raise ValueError("quantizer thresholds must be strictly increasing")
    return np.concatenate(([-np.inf], g, [np.inf]))


def quantize(z: ArrayLike, thresholds: ArrayLike) -> NDArray[np.int64]:
    """Level of each raw value z (eq 11): the number of thresholds <= z."""
    g = np.asarray(thresholds, dtype=float).reshape(-1)
    return np.searchsorted(g, np.asarray(z, dtype=float), side="right").astype(np.int64)


def _tails(e: Array, h: Array, s: Array) -> tuple[Array, Array]:
    """a = (edge - h)/sigma and the smaller Gaussian tail at each edge, Phi(-|a|): one ndtr call.
    Differences of small tails keep relative accuracy on both sides (no 1 - Phi cancellation)."""
    a = (e - h) / s
    return a, ndtr(-np.abs(a))


def _bin_probabilities(a_lo: Array, t_lo: Array, a_hi: Array, t_hi: Array) -> Array:
    """P(a_lo <= Z < a_hi) from the edges' tails: both edges above 0 -> t_lo - t_hi, both at or
    below 0 -> t_hi - t_lo, straddling 0 -> 1 - t_lo - t_hi."""
    p = np.where(a_lo > 0.0, t_lo - t_hi, np.where(a_hi <= 0.0, t_hi - t_lo, 1.0 - t_lo - t_hi))
    return np.asarray(np.maximum(p, 0.0))


def level_probabilities(h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike) -> Array:
    """P(level = l | h) = Q((gamma_l - h)/sigma) - Q((gamma_{l+1} - h)/sigma) (eq 12), shape
    (..., L) for h, sigma broadcasting to (...), with tail probabilities kept accurate."""
    e = _edges(thresholds)
    a, t = _tails(e, np.asarray(h, dtype=float)[..., None], np.asarray(sigma, dtype=float)[..., None])
    return _bin_probabilities(a[..., :-1], t[..., :-1], a[..., 1:], t[..., 1:])


def quantized_log_likelihood(level: ArrayLike, h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike) -> Array:
    """log P(level | h) for h, sigma broadcasting with level (e.g. particles (S, N), level (S, 1));
    only the reported bin's two edges are evaluated."""
    e = _edges(thresholds)
    h = np.asarray(h, dtype=float)
    s = np.asarray(sigma, dtype=float)
    lv = np.asarray(level, dtype=np.int64)
    lo, ts_lo = _tails(e[lv], h, s)
    hi, ts_hi = _tails(e[lv + 1], h, s)
    return np.asarray(np.log(np.maximum(_bin_probabilities(lo, ts_lo, hi, ts_hi), _P_FLOOR)))


def mutual_information(P: ArrayLike) -> Array:
    """I(x; m) in nats from per-particle level probabilities P (..., N, L) of equally weighted
    particles (eq 23): H(mean_i P_i) - mean_i H(P_i). 0 when every particle gives the same
    distribution (the level cannot depend on the state); at most log L."""
    P = np.asarray(P, dtype=float)
    pm = P.mean(axis=-2)
    h_marg = -np.sum(xlogy(pm, pm), axis=-1)
    h_cond = -np.sum(xlogy(P, P), axis=-1).mean(axis=-1)
    return np.asarray(np.maximum(h_marg - h_cond, 0.0))


def quantized_fisher_scale(h: ArrayLike, sigma: ArrayLike, thresholds: ArrayLike) -> Array:
    """Fisher information of the level about h: sum_l (phi(a_l) - phi(a_{l+1}))^2 / (sigma^2 P_l)
    with a_l = (gamma_l - h)/sigma; the FIM about x is this times grad h grad h^T. It tends to
    1/sigma^2 (the unquantized value) as the thresholds get dense."""
    e = _edges(thresholds)
    s = np.asarray(sigma, dtype=float)[..., None]
    a, t = _tails(e, np.asarray(h, dtype=float)[..., None], s)
    P = _bin_probabilities(a[..., :-1], t[..., :-1], a[..., 1:], t[..., 1:])
    fin = np.isfinite(a)
    phi = np.where(fin, np.exp(-0.5 * np.where(fin, a, 0.0) ** 2), 0.0) * (1.0 / np.sqrt(2.0 * np.pi))
    dphi = phi[..., :-1] - phi[..., 1:]
    ok = P > _P_FLOOR
    terms = np.where(ok, dphi**2 / np.where(ok, P, 1.0), 0.0)
    return np.asarray(terms.sum(axis=-1) / s[..., 0] ** 2)
