"""Traffic: open-loop sources offering frames to their MAC at random (Poisson) or regular times.

Every node of a ``traffic`` group that is not a sink is a source: it offers a frame of
``bits`` bits to its MAC every 1 / ``rate_pps`` local seconds on average, as a Poisson
process (exponential gaps) or at a constant rate (after a random phase), from ``start_s``
until ``stop_s``. A source does not wait for a frame to be sent before offering the next (an
open loop, so the offered load does not depend on the MAC); what became of each frame is in the
``packets`` trace, from which the network metrics (``net.*``, docs/metrics.md) are computed.

``destination``: a node id, ``"broadcast"``, or ``"sink"``: a sink (a node of role ``sink`` in
a traffic group) drawn uniformly for each frame. The sinks announce themselves at set-up in
the run's out-of-band directory, ``Node.out_of_band["traffic.sinks"]`` (the deployment's
configuration, as a node knows its sinks' addresses; a sink running another protocol joins by
appending its id there); a traffic sink only receives.
"""

from __future__ import annotations

from collections.abc import Generator
from typing import Any, ClassVar, Literal

import simpy
from pydantic import BaseModel, ConfigDict, Field

from aquasim_py.node import Node, Role
from aquasim_py.registry import register

__all__ = ["TrafficNode", "TrafficParams"]

#: the key of the sinks' ids in Node.out_of_band
_SINKS = "traffic.sinks"


class TrafficParams(BaseModel):
    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)

    rate_pps: float = Field(0.01, gt=0.0, description="frames a source offers per second of its clock, on average")
    process: Literal["poisson", "constant"] = Field("poisson", description="exponential gaps, or a constant rate")
    bits: int = Field(1000, ge=1, description="frame length (bits)")
    destination: Literal["sink", "broadcast"] | int = Field(
        "sink", description='"sink" (one drawn per frame), "broadcast", or a node id'
    )
    kind: str = Field("data", description="packet kind of the frames")
    start_s: float = Field(0.0, ge=0.0, description="local time of the first possible offer (s)")
    stop_s: float | None = Field(None, gt=0.0, description="no offers after this local time (s); none: never stop")

    @staticmethod
    def check_scenario(params: TrafficParams, net: Any) -> list[tuple[str, str]]:
        """A destination that exists: a node id of the network, or a sink for ``"sink"``."""
        d = params.destination
        if d == "sink" and not net.ids("sink"):
            return [("destination", '"sink" but the scenario has no node of role sink')]
        if isinstance(d, int) and not 0 <= d < net.n_nodes:
            return [("destination", f"node id {d} is not a node (ids 0..{net.n_nodes - 1})")]
        return []


@register
class TrafficNode(Node):
    """A traffic source, or a sink (module docstring)."""

    name = "traffic"
    Params = TrafficParams
    params: TrafficParams
    #: the run gets the network metrics (net.*) even with the default MAC
    net_metrics: ClassVar[bool] = True
    trace_tables: ClassVar[tuple[str, ...] | None] = ()  # the generic metrics' tables only
    # sinks and broadcast receivers never take their receptions: keep a few
    inbox_capacity: ClassVar[int | None] = 16

    def setup(self) -> None:
        if self.role is Role.SINK:
            self.out_of_band.setdefault(_SINKS, []).append(self.id)

    def run(self) -> Generator[Any, Any, None]:
        if self.role is Role.SINK:
            return
        p = self.params
        period = 1.0 / p.rate_pps
        t = p.start_s + (float(self.rng.uniform(0.0, period)) if p.process == "constant" else 0.0)
        while True:
            if p.process == "poisson":
                t += float(self.rng.exponential(period))
            if p.stop_s is not None and t > p.stop_s:
                return
            yield self.sleep(max(0.0, t - self.local_time()))
            self._offer(self._destination())
            if p.process == "constant":
                t += period

    def _destination(self) -> int | None:
        d = self.params.destination
        if d == "broadcast":
            return None
        if d == "sink":
            sinks = sorted(self.out_of_band.get(_SINKS, ()))
            if not sinks:
                raise RuntimeError(
                    f"traffic node {self.id}: destination 'sink', but no sink announced itself "
                    f"(a sink of another protocol appends its id to Node.out_of_band[{_SINKS!r}])"
                )
            return sinks[int(self.rng.integers(len(sinks)))] if len(sinks) > 1 else sinks[0]
        return d

    def _offer(self, dst: int | None) -> None:
        p = self.params
        ev = self.broadcast(p.kind, None, p.bits) if dst is None else self.send(dst, p.kind, None, p.bits)
        # open loop: the source goes on at once, and a process of its own takes the frame's
        # receipt (an event nobody waits for would count as a missing yield)
        self.env.process(_receipt(ev))


def _receipt(ev: simpy.Event) -> Generator[Any, Any, None]:
    """Wait until the MAC is done with a frame; nothing more (its fate is in the trace)."""
    yield ev
