"""One node's modem as the channel keeps it: its transmit queue, its own transmissions and the
signals heard, the verdict they give a reception (half-duplex, collision), and the carrier its
hydrophone senses (:meth:`Modem.busy_at`).

No SimPy: the channel (:mod:`.acoustic`) records transmissions and signals as they start and
asks :func:`verdict` when a reception's last bit arrives.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left, bisect_right
from typing import Any, Literal

import numpy as np

from ..packet import Packet
from ..radio import RadioPort

__all__ = ["Modem", "Signal", "verdict"]

#: a signal at a receiver: (arrival, end (true s), snr_db, receiver id, packet, tof (s), path, dst);
#: path: its name, or a range-dependent link's record (:class:`~.arrival_links.ArrivalPath`)
Signal = tuple[float, float, float, int, Packet, float, Any, int]


class Modem:
    """The channel's own state for one node's modem, and the node's port (its bound methods)."""

    __slots__ = (
        "busy_until",
        "clock_stamp",
        "deliver",
        "index",
        "jitter",
        "log_cap",
        "longest",
        "port",
        "pressure_rng",
        "rx_arr",
        "rx_end",
        "rx_log",
        "tx_end",
        "tx_free_at",
        "tx_start",
    )

    def __init__(self, port: RadioPort) -> None:
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

    def record(self, sig: Signal, forget: float) -> None:
        """Keep ``sig`` in the signal log (rx_log with its arrival and end times, sorted by
        arrival; after equal arrivals, as ``insort``), first forgetting the signals that
        arrived before ``forget`` (true s)."""
        keys = self.rx_arr
        if keys and keys[0] < forget:
            j = bisect_left(keys, forget)
            del keys[:j], self.rx_end[:j], self.rx_log[:j]
        arr, end = sig[0], sig[1]
        if end - arr > self.longest:
            self.longest = end - arr
        j = bisect_right(keys, arr)
        keys.insert(j, arr)
        self.rx_end.insert(j, end)
        self.rx_log.insert(j, sig)

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
