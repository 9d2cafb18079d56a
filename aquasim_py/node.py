"""The node a protocol developer subclasses: roles, modem API, local clock, sensors, logging.

A node sees only what a real node could: its local clock, the packets it receives (with local
MAC stamps) and its own noisy sensors. Everything that touches ground truth (the Simulation,
the mobility model, the clock parameters, true time) is held in one name-mangled attribute
and used only inside the methods below, which return local observables.

Times given to a node (``sleep``, ``recv(timeout=...)``, ``env.timeout``) are durations on
the node's own clock (local seconds): a node has no perfect timer.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Generator, Iterable, Mapping
from dataclasses import dataclass
from enum import Enum
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
import simpy
from pydantic import BaseModel, ConfigDict
from simpy.events import NORMAL, EventPriority

from .packet import Reception

__all__ = ["BROADCAST", "Node", "NodeEnv", "Role", "SensorUnavailable", "Sensors"]

#: ``dst`` of a broadcast packet
BROADCAST = None

#: priority of :meth:`NodeEnv.at_instant_end`'s events: SimPy orders its queue by (time,
#: priority, insertion), so one after NORMAL comes after every other event of its instant
LATE = EventPriority(NORMAL + 1)


class _Unavailable:
    """A name a node cannot use (a guess at ground truth, such as ``self.position`` or
    ``env.now``): reading it raises an AttributeError that says what to use instead.

    A non-data descriptor on the class, so a protocol may still give the name to its own
    attribute or method (an instance attribute or a subclass's definition comes first), and
    ``hasattr`` stays False. Not a ``__getattr__``: a class that defines one loses CPython's
    specialized attribute loads on every attribute of its instances, and node code reads
    ``self.<something>`` at every step.
    """

    __slots__ = ("message", "name")

    def __init__(self, message: str) -> None:
        self.message = message  # "{cls}" and "{name}" are filled in
        self.name = ""

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name

    def __get__(self, obj: object, objtype: type | None = None) -> Any:
        if obj is None:
            return self
        raise AttributeError(self.message.format(cls=type(obj).__name__, name=self.name))


class Role(str, Enum):
    """What a node is in the network (references keep true time by default)."""

    BUOY = "buoy"
    ANCHOR = "anchor"
    ORDINARY = "ordinary"
    TARGET = "target"
    SINK = "sink"


class SensorUnavailable(RuntimeError):
    """The node has no such sensor (e.g. ``velocity()`` on a role without one)."""


@dataclass(frozen=True)
class Sensors:
    """A group's sensors.

    Attributes:
        depth_std: Std of the depth gauge's Gaussian noise (m).
        position_std: Std of the position fix's Gaussian noise per axis (m).
        position: Whether the nodes know their own position (GPS at the surface, or a surveyed
            mooring); None = the role's default: buoys and anchors only.
        velocity_std: Std of the velocity sensor's Gaussian noise per axis (m/s).
        velocity: Whether the nodes have a velocity sensor (DVL / GPS-derived); None = the
            role's default: every role but ``target`` (a non-cooperative target reports nothing).
    """

    depth_std: float = 0.0
    velocity_std: float = 0.0
    velocity: bool | None = None
    position_std: float = 0.0
    position: bool | None = None

    def has_velocity(self, role: Role) -> bool:
        return self.velocity if self.velocity is not None else role is not Role.TARGET

    def has_position(self, role: Role) -> bool:
        """Position fix (GPS for buoys, survey for moored anchors); None = buoys and anchors only."""
        return self.position if self.position is not None else role in (Role.BUOY, Role.ANCHOR)


class NodeEnv:
    """The SimPy environment as one node may use it: events and processes, but no true clock.

    ``timeout(delay)`` takes a duration on the node's local clock. There is no ``now``: use
    ``Node.local_time()``. Every event a node gets back (its timeouts, ``recv``, ``broadcast``,
    its processes and conditions) has this view as its ``env``, not the simulation's
    ``simpy.Environment``, so no public attribute of an event leads to true time. SimPy itself
    schedules through :meth:`schedule`, which also reads delays as local seconds (so even
    ``simpy.Timeout(node.env, d)`` is a local-clock timer and ``Timeout._delay`` holds the
    local duration the node asked for).
    """

    __slots__ = ("__env", "__late", "__to_true_delay")

    def __init__(self, env: simpy.Environment, to_true_delay: Any) -> None:
        self.__env = env
        self.__to_true_delay = to_true_delay
        self.__late: simpy.Event | None = None  # the event at_instant_end is triggering

    if not TYPE_CHECKING:  # to a type checker these names do not exist, as they should not
        now = _Unavailable("a node has no access to true time: use Node.local_time()")

    # -- what SimPy's events and processes ask of their ``env`` --------------------------------

    def schedule(self, event: simpy.Event, priority: EventPriority = NORMAL, delay: float | None = None) -> None:
        """Schedule ``event`` after ``delay`` local seconds (SimPy's hook).

        SimPy passes a delay only for timeouts; ``succeed``/``fail`` pass none: those are
        scheduled now, without a trip through the clock model (and the event of
        :meth:`at_instant_end` with priority LATE).
        """
        if delay is None:
            if event is self.__late:
                self.__late = None
                priority = LATE
            self.__env.schedule(event, priority, 0)
        else:
            self.__env.schedule(event, priority, self.__to_true_delay(delay))

    @property
    def active_process(self) -> simpy.Process | None:
        """The process running now (a node's own process while node code runs)."""
        return self.__env.active_process

    @property
    def _active_proc(self) -> simpy.Process | None:
        return self.__env._active_proc

    @_active_proc.setter
    def _active_proc(self, proc: simpy.Process | None) -> None:
        # set by simpy.Process._resume on its env: it must reach the real environment
        self.__env._active_proc = proc

    # -- the node's API ---------------------------------------------------------------------------

    def timeout(self, delay: float, value: Any = None) -> simpy.Timeout:
        """Event after ``delay`` seconds of the node's local clock."""
        return simpy.Timeout(self, delay, value)  # type: ignore[arg-type]

    def event(self) -> simpy.Event:
        return simpy.Event(self)  # type: ignore[arg-type]

    def process(self, generator: Generator[Any, Any, Any]) -> simpy.Process:
        return simpy.Process(self, generator)  # type: ignore[arg-type]

    def all_of(self, events: Iterable[simpy.Event]) -> simpy.AllOf:
        return simpy.AllOf(self, list(events))  # type: ignore[arg-type]

    def any_of(self, events: Iterable[simpy.Event]) -> simpy.AnyOf:
        return simpy.AnyOf(self, list(events))  # type: ignore[arg-type]

    def at_instant_end(self, callback: Callable[[simpy.Event], Any]) -> simpy.Event:
        """An event that calls ``callback(event)`` after every other event of the current
        instant, including those scheduled while the instant runs: e.g. to run what several
        nodes hand in at one instant as one vectorized batch."""
        event = simpy.Event(self)  # type: ignore[arg-type]
        event.callbacks.append(callback)
        # succeed() schedules through self.schedule (SimPy's hook), which gives it LATE
        self.__late = event
        event.succeed()
        return event

    def adopt(self, event: simpy.Event) -> simpy.Event:
        """Hand a kernel/channel event to the node: its ``env`` becomes this view (kernel use)."""
        event.env = self  # type: ignore[assignment]
        return event


def _no_truth(hint: str) -> _Unavailable:
    """A node's answer to a guessed truth attribute; ``hint`` says what to use instead."""
    return _Unavailable(
        "{cls} has no attribute {name!r}: a node sees only its local clock, its receptions and its own "
        f"sensors{hint} (docs/node.md, 'Writing a protocol')"
    )


_OWN_POSITION = "; its own position comes from known_position() (a position fix) or from localization"


class _NoParams(BaseModel):
    """Protocol parameters of the base node: none."""

    model_config = ConfigDict(extra="forbid")


class Node:
    """Base class of every protocol: subclass it and override :meth:`run`.

    Public attributes: ``id`` (int), ``role`` (:class:`Role`), ``params`` (an instance of the
    class's ``Params`` model), ``rng`` (this node's own numpy Generator), ``env`` (a
    :class:`NodeEnv`). Class attributes for the registry: ``name``, ``Params``, ``metrics``
    (and ``trace_tables`` / ``trace_columns``, the tables and columns it reads).

    Examples:
        Anchors broadcast a ping every ``period_s`` seconds of their own clock; every other
        node logs the local arrival stamp of each ping it hears. Saved as ``ping.py``, a
        scenario runs it with ``protocol = "./ping.py:PingNode"`` (the tutorial
        "A protocol in one file" builds a complete one)::

            from pydantic import BaseModel, Field

            from aquasim_py.node import Node, Role


            class PingParams(BaseModel):
                period_s: float = Field(10.0, gt=0, description="time between pings (local s)")


            class PingNode(Node):
                name = "ping"
                Params = PingParams

                def run(self):
                    if self.role is Role.ANCHOR:
                        yield self.sleep(self.rng.uniform(0.0, self.params.period_s))
                        while True:
                            yield self.broadcast("ping")
                            yield self.sleep(self.params.period_s)
                    else:
                        while True:
                            rx = yield self.recv(kinds="ping")
                            self.log("pings", anchor=rx.packet.src, rx_local=rx.rx_local)
    """

    name: ClassVar[str] = "node"

    #: the protocol's parameters model (pydantic): a nested ``class Params(BaseModel)`` or an
    #: assignment ``Params = MyParams`` in a subclass; none for the base node
    Params: ClassVar[type[BaseModel]] = _NoParams

    #: receptions buffered by the modem while the protocol is not listening; the oldest are
    #: discarded beyond this (None = unbounded)
    inbox_capacity: ClassVar[int | None] = 4096

    #: the trace tables this protocol's ``metrics``, ``derived_tables`` and ``report`` read.
    #: A run keeps a table that ``[trace] tables`` does not write only when some reader needs
    #: it (streamed to a scratch file; otherwise its rows are dropped as they come). None =
    #: every table (safe, the default); reading a table not kept raises ``TableNotKept``.
    trace_tables: ClassVar[tuple[str, ...] | None] = None

    #: columns of those tables the metrics read whole (table -> columns, schema columns only):
    #: a streamed CSV run keeps copies of them as it writes the file instead of parsing it back
    #: (:meth:`aquasim_py.trace.Table.keep`); empty: every read parses the file
    trace_columns: ClassVar[dict[str, tuple[str, ...]]] = {}

    def __init__(self, core: Any) -> None:
        # Everything with ground truth in it sits behind this one name-mangled attribute.
        self.__k = core
        self.id: int = core.index
        self.role: Role = core.role
        self.params = core.params
        self.rng: np.random.Generator = core.rng_protocol
        self.env = NodeEnv(core.env, self._local_delay)
        #: one dict shared by every node of the run and by nothing else: the sanctioned place
        #: for out-of-band links that a protocol models on purpose (e.g. MSWPF's ``ideal_links``,
        #: the paper's instantaneous fusion); it holds only what protocols put there. Anything
        #: physical goes through the channel.
        self.out_of_band: dict[str, Any] = core.sim.out_of_band
        self.setup()

    # -- hooks ----------------------------------------------------------------------------------

    def setup(self) -> None:
        """Called once after construction (override instead of ``__init__``)."""

    def run(self) -> Generator[Any, Any, Any]:
        """The node's SimPy process; override it. The base node does nothing."""
        return
        yield  # pragma: no cover - makes this a generator

    @classmethod
    def metrics(cls, tables: Mapping[str, Any]) -> dict[str, float]:
        """The protocol's own metrics from trace tables (override)."""
        return {}

    @classmethod
    def measurement_noise(cls, params: BaseModel) -> tuple[float, float]:
        """The ranging noise this protocol's own measurement model adds to what the channel
        gives it, as (std in m, std relative to the range), for the bound beside its errors
        (:mod:`aquasim_py.estimate_bounds`: the noise the run applied); (0, 0), the default,
        where the protocol ranges from the MAC stamps as they are. Override it where the node
        draws noise onto its measurements itself (a modem's ToA error simulated in the protocol)."""
        return 0.0, 0.0

    # -- clock ----------------------------------------------------------------------------------

    def local_time(self) -> float:
        """The node's local clock now (s)."""
        k = self.__k
        return k.local(k.env.now)

    def _local_delay(self, dt_local: float) -> float:
        """True-time duration (s) after which the local clock has advanced by ``dt_local``."""
        return self.__k.true_delay(dt_local)

    def sleep(self, dt_local: float) -> simpy.Timeout:
        """Event after ``dt_local`` seconds of the node's local clock."""
        return self.__k.watch(self.env.timeout(dt_local), "sleep")

    # -- modem ----------------------------------------------------------------------------------

    def broadcast(self, kind: str, payload: Any = None, bits: int = 256) -> simpy.Event:
        """Transmit to everyone in range, through the group's MAC (:mod:`aquasim_py.net.mac`).
        The event fires when the MAC is done with the packet: at its last bit (after its ACK,
        for a MAC that waits for one), with the local MAC transmit stamp (first bit) as its
        value; or when the MAC gives it up, with ``None`` if it never went out. Under the
        default MAC (``direct``) a busy modem queues the packet and nothing is given up."""
        return self.__k.watch(self.env.adopt(self.__k.transmit(None, kind, payload, bits)), "broadcast")

    def send(self, dst: int, kind: str, payload: Any = None, bits: int = 256) -> simpy.Event:
        """Transmit to node ``dst`` (others in range hear it, and it collides at them, but only
        ``dst`` delivers it). Event as for :meth:`broadcast`."""
        if dst is None:
            raise ValueError("send() needs a destination id; use broadcast() for everyone")
        return self.__k.watch(self.env.adopt(self.__k.transmit(int(dst), kind, payload, bits)), "send")

    def recv(self, timeout: float | None = None, kinds: str | Iterable[str] | None = None) -> simpy.Event:
        """Event whose value is the next :class:`~aquasim_py.packet.Reception` (of one of
        ``kinds`` if given), or ``None`` after ``timeout`` local seconds.

        The timeout is handled here, on the same event: do not build ``recv() | timeout`` yourself
        (a get that loses such a race stays queued and eats the next packet).
        """
        return self.__k.watch(self.__k.recv(timeout, kinds, self.env), "recv")

    def modem_sleep(self) -> None:
        """Put the modem to sleep once its transmit queue has emptied (at once when it is idle):
        asleep, it neither sends (a packet it is given is dropped, reason "sleep", and its event
        still fires after the packet's airtime) nor receives, and draws sleep power. Until
        :meth:`modem_wake`."""
        self.__k.modem_sleep()

    def modem_wake(self) -> None:
        """Wake the modem now (a sleep still waiting for the transmit queue is cancelled)."""
        self.__k.modem_wake()

    def modem_asleep(self) -> bool:
        """Whether the modem is asleep (or will be once its transmit queue has emptied)."""
        return self.__k.modem_asleep()

    def pending(self) -> int:
        """Receptions buffered and not yet taken by :meth:`recv`."""
        return self.__k.pending()

    def take_pending(self) -> list[Reception]:
        """Every buffered reception, oldest first, taken now without an event each (what
        ``recv()`` while ``pending()`` returns, one SimPy event per reception), each with its
        own copy of the payload as ``recv`` gives it."""
        return self.__k.take_pending()

    # -- sensors --------------------------------------------------------------------------------

    def depth(self) -> float:
        """Depth gauge reading (m, positive down), with the group's Gaussian noise."""
        return self.__k.read_depth()

    def velocity(self) -> np.ndarray:
        """Velocity sensor reading (m/s, shape (3,)), with the group's Gaussian noise.

        Raises :class:`SensorUnavailable` if the node's role/group has no velocity sensor.
        """
        return self.__k.read_velocity()

    def known_position(self) -> np.ndarray:
        """Own position fix (m, shape (3,)): GPS / survey, with the group's Gaussian noise.

        Only nodes that could know where they are have one (buoys and anchors by default);
        raises :class:`SensorUnavailable` otherwise.
        """
        return self.__k.read_position()

    def position_fix_std(self) -> float:
        """The stated accuracy (noise std per axis, m) of the node's own position fix: its spec
        sheet (or a GPS's reported accuracy), not its actual error."""
        return float(self.__k.sensors.position_std)

    # -- logging --------------------------------------------------------------------------------

    def log(self, table: str, **columns: Any) -> None:
        """Append a row to a trace table (the kernel adds ``time``, ``node``, ``protocol``)."""
        self.__k.log(table, columns)

    def log_estimate(
        self,
        x: float,
        y: float,
        z: float,
        *,
        confidence: float = math.nan,
        is_reference: bool = False,
        refs: Iterable[int] | None = None,
        range_std: float = 0.0,
        range_rel_std: float = 0.0,
        depth_known: bool = True,
        **extra: Any,
    ) -> None:
        """Log a position estimate (m) to ``estimates``; the kernel adds truth and errors.

        ``refs``: the node ids whose ranges this estimate used, with the ranging noise the node
        assumed for them: variance ``range_std``^2 + (``range_rel_std`` x range)^2 (m^2; both 0:
        noise-free, a zero bound), and ``depth_known``: z came from the depth gauge, the ranges fixed (x, y).
        The kernel records the declaration (``refs`` as ids separated by spaces, ``range_std``,
        ``range_rel_std``, ``depth_known``); after the run, the geometry's bounds are computed
        from the references' true positions, which the node never sees (``bounds.csv``,
        :mod:`aquasim_py.estimate_bounds`)."""
        geometry = None
        if refs is not None:
            geometry = (tuple(int(r) for r in refs), float(range_std), float(range_rel_std), bool(depth_known))
        self.__k.log_estimate(float(x), float(y), float(z), float(confidence), bool(is_reference), extra, geometry)

    def log_clock(self, skew: float, offset: float, **extra: Any) -> None:
        """Log a clock estimate to ``clocks``: the node believes local = (1 + skew) t + offset.
        The kernel adds true_skew, true_offset and error (the estimated true time now minus the
        true time, s)."""
        self.__k.log_clock(float(skew), float(offset), extra)

    def __repr__(self) -> str:
        return f"<{type(self).__name__} id={self.id} role={self.role.value}>"

    # Ground truth a protocol author may guess at, and what a node can use instead (to a type
    # checker these names do not exist, as they should not).
    if not TYPE_CHECKING:
        position = _no_truth(_OWN_POSITION)
        true_position = _no_truth(_OWN_POSITION)
        now = _no_truth("; time is local_time()")
        time = _no_truth("; time is local_time()")
        sim = _no_truth("; the simulation is not reachable from a node")
        velocity_true = _no_truth("; velocity() is the velocity sensor")
