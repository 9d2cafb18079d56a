"""The localization-period cycle shared by STVF and SLMP (Hu et al., Sensors 2018, Sec. 5).

Every ``period_s`` (local clock) references broadcast one beacon at a uniform random offset in
[0, ``send_window_s``); unknown nodes listen until ``listen_s`` into the period, then localize
from the beacons heard. Subclasses give the payload, the localization, and when to start.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any

from aquasim_py.node import Node


class PeriodicBeaconNode(Node):
    """Node base for period-based beacon localization; ``params`` needs ``period_s``,
    ``listen_s``, ``send_window_s`` and ``bits``, and ``setup`` must set ``is_beacon``."""

    beacon_kind: str = "beacon"
    is_beacon: bool
    # An unknown node empties its inbox once a period (at most one beacon per reference in
    # range: 35 at Table 1's density 16); beacons never read theirs, so with the kernel's
    # default of 4096 each of Table 1's 40 anchors would hold its last 4096 receptions, about
    # 100 MiB at the end of a 500-s run (docs/performance.md). 256 keeps every period's beacons.
    inbox_capacity = 256

    def beacon_payload(self) -> dict[str, Any] | None:
        """What this node broadcasts this period, or None if it is not a reference."""
        raise NotImplementedError

    def localize(self, heard: list[Any]) -> None:
        """One localization from this period's beacon receptions."""
        raise NotImplementedError

    def ready(self, elapsed_s: float) -> bool:
        """Whether an unknown node localizes, ``elapsed_s`` local seconds after its start."""
        return True

    def run(self) -> Generator[Any, Any, None]:
        p = self.params
        t_start = self.local_time()
        k = 0
        while True:
            period_start = t_start + k * p.period_s
            payload = self.beacon_payload()
            if payload is not None:
                # A random offset per period: all references sending at once would be deaf to
                # each other (half-duplex modems); the paper's simulation has no MAC at all.
                offset = self.rng.uniform(0.0, p.send_window_s)
                yield self.sleep(max(0.0, period_start + offset - self.local_time()))
                yield self.broadcast(self.beacon_kind, payload, p.bits)
            if not self.is_beacon:
                yield self.sleep(max(0.0, period_start + p.listen_s - self.local_time()))
                heard = []
                while self.pending():
                    rec = yield self.recv()
                    if rec.packet.kind == self.beacon_kind:
                        heard.append(rec)
                if self.ready(self.local_time() - t_start):
                    self.localize(heard)
            k += 1
            yield self.sleep(max(0.0, t_start + k * p.period_s - self.local_time()))
