"""``slotted_aloha``: slotted ALOHA (L. G. Roberts, "ALOHA packet system with and without
slots and capture", ACM SIGCOMM Computer Communication Review 5(2), 1975).

Time is cut into slots one frame long; a node with a frame transmits it at the start of the
next slot. Frames now collide only when they start in the same slot, so the vulnerable time
halves and the throughput of Poisson traffic of G frames per slot is S = G e^(-G), at most
1 / e ~ 0.368 at G = 1.

Under water the slots must also hold the propagation delay: a frame sent at a slot start
reaches a receiver up to the largest delay later, where it overlaps the next slot's frames
from nearer nodes. Each slot is therefore the frame's airtime plus a guard time, by default
the largest propagation delay (``guard_s``); without it (``guard_s = 0``) frames from nodes
at different distances overlap across slot boundaries and the throughput falls towards pure
ALOHA's. The slots are kept on the node's local clock, so nodes whose clocks disagree by
more than the guard's margin lose the slot alignment too: add their offset to ``guard_s``.

Queue and optional ARQ as for pure ALOHA (:class:`~.base.ArqMac`); a retransmission waits its
random backoff, then the next slot start.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

from .base import ArqMac, ArqParams, Frame, MacParams, MacPort, SlotParams, next_boundary

__all__ = ["SlottedAloha", "SlottedAlohaParams"]


class SlottedAlohaParams(ArqParams, SlotParams):
    """Slotted ALOHA: the queue, the optional ARQ and the slots."""


class SlottedAloha(ArqMac):
    """Slotted ALOHA: transmit at the next slot start of the local clock (module docstring)."""

    name = "slotted_aloha"
    Params = SlottedAlohaParams
    params: SlottedAlohaParams

    def __init__(self, port: MacPort, params: MacParams) -> None:
        super().__init__(port, params)
        #: slot length (local s)
        self.slot, _guard = self.params.slot_and_guard(port, self.delay_max)

    def access(self, frame: Frame) -> Generator[Any, Any, bool]:
        yield self.wait_until_local(next_boundary(self.port.local_time(), self.slot))
        yield from self.send(frame)
        return True
