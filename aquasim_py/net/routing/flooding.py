"""``flooding``: every node rebroadcasts every datagram it hears, once.

The reference of every routing comparison: it tries every path, so no other protocol
delivers more over a loss-free channel, and none sends more copies. A node that hears a
datagram for the first time forwards it, after ``jitter_max_s`` at most (uniform, from the
router's own stream; zero by default: at once, as Aqua-Sim NG's ``AquaSimFloodingRouting``
does); later copies are duplicates and dropped. Sinks deliver and do not forward.
"""

from __future__ import annotations

from pydantic import Field

from .base import Datagram, Router, RouterParams

__all__ = ["Flooding", "FloodingParams"]


class FloodingParams(RouterParams):
    jitter_max_s: float = Field(
        0.0, ge=0.0, le=3600.0, description="a forward waits uniform(0, this) local s (0: at once)"
    )


class Flooding(Router):
    """Forward each datagram once (module docstring)."""

    name = "flooding"
    Params = FloodingParams
    params: FloodingParams

    def on_copy(self, datagram: Datagram, sender: int) -> None:
        key = datagram.header.key
        if key in self.history:
            return
        self.history.add(key)
        jitter = self.params.jitter_max_s
        if jitter > 0.0:
            self.later(float(self.port.rng.uniform(0.0, jitter)), lambda: self.forward(datagram, sender))
        else:
            self.forward(datagram, sender)
