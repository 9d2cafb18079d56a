"""One node's modem as the channel keeps it: its transmit queue, its own transmissions and the
signals heard, its sleep intervals and energy meter, the verdict they give a reception under
the threshold model (half-duplex, collision; the SINR model's is :mod:`.sinr`'s), and the
carrier its hydrophone senses (:meth:`Modem.busy_at`).

No SimPy: the channel (:mod:`.acoustic`) records transmissions and signals as they start and
asks :func:`verdict` when a reception's last bit arrives.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left, bisect_right
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from ..packet import Packet
from ..radio import RadioPort

if TYPE_CHECKING:  # pragma: no cover
    from ..energy import EnergyMeter

__all__ = ["Modem", "Signal", "verdict"]

#: a signal at a receiver: (arrival, end (true s), snr_db, receiver id, packet, tof (s), path, dst);
#: path: its name, or a range-dependent link's record (:class:`~.arrival_links.ArrivalPath`)
Signal = tuple[float, float, float, int, Packet, float, Any, int]


class Modem:
    """The channel's own state for one node's modem, and the node's port (its bound methods)."""

    __slots__ = (
        "acq_n",
        "busy_until",
        "clock_stamp",
        "deliver",
        "energy",
        "index",
        "jitter",
        "lock_k",
        "log_cap",
        "longest",
        "per_rng",
        "per_u",
        "port",
        "pressure_rng",
        "rx_acq",
        "rx_arr",
        "rx_end",
        "rx_log",
        "rx_pow",
        "sinr",
        "sleeps",
        "tx_end",
        "tx_free_at",
        "tx_start",
    )

    def __init__(self, port: RadioPort, sinr: bool = False) -> None:
        self.port = port
        self.index = port.index
        # bound once: the per-reception path then makes one call per stamp / delivery
        self.clock_stamp = port.clock_stamp
        self.deliver = port.deliver
        self.jitter: np.random.Generator | None = None  # the port's jitter stream, asked on first use
        self.pressure_rng: np.random.Generator | None = None  # ("node", id, "pressure"), on first use
        self.tx_free_at = 0.0  # true time (s) the modem is free to start the next queued packet
        # start and end (true s) of own transmissions, in order of start (arrays: a reception's
        # half-duplex test reads a slice of doubles, not a tuple and two floats per entry)
        self.tx_start = array("d")
        self.tx_end = array("d")
        self.busy_until = -math.inf  # the latest of tx_end (true s)
        self.rx_log: list[Signal] = []  # signals here, sorted by arrival (see record)
        # their arrival and end times (true s), the collision scan's keys: contiguous doubles,
        # so a scan does not chase a tuple and two float objects per signal
        self.rx_arr = array("d")
        self.rx_end = array("d")
        self.longest = 0.0  # the longest signal recorded (s): how far back busy_at looks
        self.log_cap = 8  # prune the own transmissions beyond this many (see transmitting)
        # the SINR receiver's state (channel.sinr; kept only under it): each signal's power in
        # units of the noise and its acquisition state, beside rx_log; how many signals at the
        # front are decided; the rx_log index of the packet the receiver is locked on (-1: none)
        self.sinr = sinr
        self.rx_pow = array("d")
        self.rx_acq = bytearray()
        self.acq_n = 0
        self.lock_k = -1
        self.per_rng: np.random.Generator | None = None  # ("node", id, "per"), on first use
        self.per_u: list[float] = []  # uniforms drawn ahead, in blocks (consumed from the end)
        # the node's energy meter (aquasim_py.energy) when the kernel counts energy
        self.energy: EnergyMeter | None = getattr(port, "energy", None)
        self.sleeps: list[list[float]] = []  # [start, end) of the modem's sleeps (end inf: asleep)

    def transmitting(self, start: float, end: float, now: float, max_duration: float) -> None:
        """Log an own transmission over [start, end) (true s), forgetting those that can no
        longer overlap a pending reception once the log has doubled."""
        self.tx_start.append(start)
        self.tx_end.append(end)
        if end > self.busy_until:
            self.busy_until = end
        if len(self.tx_start) > self.log_cap:
            self._prune(now - max_duration)

    def _prune(self, cutoff: float) -> None:
        """Forget own transmissions that ended before ``cutoff`` (true s).

        A pending reception ends at or after now and lasts at most the longest packet so far,
        so it began after now - max_duration; anything that ended before cannot touch it.
        """
        keep = [i for i, b in enumerate(self.tx_end) if b >= cutoff]
        self.tx_start = array("d", [self.tx_start[i] for i in keep])
        self.tx_end = array("d", [self.tx_end[i] for i in keep])
        # next prune when the log has doubled: amortized O(1) per entry, short scans
        self.log_cap = max(8, 2 * len(keep))

    def record(self, sig: Signal, forget: float, power: float = 0.0) -> None:
        """Keep ``sig`` in the signal log (rx_log with its arrival and end times, sorted by
        arrival; after equal arrivals, as ``insort``), first forgetting the signals that
        arrived before ``forget`` (true s). ``power``: the signal's power in noise units, kept
        by the SINR receiver (which has decided every signal it forgets here, see
        :meth:`.sinr.SinrReceiver.advance`)."""
        keys = self.rx_arr
        sinr = self.sinr
        if keys and keys[0] < forget:
            j = bisect_left(keys, forget)
            del keys[:j], self.rx_end[:j], self.rx_log[:j]
            if sinr:
                del self.rx_pow[:j], self.rx_acq[:j]
                self.acq_n -= j
                self.lock_k = self.lock_k - j if self.lock_k >= j else -1
        arr, end = sig[0], sig[1]
        if end - arr > self.longest:
            self.longest = end - arr
        j = bisect_right(keys, arr)
        keys.insert(j, arr)
        self.rx_end.insert(j, end)
        self.rx_log.insert(j, sig)
        if sinr:
            self.rx_pow.insert(j, power)
            self.rx_acq.insert(j, 0)  # undecided

    def per_draw(self) -> float:
        """The next uniform of the node's own ("node", id, "per") stream (drawn in blocks)."""
        u = self.per_u
        if not u:
            rng = self.per_rng
            if rng is None:
                rng = self.per_rng = self.port.stream("per")
            u.extend(rng.random(256)[::-1].tolist())
        return u.pop()

    # -- sleep and energy -------------------------------------------------------------------------

    def sleep(self, t: float) -> None:
        """Put the modem to sleep from true time ``t`` (it neither sends nor receives)."""
        if not (self.sleeps and self.sleeps[-1][1] == math.inf):
            self.sleeps.append([t, math.inf])

    def wake(self, t: float) -> None:
        """Wake the modem at true time ``t`` (a sleep not begun yet is cancelled)."""
        if self.sleeps and self.sleeps[-1][1] == math.inf:
            if self.sleeps[-1][0] >= t:
                self.sleeps.pop()
            else:
                self.sleeps[-1][1] = t

    def offline(self, start: float, end: float) -> str | None:
        """Why the modem cannot take part in [start, end] (true s; an instant when equal):
        "energy" (its battery is empty by ``end``), "sleep" (asleep during any of it) or None."""
        meter = self.energy
        if meter is not None and meter.depleted_by(end):
            return "energy"
        for a, b in self.sleeps:
            if (a < end or a <= start) and b > start:
                return "sleep"
        return None

    def forget_sleeps(self, before: float) -> None:
        """Forget the sleeps that ended before ``before`` (true s)."""
        if self.sleeps and self.sleeps[0][1] < before:
            self.sleeps = [s for s in self.sleeps if s[1] >= before]

    def busy_at(self, t: float) -> bool:
        """Carrier sense at true time ``t`` (s): whether this modem is transmitting, or a signal
        recorded here is arriving (arrival <= t < end), at ``t``.

        Causal: a signal is recorded when its first bit leaves the sender, before it arrives,
        so only arrivals at or before ``t`` count. It senses what the channel records: the
        signals of the links it hears (within range, above the SNR threshold)."""
        if self.busy_until > t:
            # own transmissions never overlap (one queue): only the last one started by t can cover t
            i = bisect_right(self.tx_start, t)
            if i and self.tx_end[i - 1] > t:
                return True
        keys = self.rx_arr
        ends = self.rx_end
        j = bisect_right(keys, t) - 1
        # a signal that arrived before t - longest ended by t (twice that, so the rounding of
        # arrival + duration cannot hide one)
        first = t - 2.0 * self.longest
        while j >= 0 and keys[j] >= first:
            if ends[j] > t:
                return True
            j -= 1
        return False


def verdict(
    sig: Signal,
    rx: Modem,
    max_duration: float,
    collision: Literal["none", "destructive", "capture"],
    capture_threshold_db: float,
) -> str | None:
    """The verdict of a delivery from the receiver's logs when its last bit arrives:
    "half_duplex" (the receiver transmitted during it), "collision" (another signal overlapped
    it: any with "destructive"; with "capture", unless its SNR beats the overlapping signals'
    summed power by ``capture_threshold_db``) or None (delivered). ``max_duration``: the
    longest packet so far (s), which bounds how far back an overlapping signal can start."""
    arr, end, snr = sig[0], sig[1], sig[2]
    # own transmissions overlapping [arr, end): started before end and, lasting at most
    # the longest packet, after arr - longest packet (twice that here, so the rounding of
    # start + duration cannot hide one); the exact test decides within that slice; none
    # when every own transmission ended by arr
    if rx.busy_until > arr:
        starts = rx.tx_start
        i = bisect_left(starts, arr - 2.0 * max_duration)
        n = len(starts)
        while i < n and starts[i] < end:
            if rx.tx_end[i] > arr:
                return "half_duplex"
            i += 1
    if collision == "none":
        return None
    destructive = collision == "destructive"
    # rx_log is sorted by arrival; a signal overlapping [arr, end) arrived in
    # (arr - longest packet, end), so only that slice is examined
    keys = rx.rx_arr
    ends = rx.rx_end
    i = bisect_left(keys, arr - max_duration)
    n = len(keys)
    power = 0.0
    hit = False
    while i < n:
        if keys[i] >= end:
            break
        if ends[i] > arr:
            e = rx.rx_log[i]
            if e is not sig:
                hit = True
                if destructive:
                    break
                power += 10.0 ** (e[2] / 10.0)
        i += 1
    if hit and (destructive or not (snr - 10.0 * math.log10(power) >= capture_threshold_db)):
        return "collision"
    return None
