"""What every router is: one small component per node between its protocol and its MAC that
carries packets over several hops to a surface sink.

A protocol calls ``send(dst, ...)`` with ``dst`` a sink or :data:`~aquasim_py.node.ANY_SINK`;
the node hands the packet to its router (:meth:`Router.send`), which wraps it in a
:class:`Datagram` (the network header and the application's payload) and broadcasts it through
the node's MAC. Every router that hears a copy decides, by its protocol's rule, whether to
forward it, when (a holding time), and whether a copy overheard meanwhile makes its own
redundant (:meth:`Router.on_copy`, the protocol's). Broadcasts, and unicasts to a node that is
not a sink, go to the MAC unrouted, one hop, as without a router.

Delivery. A copy reaching a sink (a node of role ``sink`` whose group routes) is delivered
there if it is the first copy any sink got: the sinks are surface buoys linked by radio, so the
first sink reached delivers it (to the addressed sink's protocol, over the radio, or to its
own for ``ANY_SINK``) and every later copy at any sink is a duplicate. Sinks never forward.
The delivered packet's ``src`` is the origin; its stamps and SNR are the last hop's.

A router sits on the node's side of the truth barrier: it sees the node through a
:class:`RouterPort` only (its local clock and timers, its depth gauge, its position fix when
the group has one, its MAC), never true positions or true time. Holding times run on the
node's local clock. What the sinks share (their ids, their positions when they have a fix,
the set of datagrams delivered) is the run's out-of-band directory: the deployment's
configuration and the sinks' radio link, modelled on purpose.

Trace. Each router writes the ``routes`` table (:data:`ROUTE_COLUMNS`): an ``originate`` row
at the source, a ``forward`` row per copy a node hands its MAC (the source's own transmission
included), ``suppress`` when a held copy is given up, ``drop`` (reason ``max_hops``) when a
copy would exceed the hop limit, ``deliver`` at the first sink and ``sink_copy`` for each later
copy at a sink. The network metrics (``net.pdr`` and the rest, :mod:`.metrics`) come from it.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, replace
from typing import Any, ClassVar, Protocol

import numpy as np
import simpy
from pydantic import BaseModel, ConfigDict, Field

from ...node import ANY_SINK, NodeEnv
from ...packet import Packet

__all__ = [
    "BASE_HEADER_BITS",
    "DIRECTORY_DELIVERED",
    "DIRECTORY_SINKS",
    "NOMINAL_SOUND_SPEED_MPS",
    "ROUTE_COLUMNS",
    "Datagram",
    "Header",
    "History",
    "RangeParams",
    "Router",
    "RouterParams",
    "RouterPort",
    "SinkEntry",
]

#: the ``routes`` table's columns after ``time`` and ``node`` (which the kernel adds): what
#: happened (``event``) and why (``reason``, drops only), the datagram (``origin``, ``seq``,
#: ``dst``: a sink id or -2 for any sink), the hops it had travelled (at a forward: the copy's
#: hops including this transmission), ``prev``: the node whose copy the row answers (-1 at the
#: origin), ``value``: the protocol's quantity behind the decision (DBR: the depth gained, m;
#: VBF: the desirableness factor; NaN where none)
ROUTE_COLUMNS = ("event", "reason", "origin", "seq", "dst", "hops", "prev", "value")

#: bits of the header fields every router carries: origin id, sequence number, destination (16
#: bits each) and hop count (8 bits)
BASE_HEADER_BITS = 56

#: the sound speed (m/s) a router converts its range into a one-hop delay with
NOMINAL_SOUND_SPEED_MPS = 1500.0

#: out-of-band keys: the sinks (id -> :class:`SinkEntry`) and the datagrams delivered
DIRECTORY_SINKS = "routing.sinks"
DIRECTORY_DELIVERED = "routing.delivered"


@dataclass(frozen=True, slots=True)
class Header:
    """The network header every routed packet carries; a protocol adds its fields in a subclass.

    ``origin`` and ``seq`` name the datagram; ``dst`` is a sink's id or ``ANY_SINK``; ``hops``
    counts the transmissions it has had (1 on the source's); ``sender`` is the node transmitting
    this copy."""

    origin: int
    seq: int
    dst: int
    hops: int
    sender: int

    @property
    def key(self) -> tuple[int, int]:
        """The datagram's identity: (origin, sequence number)."""
        return (self.origin, self.seq)

    def common(self) -> tuple[int, int, int, int, int]:
        """The common fields, in order (to build a protocol's header from them)."""
        return (self.origin, self.seq, self.dst, self.hops, self.sender)


@dataclass(frozen=True, slots=True)
class Datagram:
    """A routed packet on the air: header, the application's kind, payload (its send-time
    snapshot, shared by every copy and never handed out: each delivery takes a copy) and bits."""

    header: Header
    kind: str
    payload: Any
    bits: int


@dataclass(frozen=True, slots=True)
class SinkEntry:
    """A sink as the directory knows it: its position fix at set-up (None without one), the
    way the radio link hands a packet up to its protocol, and its local clock (the stamp of a
    packet it gets over the radio)."""

    position: tuple[float, float, float] | None
    deliver: Callable[[Packet, float, float, float], None]
    local_time: Callable[[], float]


class RouterPort(Protocol):
    """What a router may use of its node: local observables, its sensors and its MAC (the
    kernel implements it)."""

    @property
    def index(self) -> int:
        """The node's id."""
        ...

    @property
    def env(self) -> NodeEnv:
        """The node's view of the simulation: timers in local seconds, no true clock."""
        ...

    @property
    def rng(self) -> np.random.Generator:
        """The router's own random stream ("node", id, "routing"), made on first use."""
        ...

    @property
    def is_sink(self) -> bool:
        """Whether the node is a sink (a surface gateway)."""
        ...

    @property
    def max_range_m(self) -> float:
        """The modem's configured range (m), ``[channel] max_range_m``."""
        ...

    @property
    def directory(self) -> dict[str, Any]:
        """The run's out-of-band directory (:attr:`aquasim_py.node.Node.out_of_band`)."""
        ...

    def local_time(self) -> float:
        """The node's local clock now (s)."""
        ...

    def depth(self) -> float:
        """The depth gauge's reading now (m, positive down), with the group's noise."""
        ...

    def position(self) -> tuple[float, float, float]:
        """The node's position fix now (m), with the group's noise; raises
        :class:`~aquasim_py.node.SensorUnavailable` when the group has none."""
        ...

    def residual_energy(self) -> float:
        """The battery gauge: the residual fraction of the battery's capacity now (1 without a
        battery)."""
        ...

    def offer(self, dst: int | None, kind: str, payload: Any, bits: int) -> simpy.Event:
        """Hand a frame to the node's MAC (its event: the MAC's, see :mod:`aquasim_py.net.mac`)."""
        ...

    def deliver(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        """Hand a packet up to the node's protocol (its waiting ``recv`` or its inbox)."""
        ...

    def row(self, values: tuple[Any, ...]) -> None:
        """Write a ``routes`` row now: the :data:`ROUTE_COLUMNS` in that order."""
        ...


class RouterParams(BaseModel):
    """Parameters every router has."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    max_hops: int | None = Field(
        None, ge=1, le=10_000, description="a copy is not forwarded past this many hops (a TTL); none: no limit"
    )
    history_length: int = Field(
        4096, ge=1, le=10_000_000, description="datagrams a node remembers having handled (its duplicate cache)"
    )
    header_bits: int | None = Field(
        None, ge=0, description="bits the network header adds to each packet; default the protocol's header"
    )


class RangeParams(RouterParams):
    """Parameters of a router whose rule uses the range and the speed of sound."""

    range_m: float | None = Field(
        None, gt=0.0, description="R, the transmission range (m); default [channel] max_range_m"
    )
    sound_speed_mps: float = Field(
        NOMINAL_SOUND_SPEED_MPS, gt=0.0, description="v0, the speed of sound of the rule's delays (m/s)"
    )


class History:
    """The datagrams a node remembers, the oldest forgotten beyond ``length`` (a FIFO set)."""

    __slots__ = ("_keys", "length")

    def __init__(self, length: int) -> None:
        self.length = length
        self._keys: OrderedDict[Hashable, None] = OrderedDict()

    def __contains__(self, key: Hashable) -> bool:
        return key in self._keys

    def add(self, key: Hashable) -> None:
        keys = self._keys
        if key not in keys:
            keys[key] = None
            if len(keys) > self.length:
                keys.popitem(last=False)


class Router:
    """Base of every router: subclass it, give ``name``, ``Params``, a citation in the
    docstring, and write :meth:`on_copy` (and :meth:`originate` / :meth:`relay` for header
    fields of its own).

    One instance per node, made with the node's :class:`RouterPort` and its group's
    parameters (an instance of ``Params``)."""

    name: ClassVar[str] = ""
    Params: ClassVar[type[RouterParams]] = RouterParams
    #: bits of the protocol's own header fields (added to :data:`BASE_HEADER_BITS`)
    header_fields_bits: ClassVar[int] = 0
    #: the group's nodes (and the sinks) need a position fix for this router
    needs_position: ClassVar[bool] = False

    def __init__(self, port: RouterPort, params: RouterParams) -> None:
        self.port = port
        self.params = params
        self.env = port.env
        self.index = port.index
        self.is_sink = port.is_sink
        hb = params.header_bits
        self.header_bits = BASE_HEADER_BITS + self.header_fields_bits if hb is None else hb
        self.history = History(params.history_length)
        self._seq = 0
        self._sinks: dict[int, SinkEntry] = port.directory.setdefault(DIRECTORY_SINKS, {})
        self._delivered: set[tuple[int, int]] = port.directory.setdefault(DIRECTORY_DELIVERED, set())
        if self.is_sink:
            self._sinks[self.index] = SinkEntry(self.sink_position(), port.deliver, port.local_time)

    def sink_position(self) -> tuple[float, float, float] | None:
        """The position a sink announces in the directory (override: a router that needs it)."""
        return None

    # -- the application's side ------------------------------------------------------------------

    def routes(self, dst: int) -> bool:
        """Whether a unicast to ``dst`` is routed (to a sink, from a node that is not one)."""
        return not self.is_sink and (dst == ANY_SINK or dst in self._sinks)

    def send(self, dst: int, kind: str, payload: Any, bits: int) -> simpy.Event:
        """Originate a datagram to ``dst`` (a sink or ``ANY_SINK``) and transmit it now; the
        event is the MAC's for that first transmission. A node whose battery is empty
        originates nothing (no row; the event fires at once with None)."""
        if not self.alive():
            return self.env.event().succeed(None)
        seq = self._seq
        self._seq = seq + 1
        header = self.originate(Header(self.index, seq, dst, 1, self.index))
        self.history.add(header.key)
        self.port.row(("originate", None, self.index, seq, dst, 0, -1, math.nan))
        sent = self.transmit(Datagram(header, kind, payload, bits), -1, math.nan)
        if sent is None:  # the protocol gave it up at once (its drop row says why)
            sent = self.env.event().succeed(None)
        return sent

    def originate(self, header: Header) -> Header:
        """The header of a new datagram (override: add the protocol's fields)."""
        return header

    # -- the network's side ----------------------------------------------------------------------

    def receive(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> bool:
        """A reception at this node: True if it was a routed packet (taken here), False to hand
        it up to the protocol."""
        d = packet.payload
        if not isinstance(d, Datagram):
            return False
        if self.is_sink:
            self._at_sink(d, packet, rx_local, snr_db, pressure)
        elif d.header.origin != self.index:
            self.on_copy(d, packet.src)
        return True

    def on_copy(self, datagram: Datagram, sender: int) -> None:
        """The protocol's rule for a copy of ``datagram`` heard from ``sender`` (override)."""
        raise NotImplementedError

    def relay(self, header: Header) -> Header:
        """The header of this node's copy (override: update the protocol's fields)."""
        return header

    def forward(self, datagram: Datagram, prev: int, value: float = math.nan) -> simpy.Event | None:
        """Transmit this node's copy of ``datagram`` (a received copy from ``prev``); None, and a
        ``drop`` row, past the hop limit; None and no row once the node's battery is empty (a
        copy held when it died)."""
        if not self.alive():
            return None
        h = datagram.header
        limit = self.params.max_hops
        if limit is not None and h.hops >= limit:
            self.port.row(("drop", "max_hops", h.origin, h.seq, h.dst, h.hops, prev, value))
            return None
        header = self.relay(replace(h, hops=h.hops + 1, sender=self.index))
        return self.transmit(replace(datagram, header=header), prev, value)

    def transmit(self, datagram: Datagram, prev: int, value: float) -> simpy.Event | None:
        """Hand a copy to the MAC, as a broadcast, and write its ``forward`` row (override to
        refuse: None, with a ``drop`` row)."""
        h = datagram.header
        self.port.row(("forward", None, h.origin, h.seq, h.dst, h.hops, prev, value))
        return self.port.offer(None, datagram.kind, datagram, datagram.bits + self.header_bits_of(h))

    def header_bits_of(self, header: Header) -> int:
        """Bits the network header of ``header`` adds (override for a header of varying length)."""
        return self.header_bits

    def suppressed(self, datagram: Datagram, prev: int, value: float = math.nan) -> None:
        """Write the ``suppress`` row of a held copy given up."""
        h = datagram.header
        self.port.row(("suppress", None, h.origin, h.seq, h.dst, h.hops, prev, value))

    def alive(self) -> bool:
        """Whether the node still has power: its battery gauge above empty (always, without a
        battery). A dead node's modem neither sends nor receives; its router does nothing."""
        return self.port.residual_energy() > 0.0

    def later(self, delay_local: float, callback: Callable[[], object]) -> None:
        """Call ``callback()`` after ``delay_local`` seconds of the node's clock (a holding time)."""

        def fire(_event: simpy.Event) -> None:
            callback()

        self.env.timeout(max(0.0, delay_local)).callbacks.append(fire)

    # -- at a sink -------------------------------------------------------------------------------

    def _at_sink(self, d: Datagram, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        h = d.header
        key = h.key
        if key in self._delivered:
            self.port.row(("sink_copy", None, h.origin, h.seq, h.dst, h.hops, packet.src, math.nan))
            return
        self._delivered.add(key)
        self.port.row(("deliver", None, h.origin, h.seq, h.dst, h.hops, packet.src, math.nan))
        addressee = h.dst if h.dst in self._sinks else self.index
        sink = self._sinks[addressee]
        if addressee != self.index:  # over the radio, at once: stamped by the addressee's clock
            rx_local = sink.local_time()
        up = Packet(packet.uid, h.origin, addressee, d.kind, d.payload, d.bits, packet.tx_local)
        sink.deliver(up, rx_local, snr_db, pressure)

    # -- helpers ---------------------------------------------------------------------------------

    def range_m(self, range_m: float | None) -> float:
        """The range R (m) a router's rule uses: ``range_m``, or the modem's configured range."""
        r = range_m if range_m is not None else self.port.max_range_m
        if not math.isfinite(r) or r <= 0.0:
            raise ValueError(f"{self.name}: the range must be finite and > 0 m, got {r!r} (set range_m)")
        return float(r)
