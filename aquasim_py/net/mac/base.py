"""What every MAC is: one small component per node between its protocol and its modem.

A protocol calls ``broadcast`` / ``send``; the node hands the frame to its MAC
(:meth:`Mac.offer`), which decides when the modem transmits it, retransmits it, or gives it up.
Receptions pass through the MAC first (:meth:`Mac.receive`): it keeps its own control frames
(RTS, CTS, ACK: packets of their own kinds, :data:`CONTROL_KINDS`) and hands the rest up.

A MAC sits on the node's side of the truth barrier: it sees the node through a
:class:`MacPort` only (its local clock and timers, its own modem's carrier sense, the modem's
configuration), never the channel's global state or true time. Its timers run on the node's
local clock, so slot boundaries of different nodes differ by their clock offsets: the guard
times must cover them.

Contract with the protocol: the event ``offer`` returns (the protocol's ``broadcast`` / ``send``
event) fires once the MAC is done with the frame: at its last bit (after its ACK, for a MAC
that waits for one), with the local MAC transmit stamp of its last transmission as its value;
or when the MAC gives it up, with that stamp if it was transmitted and ``None`` if it never
was. A frame given up gets a ``drop`` row with the reason (:data:`DROP_REASONS`); a frame
offered gets an ``offer`` row (except under ``direct``, today's path straight to the modem).
Every frame has one uid, from its offer on; its retransmissions carry it.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol

import numpy as np
import simpy
from pydantic import BaseModel, ConfigDict, Field

from ...node import NodeEnv
from ...packet import Packet

__all__ = [
    "ACK",
    "CONTROL_KINDS",
    "CTS",
    "DROP_REASONS",
    "NOMINAL_SOUND_SPEED_MPS",
    "RTS",
    "ArqMac",
    "ArqParams",
    "Frame",
    "Mac",
    "MacParams",
    "MacPort",
    "QueueParams",
    "QueuedMac",
    "SlotParams",
]

#: kinds of the MAC control frames (the ``kind`` column of their ``packets`` rows)
RTS = "mac.rts"
CTS = "mac.cts"
ACK = "mac.ack"
CONTROL_KINDS = frozenset((RTS, CTS, ACK))

#: why a MAC gives a frame up (the ``reason`` of its ``drop`` row at the sender)
DROP_REASONS = {
    "queue_full": "offered while the MAC held queue_length frames already (pure ALOHA: while transmitting)",
    "retries": "no ACK (or no CTS) after the last retry",
    "busy": "the carrier was sensed at every attempt allowed",
    "too_long": "longer than the MAC's slot can carry",
}

#: the sound speed (m/s) a MAC converts its modem's range into a largest delay with
#: (a deployment's guard times are set from a nominal speed; give max_delay_s for a slower sea)
NOMINAL_SOUND_SPEED_MPS = 1500.0


class MacPort(Protocol):
    """What a MAC may use of its node: local observables and its own modem (the kernel implements it)."""

    @property
    def index(self) -> int:
        """The node's id (its address)."""
        ...

    @property
    def env(self) -> NodeEnv:
        """The node's view of the simulation: timers in local seconds, no true clock."""
        ...

    @property
    def rng(self) -> np.random.Generator:
        """The MAC's own random stream ("node", id, "mac"), made on first use."""
        ...

    @property
    def max_range_m(self) -> float:
        """The modem's configured range (m), ``[channel] max_range_m``."""
        ...

    @property
    def network_size(self) -> int:
        """How many nodes the deployment has (ids 0 .. n-1), e.g. for a TDMA schedule."""
        ...

    def local_time(self) -> float:
        """The node's local clock now (s)."""
        ...

    def airtime(self, bits: int) -> float:
        """How long a packet of ``bits`` bits lasts on the air (s): the modem's bit rate."""
        ...

    def transmit(
        self, dst: int | None, kind: str, payload: Any, bits: int, uid: int | None, overhear: bool = False
    ) -> simpy.Event:
        """Start one transmission now (behind the modem's own queue, if it is still sending);
        the event fires at its last bit with the local MAC transmit stamp. ``uid``: the frame's
        (None: numbered when its first bit leaves). ``overhear``: a unicast every node decoding
        it is handed (an RTS or CTS that others must defer to)."""
        ...

    def carrier_busy(self) -> bool:
        """Carrier sense now, from the node's own modem: it is transmitting or receiving a signal."""
        ...

    def new_uid(self) -> int:
        """A packet uid never used before."""
        ...

    def row(self, event: str, reason: str | None, dst: int | None, uid: int, kind: str, bits: int) -> None:
        """Write a ``packets`` row now about one of the node's frames (``offer`` or ``drop``)."""
        ...


@dataclass(slots=True)
class Frame:
    """A frame a protocol offered: the packet to be and the protocol's event."""

    dst: int | None
    kind: str
    payload: Any
    bits: int
    uid: int
    done: simpy.Event
    #: the local MAC stamp of its last transmission (None: not transmitted yet)
    tx_local: float | None = None
    #: retransmissions so far
    retries: int = 0


class MacParams(BaseModel):
    """Parameters every MAC model derives from (none here)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class Mac:
    """Base of every MAC: subclass it, give ``name``, ``Params`` and a citation in the
    docstring, and override :meth:`offer` (and :meth:`receive` for control frames).

    One instance per node, made with the node's :class:`MacPort` and the group's parameters
    (an instance of ``Params``)."""

    name: ClassVar[str] = ""
    Params: ClassVar[type[MacParams]] = MacParams
    #: the channel must record every signal at every receiver for this MAC's carrier sense
    senses_carrier: ClassVar[bool] = False

    def __init__(self, port: MacPort, params: MacParams) -> None:
        self.port = port
        self.params = params
        self.env = port.env
        self.index = port.index
        self._delivered: dict[int, deque[int]] = {}  # src -> the last uids handed up (first_delivery)

    def offer(self, dst: int | None, kind: str, payload: Any, bits: int) -> simpy.Event:
        """Take a frame from the protocol; returns the protocol's event (see the module docstring)."""
        raise NotImplementedError

    def receive(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> bool:
        """A reception at this node: True if the MAC keeps it (a control frame), False to hand
        it up to the protocol."""
        return False

    # -- helpers ----------------------------------------------------------------------------------

    def max_delay(self, max_delay_s: float | None) -> float:
        """The largest propagation delay (s): ``max_delay_s``, or the modem's range at the
        nominal sound speed."""
        return max_delay_s if max_delay_s is not None else self.port.max_range_m / NOMINAL_SOUND_SPEED_MPS

    def new_frame(self, dst: int | None, kind: str, payload: Any, bits: int) -> Frame:
        """Number a frame just offered and write its ``offer`` row."""
        uid = self.port.new_uid()
        self.port.row("offer", None, dst, uid, kind, bits)
        return Frame(dst, kind, payload, bits, uid, self.env.event())

    def finish(self, frame: Frame) -> None:
        """The MAC is done with a frame it delivered to the modem (and had acknowledged)."""
        frame.done.succeed(frame.tx_local)

    def give_up(self, frame: Frame, reason: str) -> None:
        """Drop a frame: a ``drop`` row at the sender, and the protocol's event fires."""
        self.port.row("drop", reason, frame.dst, frame.uid, frame.kind, frame.bits)
        frame.done.succeed(frame.tx_local)

    def send(self, frame: Frame) -> Generator[Any, Any, float]:
        """One transmission of ``frame`` now; returns (and keeps) its local transmit stamp."""
        tx = yield self.port.transmit(frame.dst, frame.kind, frame.payload, frame.bits, frame.uid)
        frame.tx_local = tx
        return float(tx)

    def control(self, dst: int, kind: str, payload: Any, bits: int, overhear: bool = False) -> simpy.Event:
        """Transmit a control frame (RTS, CTS, ACK) of its own uid now."""
        return self.port.transmit(dst, kind, payload, bits, self.port.new_uid(), overhear)

    def reply(self, dst: int, kind: str, payload: Any, bits: int, overhear: bool = False) -> None:
        """Transmit a control frame in answer to the reception being handed over now, once that
        reception is done (:meth:`receive` runs inside it)."""

        def send(_: simpy.Event) -> None:
            self.control(dst, kind, payload, bits, overhear)

        self.env.timeout(0.0).callbacks.append(send)

    def first_delivery(self, packet: Packet) -> bool:
        """Whether ``packet`` (unicast data addressed here) is handed up for the first time: a
        retransmission whose first copy was delivered (its ACK lost) is not handed up again."""
        seen = self._delivered.get(packet.src)
        if seen is None:
            seen = self._delivered[packet.src] = deque(maxlen=16)
        if packet.uid in seen:
            return False
        seen.append(packet.uid)
        return True

    def wait_until_local(self, t_local: float) -> simpy.Timeout:
        """A timer to the local clock reading ``t_local`` (at once if it has passed)."""
        return self.env.timeout(max(0.0, t_local - self.port.local_time()))


class QueueParams(MacParams):
    """The frame queue of a MAC."""

    queue_length: int = Field(
        1, ge=1, le=100_000, description="frames the MAC holds at once, the one it serves included; more are refused"
    )


class QueuedMac(Mac):
    """A MAC serving one frame at a time from a FIFO of ``queue_length`` frames: an offer to
    a full queue is refused (``drop`` reason ``queue_full``). Subclasses write
    :meth:`serve`, one frame's channel access (a generator)."""

    params: QueueParams

    def __init__(self, port: MacPort, params: MacParams) -> None:
        super().__init__(port, params)
        self.queue: deque[Frame] = deque()
        self._wake: simpy.Event | None = None  # the idle server's event
        self.env.process(self._server())

    def offer(self, dst: int | None, kind: str, payload: Any, bits: int) -> simpy.Event:
        frame = self.new_frame(dst, kind, payload, bits)
        if len(self.queue) >= self.params.queue_length:
            self.give_up(frame, "queue_full")
        else:
            self.queue.append(frame)
            if self._wake is not None:
                self._wake.succeed()
                self._wake = None
        return frame.done

    def _server(self) -> Generator[Any, Any, None]:
        queue = self.queue
        while True:
            if not queue:
                self._wake = self.env.event()
                yield self._wake
            yield from self.serve(queue[0])
            queue.popleft()

    def serve(self, frame: Frame) -> Generator[Any, Any, None]:
        """Channel access for one frame, ending with :meth:`finish` or :meth:`give_up`."""
        raise NotImplementedError


class ArqParams(QueueParams):
    """Acknowledgements and retransmissions (stop and wait) of a random-access MAC."""

    ack: bool = Field(
        False,
        description="unicast frames are acknowledged by the receiver's MAC (set it on the receivers' "
        "groups too) and retransmitted until acknowledged",
    )
    retries: int = Field(3, ge=0, le=1000, description="retransmissions of a frame not acknowledged, at most")
    ack_bits: int = Field(100, ge=1, description="length of an ACK (bits)")
    ack_timeout_s: float | None = Field(
        None,
        gt=0.0,
        description="wait for an ACK after the last bit (local s); default twice the largest delay plus "
        "the ACK's airtime",
    )
    backoff_max_s: float | None = Field(
        None,
        gt=0.0,
        description="a retransmission (or a new sense) waits uniform(0, this) local s; default twice "
        "the frame's airtime plus the largest delay",
    )
    max_delay_s: float | None = Field(
        None, gt=0.0, description="the largest propagation delay (s); default [channel] max_range_m / 1500 m/s"
    )


class ArqMac(QueuedMac):
    """A queued MAC with optional stop-and-wait ARQ: :meth:`serve` makes one channel access
    (:meth:`access`, the subclass's), then, with ``ack``, waits for the ACK and retries after
    a random backoff. The receiver's MAC acknowledges unicast data addressed to it and hands
    a retransmission it has delivered already up only once."""

    params: ArqParams

    def __init__(self, port: MacPort, params: MacParams) -> None:
        super().__init__(port, params)
        self.delay_max = self.max_delay(self.params.max_delay_s)
        self._ack_wait: tuple[int, simpy.Event] | None = None  # (uid, event) of the ACK awaited

    def access(self, frame: Frame) -> Generator[Any, Any, bool]:
        """One channel access for ``frame``: True once it was transmitted, False if the MAC
        gave it up (having written the drop row and fired the event)."""
        raise NotImplementedError

    def backoff(self, frame: Frame) -> float:
        """A random backoff (local s): uniform(0, backoff_max_s)."""
        hi = self.params.backoff_max_s
        if hi is None:
            hi = 2.0 * (self.port.airtime(frame.bits) + self.delay_max)
        return float(self.port.rng.uniform(0.0, hi))

    def serve(self, frame: Frame) -> Generator[Any, Any, None]:
        p = self.params
        while True:
            if not (yield from self.access(frame)):
                return
            if not p.ack or frame.dst is None:
                self.finish(frame)
                return
            if (yield from self._acked(frame)):
                self.finish(frame)
                return
            if frame.retries >= p.retries:
                self.give_up(frame, "retries")
                return
            frame.retries += 1
            yield self.env.timeout(self.backoff(frame))

    def _acked(self, frame: Frame) -> Generator[Any, Any, bool]:
        p = self.params
        timeout = p.ack_timeout_s
        if timeout is None:
            timeout = 2.0 * self.delay_max + self.port.airtime(p.ack_bits)
        got = self.env.event()
        self._ack_wait = (frame.uid, got)
        yield self.env.any_of([got, self.env.timeout(timeout)])
        self._ack_wait = None
        return got.triggered

    def receive(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> bool:
        if packet.kind == ACK:
            wait = self._ack_wait
            if wait is not None and wait[0] == packet.payload and not wait[1].triggered:
                wait[1].succeed()
            return True
        if self.params.ack and packet.dst == self.index:
            self.reply(packet.src, ACK, packet.uid, self.params.ack_bits)
            return not self.first_delivery(packet)
        return False


class SlotParams(MacParams):
    """Slots of a frame's airtime plus a guard time (slotted ALOHA, TDMA)."""

    slot_bits: int = Field(256, ge=1, description="the frame length a slot is made for (bits)")
    guard_s: float | None = Field(
        None, ge=0.0, description="guard time at each slot's end (s); default the largest propagation delay"
    )
    slot_s: float | None = Field(
        None, gt=0.0, description="slot length (local s); default the airtime of slot_bits plus guard_s"
    )

    def slot_and_guard(self, port: MacPort, delay_max: float) -> tuple[float, float]:
        """(slot length, guard time) in local s, ``delay_max`` the largest propagation delay (s)."""
        guard = delay_max if self.guard_s is None else self.guard_s
        return (self.slot_s if self.slot_s is not None else port.airtime(self.slot_bits) + guard), guard


def next_boundary(t_local: float, period: float, phase: float = 0.0) -> float:
    """The first local time ``phase + k period`` (k integer) after ``t_local`` (s)."""
    return phase + (math.floor((t_local - phase) / period) + 1.0) * period
