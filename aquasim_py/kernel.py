"""The simulation kernel: a SimPy environment, seeded random streams, the node registry,
ground truth (positions, clocks) and the run loop.

Ground truth lives here. Nodes reach it only through :class:`_NodeCore` (held by each node in
a name-mangled attribute), whose methods hand back local observables: local clock readings,
noisy sensor readings, receptions with local MAC stamps.

The acoustic channel sees the kernel only through the interfaces of :mod:`aquasim_py.radio`:
the Simulation is its :class:`~aquasim_py.radio.NetworkView`, each ``_NodeCore`` its node's
:class:`~aquasim_py.radio.RadioPort`, and the trace's ``packets`` table its
:class:`~aquasim_py.radio.PacketLog`.
"""

from __future__ import annotations

import gc
import hashlib
import math
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from types import GeneratorType
from typing import Any

import numpy as np
import simpy
from pydantic import BaseModel

from .channel.acoustic import AcousticChannel
from .channel.config import ChannelConfig, LossModel
from .channel.ssp import Constant, SoundSpeedProfile
from .mobility import Mobility
from .node import Node, NodeEnv, Role, Sensors, SensorUnavailable
from .packet import Packet, Reception, copy_payload, snapshot_payload
from .trace import SCHEMAS, Trace, TraceConfig

__all__ = ["ChannelConfig", "Group", "Simulation", "TraceConfig", "quiet_gc"]

ClockSpec = Sequence[Any] | Callable[[int, np.random.Generator], Any] | None
MobilitySpec = Any  # a Mobility object, or a callable rng -> Mobility


def _key_words(key: Iterable[Any]) -> list[int]:
    """Stable integers for an rng key: independent of Python's hash seed and of the platform.

    Each part becomes (type tag, value): ints zig-zag encoded, strings (and anything else, by
    repr) through an 8-byte BLAKE2b digest, so ("node", 3) and ("node", "3") differ.
    """
    words: list[int] = []
    for part in key:
        if isinstance(part, (bool, np.bool_)):
            words += [2, int(part)]
        elif isinstance(part, (int, np.integer)):
            v = int(part)
            words += [0, 2 * v if v >= 0 else -2 * v - 1]
        else:
            s = part if isinstance(part, str) else repr(part)
            words += [1, int.from_bytes(hashlib.blake2b(s.encode(), digest_size=8).digest(), "little")]
    return words


@dataclass
class Group:
    """Nodes added by one :meth:`Simulation.add_group` call (one mobility object)."""

    name: str
    node_cls: type
    role: Role
    mobility: Any
    start: int
    count: int
    static: bool
    # the group's positions at the last true time a node asked for its own (_NodeCore.position):
    # nodes of a group often ask at one instant (a period's depth readings and estimates)
    pos_t: float = field(default=math.nan, repr=False)
    pos: Any = field(default=None, repr=False)


class _NodeCore:
    """Kernel-side state of one node; the only bridge between a Node and ground truth, and the
    node's :class:`~aquasim_py.radio.RadioPort` on the channel."""

    # What deliver reads comes first: CPython lays slots out in sorted order, and the names
    # starting with "_" sort before the rest, so these six share the object's first 64 bytes
    # with its reference count (one or two cache lines per reception, not four, in a network
    # too large for the cache).
    __slots__ = (
        "_inbox",
        "_snr_noise",
        "_snr_std",
        "_waiter",
        "_waiter_kinds",
        "_waiters",
        "affine",
        "channel",
        "clock",
        "env",
        "exact_stamp",
        "group",
        "has_position",
        "has_velocity",
        "index",
        "params",
        "protocol",
        "rng_protocol",
        "role",
        "sensor_rngs",
        "sensors",
        "sim",
        "slot",
        "snr_rng",
    )

    def __init__(
        self,
        sim: Simulation,
        index: int,
        group: Group,
        local: int,
        clock: Any,
        sensors: Sensors,
        params: BaseModel,
        protocol: str,
    ) -> None:
        self.sim = sim
        self.env = sim.env
        self.channel = sim.channel
        self.index = index
        self.role = group.role
        self.params = params
        self.protocol = protocol
        self.group = group
        self.slot = local
        self.clock = clock
        # A drift-free Clock is the affine map local = (1 + skew) t + offset: evaluate it on
        # Python floats (same IEEE operations as Clock.to_local) to skip numpy scalar overhead
        # on the per-packet path.
        self.affine = getattr(clock, "drift_std", None) == 0.0 and hasattr(clock, "skew") and hasattr(clock, "offset")
        self.exact_stamp = self.affine and getattr(clock, "jitter_std", None) == 0.0
        self.sensors = sensors
        self.has_velocity = sensors.has_velocity(group.role)
        self.has_position = sensors.has_position(group.role)
        self.rng_protocol = sim.sealed_rng("node", index, "protocol")
        # std (dB) of the receiver's SNR estimate; its stream ("node", id, "snr_estimate") is
        # made on first use, so no other stream's draws change
        self._snr_std = float(sim.channel_config.snr_estimate_std_db)
        self.snr_rng: np.random.Generator | None = None
        self._snr_noise: list[float] = []  # standard normals drawn ahead, in blocks (consumed from the end)
        self.sensor_rngs: dict[str, np.random.Generator] = {}  # purpose -> stream, made on first use
        cap = getattr(group.node_cls, "inbox_capacity", None)
        # receptions not taken yet: (packet, rx_local, snr_db, pressure), see deliver
        self._inbox: deque[tuple[Packet, float, float, float]] = deque(maxlen=cap)
        # The waiting recv events in the order they were made, each with its kinds (None: any):
        # the first in two slots of its own, the others (rare: a node with several processes
        # receiving at once) in a list, None when there are none. A node waits in almost every
        # reception's deliver, and a list of tuples would be two or three more cold lines each.
        self._waiter: simpy.Event | None = None
        self._waiter_kinds: frozenset[str] | None = None
        self._waiters: list[tuple[simpy.Event, frozenset[str] | None]] | None = None
        self.channel.attach(self)

    # -- truth ------------------------------------------------------------------------------------

    def position(self, t: float) -> np.ndarray:
        g = self.group
        if t != g.pos_t:  # one trajectory evaluation per group and instant
            g.pos, g.pos_t = g.mobility.position(t), t
        return g.pos[self.slot]

    def local(self, t: float) -> float:
        """The node's clock reading at true time ``t`` (no jitter)."""
        c = self.clock
        if self.affine:
            return (1.0 + c.skew) * t + c.offset
        return float(c.to_local(t))

    def true_delay(self, dt_local: float) -> float:
        """True-time duration (s) after which the local clock has advanced by ``dt_local``."""
        dt_local = float(dt_local)
        if not dt_local >= 0.0:
            raise ValueError(f"a delay must be >= 0 local seconds, got {dt_local!r}")
        now = self.env.now
        c = self.clock
        if self.affine:
            return dt_local / (1.0 + c.skew)
        return max(0.0, float(c.to_true(c.to_local(now) + dt_local)) - now)

    # -- modem (the RadioPort the channel uses, and the node's way onto the channel) ---------------

    def clock_stamp(self, t: float) -> float:
        """The clock's MAC stamp of true time ``t`` (local s); the channel adds its jitter."""
        c = self.clock
        return (1.0 + c.skew) * t + c.offset if self.exact_stamp else float(c.stamp(t))

    def jitter_stream(self) -> np.random.Generator:
        """The node's MAC-jitter stream ("node", id, "mac_jitter")."""
        return self.sim.rng("node", self.index, "mac_jitter")

    def stream(self, purpose: str) -> np.random.Generator:
        """The node's own stream ("node", id, ``purpose``) for a channel-side measurement."""
        return self.sim.rng("node", self.index, purpose)

    def transmit(self, dst: int | None, kind: str, payload: Any, bits: int) -> simpy.Event:
        if dst is not None and not 0 <= dst < len(self.sim.nodes):
            raise ValueError(f"node {self.index}: no node with id {dst}")
        # the packet carries a snapshot: the sender's later changes to its object reach no one
        return self.channel.transmit(self.index, dst, str(kind), snapshot_payload(payload), int(bits))

    def deliver(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        # What the node gets: the modem's SNR estimate (the channel traced the true SNR), drawn
        # here in delivery order, and its own copy of the payload in a Reception (_taken),
        # made when the node takes it: at once for a waiting recv, from the inbox (which keeps
        # the fields as a tuple) in recv / take_pending. The packet holds the send-time
        # snapshot, which no node ever gets (each takes a copy), so a copy made later is the
        # same copy; a reception never taken (a node that does not listen) costs no copy and
        # no Reception.
        if self._snr_std > 0.0 and snr_db == snr_db:  # NaN (no loss model) stays NaN
            noise = self._snr_noise
            if not noise:
                # blocks of draws: one numpy call per 256 receptions, not one per reception
                rng = self.snr_rng
                if rng is None:
                    rng = self.snr_rng = self.sim.rng("node", self.index, "snr_estimate")
                noise.extend(rng.standard_normal(256)[::-1].tolist())
            snr_db = snr_db + self._snr_std * noise.pop()
        ev = self._waiter
        if ev is not None:
            kinds = self._waiter_kinds
            if kinds is None or packet.kind in kinds:
                if self._waiters is None:  # the usual case, one waiter: _next_waiter's first branch, inline
                    self._waiter = self._waiter_kinds = None
                else:
                    self._next_waiter()
                ev.succeed(_taken(packet, rx_local, snr_db, pressure))
                return
            more = self._waiters
            if more is not None:
                kind = packet.kind
                for i, (ev, kinds) in enumerate(more):
                    if kinds is None or kind in kinds:
                        del more[i]
                        if not more:
                            self._waiters = None
                        ev.succeed(_taken(packet, rx_local, snr_db, pressure))
                        return
        self._inbox.append((packet, rx_local, snr_db, pressure))

    def _next_waiter(self) -> None:
        """The first waiting recv is served or expired: the next in line, if any, moves up."""
        more = self._waiters
        if more is None:
            self._waiter = self._waiter_kinds = None
        else:
            self._waiter, self._waiter_kinds = more.pop(0)
            if not more:
                self._waiters = None

    def _unwait(self, ev: simpy.Event) -> None:
        """Take the waiting recv ``ev`` out of the line (its timeout won the race)."""
        if self._waiter is ev:
            self._next_waiter()
            return
        more = self._waiters
        assert more is not None  # ev waits: if not first, then behind it
        for i, (waiting, _) in enumerate(more):
            if waiting is ev:
                del more[i]
                break
        if not more:
            self._waiters = None

    def pending(self) -> int:
        """Receptions buffered and not taken yet."""
        return len(self._inbox)

    def take_pending(self) -> list[Reception]:
        """Every buffered reception, oldest first, as the node takes it (:func:`_taken`)."""
        out = [_taken(*rec) for rec in self._inbox]
        self._inbox.clear()
        return out

    def recv(self, timeout: float | None, kinds: str | Iterable[str] | None, view: NodeEnv) -> simpy.Event:
        """The node's receive event (its ``env`` is the node's ``view``); the expiry timer is
        the kernel's own, in true time."""
        ks: frozenset[str] | None
        if kinds is None:
            ks = None
        elif isinstance(kinds, str):
            ks = frozenset((kinds,))
        else:
            ks = frozenset(kinds)
        ev = view.event()
        inbox = self._inbox
        if inbox:
            if ks is None:
                return ev.succeed(_taken(*inbox.popleft()))
            for i, rec in enumerate(inbox):
                if rec[0].kind in ks:
                    del inbox[i]
                    return ev.succeed(_taken(*rec))
        if self._waiter is None:
            self._waiter, self._waiter_kinds = ev, ks
        elif self._waiters is None:
            self._waiters = [(ev, ks)]
        else:
            self._waiters.append((ev, ks))
        if timeout is not None:
            delay = self.true_delay(timeout)

            def expire(_: simpy.Event) -> None:
                # The reception may have won the race in the meantime: then do nothing.
                if not ev.triggered:
                    self._unwait(ev)
                    ev.succeed(None)

            self.env.timeout(delay).callbacks.append(expire)
        return ev

    # -- sensors ----------------------------------------------------------------------------------

    def _noisy(self, purpose: str, value: Any, std: float) -> Any:
        """``value`` plus Gaussian noise of ``std`` from the node's own ("node", id, purpose)
        stream, made on first use; ``value`` itself when std = 0."""
        if std <= 0.0:
            return value
        rng = self.sensor_rngs.get(purpose)
        if rng is None:
            rng = self.sensor_rngs[purpose] = self.sim.rng("node", self.index, purpose)
        if isinstance(value, float):
            return value + float(rng.normal(0.0, std))
        return value + rng.normal(0.0, std, np.shape(value))

    def read_depth(self) -> float:
        return self._noisy("depth", float(self.position(self.env.now)[2]), self.sensors.depth_std)

    def read_velocity(self) -> np.ndarray:
        if not self.has_velocity:
            raise SensorUnavailable(
                f"node {self.index} ({self.role.value}) has no velocity sensor; give its group "
                "Sensors(velocity=True) to add one"
            )
        v = np.array(self.group.mobility.velocity(self.env.now)[self.slot], dtype=float)
        return self._noisy("velocity", v, self.sensors.velocity_std)

    def read_position(self) -> np.ndarray:
        if not self.has_position:
            raise SensorUnavailable(
                f"node {self.index} ({self.role.value}) has no position fix; give its group "
                "Sensors(position=True) to add one (GPS / surveyed mooring)"
            )
        p = np.array(self.position(self.env.now), dtype=float)
        return self._noisy("position", p, self.sensors.position_std)

    # -- logging ----------------------------------------------------------------------------------

    def log(self, table: str, columns: Mapping[str, Any]) -> None:
        if "time" in columns or "node" in columns or "protocol" in columns:
            reserved = sorted({"time", "node", "protocol"} & set(columns))
            raise ValueError(f"log(): columns {reserved} are added by the kernel")
        # straight to the table as tuples, no keyword packing (a protocol may log per reception)
        self.sim.trace.table(table).append(
            (self.env.now, self.index, self.protocol, *columns.values()), ("time", "node", "protocol", *columns)
        )

    def log_estimate(
        self, x: float, y: float, z: float, confidence: float, is_reference: bool, extra: Mapping[str, Any]
    ) -> None:
        _no_reserved("log_estimate", extra, _ESTIMATE_COLUMNS)
        t = self.env.now
        tx, ty, tz = (float(v) for v in self.position(t))
        err = math.sqrt((x - tx) ** 2 + (y - ty) ** 2 + (z - tz) ** 2)
        self.sim.trace.table("estimates").append(
            (t, self.index, self.protocol, x, y, z, tx, ty, tz, err, confidence, is_reference, *extra.values()),
            _ESTIMATE_COLUMNS + tuple(extra),
        )

    def log_clock(self, skew: float, offset: float, extra: Mapping[str, Any]) -> None:
        _no_reserved("log_clock", extra, _CLOCK_COLUMNS)
        t = self.env.now
        clock = self.clock
        local = float(clock.to_local(t))
        true_skew = float(clock.skew_at(t))
        true_offset = float(clock.offset_at(t))
        # the node's estimate of true time now, from its own clock reading and its clock model
        err = (local - offset) / (1.0 + skew) - t
        self.sim.trace.table("clocks").append(
            (t, self.index, self.protocol, skew, offset, true_skew, true_offset, err, *extra.values()),
            _CLOCK_COLUMNS + tuple(extra),
        )


_ESTIMATE_COLUMNS = tuple(c for c, _ in SCHEMAS["estimates"])
_CLOCK_COLUMNS = tuple(c for c, _ in SCHEMAS["clocks"])


def _no_reserved(what: str, extra: Mapping[str, Any], columns: tuple[str, ...]) -> None:
    """A protocol's extra columns must not be the table's own (the kernel fills those)."""
    reserved = sorted(set(extra).intersection(columns))
    if reserved:
        raise ValueError(f"{what}(): columns {reserved} are the table's own (added by the kernel)")


def _taken(pkt: Packet, rx_local: float, snr_db: float, pressure: float) -> Reception:
    """The reception as a node takes it: with its own copy of the payload (the packet's
    send-time snapshot shared only when it is immutable, :func:`~aquasim_py.packet.copy_payload`)."""
    payload = copy_payload(pkt.payload)
    if payload is not pkt.payload:
        pkt = Packet(pkt.uid, pkt.src, pkt.dst, pkt.kind, payload, pkt.bits, pkt.tx_local)
    return Reception(pkt, rx_local, snr_db, pressure)


#: young-generation threshold of the garbage collector while a simulation runs (Python's
#: default is 700): see quiet_gc
RUN_GC_THRESHOLD = 20_000


@contextmanager
def quiet_gc() -> Iterator[None]:
    """The garbage collector's settings for a run (restored afterwards, so nothing leaks).

    Objects that exist before the run (imported modules, the scenario, earlier tables) are
    frozen out of the collector's scans: a long run triggers many of them, and rescanning a
    large, unchanging heap each time costs more than the events. And the young generation is
    collected every RUN_GC_THRESHOLD allocations instead of 700: the run's garbage is freed by
    reference counting (SimPy breaks its event-process cycles when an event is processed), so
    the collections mostly rescan the live signal records, queue entries and packets, whose
    number grows with the network: at 5000 nodes they cost about a fifth of the run
    (tools/bench_kernel.py, docs/performance.md)."""
    gc.freeze()
    old = gc.get_threshold()
    gc.set_threshold(max(old[0], RUN_GC_THRESHOLD), *old[1:])
    try:
        yield
    finally:
        gc.set_threshold(*old)
        gc.unfreeze()


def _perfect_clock() -> Any:
    from .clock import Clock

    return Clock.perfect()


def _is_static(mobility: Any) -> bool:
    from .mobility import Static

    return bool(getattr(mobility, "is_static", False)) or isinstance(mobility, Static)


class Simulation:
    """One run: ``Simulation(seed, ssp, volume, channel, trace)``; add groups, then ``run``.

    seed: int for the run's ``numpy.random.SeedSequence`` (None = fresh entropy, kept in
    ``seed`` so the run can be repeated). ssp: the sound-speed profile (default 1500 m/s
    constant). volume: the scenario's ``mobility.Box`` (used to build default static mobility).
    channel: :class:`ChannelConfig`. trace: :class:`TraceConfig`. loss_model: SNR model for the
    channel (default: ``aquasim_py.channel.loss`` when present, else no SNR).
    """

    def __init__(
        self,
        seed: int | None = 0,
        ssp: SoundSpeedProfile | None = None,
        volume: Any = None,
        channel: ChannelConfig | None = None,
        trace: TraceConfig | None = None,
        *,
        loss_model: LossModel | None = None,
    ) -> None:
        ss = np.random.SeedSequence(seed)
        self.seed: int = int(ss.entropy)  # type: ignore[arg-type]
        self._seedseq = ss
        self.env = simpy.Environment()
        self.ssp: SoundSpeedProfile = ssp if ssp is not None else Constant(1500.0)
        self.volume = volume
        self.out_of_band: dict[str, Any] = {}  # Node.out_of_band: shared by the run's nodes
        self.channel_config = channel if channel is not None else ChannelConfig()
        self.trace = Trace(trace)
        # the channel's view of the kernel: this Simulation (NetworkView), the packets table
        # (PacketLog) and, attached node by node, each _NodeCore (RadioPort); see aquasim_py.radio
        self.channel = AcousticChannel(
            self.env,
            self,
            self.trace.table("packets"),
            self.ssp,
            self.channel_config,
            loss_model=loss_model,
            streams=self.rng,
        )
        # rows reach the packets table out of time order; the channel says which can still come
        self.trace.table("packets").order_by_time(self.channel.packets_watermark)
        self.nodes: list[Node] = []
        self.groups: list[Group] = []
        self._cores: list[_NodeCore] = []
        self._moving = np.zeros(0, dtype=bool)
        self._group_of = np.zeros(0, dtype=np.intp)
        self._pos_t = math.nan
        self._pos_cache = np.zeros((0, 3))
        self._vel_t = math.nan  # velocities evaluated with the cached positions (_gather)
        self._vel_cache = np.zeros((0, 3))
        self._static_pos: np.ndarray | None = None
        self._sampler_started = False
        self._one_call_states = True  # every group's model a Mobility (states_at per group)

    # -- randomness -------------------------------------------------------------------------------

    def rng(self, *key: Any) -> np.random.Generator:
        """A Generator for ``key`` (e.g. ``("node", 3, "depth")``), independent of every other key.

        Derived from the run's SeedSequence with the key as spawn key, so it does not depend on
        which other streams exist or in what order they were made. The same key gives a fresh
        Generator in the same state each call: ask once and keep it.
        """
        if not key:
            raise ValueError("rng() needs a key, e.g. sim.rng('node', 3, 'depth')")
        ss = np.random.SeedSequence(
            self._seedseq.entropy, spawn_key=tuple(self._seedseq.spawn_key) + tuple(_key_words(key))
        )
        return np.random.Generator(np.random.PCG64(ss))

    def sealed_rng(self, *key: Any) -> np.random.Generator:
        """The stream :meth:`rng` gives for ``key``, in a Generator that does not lead back to
        the run seed (the one handed to protocol code as ``Node.rng``).

        Same state, so the same draws; but its ``bit_generator.seed_seq`` is a SeedSequence
        whose entropy is a SHA-256 digest of (run entropy, key), a one-way function: neither
        it nor its ``spawn()`` children give the run seed, from which every other stream
        (every node's true clock, for one) could be rebuilt.
        """
        inner = self.rng(*key).bit_generator
        digest = hashlib.sha256(repr((self._seedseq.entropy, self._seedseq.spawn_key, _key_words(key))).encode())
        bg = np.random.PCG64(np.random.SeedSequence(int.from_bytes(digest.digest(), "little")))
        bg.state = inner.state  # type: ignore[assignment]  # a PCG64 state dict, by construction
        return np.random.Generator(bg)

    # -- building ---------------------------------------------------------------------------------

    @property
    def now(self) -> float:
        """True simulation time (s): kernel, channel, trace and metrics only."""
        return self.env.now

    def add_group(
        self,
        node_cls: type[Node],
        count: int,
        *,
        role: Role | str = Role.ORDINARY,
        mobility: MobilitySpec = None,
        positions: Any = None,
        clocks: ClockSpec = None,
        params: Mapping[str, Any] | BaseModel | None = None,
        sensors: Sensors | None = None,
        name: str | None = None,
    ) -> list[Node]:
        """Add ``count`` nodes of ``node_cls`` sharing one mobility model; returns them.

        mobility: a Mobility (``position(t) -> (count, 3)``) or a callable ``rng -> Mobility``
        (given the stream ("group", name, "mobility")); None = static at ``positions``.
        clocks: None (perfect clocks), a sequence of ``count`` Clocks, or a callable
        ``(node_id, rng) -> Clock`` (rng = stream ("node", id, "clock")).
        params: the protocol's parameters (validated by ``node_cls.Params``).
        sensors: depth / velocity sensor noise (:class:`~aquasim_py.node.Sensors`).
        """
        if not (isinstance(node_cls, type) and issubclass(node_cls, Node)):
            raise TypeError(f"add_group: {node_cls!r} is not a Node subclass")
        count = int(count)
        if count < 1:
            raise ValueError(f"add_group: count must be >= 1, got {count}")
        role = Role(role)
        gname = name if name is not None else f"group{len(self.groups)}"
        if any(g.name == gname for g in self.groups):
            raise ValueError(f"add_group: a group named {gname!r} exists already")
        if mobility is None:
            if positions is None:
                raise ValueError("add_group: give a mobility model or static positions")
            from .mobility import Box, Static

            p0 = np.asarray(positions, dtype=float).reshape(count, 3)
            box = self.volume
            if box is None:  # no scenario volume: any box holding the nodes will do for Static
                box = Box(
                    np.minimum(p0.min(axis=0) - 1.0, [np.inf, np.inf, 0.0]).clip([-np.inf, -np.inf, 0.0]),
                    p0.max(axis=0) + 1.0,
                )
            mobility = Static(p0, box, self.rng("group", gname, "mobility"))
        elif callable(mobility) and not hasattr(mobility, "position"):
            mobility = mobility(self.rng("group", gname, "mobility"))
        p0 = np.asarray(mobility.position(0.0))
        if p0.shape != (count, 3):
            raise ValueError(
                f"add_group {gname!r}: mobility gives positions of shape {p0.shape}, expected ({count}, 3)"
            )
        start = len(self.nodes)
        group = Group(gname, node_cls, role, mobility, start, count, _is_static(mobility))
        if params is None:
            p = node_cls.Params()
        elif isinstance(params, node_cls.Params):
            p = params
        else:
            p = node_cls.Params.model_validate(dict(params))
        sensors = sensors if sensors is not None else Sensors()
        if callable(clocks):
            clock_list = [clocks(start + i, self.rng("node", start + i, "clock")) for i in range(count)]
        elif clocks is None:
            clock_list = [_perfect_clock() for _ in range(count)]
        else:
            clock_list = list(clocks)
            if len(clock_list) != count:
                raise ValueError(f"add_group {gname!r}: {len(clock_list)} clocks for {count} nodes")
        protocol = getattr(node_cls, "name", node_cls.__name__)
        new: list[Node] = []
        for i in range(count):
            core = _NodeCore(self, start + i, group, i, clock_list[i], sensors, p, protocol)
            node = node_cls(core)
            self._cores.append(core)
            self.nodes.append(node)
            new.append(node)
            self.trace.table("nodes").append(
                (start + i, role.value, protocol, gname), ("node", "role", "protocol", "group")
            )
        self.groups.append(group)
        self._moving = np.concatenate([self._moving, np.full(count, not group.static)])
        self._group_of = np.concatenate([self._group_of, np.full(count, len(self.groups) - 1)])
        self._static_pos = None
        self._pos_t = self._vel_t = math.nan
        self._one_call_states = all(isinstance(g.mobility, Mobility) for g in self.groups)
        for node in new:
            gen = node.run()
            if not isinstance(gen, GeneratorType):  # what inspect.isgenerator tests, keeping the type
                raise TypeError(f"{node_cls.__name__}.run() must be a generator (use yield)")
            simpy.Process(node.env, gen)  # type: ignore[arg-type]  # its env: the node's view
        return new

    # -- ground truth -----------------------------------------------------------------------------

    def positions(self, t: float | None = None) -> np.ndarray:
        """True positions (N, 3) of every node at true time ``t`` (default now)."""
        t = self.env.now if t is None else float(t)
        if t == self._pos_t:
            return self._pos_cache
        if not self._moving.any():
            if self._static_pos is None:
                self._static_pos = self._gather(0.0)
            return self._static_pos
        p = self._gather(t)
        self._pos_t, self._pos_cache = t, p
        return p

    def _gather(self, t: float) -> np.ndarray:
        if not self.groups:
            return np.zeros((0, 3))
        if self._one_call_states:
            # Positions and velocities from one evaluation (Mobility.state: the bits of
            # position(t) and velocity(t)), the velocities kept for velocities(t): without a
            # neighbour index (a model with no speed bound) the channel asks for both at every
            # transmission's instant, and each asked alone evaluates the trajectory again.
            states = [g.mobility.state(t) for g in self.groups]
            if len(states) == 1:
                p, v = (np.asarray(a, dtype=float) for a in states[0])
            else:
                p = np.concatenate([np.asarray(s[0], dtype=float) for s in states])
                v = np.concatenate([np.asarray(s[1], dtype=float) for s in states])
            self._vel_t, self._vel_cache = t, v
            return p
        if len(self.groups) == 1:
            return np.asarray(self.groups[0].mobility.position(t), dtype=float)
        return np.concatenate([np.asarray(g.mobility.position(t), dtype=float) for g in self.groups])

    def velocities(self, t: float | None = None) -> np.ndarray:
        """True velocities (N, 3) at true time ``t`` (default now)."""
        t = self.env.now if t is None else float(t)
        if t == self._vel_t:
            return self._vel_cache
        if not self.groups:
            return np.zeros((0, 3))
        return np.concatenate([np.asarray(g.mobility.velocity(t), dtype=float) for g in self.groups])

    def positions_at(self, idx: np.ndarray, times: np.ndarray) -> np.ndarray:
        """True positions (k, 3) of nodes ``idx[i]`` at true times ``times[i]``."""
        if len(self.groups) == 1:
            # one group (the common case, on the moving-receiver hot path): no per-group split
            group = self.groups[0]
            ts = np.asarray(times, dtype=float)
            if isinstance(group.mobility, Mobility) and ts.shape == np.shape(idx):
                # the channel's ids and times are valid: skip position_at's argument checks
                return group.mobility._position_at(idx - group.start, ts)
            batched = getattr(group.mobility, "position_at", None)
            if batched is not None:
                return np.asarray(batched(idx - group.start, times), dtype=float)
        out = np.empty((len(idx), 3))
        ts = np.asarray(times, dtype=float)
        gids = self._group_of[idx]
        for g, group in enumerate(self.groups):  # a pass per group (a handful): no sort of the ids
            sel = np.flatnonzero(gids == g)
            if not sel.size:
                continue
            mob = group.mobility
            if isinstance(mob, Mobility) and ts.shape == np.shape(idx):
                out[sel] = mob._position_at(idx[sel] - group.start, ts[sel])  # as above
                continue
            batched = getattr(mob, "position_at", None)
            if batched is not None:
                # Mobility.position_at: every (node, time) pair of the group in one vectorized call
                out[sel] = batched(idx[sel] - group.start, times[sel])
                continue
            # a third-party model without position_at: one query per (node, time)
            for i, j, t in zip(sel.tolist(), (idx[sel] - group.start).tolist(), times[sel].tolist()):
                out[i] = mob.position(t)[j]
        return out

    def states_at(self, idx: np.ndarray, t: float) -> tuple[np.ndarray, np.ndarray]:
        """True positions and velocities ((k, 3) each) of nodes ``idx`` at true time ``t``, in
        one evaluation of the trajectories when the nodes are in one group."""
        if len(self.groups) == 1 and isinstance(self.groups[0].mobility, Mobility):
            group = self.groups[0]
            return group.mobility._state_at(idx - group.start, np.full(len(idx), float(t)))
        if self._one_call_states:
            # several groups: one trajectory evaluation per group for the nodes asked for,
            # instead of positions_at and then every node's velocity
            pos, vel = np.empty((len(idx), 3)), np.empty((len(idx), 3))
            gids = self._group_of[idx]
            for g, group in enumerate(self.groups):
                sel = np.flatnonzero(gids == g)
                if sel.size:
                    pos[sel], vel[sel] = group.mobility._state_at(idx[sel] - group.start, np.full(sel.size, float(t)))
            return pos, vel
        return self.positions_at(idx, np.full(len(idx), float(t))), self.velocities_at(idx, t)

    def velocities_at(self, idx: np.ndarray, t: float) -> np.ndarray:
        """True velocities (k, 3) of nodes ``idx`` at true time ``t`` (the rows of
        :meth:`velocities`, without evaluating the other nodes when the model can)."""
        if len(self.groups) == 1:
            group = self.groups[0]
            batched = getattr(group.mobility, "velocity_at", None)
            if batched is not None:
                return np.asarray(batched(idx - group.start, t), dtype=float)
        return self.velocities(t)[idx]

    def is_moving(self) -> np.ndarray:
        """(N,) bool: which nodes belong to a non-static mobility group."""
        return self._moving

    def max_speed(self) -> float:
        """An upper bound (m/s) on every node's speed at all times: 0 when no node moves, inf
        when a moving group's model gives no bound (``Mobility.max_speed``)."""
        bound = 0.0
        for g in self.groups:
            if not g.static:
                bound = max(bound, float(getattr(g.mobility, "max_speed", lambda: math.inf)()))
        return bound

    def clock_of(self, node_id: int) -> Any:
        """The Clock of a node (kernel, trace and tests only)."""
        return self._cores[node_id].clock

    # -- running ----------------------------------------------------------------------------------

    def _sample_positions(self, interval: float) -> Any:
        k = 0
        table = self.trace.table("positions")
        while True:
            t = self.env.now
            n = len(self.nodes)
            if n:
                p = self.positions(t)
                v = self.velocities(t)
                table.extend(
                    time=np.full(n, t),
                    node=np.arange(n),
                    x=p[:, 0],
                    y=p[:, 1],
                    z=p[:, 2],
                    vx=v[:, 0],
                    vy=v[:, 1],
                    vz=v[:, 2],
                )
            k += 1
            # absolute grid k * interval, so sample times carry no accumulated rounding
            yield self.env.timeout(max(0.0, k * interval - self.env.now))

    def _progress(self, until: float, callback: Callable[[float, float], Any]) -> Any:
        step = (until - self.env.now) / 100.0
        while self.env.now + step < until:
            yield self.env.timeout(step)
            callback(self.env.now, until)

    def run(self, until: float, progress: Callable[[float, float], Any] | None = None) -> None:
        """Run to true time ``until`` (s). ``progress(t, until)`` is called about every 1 %."""
        until = float(until)
        if not until > self.env.now:
            raise ValueError(f"run(until={until}) must be later than now ({self.env.now})")
        if not self._sampler_started:
            self._sampler_started = True
            interval = self.trace.config.position_interval
            if interval:
                self.env.process(self._sample_positions(float(interval)))
        if progress is not None:
            self.env.process(self._progress(until, progress))
        with quiet_gc():
            self.env.run(until=until)
        if progress is not None:
            progress(until, until)
