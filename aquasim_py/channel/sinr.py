"""The SINR receiver (``[channel] reception = "sinr"``): acquisition, SINR over the packet in
pieces and the packet-error draw, from the receiver's signal log (:class:`~.modem.Modem`).

No SimPy. The channel (:mod:`.acoustic`) records every signal at every receiver it reaches
(also the weak ones, down to ``interference_floor_db``, which interfere but are never decoded)
with its power in units of the noise (the loss model's SNR, linear), and asks :meth:`verdict`
at a reception's last bit. By then every signal that overlaps it has been recorded (each was
sent before that instant), so the verdict needs no event of its own.

Acquisition (``lock``). A signal is *acquired* when, at its first bit, the receiver is awake,
not transmitting, and the signal's SINR there (its power over the noise plus every other signal
present) reaches ``snr_threshold_db``; only an acquired signal is demodulated.

- "first" (ns-3's ``UanPhyGen``): a receiver that has acquired a packet acquires no other until
  that packet's last bit (a later, stronger one only interferes); a transmission of its own
  abandons the packet being received.
- "relock": a signal acquired while the receiver holds another takes the receiver over; the
  one it held is lost (a receiver that keeps searching for preambles while it demodulates).
- "none": every signal is judged on its own SINR at its first bit, as if the receiver had a
  demodulator per arrival (no lock).

With a lock, whether a signal was acquired depends on the signals before it, so decisions are
made in order of arrival, lazily: :meth:`advance` decides every signal that arrived before
now (all of them are known then, since a signal is recorded when it is sent) and keeps the
decision beside the signal (``Modem.rx_acq``); it runs before a signal log is pruned or the
receiver transmits, so no decision is lost or made without the facts it needs.

Packet error. An acquired packet's data part (after ``overhead_s``) is cut where interferers
start and end (:func:`.phy.sinr_pieces`), each piece's bits error at the modulation's rate and
the packet is lost with PER = 1 - prod_k (1 - BER_k)^(b_k) (or, ``per_combining = "worst"``,
every bit at the lowest piece's SINR). One uniform u from the receiver's own ("node", id,
"per") stream decides: lost when u < PER; the reason is "per" when the noise alone would have
lost it with the same draw (u < PER_noise), else "collision". So the same draw attributes the
loss, and a "collision" is a loss the interference caused: a signal not acquired because the
receiver was locked on another, or whose SINR at its first bit fell below the threshold only
through interference, or whose bit errors the interference added.
"""

from __future__ import annotations

from bisect import bisect_left
from typing import TYPE_CHECKING

from .phy import ErrorModel, packet_error, packet_error_at, sinr_pieces

if TYPE_CHECKING:  # pragma: no cover
    from .config import ChannelConfig
    from .modem import Modem, Signal

__all__ = ["ACQUIRED", "LOST", "NOT_ACQUIRED", "UNDECIDED", "SinrReceiver"]

#: states of a signal at a receiver (``Modem.rx_acq``)
UNDECIDED, NOT_ACQUIRED, ACQUIRED, LOST = 0, 1, 2, 3


class SinrReceiver:
    """The "sinr" reception rules of one channel (its config's constants); the per-receiver
    state lives in each :class:`~.modem.Modem`.

    config: the channel's :class:`~.config.ChannelConfig` (``snr_threshold_db``, ``lock``,
    ``per_combining``, ``overhead_s``, the error model)."""

    __slots__ = ("floor", "lock", "model", "overhead", "threshold", "worst")

    def __init__(self, config: ChannelConfig) -> None:
        self.threshold = 10.0 ** (config.snr_threshold_db / 10.0)  # linear SINR to acquire
        self.floor = config.interference_floor_db  # dB: weaker signals are not recorded
        self.lock = config.lock
        self.worst = config.per_combining == "worst"
        self.overhead = float(config.overhead_s)
        self.model: ErrorModel = config.error_model()

    # -- acquisition ------------------------------------------------------------------------------

    def advance(self, rx: Modem, now: float, max_duration: float) -> None:
        """Decide, in order of arrival, whether each signal that reached ``rx`` before ``now``
        (true s) was acquired (with a lock; "none" decides each signal at its verdict)."""
        keys = rx.rx_arr
        n = len(keys)
        i = rx.acq_n
        if i >= n or keys[i] >= now:
            return
        power = rx.rx_pow
        acq = rx.rx_acq
        ends = rx.rx_end
        thr = self.threshold
        relock = self.lock == "relock"
        while i < n and keys[i] < now:
            t = keys[i]
            p = power[i]
            state = NOT_ACQUIRED
            if p >= thr and not _deaf(rx, t, max_duration):
                k = rx.lock_k
                locked = k >= 0 and ends[k] > t
                if (relock or not locked) and p >= thr * (1.0 + _interference(rx, i, t, max_duration)):
                    state = ACQUIRED
                    if locked:
                        acq[k] = LOST  # relock: the receiver leaves the packet it held
                    rx.lock_k = i
            acq[i] = state
            i += 1
        rx.acq_n = i

    def transmitting(self, rx: Modem, now: float, max_duration: float) -> None:
        """``rx`` starts a transmission now: decide what arrived before, then drop its lock
        (a transmission abandons the packet being received; it then fails as half-duplex)."""
        if self.lock != "none":
            self.advance(rx, now, max_duration)
            rx.lock_k = -1

    # -- the verdict ------------------------------------------------------------------------------

    def verdict(self, sig: Signal, rx: Modem, max_duration: float) -> str | None:
        """The reason ``sig`` (an acquired-or-not signal at ``rx``, its last bit arriving now)
        is lost ("half_duplex", "collision", "per"), or None: delivered."""
        arr, end = sig[0], sig[1]
        if rx.busy_until > arr and _overlaps_own(rx, arr, end, max_duration):
            return "half_duplex"
        keys = rx.rx_arr
        i = bisect_left(keys, arr)
        log = rx.rx_log
        while log[i] is not sig:  # equal arrivals: the record itself
            i += 1
        p = rx.rx_pow[i]
        if self.lock == "none":
            if p < self.threshold * (1.0 + _interference(rx, i, arr, max_duration)):
                return "collision"
        else:
            # "first": a decided signal's state is final; "relock": a signal that arrived
            # during it may still take the receiver over
            if rx.acq_n <= i or self.lock == "relock":
                self.advance(rx, end, max_duration)
            if rx.rx_acq[i] != ACQUIRED:
                return "collision"
        # the data part's SINR pieces, and the PER with and without the interference
        start = arr + self.overhead
        others = _overlapping(rx, i, start, end, max_duration)
        model = self.model
        bits = float(sig[4].bits)
        per0 = packet_error_at(model, p, bits)
        if others:
            pieces = sinr_pieces(start, end, p, others)
            span = end - start
            if self.worst:
                per = packet_error_at(model, min(s for s, _ in pieces), bits)
            else:
                per = packet_error(model, [(s, bits * d / span) for s, d in pieces])
        else:
            per = per0
        u = rx.per_draw()
        if u < per:
            return "per" if u < per0 else "collision"
        return None


def _deaf(rx: Modem, t: float, max_duration: float) -> bool:
    """Whether ``rx`` cannot acquire a signal whose first bit arrives at ``t``: it is
    transmitting, asleep, or its battery is empty."""
    if rx.busy_until > t:
        starts = rx.tx_start
        j = bisect_left(starts, t - 2.0 * max_duration)
        n = len(starts)
        while j < n and starts[j] <= t:
            if rx.tx_end[j] > t:
                return True
            j += 1
    if rx.energy is None and not rx.sleeps:
        return False
    return rx.offline(t, t) is not None


def _overlaps_own(rx: Modem, arr: float, end: float, max_duration: float) -> bool:
    """Whether one of ``rx``'s own transmissions overlaps [arr, end) (as :func:`.modem.verdict`)."""
    starts = rx.tx_start
    j = bisect_left(starts, arr - 2.0 * max_duration)
    n = len(starts)
    while j < n and starts[j] < end:
        if rx.tx_end[j] > arr:
            return True
        j += 1
    return False


def _interference(rx: Modem, i: int, t: float, max_duration: float) -> float:
    """Summed power (noise units) at instant ``t`` of the signals at ``rx`` other than entry
    ``i`` (arrived at or before ``t``, not ended)."""
    keys = rx.rx_arr
    ends = rx.rx_end
    power = rx.rx_pow
    j = bisect_left(keys, t - max_duration)
    n = len(keys)
    total = 0.0
    while j < n and keys[j] <= t:
        if ends[j] > t and j != i:
            total += power[j]
        j += 1
    return total


def _overlapping(rx: Modem, i: int, start: float, end: float, max_duration: float) -> list[tuple[float, float, float]]:
    """(arrival, end, power) of the signals at ``rx`` other than entry ``i`` that overlap
    [start, end)."""
    keys = rx.rx_arr
    ends = rx.rx_end
    power = rx.rx_pow
    j = bisect_left(keys, start - max_duration)
    n = len(keys)
    out = []
    while j < n:
        a = keys[j]
        if a >= end:
            break
        if ends[j] > start and j != i:
            out.append((a, ends[j], power[j]))
        j += 1
    return out
