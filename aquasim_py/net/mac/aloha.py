"""``aloha``: pure ALOHA (N. Abramson, "The ALOHA System: another alternative for computer
communications", AFIPS Fall Joint Computer Conference, 1970).

A node transmits a frame as soon as it has one, with no regard for anyone else. Two frames
that overlap at a receiver by any part are lost there, so a frame sent at t is safe only if
no other starts in (t - T, t + T): with Poisson traffic of G frames per frame time T, the
throughput is S = G e^(-2G) frames per frame time, at most 1 / (2e) ~ 0.184 at G = 1/2.

Abramson's terminals wait for an acknowledgement and retransmit after a random delay
(``ack``, ``retries``, ``backoff_max_s``: :class:`~.base.ArqMac`); off by default, as in ns-3's
``UanMacAloha``. With the default ``queue_length = 1`` a node transmitting refuses a new frame
(``drop`` reason ``queue_full``), as ``UanMacAloha::Enqueue`` returns false while its PHY
transmits; a longer queue sends the waiting frames back to back.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

from .base import ArqMac, ArqParams, Frame

__all__ = ["Aloha", "AlohaParams"]


class AlohaParams(ArqParams):
    """Pure ALOHA: the queue and the optional ARQ (:class:`~.base.ArqParams`)."""


class Aloha(ArqMac):
    """Pure ALOHA: transmit at once (see the module docstring)."""

    name = "aloha"
    Params = AlohaParams

    def access(self, frame: Frame) -> Generator[Any, Any, bool]:
        yield from self.send(frame)
        return True
