"""The physical layer's maths: bit error rates of the modulations, a packet's error over the
SINR pieces it was received in, and the SINR pieces themselves. Pure ``math``, no SimPy and no
kernel: the SINR receiver (:mod:`.sinr`) calls it at a reception's last bit.

Bit error rates (AWGN, per bit, as functions of gamma = Eb/N0, linear), from Proakis & Salehi,
*Digital Communications* (5th ed., 2008), sec. 4.3 and 4.5:

- ``bpsk``: Q(sqrt(2 gamma)) = erfc(sqrt(gamma)) / 2 (eq 4.3-13);
- ``qpsk``: Gray-coded QPSK, the same bit error rate as BPSK (two BPSK on I and Q);
- ``bfsk``: non-coherent binary FSK (orthogonal tones, envelope detection), exp(-gamma / 2) / 2
  (eq 4.5-45);
- ``mfsk``: non-coherent M-ary orthogonal FSK, k = log2 M bits per symbol: symbol error
  P_M = sum_{n=1}^{M-1} (-1)^(n+1) C(M-1, n) / (n+1) exp(-n k gamma / (n+1)) (eq 4.5-43) and
  bit error P_M (M/2) / (M-1) (eq 4.5-44).

An optional coding gain G (dB) multiplies Eb/N0 by 10^(G/10): a simple stand-in for a code
whose gain at the operating point is known (it is not a code model). Or a measured PER-vs-SINR
table (:class:`PerTable`, as a modem's characterization gives it) replaces the modulation.

Eb/N0 from the SINR over the receiver's band B at bit rate R: Eb/N0 = SINR B / R (the signal
energy per bit S / R over the noise density N / B). Interference is treated as Gaussian noise
over the band, the usual assumption of network simulators (ns-3's UAN module among them; ns-3's
``UanPhyPerCommonModes`` takes the SINR itself as Eb/N0 for PSK and FSK, i.e. B = R).

A packet received in pieces k of constant SINR (interferers start and end during it), b_k bits
each, is lost with probability PER = 1 - prod_k (1 - BER_k)^(b_k), bit errors independent.
"""

from __future__ import annotations

import itertools
import math
from bisect import bisect_right
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

__all__ = [
    "MODULATIONS",
    "ErrorModel",
    "PerTable",
    "ber_bfsk_nc",
    "ber_bpsk",
    "ber_mfsk_nc",
    "ber_qpsk",
    "packet_error",
    "packet_error_at",
    "sinr_pieces",
]

#: modulations by name (``[channel] modulation``); "table" is a :class:`PerTable`
MODULATIONS = ("bpsk", "qpsk", "bfsk", "mfsk", "table")


def ber_bpsk(ebn0: float) -> float:
    """Bit error rate of coherent BPSK: Q(sqrt(2 Eb/N0)) = erfc(sqrt(Eb/N0)) / 2."""
    return 0.5 * math.erfc(math.sqrt(ebn0))


def ber_qpsk(ebn0: float) -> float:
    """Bit error rate of coherent Gray-coded QPSK: that of BPSK at the same Eb/N0."""
    return 0.5 * math.erfc(math.sqrt(ebn0))


def ber_bfsk_nc(ebn0: float) -> float:
    """Bit error rate of non-coherent orthogonal binary FSK: exp(-Eb/(2 N0)) / 2."""
    return 0.5 * math.exp(-0.5 * ebn0)


def _mfsk_terms(m: int) -> tuple[tuple[float, float], ...]:
    """(coefficient, exponent factor) of each term of the M-ary symbol error sum (eq 4.5-43)."""
    k = math.log2(m)
    return tuple(((-1.0) ** (n + 1) * math.comb(m - 1, n) / (n + 1), n * k / (n + 1)) for n in range(1, m))


def ber_mfsk_nc(ebn0: float, m: int) -> float:
    """Bit error rate of non-coherent orthogonal M-ary FSK (M a power of 2) at Eb/N0 ``ebn0``."""
    ps = sum(c * math.exp(-e * ebn0) for c, e in _mfsk_terms(m))
    # the alternating sum cancels to below its terms' rounding when the answer is tiny: clip
    return min(max(ps, 0.0), 1.0) * (m / 2) / (m - 1)


@dataclass(frozen=True)
class PerTable:
    """A measured packet error rate against SINR: ``points`` = ((sinr_db, per), ...) in
    increasing SINR, for packets of ``bits`` bits at constant SINR. PER is interpolated linearly
    in SINR (dB) between the points and held at the end points beyond them.

    Over pieces of different SINR the table is read as the per-bit error it implies,
    1 - (1 - PER)^(1 / bits), so that a packet of ``bits`` bits at one SINR gets the table's PER
    back and other lengths scale as independent bit errors would."""

    points: tuple[tuple[float, float], ...]
    bits: int

    def __post_init__(self) -> None:
        if len(self.points) < 2:
            raise ValueError("a PER table needs at least two (sinr_db, per) points")
        xs = [p[0] for p in self.points]
        if any(b <= a for a, b in itertools.pairwise(xs)):
            raise ValueError("the PER table's SINR values must increase")
        if any(not 0.0 <= p[1] <= 1.0 for p in self.points):
            raise ValueError("the PER table's PER values must be in [0, 1]")
        if self.bits < 1:
            raise ValueError(f"the PER table's packet length must be >= 1 bit, got {self.bits}")

    def per(self, sinr_db: float) -> float:
        """The table's PER at ``sinr_db`` (interpolated; held beyond the ends)."""
        pts = self.points
        if sinr_db <= pts[0][0]:
            return pts[0][1]
        if sinr_db >= pts[-1][0]:
            return pts[-1][1]
        i = bisect_right([p[0] for p in pts], sinr_db)
        (x0, y0), (x1, y1) = pts[i - 1], pts[i]
        return y0 + (y1 - y0) * (sinr_db - x0) / (x1 - x0)

    def bit_error(self, sinr_lin: float) -> float:
        """The per-bit error equivalent to the table's PER at this SINR (linear)."""
        per = self.per(10.0 * math.log10(sinr_lin)) if sinr_lin > 0.0 else self.points[0][1]
        if per >= 1.0:
            return 1.0
        return -math.expm1(math.log1p(-per) / self.bits)


@dataclass(frozen=True)
class ErrorModel:
    """Bit errors at a given SINR: the modulation, its order (M-ary FSK), the Eb/N0 per unit
    SINR (B / R times the coding gain) or a PER table.

    modulation: one of :data:`MODULATIONS`. order: M of "mfsk" (a power of 2, >= 2).
    bandwidth_hz, bitrate_bps: B and R. coding_gain_db: G. table: for "table"."""

    modulation: str = "bfsk"
    order: int = 2
    bandwidth_hz: float = 5000.0
    bitrate_bps: float = 1000.0
    coding_gain_db: float = 0.0
    table: PerTable | None = None
    _scale: float = field(init=False, repr=False, compare=False, default=1.0)  # Eb/N0 per unit SINR

    def __post_init__(self) -> None:
        if self.modulation not in MODULATIONS:
            raise ValueError(f"unknown modulation {self.modulation!r} (one of {', '.join(MODULATIONS)})")
        if self.modulation == "table" and self.table is None:
            raise ValueError("modulation 'table' needs a PER table")
        if self.modulation == "mfsk" and not (self.order >= 2 and self.order & (self.order - 1) == 0):
            raise ValueError(f"M-ary FSK needs an order that is a power of 2 (>= 2), got {self.order}")
        # computed once: a verdict asks for a bit error rate or two
        object.__setattr__(self, "_scale", self.bandwidth_hz / self.bitrate_bps * 10.0 ** (self.coding_gain_db / 10.0))

    @property
    def ebn0_per_sinr(self) -> float:
        """Eb/N0 per unit of SINR (linear): B / R x 10^(G / 10)."""
        return self._scale

    def bit_error(self, sinr_lin: float) -> float:
        """The bit error rate at SINR ``sinr_lin`` (linear, over the receiver's band)."""
        if self.table is not None:
            return self.table.bit_error(sinr_lin)
        g = sinr_lin * self._scale
        m = self.modulation
        if m == "bfsk":
            return 0.5 * math.exp(-0.5 * g)  # ber_bfsk_nc, inline: once or twice per reception
        if m == "mfsk":
            return ber_mfsk_nc(g, self.order)
        return 0.5 * math.erfc(math.sqrt(g))  # ber_bpsk (bpsk, qpsk)


def packet_error_at(model: ErrorModel, sinr: float, bits: float) -> float:
    """PER of ``bits`` bits all at SINR ``sinr`` (linear): -expm1(bits log1p(-BER))."""
    ber = model.bit_error(sinr)
    return 1.0 if ber >= 1.0 else -math.expm1(bits * math.log1p(-ber))


def packet_error(model: ErrorModel, pieces: Iterable[tuple[float, float]]) -> float:
    """PER = 1 - prod_k (1 - BER_k)^(b_k) of a packet received in ``pieces`` (SINR linear,
    bits), computed as -expm1(sum_k b_k log1p(-BER_k)) so that a small PER keeps its digits."""
    acc = 0.0
    for sinr, bits in pieces:
        if bits <= 0.0:
            continue
        ber = model.bit_error(sinr)
        if ber >= 1.0:
            return 1.0
        acc += bits * math.log1p(-ber)
    return -math.expm1(acc)


def sinr_pieces(
    start: float, end: float, power: float, others: Sequence[tuple[float, float, float]], noise: float = 1.0
) -> list[tuple[float, float]]:
    """The SINR pieces of a signal of ``power`` received over [start, end) (s): (SINR linear,
    duration s) of each interval between the instants where one of ``others`` (arrival s,
    end s, power, in the signal's units) starts or ends, summing the power of those present
    plus ``noise``. Pieces of zero length are left out."""
    events: list[tuple[float, float]] = []
    for a, b, p in others:
        lo = a if a > start else start
        hi = b if b < end else end
        if lo < hi:
            events.append((lo, p))
            events.append((hi, -p))
    events.sort()
    out: list[tuple[float, float]] = []
    t = start
    level = noise
    active = 0
    for when, dp in events:
        if when > t:
            out.append((power / level, when - t))
            t = when
        active += 1 if dp > 0.0 else -1
        # back to the noise alone: exactly, not after a sum and differences that round
        level = level + dp if active else noise
    if end > t:  # every interferer has ended here
        out.append((power / noise, end - t))
    return out
