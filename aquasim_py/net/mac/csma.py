"""``csma``: non-persistent carrier sense multiple access (L. Kleinrock and F. A. Tobagi,
"Packet switching in radio channels: part I - carrier sense multiple-access modes and their
throughput-delay characteristics", IEEE Transactions on Communications 23(12), 1975).

A node with a frame senses the carrier. Idle: it transmits the frame. Busy: it draws a random
delay, and senses again when it has passed (non-persistent: it does not listen on until the
channel clears). Kleinrock and Tobagi's gain over ALOHA rests on a propagation delay short
against the frame (their a = tau / T << 1); under water tau is often longer than the frame, a
frame is heard late or not at all, and the gain shrinks.

The carrier is the node's own: its modem transmitting, or a signal arriving at its
hydrophone now (``Modem.busy_at``: signals of the links the node hears, within range and
above the SNR threshold; a signal counts from its first bit's arrival on, so sensing is
causal). ``max_attempts`` senses busy in a row give the frame up (``drop`` reason ``busy``);
queue and optional ARQ as for ALOHA (:class:`~.base.ArqMac`).
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

from pydantic import Field

from .base import ArqMac, ArqParams, Frame

__all__ = ["Csma", "CsmaParams"]


class CsmaParams(ArqParams):
    max_attempts: int | None = Field(
        None,
        ge=1,
        le=100_000,
        description="carrier senses per transmission before the frame is given up; none: no limit",
    )


class Csma(ArqMac):
    """Non-persistent CSMA (module docstring)."""

    name = "csma"
    Params = CsmaParams
    params: CsmaParams
    senses_carrier = True

    def access(self, frame: Frame) -> Generator[Any, Any, bool]:
        busy = 0
        while self.port.carrier_busy():
            busy += 1
            if self.params.max_attempts is not None and busy >= self.params.max_attempts:
                self.give_up(frame, "busy")
                return False
            yield self.env.timeout(self.backoff(frame))
        yield from self.send(frame)
        return True
