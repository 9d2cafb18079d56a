"""``sfama``: Slotted FAMA (M. Molins and M. Stojanovic, "Slotted FAMA: a MAC protocol for
underwater acoustic networks", IEEE OCEANS 2006 Asia Pacific).

FAMA (C. L. Fullmer and J. J. Garcia-Luna-Aceves, SIGCOMM 1995) reserves the channel with an
RTS / CTS handshake before the data, and needs control frames longer than the largest
propagation delay to avoid collisions, far too long under water. Slotted FAMA puts every
frame at the start of a slot instead, a slot being the largest propagation delay plus a
CTS's airtime (tau_max + gamma), so that any frame sent at a slot start has reached every node
in range by the slot's end:

1. A node with a unicast frame sends an RTS to its addressee at a slot start (not while it
   is deferring, and not when its modem senses a carrier then).
2. The addressee, idle, answers with a CTS at the next slot start.
3. On the CTS the sender sends the data at the next slot start; it lasts
   ceil((airtime + tau_max) / slot) slots.
4. The addressee acknowledges it with an ACK at the first slot start after its last bit.

A node that overhears an RTS for another defers for two slots (the CTS and the start of the
data, which it will then hear); one that overhears a CTS for another defers until the data
and its ACK are over (the CTS carries the data's length). A sender without a CTS two slots
after its RTS, or without an ACK when the data's slots and one more are over, backs off a
random number of slots, 1 to ``max_backoff_slots``, and tries again, at most ``retries`` more
times (then ``drop`` reason ``retries``); a deferral met during the backoff delays the RTS
further but does not redraw the backoff (the paper's "do not reset the backoff timer").

Choices where the paper is open or where this implementation is simpler: carrier sense is
sampled at the slot start of an RTS (busy: try the next slot), not tracked; a broadcast frame
needs no handshake and goes at a slot start like an RTS would, unacknowledged; one data frame
per handshake (the paper's packet trains are not modelled); a node answers an RTS only when it
is neither deferring nor in a handshake of its own. Slots run on the local clock from local
time 0; ``guard_s`` lengthens them to cover clock offsets between nodes.
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

import simpy
from pydantic import Field

from ...packet import Packet
from .base import ACK, CTS, RTS, Frame, MacParams, MacPort, QueuedMac, QueueParams, next_boundary

__all__ = ["SlottedFama", "SlottedFamaParams"]

#: how close to a slot start (local s) counts as at it: the rounding of a timer, not a margin
_EPS = 1e-9


class SlottedFamaParams(QueueParams):
    control_bits: int = Field(100, ge=1, description="length of an RTS, CTS and ACK (bits)")
    retries: int = Field(3, ge=0, le=1000, description="new handshakes after a failed one, at most")
    max_backoff_slots: int = Field(4, ge=1, le=100_000, description="a backoff lasts 1 to this many slots")
    max_delay_s: float | None = Field(
        None, gt=0.0, description="the largest propagation delay tau_max (s); default [channel] max_range_m / 1500 m/s"
    )
    guard_s: float = Field(0.0, ge=0.0, description="added to each slot (s), e.g. for clock offsets between nodes")


class SlottedFama(QueuedMac):
    """Slotted FAMA (module docstring)."""

    name = "sfama"
    Params = SlottedFamaParams
    params: SlottedFamaParams
    senses_carrier = True

    def __init__(self, port: MacPort, params: MacParams) -> None:
        super().__init__(port, params)
        p = self.params
        self.tau = self.max_delay(p.max_delay_s)
        #: slot length (local s): tau_max + gamma (+ guard)
        self.slot = self.tau + port.airtime(p.control_bits) + p.guard_s
        self.hold_until = -math.inf  # no RTS (nor CTS) before this local time: deferring
        self.answer_until = -math.inf  # answering an RTS (a CTS sent, its data awaited) until then
        self.sending = False  # between an RTS of ours and the end of its handshake
        self._wait: tuple[str, int, simpy.Event] | None = None  # (kind, uid, event) the sender awaits

    # -- slots --------------------------------------------------------------------------------

    def data_slots(self, bits: int) -> int:
        """Slots a data frame of ``bits`` occupies until its last bit has reached everyone in range."""
        return math.ceil((self.port.airtime(bits) + self.tau) / self.slot - _EPS)

    def next_slot(self, after: float | None = None) -> float:
        """The first slot start (local s) after ``after`` (default now)."""
        return next_boundary(self.port.local_time() if after is None else after, self.slot)

    def defer(self, until: float) -> None:
        self.hold_until = max(self.hold_until, until)

    def answering(self) -> bool:
        return self.port.local_time() < self.answer_until

    # -- sender -------------------------------------------------------------------------------

    def serve(self, frame: Frame) -> Generator[Any, Any, None]:
        backoff_end = -math.inf
        not_before = -math.inf  # after a slot start found unfit: the next one
        while True:
            # the first slot start not before a deferral or the backoff ends, at which the
            # modem senses no carrier and the node is not answering someone else
            earliest = max(self.port.local_time(), self.hold_until, backoff_end)
            start = self.next_slot(max(earliest - _EPS, not_before))
            yield self.wait_until_local(start)
            if self.port.local_time() < self.hold_until - _EPS or self.answering() or self.port.carrier_busy():
                not_before = start + _EPS
                continue
            if frame.dst is None:  # a broadcast: no handshake, no ACK
                yield from self.send(frame)
                self.finish(frame)
                return
            n = self.data_slots(frame.bits)
            self.sending = True
            cts = self._await(CTS, frame.uid)
            self.control(frame.dst, RTS, (frame.uid, n), self.params.control_bits, overhear=True)
            yield self.env.any_of([cts, self.wait_until_local(start + 2.0 * self.slot)])
            if cts.triggered:
                data_start = self.next_slot()
                yield self.wait_until_local(data_start)
                ack = self._await(ACK, frame.uid)
                yield from self.send(frame)
                yield self.env.any_of([ack, self.wait_until_local(data_start + (n + 1) * self.slot)])
                if ack.triggered:
                    self.sending = False
                    self._wait = None
                    self.finish(frame)
                    return
            self.sending = False
            self._wait = None
            if frame.retries >= self.params.retries:
                self.give_up(frame, "retries")
                return
            frame.retries += 1
            k = int(self.port.rng.integers(1, self.params.max_backoff_slots + 1))
            backoff_end = self.next_slot() + (k - 1) * self.slot

    def _await(self, kind: str, uid: int) -> simpy.Event:
        ev = self.env.event()
        self._wait = (kind, uid, ev)
        return ev

    # -- receiver -----------------------------------------------------------------------------

    def receive(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> bool:
        kind = packet.kind
        mine = packet.dst == self.index
        if kind == RTS:
            uid, n = packet.payload
            if not mine:
                self.defer(self.next_slot() + 2.0 * self.slot)
            elif not (self.sending or self.answering()) and self.port.local_time() >= self.hold_until - _EPS:
                self._answer(packet.src, uid, n)
            return True
        if kind == CTS:
            uid, n = packet.payload
            if not mine:
                self.defer(self.next_slot() + (n + 1) * self.slot)
            else:
                self._resolve(CTS, uid)
            return True
        if kind == ACK:
            if mine:
                self._resolve(ACK, packet.payload)
            return True
        if mine:  # data for this node: acknowledge it at the next slot start, hand it up once
            self.answer_until = -math.inf
            ack_at = self.next_slot()
            self.defer(ack_at + self.slot)
            self.env.process(self._at(ack_at, packet.src, ACK, packet.uid))
            return not self.first_delivery(packet)
        return False

    def _answer(self, src: int, uid: int, n: int) -> None:
        """Answer an RTS: a CTS at the next slot start, then wait for the data it announces."""
        cts_at = self.next_slot()
        end = cts_at + (n + 2) * self.slot  # the data's slots after the CTS's, and its ACK's
        self.answer_until = end
        self.defer(end)
        self.env.process(self._at(cts_at, src, CTS, (uid, n), overhear=True))

    def _at(
        self, t_local: float, dst: int, kind: str, payload: Any, overhear: bool = False
    ) -> Generator[Any, Any, None]:
        yield self.wait_until_local(t_local)
        self.control(dst, kind, payload, self.params.control_bits, overhear)

    def _resolve(self, kind: str, uid: int) -> None:
        wait = self._wait
        if wait is not None and wait[0] == kind and wait[1] == uid and not wait[2].triggered:
            wait[2].succeed()
