"""``eedbr``: energy-efficient depth-based routing (A. Wahid, S. Lee, H.-J. Jeong and D. Kim,
"EEDBR: Energy-Efficient Depth-Based Routing Protocol for Underwater Wireless Sensor Networks",
AST 2011, CCIS 195, pp. 223-234; A. Wahid and D. Kim, "An Energy Efficient Localization-Free
Routing Protocol for Underwater Wireless Sensor Networks", International Journal of Distributed
Sensor Networks 2012, 307246).

DBR lets every shallower node that hears a packet compete to forward it, so the same
well-placed nodes forward again and again and their batteries empty first. EEDBR spreads the
work by residual energy, in two phases:

1. *Knowledge acquisition*: every node broadcasts a hello with its depth and residual
   energy; its neighbours keep both in a table. Every packet a node sends carries the same two
   figures, so the tables follow as the network works (a drifting network needs its hellos
   repeated, ``hello_interval_s``, and its stale entries forgotten, ``neighbour_timeout_s``).
2. *Data forwarding*: the sender names its forwarders in the packet: its neighbours shallower
   than itself, highest residual energy first. A node not named drops the packet. A named one
   holds it for

       T_h = (1 - E_r / E_0) T_max + P_k,

   ``E_r / E_0`` its battery's residual fraction, ``T_max`` the longest hold, ``P_k`` the
   priority of its rank k in the list (``P_1 = 0``, ``P_k = p_min 2^(k - 2)``), so the
   richest forwarder sends first; a named node that hears another named node's copy while it
   holds stands down.

A sink sends hellos too, so that the nodes under it name it. A node with no shallower
neighbour in its table does not send (``drop``, reason ``no_forwarder``).

Readings (documented switches). The texts of the two papers were not available to us in full;
the rules above are their published summary as the later literature repeats it, and the
holding time with its rank priority is the reading of a public MATLAB UWSN simulator that cites
the journal version. Open choices: ``holding_max_s`` (T_max, default 1 s), ``priority_s``
(p_min, default 2 R / v0, the separation DBR gives two candidates), ``max_forwarders`` (default
all shallower neighbours; that simulator names two), ``hello_interval_s`` (default once, at a
random time within ``hello_spread_s`` of the start), ``neighbour_timeout_s`` (default never),
ties in residual energy (the shallower first). Residual energy comes from the node's battery gauge; a node without a battery reads
full (E_r / E_0 = 1), which leaves only the rank priority.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import simpy
from pydantic import Field

from ...packet import Packet
from .base import Datagram, Header, RangeParams, Router, RouterParams, RouterPort

__all__ = ["HELLO", "Eedbr", "EedbrHeader", "EedbrParams", "Hello"]

#: the kind of EEDBR's hello packets
HELLO = "routing.hello"


@dataclass(frozen=True, slots=True)
class Hello:
    """A hello: the sender's depth (m) and residual energy fraction."""

    depth: float
    energy: float


@dataclass(frozen=True, slots=True)
class EedbrHeader(Header):
    """EEDBR's header: the common fields, the sender's depth (m) and residual energy fraction,
    and the forwarders it names, in rank order."""

    depth: float = math.nan
    energy: float = math.nan
    forwarders: tuple[int, ...] = ()


class EedbrParams(RangeParams):
    holding_max_s: float = Field(1.0, gt=0.0, le=3600.0, description="T_max of the holding time (local s)")
    priority_s: float | None = Field(
        None, ge=0.0, description="p_min of the rank priority p_min 2^(k - 2) (local s); default 2 R / v0"
    )
    max_forwarders: int | None = Field(None, ge=1, description="forwarders a sender names, at most; none: every one")
    hello_spread_s: float = Field(10.0, ge=0.0, description="the first hello goes at uniform(0, this) local s")
    hello_interval_s: float | None = Field(None, gt=0.0, description="hellos repeat this often (local s); none: once")
    neighbour_timeout_s: float | None = Field(
        None, gt=0.0, description="a neighbour not heard for this long (local s) is forgotten; none: never"
    )
    hello_bits: int = Field(56, ge=1, description="length of a hello (bits): id, depth, residual energy")


@dataclass(slots=True)
class _Held:
    datagram: Datagram
    prev: int
    named: tuple[int, ...]  # the forwarders the copy named (this node among them)


class Eedbr(Router):
    """Energy-efficient depth-based routing (module docstring)."""

    name = "eedbr"
    Params = EedbrParams
    params: EedbrParams
    header_fields_bits = 16 + 8  # depth, residual energy (and 16 bits per named forwarder)

    def __init__(self, port: RouterPort, params: RouterParams) -> None:
        super().__init__(port, params)
        p = self.params
        if p.priority_s is not None:
            self.p_min = p.priority_s
        else:
            self.p_min = 0.0 if self.is_sink else 2.0 * self.range_m(p.range_m) / p.sound_speed_mps
        # id -> (depth m, residual energy fraction, local time last heard)
        self.neighbours: dict[int, tuple[float, float, float]] = {}
        self.held: dict[tuple[int, int], _Held] = {}
        self.later(float(port.rng.uniform(0.0, p.hello_spread_s)), self._hello)

    # -- knowledge acquisition -------------------------------------------------------------------

    def _hello(self) -> None:
        if not self.alive():
            return
        self.port.offer(None, HELLO, Hello(self.port.depth(), self.port.residual_energy()), self.params.hello_bits)
        if self.params.hello_interval_s is not None:
            self.later(self.params.hello_interval_s, self._hello)

    def receive(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> bool:
        d = packet.payload
        if isinstance(d, Hello):
            self.neighbours[packet.src] = (d.depth, d.energy, rx_local)
            return True
        if isinstance(d, Datagram) and isinstance(d.header, EedbrHeader):
            self.neighbours[packet.src] = (d.header.depth, d.header.energy, rx_local)
        return super().receive(packet, rx_local, snr_db, pressure)

    # -- data forwarding -------------------------------------------------------------------------

    def forwarders(self, depth: float) -> tuple[int, ...]:
        """The neighbours shallower than ``depth``, highest residual energy first (the shallower
        first among equals), at most ``max_forwarders``; those not heard for
        ``neighbour_timeout_s`` are forgotten."""
        timeout = self.params.neighbour_timeout_s
        if timeout is not None:
            now = self.port.local_time()
            self.neighbours = {i: n for i, n in self.neighbours.items() if now - n[2] <= timeout}
        up = sorted((-e, d, i) for i, (d, e, _) in self.neighbours.items() if d < depth)
        return tuple(i for _, _, i in up[: self.params.max_forwarders])

    def _stamped(self, header: Header) -> Header:
        depth = self.port.depth()
        energy, named = self.port.residual_energy(), self.forwarders(depth)
        if isinstance(header, EedbrHeader):
            return replace(header, depth=depth, energy=energy, forwarders=named)
        return EedbrHeader(*header.common(), depth=depth, energy=energy, forwarders=named)

    originate = _stamped
    relay = _stamped

    def header_bits_of(self, header: Header) -> int:
        assert isinstance(header, EedbrHeader)
        return self.header_bits + 16 * len(header.forwarders)

    def transmit(self, datagram: Datagram, prev: int, value: float) -> simpy.Event | None:
        h = datagram.header
        assert isinstance(h, EedbrHeader)
        if not h.forwarders:
            self.port.row(("drop", "no_forwarder", h.origin, h.seq, h.dst, h.hops, prev, value))
            return None
        return super().transmit(datagram, prev, value)

    def holding_time(self, rank: int) -> float:
        """T_h = (1 - E_r / E_0) T_max + P_k for the ``rank``-th named forwarder (1-based)."""
        priority = 0.0 if rank == 1 else self.p_min * 2.0 ** (rank - 2)
        return (1.0 - self.port.residual_energy()) * self.params.holding_max_s + priority

    def on_copy(self, datagram: Datagram, sender: int) -> None:
        h = datagram.header
        assert isinstance(h, EedbrHeader)
        key = h.key
        held = self.held.get(key)
        if held is not None:
            if sender in held.named:  # another named forwarder sent it: stand down
                del self.held[key]
                self.suppressed(held.datagram, held.prev)
            return
        if key in self.history or self.index not in h.forwarders:
            return
        self.history.add(key)
        self.held[key] = _Held(datagram, sender, h.forwarders)
        self.later(self.holding_time(h.forwarders.index(self.index) + 1), lambda: self._due(key))

    def _due(self, key: tuple[int, int]) -> None:
        held = self.held.pop(key, None)
        if held is not None:
            self.forward(held.datagram, held.prev)
