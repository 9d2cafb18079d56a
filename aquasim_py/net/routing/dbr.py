"""``dbr``: depth-based routing (H. Yan, Z. J. Shi and J.-H. Cui, "DBR: Depth-Based Routing for
Underwater Sensor Networks", IFIP Networking 2008, LNCS 4982, pp. 72-86).

A node needs no position, only its depth gauge. Every packet carries the depth ``d_p`` of the
node that sent this copy. A node of depth ``d_c`` that hears it is a candidate forwarder if it
is shallower by more than the depth threshold, ``d = d_p - d_c > d_th``; otherwise it drops
the copy. A candidate holds the packet for

    f(d) = (2 tau / delta) (R - d),        tau = R / v0,

so the candidate that gains the most depth sends first, and candidates below it, hearing that
copy, stand down. ``R`` is the maximal transmission range, ``v0`` the speed of sound and
``delta`` a global parameter that trades delay for redundancy.

Two buffers per node, as published: the priority queue Q1 of the packets it will send, ordered
by their sending times (its head sent when its time comes), and the history buffer Q2 of the
packets it has sent. A copy of a packet in Q2 is dropped. A copy of a packet in Q1 either
removes it from Q1 (its sender is not ``d_th`` deeper than this node: a better-placed node has
sent it) or, coming from deeper, moves its sending time to the earlier of the two.

Readings (open choices, documented switches):

- ``delta_m``: the paper leaves ``delta`` to the deployment (0 < delta <= R): two candidates
  whose depths differ by delta or more hold 2 tau apart, enough for the deeper one to hear the
  shallower one's copy whatever their distances (the paper's argument, which leaves out the
  packet's airtime); closer ones may both send. Default R/2, the holding time 4 tau (1 - d/R)
  of the authors' group's Aqua-Sim NG code (its disabled depth path); a MATLAB UWSN simulator
  uses delta = R (2 tau (1 - d/R)).
- The Q1 rule for a later copy follows the text as the three public implementations we read
  agree on it (Aqua-Sim NG's disabled path, UANSim, a MATLAB UWSN simulator): cancel when the
  copy's depth gain does not exceed ``d_th``, else keep the earlier sending time.
- Depths are the node's gauge readings (``sensors.depth_noise_std_m``), one per copy heard and
  one when it sends; positive down (Aqua-Sim NG's z is up: its test reads the other way).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, replace

from pydantic import Field

from .base import Datagram, Header, History, RangeParams, Router, RouterParams, RouterPort

__all__ = ["Dbr", "DbrHeader", "DbrParams"]


@dataclass(frozen=True, slots=True)
class DbrHeader(Header):
    """DBR's header: the common fields and the depth of the node sending this copy (m)."""

    depth: float = math.nan


class DbrParams(RangeParams):
    depth_threshold_m: float = Field(
        0.0, ge=0.0, le=10_000.0, description="d_th: a node forwards only if it is more than this shallower (m)"
    )
    delta_m: float | None = Field(
        None, gt=0.0, description="delta of the holding time (2 tau / delta)(R - d) (m); default R / 2"
    )


@dataclass(slots=True)
class _Queued:
    """A packet in Q1: this node's copy to be, when it is due (local s), what decided it."""

    datagram: Datagram
    send_at: float
    prev: int
    gain: float


class Dbr(Router):
    """Depth-based routing (module docstring)."""

    name = "dbr"
    Params = DbrParams
    params: DbrParams
    header_fields_bits = 16  # the sender's depth

    def __init__(self, port: RouterPort, params: RouterParams) -> None:
        super().__init__(port, params)
        p = self.params
        self.R = self.range_m(p.range_m) if not self.is_sink else math.nan
        tau = self.R / p.sound_speed_mps
        self.scale = 2.0 * tau / (p.delta_m if p.delta_m is not None else self.R / 2.0)
        self.q1: dict[tuple[int, int], _Queued] = {}
        self._heap: list[tuple[float, int, tuple[int, int]]] = []  # (send_at, tie, key); stale ones skipped
        self._tie = 0
        self._armed = math.inf  # the local time the send timer fires next
        self._timer = 0  # the send timer's number: an earlier one set since makes it stale
        self.q2 = History(p.history_length)  # the packets this node has sent

    def holding_time(self, gain: float) -> float:
        """f(d) = (2 tau / delta)(R - d), local s."""
        return self.scale * (self.R - gain)

    def originate(self, header: Header) -> Header:
        self.q2.add(header.key)
        return DbrHeader(*header.common(), depth=self.port.depth())

    def relay(self, header: Header) -> Header:
        assert isinstance(header, DbrHeader)
        return replace(header, depth=self.port.depth())

    def on_copy(self, datagram: Datagram, sender: int) -> None:
        h = datagram.header
        assert isinstance(h, DbrHeader)
        key = h.key
        if key in self.q2:  # sent already
            return
        gain = h.depth - self.port.depth()
        queued = self.q1.get(key)
        if gain <= self.params.depth_threshold_m:
            if queued is not None:  # a node not d_th deeper than this one has sent it
                del self.q1[key]
                self.suppressed(queued.datagram, queued.prev, queued.gain)
            return
        send_at = self.port.local_time() + self.holding_time(gain)
        if queued is None:
            self.q1[key] = _Queued(datagram, send_at, sender, gain)
        elif send_at < queued.send_at:
            queued.send_at, queued.prev, queued.gain, queued.datagram = send_at, sender, gain, datagram
        else:
            return
        self._tie += 1
        heapq.heappush(self._heap, (send_at, self._tie, key))
        self._arm()

    # -- Q1's head -------------------------------------------------------------------------------

    def _arm(self) -> None:
        """Set the send timer to Q1's head, if it is earlier than the timer set."""
        heap = self._heap
        while heap and (heap[0][2] not in self.q1 or self.q1[heap[0][2]].send_at != heap[0][0]):
            heapq.heappop(heap)  # sent, cancelled or moved earlier
        if heap and heap[0][0] < self._armed:
            self._armed = heap[0][0]
            self._timer += 1
            timer = self._timer
            self.later(self._armed - self.port.local_time(), lambda: self._due(timer))

    def _due(self, timer: int) -> None:
        """Send every packet whose time has come, head first, and re-arm for the next."""
        if timer != self._timer:
            return
        now = self.port.local_time()
        self._armed = math.inf
        heap = self._heap
        while heap:
            send_at, _, key = heap[0]
            queued = self.q1.get(key)
            if queued is None or queued.send_at != send_at:
                heapq.heappop(heap)
                continue
            if send_at > now + 1e-9:
                break
            heapq.heappop(heap)
            del self.q1[key]
            self.q2.add(key)
            self.forward(queued.datagram, queued.prev, queued.gain)
        self._arm()
