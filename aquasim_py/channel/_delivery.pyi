"""Typed signatures of the compiled delivery (aquasim_py/channel/_delivery.c)."""

from collections.abc import Callable
from typing import Any

from ..packet import Packet

#: 1 when the kernel's compiled event queue (aquasim_py._events) was found at import: the core
#: then also accepts that queue and pushes its entries on it directly
EVENTS: int

class Links:
    """The heard receivers of one transmission, packed (:meth:`Core.pack`)."""

class Deliveries:
    """One transmission's deliveries, one entry at a time on SimPy's queue."""

    callbacks: list[Callable[[Deliveries], None]] | None
    _ok: bool

class Core:
    """Every node's channel-side state and the delivery loop of one AcousticChannel."""

    max_duration: float
    drain: int
    def __init__(
        self,
        env: Any,
        queue: Any,
        eid: Any,
        priority: Any,
        rows: list[tuple[Any, ...]],
        collision: str,
        capture_threshold_db: float,
        jitter: bool,
        stamp: Callable[[int, float], float],
        pressure: Callable[[Packet, int, float, float], float],
        pressure_kind: str | None,
        drain: bool,
        own_heap: bool,
    ) -> None: ...
    def attach(
        self, deliver: Callable[[Packet, float, float, float], None], exact: bool, skew: float, offset: float, /
    ) -> None: ...
    def transmit(self, node: int, start: float, end: float, now: float, /) -> None: ...
    def pack(self, heard: list[tuple[Any, float, str, float]], /) -> Links: ...
    def start(
        self, pkt: Packet, dst: int | None, t0: float, duration: float, links: Links, forget: float, /
    ) -> bool: ...
    def run(self, entry: Deliveries, /) -> None: ...
    def signals(self, node: int, /) -> int: ...
