"""The seam between the kernel and the acoustic channel: what the channel may ask of the kernel.

The kernel owns ground truth (positions, clocks) and the nodes; the SimPy channel
(:class:`aquasim_py.channel.acoustic.AcousticChannel`) decides who hears a transmission,
when, and whether it survives. The channel sees the kernel only through the three small
interfaces below, which the kernel implements and hands to it:

- :class:`NetworkView` (given at construction): true positions and velocities of the nodes
  and which of them move; the node ids are 0 .. N-1, in the order their ports were attached.
- :class:`RadioPort` (one per node, given by ``AcousticChannel.attach``): the node's clock as
  its modem stamps with, its own MAC-jitter random stream, and its inbox.
- :class:`PacketLog` (given at construction): where the channel writes the ``packets`` trace.

A port may also carry ``energy``, the node's :class:`aquasim_py.energy.EnergyMeter` (or None),
which the channel feeds with the node's transmissions, detected signals and sleeps (found with
``getattr``: a port without one counts no energy).

A network may also offer, and the channel then uses (found with ``getattr``, so a stub need
not): ``max_speed() -> float`` (an upper bound on every node's speed in m/s; finite enables the
k-d tree neighbour index, :mod:`aquasim_py.channel.neighbours`), ``states_at(idx, t)`` and
``velocities_at(idx, t)`` (the rows ``idx`` of positions / velocities at ``t`` without the
other nodes). :class:`aquasim_py.kernel.Simulation` implements all three.

Everything the channel keeps per node (the transmit queue, its own transmissions for
half-duplex, the signals heard for collisions) is the channel's own state: the kernel never
reads it. This module imports neither the kernel nor the channel, so the two do not import
each other and the channel can be driven by a stub network in tests.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np
from numpy.typing import NDArray

from .packet import Packet

__all__ = ["PACKET_FIELDS", "NetworkView", "PacketLog", "RadioPort"]

#: The fields of a ``packets`` row, in the order the channel writes them (the trace's schema).
#: event: "tx" | "rx" | "drop" | "offer" (a frame handed to a node's MAC); reason: None |
#: "range" | "no_path" | "snr" | "half_duplex" | "collision" | "per" | "sleep" | "energy", or a
#: MAC's (``aquasim_py.net.mac.DROP_REASONS``; docs/traces.md); node: the node the row is about
#: (sender for "tx", "offer" and a MAC's drop, receiver otherwise); dst: -1 for a broadcast;
#: tof (s), snr_db, path: of the signal at that receiver; local_time: the MAC stamp of that
#: node (NaN for a drop or an offer).
PACKET_FIELDS = (
    "time",
    "event",
    "reason",
    "node",
    "src",
    "dst",
    "uid",
    "kind",
    "bits",
    "tof",
    "snr_db",
    "path",
    "local_time",
)


class NetworkView(Protocol):
    """Ground truth of the whole network as the channel needs it (true time in s, m, m/s)."""

    def positions(self, t: float) -> NDArray[np.float64]:
        """True positions (N, 3) of every node at true time ``t``."""
        ...

    def positions_at(self, idx: NDArray[np.intp], times: NDArray[np.float64]) -> NDArray[np.float64]:
        """True positions (k, 3) of nodes ``idx[i]`` at true times ``times[i]``."""
        ...

    def velocities(self, t: float) -> NDArray[np.float64]:
        """True velocities (N, 3) of every node at true time ``t``."""
        ...

    def is_moving(self) -> NDArray[np.bool_]:
        """(N,) bool: which nodes can move (the others keep their position forever)."""
        ...


class RadioPort(Protocol):
    """One node's modem as the kernel offers it to the channel."""

    @property
    def index(self) -> int:
        """The node's id (its row in :meth:`NetworkView.positions`)."""
        ...

    def clock_stamp(self, t: float) -> float:
        """The node clock's MAC stamp (local s) of true time ``t``, before the channel's jitter."""
        ...

    def jitter_stream(self) -> np.random.Generator:
        """The node's own random stream for MAC timestamp jitter (the channel asks once)."""
        ...

    def stream(self, purpose: str) -> np.random.Generator:
        """The node's own random stream ("node", id, ``purpose``), e.g. its hydrophone noise."""
        ...

    def deliver(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        """Hand a reception to the node (its waiting ``recv`` or its inbox): the fields of its
        :class:`~aquasim_py.packet.Reception` (the node makes one when it takes the reception)."""
        ...


class PacketLog(Protocol):
    """The ``packets`` trace table: the channel appends rows in :data:`PACKET_FIELDS` order (a
    range-dependent channel: those and its own columns after them, named in ``columns``)."""

    def append(self, values: tuple[Any, ...], columns: tuple[str, ...] | None = None) -> None:
        """Append one row: a tuple of the :data:`PACKET_FIELDS` in that order, or of ``columns``."""
        ...
