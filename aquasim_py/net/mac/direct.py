"""``direct``: no medium access control, the default.

Each frame goes to the modem at once and waits behind the frames the modem is still sending
(one FIFO per modem, never full); nothing is acknowledged or retransmitted, and a protocol
times its own sending (ITMTL's response slots, STVF's random send offsets). This is the
simulator's behaviour from before MACs existed, event for event: its frames are numbered when
their first bit leaves and it writes no ``offer`` rows, so every trace stays as it was.
"""

from __future__ import annotations

from typing import Any

import simpy

from .base import Mac

__all__ = ["Direct"]


class Direct(Mac):
    """The modem's own FIFO, nothing more (see the module docstring)."""

    name = "direct"

    def offer(self, dst: int | None, kind: str, payload: Any, bits: int) -> simpy.Event:
        return self.port.transmit(dst, kind, payload, bits, None)
