"""The simulation kernel: a SimPy environment, seeded random streams, the node registry,
ground truth (positions, clocks) and the run loop.

Ground truth lives here. Nodes reach it only through their :class:`~aquasim_py.nodecore.NodeCore`
(held by each node in a name-mangled attribute), whose methods hand back local observables:
local clock readings, noisy sensor readings, receptions with local MAC stamps.

The acoustic channel sees the kernel only through the interfaces of :mod:`aquasim_py.radio`:
the Simulation is its :class:`~aquasim_py.radio.NetworkView`, each ``NodeCore`` its node's
:class:`~aquasim_py.radio.RadioPort`, and the trace's ``packets`` table its
:class:`~aquasim_py.radio.PacketLog`.
"""

from __future__ import annotations

import gc
import hashlib
import math
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from types import GeneratorType
from typing import Any

import numpy as np
import simpy
from pydantic import BaseModel

from .channel.acoustic import AcousticChannel
from .channel.config import ChannelConfig, LossModel
from .channel.environment import Environment
from .channel.ssp import Constant, SoundSpeedProfile
from .energy import ENERGY_COLUMNS
from .mobility import Mobility
from .net.mac import Direct, Mac
from .net.mac import get as get_mac
from .node import Node, Role, Sensors
from .nodecore import Group, NodeCore
from .trace import Trace, TraceConfig

__all__ = ["ChannelConfig", "Group", "Simulation", "TraceConfig", "UnawaitedEventsWarning", "quiet_gc"]


class UnawaitedEventsWarning(UserWarning):
    """A protocol's nodes made ``sleep`` / ``recv`` / ``send`` / ``broadcast`` events that fired
    with nobody waiting on them: almost always a missing ``yield``."""


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
    (tools/bench_kernel.py)."""
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
    channel (default: ``aquasim_py.channel.loss`` when present, else no SNR). environment: a
    range-dependent :class:`~aquasim_py.channel.environment.Environment` the channel traces
    instead of ``ssp`` (every arrival of a link, :mod:`aquasim_py.channel.arrival_links`).
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
        environment: Environment | None = None,
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
        # (PacketLog) and, attached node by node, each NodeCore (RadioPort); see aquasim_py.radio
        self.channel = AcousticChannel(
            self.env,
            self,
            self.trace.table("packets"),
            self.ssp if environment is None else environment,
            self.channel_config,
            loss_model=loss_model,
            streams=self.rng,
        )
        # rows reach the packets table out of time order; the channel says which can still come
        self.trace.table("packets").order_by_time(self.channel.packets_watermark)
        self.nodes: list[Node] = []
        self.groups: list[Group] = []
        self._cores: list[NodeCore] = []
        self._moving = np.zeros(0, dtype=bool)
        self._group_of = np.zeros(0, dtype=np.intp)
        self._pos_t = math.nan
        self._pos_cache = np.zeros((0, 3))
        self._vel_t = math.nan  # velocities evaluated with the cached positions (_gather)
        self._vel_cache = np.zeros((0, 3))
        self._static_pos: np.ndarray | None = None
        self._sampler_started = False
        self._one_call_states = True  # every group's model a Mobility (states_at per group)
        #: protocol -> {"sleep" | "recv" | "send" | "broadcast": events its nodes made that
        #: fired with nobody waiting on them}
        self.unawaited: dict[str, dict[str, int]] = {}
        self._unawaited_told: dict[str, int] = {}

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
        battery_j: float | None = None,
        mac: str | type[Mac] | None = None,
        mac_params: Mapping[str, Any] | BaseModel | None = None,
    ) -> list[Node]:
        """Add ``count`` nodes of ``node_cls`` sharing one mobility model; returns them.

        mobility: a Mobility (``position(t) -> (count, 3)``) or a callable ``rng -> Mobility``
        (given the stream ("group", name, "mobility")); None = static at ``positions``.
        clocks: None (perfect clocks), a sequence of ``count`` Clocks, or a callable
        ``(node_id, rng) -> Clock`` (rng = stream ("node", id, "clock")).
        params: the protocol's parameters (validated by ``node_cls.Params``).
        sensors: depth / velocity sensor noise (:class:`~aquasim_py.node.Sensors`).
        battery_j: each node's battery capacity (J; :mod:`aquasim_py.energy`); needs the modem's
        power in the channel config. None: unlimited.
        mac: the MAC of every node of the group (:mod:`aquasim_py.net.mac`: a name or a class;
        None = ``direct``), with ``mac_params`` (validated by its ``Params``).
        """
        if not (isinstance(node_cls, type) and issubclass(node_cls, Node)):
            raise TypeError(f"add_group: {node_cls!r} is not a Node subclass")
        count = int(count)
        if count < 1:
            raise ValueError(f"add_group: count must be >= 1, got {count}")
        role = Role(role)
        if battery_j is not None and self.channel_config.powers is None:
            raise ValueError(
                "add_group: a battery needs the modem's power (ChannelConfig tx_power_w, rx_power_w, idle_power_w, "
                "sleep_power_w, or a modem preset)"
            )
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
        mac_cls = get_mac(mac) if isinstance(mac, str) else (mac if mac is not None else Direct)
        if isinstance(mac_params, mac_cls.Params):
            mp = mac_params
        else:
            mp = mac_cls.Params.model_validate(dict(mac_params or {}))
        group = Group(
            gname, node_cls, role, mobility, start, count, _is_static(mobility), battery_j, mac=mac_cls, mac_params=mp
        )
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
            core = NodeCore(self, start + i, group, i, clock_list[i], sensors, p, protocol)
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
        self._write_energy(until)
        self._warn_unawaited()

    def _write_energy(self, t: float) -> None:
        """One ``energy`` row per node whose energy is counted, charged up to ``t`` (true s)."""
        if self.channel_config.powers is None:
            return
        table = self.trace.table("energy")
        for core in self._cores:
            if core.energy is not None:
                table.append((t, core.index, *core.energy.row(t)), ENERGY_COLUMNS)

    def note_unawaited(self, protocol: str, what: str) -> None:
        """Count an event made by a node of ``protocol`` (its ``what`` call) that fired unawaited."""
        counts = self.unawaited.setdefault(protocol, {})
        counts[what] = counts.get(what, 0) + 1

    def _warn_unawaited(self) -> None:
        """One :class:`UnawaitedEventsWarning` per protocol with unawaited events not told yet."""
        for protocol, counts in self.unawaited.items():
            total = sum(counts.values())
            if total > self._unawaited_told.get(protocol, 0):
                self._unawaited_told[protocol] = total
                what = ", ".join(f"{n} {kind}" for kind, n in sorted(counts.items()))
                warnings.warn(
                    f"protocol {protocol!r}: its nodes made events they never waited on ({what}); "
                    "a call such as self.sleep(...) does nothing without `yield` before it",
                    UnawaitedEventsWarning,
                    stacklevel=2,
                )
