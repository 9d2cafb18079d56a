"""The localization-period cycle shared by STVF and SLMP (Hu et al., Sensors 2018, Sec. 5).

Every ``period_s`` (local clock) references broadcast one beacon at a uniform random offset in
[0, ``send_window_s``); unknown nodes listen until ``listen_s`` into the period, then localize
from the beacons heard. Subclasses say whether the node is a reference this period
(:meth:`PeriodicBeaconNode.advertises`, decided at the period start), what a reference does
right before it speaks (:meth:`~PeriodicBeaconNode.localize_reference`), the payload
(:meth:`~PeriodicBeaconNode.beacon_payload`, composed at the send instant, so the position it
carries is the sender's at the MAC transmit stamp the receivers measure from), the
localization, and when to start.
"""

from __future__ import annotations

from collections.abc import Generator
from operator import itemgetter
from typing import Any

import simpy
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.node import Node
from aquasim_py.packet import Reception

_TURNS = "periodic_turns"  # key of the run's _Turns in Node.out_of_band


class PeriodicParams(BaseModel):
    """The period cycle's parameters (STVF Table 1 / Sec. 5.3 defaults)."""

    model_config = ConfigDict(extra="forbid")

    period_s: float = Field(1.0, gt=0, description="localization period (s)")
    listen_s: float = Field(0.9, gt=0, description="collection time after the period start (s)")
    send_window_s: float = Field(0.5, ge=0, description="random send offset range per period (s)")
    bits: int = Field(160, ge=1, description="beacon packet size (bits)")


class _Turns:
    """The unknown nodes that end their listening at one instant, resumed in the order a
    ``recv()`` event per reception gave them, without those events.

    With one event per reception, the nodes woken at an instant take turns, one reception
    each, in wake-up order, and a node localizes (and schedules its next wake-up) right after
    its last one: in order of (receptions taken, wake-up order). Here a node takes its whole
    inbox when it wakes (``Node.take_pending``) and waits for its turn, and the instant's end
    (``NodeEnv.at_instant_end``) resumes the nodes in that order, one event each. Every node
    sees the same receptions, localizes in the same order and schedules its later events in the
    same order, so the traces are those of the per-reception loop (a test compares them)."""

    def __init__(self) -> None:
        self.waiting: list[tuple[int, simpy.Event]] = []

    def take(self, node: Node, count: int) -> simpy.Event:
        """The event resuming ``node``, which took ``count`` receptions, at its turn."""
        if not self.waiting:
            node.env.at_instant_end(self._release)
        ev = node.env.event()
        self.waiting.append((count, ev))
        return ev

    def _release(self, _event: object) -> None:
        waiting, self.waiting = self.waiting, []
        waiting.sort(key=itemgetter(0))  # stable: equal counts keep their wake-up order
        for _, ev in waiting:
            ev.succeed()


class PeriodicBeaconNode(Node):
    """Node base for period-based beacon localization; ``params`` needs ``period_s``,
    ``listen_s``, ``send_window_s`` and ``bits`` (:class:`PeriodicParams`), and ``setup``
    must set ``is_beacon``."""

    beacon_kind: str = "beacon"
    is_beacon: bool
    # An unknown node empties its inbox once a period (at most one beacon per reference in
    # range: 35 at Table 1's density 16); beacons never read theirs, so with the kernel's
    # default of 4096 each of Table 1's 40 anchors would hold its last 4096 receptions, about
    # 100 MiB at the end of a 500-s run. 256 keeps every period's beacons.
    inbox_capacity = 256

    @classmethod
    def measurement_noise(cls, params: BaseModel) -> tuple[float, float]:
        """The family's ToA error: each of its nodes draws ``noise_ratio`` x delay onto the
        delays it measures (STVF, SLMP and their baselines), a range std relative to the range."""
        return 0.0, float(getattr(params, "noise_ratio", 0.0))

    #: take the inbox at once and localize in turn (_Turns) instead of one recv() event per
    #: reception; False keeps the per-reception loop (the same traces, a test compares them)
    drain_inbox = True

    def advertises(self) -> bool:
        """Whether this node is a reference this period (asked at the period start)."""
        raise NotImplementedError

    def localize_reference(self) -> None:
        """A reference's own localization right before its beacon (default: none)."""

    def beacon_payload(self) -> Any:
        """The beacon, composed at its send instant (no side effects)."""
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
            if self.advertises():
                # A random offset per period: all references sending at once would be deaf to
                # each other (half-duplex modems); the paper's simulation has no MAC at all.
                offset = self.rng.uniform(0.0, p.send_window_s)
                yield self.sleep(max(0.0, period_start + offset - self.local_time()))
                self.localize_reference()
                yield self.broadcast(self.beacon_kind, self.beacon_payload(), p.bits)
            if not self.is_beacon:
                yield self.sleep(max(0.0, period_start + p.listen_s - self.local_time()))
                received: list[Reception] = []
                if self.drain_inbox and p.listen_s < p.period_s:
                    # (not when the next period starts at this instant: the node's own period
                    # start would then wait for the instant's end, after the other nodes')
                    received = self.take_pending()
                    yield self.out_of_band.setdefault(_TURNS, _Turns()).take(self, len(received))
                else:
                    while self.pending():
                        received.append((yield self.recv()))
                heard = [rec for rec in received if rec.packet.kind == self.beacon_kind]
                if self.ready(self.local_time() - t_start):
                    self.localize(heard)
            k += 1
            yield self.sleep(max(0.0, t_start + k * p.period_s - self.local_time()))
