"""``tdma``: time-division multiple access with guard times (fixed assignment; D. Bertsekas
and R. Gallager, Data Networks, 2nd ed., Prentice Hall 1992, Sec. 4.1; under water as in
Aqua-Sim NG's ``AquaSimTdmaMac``).

Time is a cycle of ``slots`` slots; node i owns slot i mod ``slots`` of every cycle and
transmits only in it, the frames it holds back to back while each still ends a guard time
before the slot does. The guard (by default the largest propagation delay) lets the last
frame of a slot reach every node in range before the next slot's owner starts, so frames of
different slots never overlap anywhere: no collisions, at the price of waiting for the own
slot, and of a cycle as long as the network is large. With fewer slots than nodes (spatial
reuse), nodes sharing a slot collide where both are heard.

The cycle runs on the node's local clock from local time 0: nodes whose clocks are offset
from each other by more than the guard's margin overlap their neighbours' slots (add their
offset to ``guard_s``). A frame that cannot fit in a slot is given up (``drop`` reason
``too_long``); an offer to a full queue is refused (``queue_full``).
"""

from __future__ import annotations

import math
from collections.abc import Generator
from typing import Any

from pydantic import Field

from .base import Frame, MacParams, MacPort, QueuedMac, QueueParams, SlotParams

__all__ = ["Tdma", "TdmaParams"]

#: how far past its slot start a node may find itself and still count as in the slot (s): the
#: rounding of a timer to the slot start, not a timing margin
_EPS = 1e-9


class TdmaParams(QueueParams, SlotParams):
    queue_length: int = Field(
        16, ge=1, le=100_000, description="frames the MAC holds at once (they wait for the own slot)"
    )
    slots: int | None = Field(None, ge=1, le=100_000, description="slots per cycle; default one per node")
    max_delay_s: float | None = Field(
        None, gt=0.0, description="the largest propagation delay (s); default [channel] max_range_m / 1500 m/s"
    )


class Tdma(QueuedMac):
    """Fixed-assignment TDMA (module docstring)."""

    name = "tdma"
    Params = TdmaParams
    params: TdmaParams

    def __init__(self, port: MacPort, params: MacParams) -> None:
        super().__init__(port, params)
        #: slot length, guard, cycle length (local s), and the start of the own slot in the cycle
        self.slot, self.guard = self.params.slot_and_guard(port, self.max_delay(self.params.max_delay_s))
        self.cycle = math.nan  # set at the first frame, when the network is complete
        self.own = math.nan

    def schedule(self) -> None:
        """The cycle and the own slot's start in it (local s): one slot per node by default."""
        n = self.params.slots if self.params.slots is not None else self.port.network_size
        self.cycle = n * self.slot
        self.own = (self.index % n) * self.slot

    def serve(self, frame: Frame) -> Generator[Any, Any, None]:
        if math.isnan(self.cycle):
            self.schedule()
        room = self.slot - self.guard  # how long a frame may last, sent at the slot start
        airtime = self.port.airtime(frame.bits)
        if airtime > room + _EPS:
            self.give_up(frame, "too_long")
            return
        now = self.port.local_time()
        # the own slot this cycle (its start at or before now), or the next one
        start = self.own + math.floor((now - self.own) / self.cycle) * self.cycle
        if now - start + airtime > room + _EPS:
            start += self.cycle
        yield self.wait_until_local(start)
        yield from self.send(frame)
        self.finish(frame)
