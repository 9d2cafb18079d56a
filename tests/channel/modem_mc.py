"""Monte Carlo of the modulations of ``aquasim_py.channel.phy``: symbols through complex AWGN
and a demodulator, counting bit errors. The independent oracle of the closed-form bit error
rates (``tests/channel/test_phy.py``; drawn by ``tools/phy_figures.py``).

Complex baseband, ``SPS`` samples per symbol, rectangular pulses; per-sample noise CN(0, N0).

- BPSK: +-a per sample; correlator Re(sum r); decide by sign.
- QPSK (Gray): (+-1 +-j) a / sqrt(2); the in-phase bit decided by the sign of Re(sum r) (the
  quadrature bit is its mirror image, so its errors have the same rate).
- non-coherent M-FSK (M = 2: BFSK): tone m is a exp(j (2 pi m n / SPS + phi)), tones orthogonal
  over a symbol, phi uniform per symbol (unknown to the receiver); the receiver correlates with
  each tone and takes the largest magnitude (envelope detection); bit errors are the Hamming
  distance between the sent and the decided symbol's natural-binary labels.

Bit errors at 15 dB are rarer than 1e-15 (BPSK), far below what plain sampling reaches, so the
noise is drawn by importance sampling with its mean translated towards the decision boundary
(the standard mean-translation estimator, e.g. Jeruchim, Balaban & Shanmugan, *Simulation of
Communication Systems*, 2nd ed., sec. 11.2.5): noise from CN(mu, N0) instead of CN(0, N0), each
trial weighted by the likelihood ratio exp((|mu|^2 - 2 Re <w, mu>) / N0). The estimator is
unbiased for any shift; its standard error is the weighted sample's, so the reported interval
is honest at every Eb/N0. For FSK the shift points at one competing tone (drawn per trial, with
a random phase), which is an unbiased choice per trial.
"""

from __future__ import annotations

import math

import numpy as np

SPS = 8  # samples per symbol


def _weights(w: np.ndarray, mu: np.ndarray, n0: float) -> np.ndarray:
    """Likelihood ratio p(w) / q(w) of noise w (trials, SPS) drawn from CN(mu, N0) vs CN(0, N0)."""
    return np.exp((np.sum(np.abs(mu) ** 2, axis=1) - 2.0 * np.sum((np.conj(w) * mu).real, axis=1)) / n0)


def _noise(rng: np.random.Generator, shape: tuple[int, int], n0: float) -> np.ndarray:
    return (rng.standard_normal(shape) + 1j * rng.standard_normal(shape)) * math.sqrt(n0 / 2.0)


def ber_psk(ebn0_db: float, n: int, rng: np.random.Generator, qpsk: bool = False) -> tuple[float, float]:
    """(BER estimate, its standard error) of BPSK (or the in-phase bit of Gray QPSK) at Eb/N0 (dB)."""
    eb = 1.0
    n0 = eb / 10.0 ** (ebn0_db / 10.0)
    es = 2.0 * eb if qpsk else eb
    a = math.sqrt(es / SPS)
    bits_i = rng.integers(0, 2, n) * 2 - 1  # +-1 on the in-phase branch
    if qpsk:
        bits_q = rng.integers(0, 2, n) * 2 - 1
        sym = (bits_i + 1j * bits_q) * a / math.sqrt(2.0)
    else:
        sym = bits_i * a + 0j
    s = np.repeat(sym[:, None], SPS, axis=1)
    # shift the in-phase noise by minus the in-phase amplitude: the correlator's mean moves to
    # the decision boundary
    mu = np.repeat((-bits_i * (a / math.sqrt(2.0) if qpsk else a))[:, None], SPS, axis=1) + 0j
    w = _noise(rng, (n, SPS), n0) + mu
    r = s + w
    decided = np.where(np.sum(r.real, axis=1) >= 0.0, 1, -1)
    x = (decided != bits_i) * _weights(w, mu, n0)
    return float(x.mean()), float(x.std(ddof=1) / math.sqrt(n))


def ber_fsk_nc(ebn0_db: float, m: int, n: int, rng: np.random.Generator) -> tuple[float, float]:
    """(BER estimate, its standard error) of non-coherent orthogonal M-FSK at Eb/N0 (dB)."""
    k = int(math.log2(m))
    eb = 1.0
    es = k * eb
    n0 = eb / 10.0 ** (ebn0_db / 10.0)
    a = math.sqrt(es / SPS)
    t = np.arange(SPS)
    tones = np.exp(2j * np.pi * np.outer(np.arange(m), t) / SPS)  # (m, SPS), orthogonal rows
    unit = tones / math.sqrt(SPS)
    sent = rng.integers(0, m, n)
    phi = rng.uniform(0.0, 2.0 * np.pi, n)
    s = a * tones[sent] * np.exp(1j * phi)[:, None]
    # the sent tone's noise shifted by -s/2 (its correlator halfway to zero), and each competing
    # tone's noise component scaled up to variance v N0, v = Es / (4 N0): the error region's
    # closest point, |n0| = |n1| = |s| / 2, becomes typical
    mu = -0.5 * s
    w = _noise(rng, (n, SPS), n0) + mu
    v = max(1.0, es / (4.0 * n0))
    log_w = (np.sum(np.abs(mu) ** 2, axis=1) - 2.0 * np.sum((np.conj(w) * mu).real, axis=1)) / n0
    for j in range(m):
        other = sent != j
        c = w[other] @ np.conj(unit[j])  # the noise's component along tone j (CN(0, N0) there)
        w[other] += (math.sqrt(v) - 1.0) * c[:, None] * unit[j]
        c2 = v * np.abs(c) ** 2
        log_w[other] += math.log(v) - c2 / n0 + c2 / (v * n0)
    r = s + w
    z = np.abs(r @ np.conj(tones).T)  # (n, m) envelope of each tone's correlator
    decided = np.argmax(z, axis=1)
    flips = np.array([bin(v).count("1") for v in range(m)])[decided ^ sent]
    x = flips / k * np.exp(log_w)
    return float(x.mean()), float(x.std(ddof=1) / math.sqrt(n))
