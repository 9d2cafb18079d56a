"""The kernel side of one node: the only bridge between a :class:`~aquasim_py.node.Node` and
ground truth, and the node's :class:`~aquasim_py.radio.RadioPort` on the channel.

A :class:`NodeCore` is held by its node in a name-mangled attribute; its methods hand back
local observables only: local clock readings, noisy sensor readings, receptions with local MAC
stamps. It logs the node's rows (with the truth beside them, for the metrics) into the trace.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import simpy
from pydantic import BaseModel

from .energy import EnergyMeter
from .net.mac.base import Mac, MacParams
from .net.mac.direct import Direct
from .node import NodeEnv, Role, Sensors, SensorUnavailable
from .packet import Packet, Reception, copy_payload, snapshot_payload
from .trace import SCHEMAS

__all__ = ["Group", "MacPortView", "NodeCore"]


class _WaitCheck:
    """The first callback of an event a node's API made (``sleep``, ``recv``, ``send``,
    ``broadcast``): when the event fires, whether anyone ever waited on it. ``waited`` is set
    by the event's callback list (:class:`_Callbacks`) when a process that yields the event, a
    condition over it (``a | b``), or anything else adds a callback; never set means the node
    made the event and never waited on it (a missing ``yield``). Counted per protocol in
    :attr:`aquasim_py.kernel.Simulation.unawaited`."""

    __slots__ = ("core", "waited", "what")

    def __init__(self, core: NodeCore, what: str) -> None:
        self.core = core
        self.what = what
        self.waited = False

    def __call__(self, _event: simpy.Event) -> None:
        if not self.waited:
            self.core.sim.note_unawaited(self.core.protocol, self.what)


class _Callbacks(list[Any]):
    """An API event's callback list (SimPy's public ``Event.callbacks``) that tells its
    :class:`_WaitCheck` when someone adds a callback (a condition that later drops its own,
    once another event won, still counts: the node waited)."""

    __slots__ = ("check",)

    def __init__(self, check: _WaitCheck, callbacks: list[Any]) -> None:
        super().__init__([check, *callbacks])
        self.check = check

    def append(self, callback: Any) -> None:
        self.check.waited = True
        super().append(callback)


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
    battery_j: float | None = None  # each node's battery capacity (J); None: unlimited
    #: the MAC every node of the group runs (:mod:`aquasim_py.net.mac`), and its parameters
    mac: type[Mac] = Direct
    mac_params: MacParams = field(default_factory=MacParams)
    # the group's positions at the last true time a node asked for its own (NodeCore.position):
    # nodes of a group often ask at one instant (a period's depth readings and estimates)
    pos_t: float = field(default=math.nan, repr=False)
    pos: Any = field(default=None, repr=False)


class NodeCore:
    """Kernel-side state of one node; the only bridge between a Node and ground truth, and the
    node's :class:`~aquasim_py.radio.RadioPort` on the channel.

    sim: the :class:`~aquasim_py.kernel.Simulation` (its env, channel, channel_config, nodes,
    trace and keyed streams; typed loosely so that this module need not import the kernel,
    which imports it)."""

    __slots__ = (
        "_inbox",
        "_snr_noise",
        "_snr_std",
        "_waiters",
        "affine",
        "channel",
        "clock",
        "energy",
        "env",
        "exact_stamp",
        "group",
        "has_position",
        "has_velocity",
        "index",
        "mac",
        "mac_rx",
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
        sim: Any,
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
        # the waiting recv events in the order they were made, each with its kinds (None: any)
        self._waiters: list[tuple[simpy.Event, frozenset[str] | None]] = []
        # the modem's energy meter (aquasim_py.energy) when the channel config gives its power
        powers = sim.channel_config.powers
        self.energy = None if powers is None else EnergyMeter(powers, group.battery_j)
        self.channel.attach(self)
        mac_cls = group.mac
        #: the node's MAC, which takes its frames (transmit) and sees its receptions first
        self.mac: Mac = mac_cls(MacPortView(self), group.mac_params)
        # only a MAC that keeps some receptions (control frames) sits on the receive path
        self.mac_rx = None if mac_cls.receive is Mac.receive else self.mac.receive
        if mac_cls.senses_carrier:
            self.channel.sense_carrier()

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
        bits = int(bits)
        if bits <= 0:  # before the MAC takes it: a MAC transmits later, from its own process
            raise ValueError(f"a packet needs bits > 0, got {bits}")
        # the packet carries a snapshot: the sender's later changes to its object reach no one
        return self.mac.offer(dst, str(kind), snapshot_payload(payload), bits)

    def modem_sleep(self) -> None:
        self.channel.sleep(self.index)

    def modem_wake(self) -> None:
        self.channel.wake(self.index)

    def modem_asleep(self) -> bool:
        return bool(self.channel.asleep(self.index))

    def deliver(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        """A reception (RadioPort): to the MAC first, then, unless the MAC keeps it, up to the node."""
        mac_rx = self.mac_rx
        if mac_rx is not None and mac_rx(packet, rx_local, snr_db, pressure):
            return
        self.hand_up(packet, rx_local, snr_db, pressure)

    def hand_up(self, packet: Packet, rx_local: float, snr_db: float, pressure: float) -> None:
        """A reception the MAC passed on: to the node's waiting ``recv`` or its inbox."""
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
        if self._waiters:
            kind = packet.kind
            for i, (ev, kinds) in enumerate(self._waiters):
                if kinds is None or kind in kinds:  # the first waiting recv that takes this kind
                    del self._waiters[i]
                    ev.succeed(_taken(packet, rx_local, snr_db, pressure))
                    return
        self._inbox.append((packet, rx_local, snr_db, pressure))

    def watch(self, event: simpy.Event, what: str) -> simpy.Event:
        """``event``, made by the node's ``what`` call, its callbacks a :class:`_Callbacks`
        list whose first is a :class:`_WaitCheck`."""
        if event.callbacks is not None:  # not processed yet (always, for an event just made)
            event.callbacks = _Callbacks(_WaitCheck(self, what), event.callbacks)
        return event

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
        waiting = (ev, ks)
        self._waiters.append(waiting)
        if timeout is not None:
            delay = self.true_delay(timeout)

            def expire(_: simpy.Event) -> None:
                # The reception may have won the race in the meantime: then do nothing.
                if not ev.triggered:
                    self._waiters.remove(waiting)
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
        self,
        x: float,
        y: float,
        z: float,
        confidence: float,
        is_reference: bool,
        extra: Mapping[str, Any],
        geometry: tuple[tuple[int, ...], float, float, bool] | None = None,
    ) -> None:
        """``geometry``: (reference ids, range std m, relative range std, depth known), as
        :meth:`Node.log_estimate` declares them, or None."""
        _no_reserved("log_estimate", extra, _ESTIMATE_COLUMNS)
        t = self.env.now
        tx, ty, tz = (float(v) for v in self.position(t))
        err = math.sqrt((x - tx) ** 2 + (y - ty) ** 2 + (z - tz) ** 2)
        err_h = math.hypot(x - tx, y - ty)
        err_v = abs(z - tz)
        if geometry is not None:
            refs, std, rel_std, depth_known = geometry
            self._check_declaration(refs, std, rel_std)
            extra = {
                **extra,
                "refs": " ".join(map(str, refs)),
                "range_std": std,
                "range_rel_std": rel_std,
                "depth_known": depth_known,
            }
        self.sim.trace.table("estimates").append(
            (t, self.index, self.protocol, x, y, z, tx, ty, tz, err, confidence, is_reference, err_h, err_v)
            + tuple(extra.values()),
            _ESTIMATE_COLUMNS + tuple(extra),
        )

    def _check_declaration(self, refs: tuple[int, ...], std: float, rel_std: float) -> None:
        """The references and noise an estimate declared name nodes and a noise that exist (the
        bound itself is computed after the run: :mod:`aquasim_py.estimate_bounds`)."""
        n = len(self.sim.nodes)
        bad = [r for r in refs if not 0 <= r < n]
        if bad:
            raise ValueError(f"log_estimate(refs=...): no node with id {bad[0]} (ids are 0..{n - 1})")
        if not (math.isfinite(std) and math.isfinite(rel_std) and std >= 0.0 and rel_std >= 0.0):
            raise ValueError(
                f"log_estimate(refs=...): range_std ({std}) and range_rel_std ({rel_std}) must be >= 0 and finite"
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


class MacPortView:
    """A node's :class:`~aquasim_py.net.mac.base.MacPort`: what its MAC may use of it, local
    observables and its own modem only (the core, with its ground truth, sits behind one
    name-mangled attribute, as in :class:`~aquasim_py.node.Node`)."""

    __slots__ = ("__core", "__rng", "env", "index")

    def __init__(self, core: NodeCore) -> None:
        self.__core = core
        self.__rng: np.random.Generator | None = None
        self.index: int = core.index
        #: the node's view of the simulation (local-clock timers; no true time)
        self.env = NodeEnv(core.env, core.true_delay)

    @property
    def rng(self) -> np.random.Generator:
        """The MAC's own stream ("node", id, "mac"), made on first use."""
        if self.__rng is None:
            self.__rng = self.__core.sim.sealed_rng("node", self.index, "mac")
        return self.__rng

    @property
    def max_range_m(self) -> float:
        return float(self.__core.sim.channel_config.max_range_m)

    @property
    def network_size(self) -> int:
        return len(self.__core.sim.nodes)

    def local_time(self) -> float:
        k = self.__core
        return k.local(k.env.now)

    def airtime(self, bits: int) -> float:
        return float(self.__core.channel.airtime(bits))

    def transmit(
        self, dst: int | None, kind: str, payload: Any, bits: int, uid: int | None, overhear: bool = False
    ) -> simpy.Event:
        return self.env.adopt(self.__core.channel.transmit(self.index, dst, kind, payload, bits, uid, overhear))

    def carrier_busy(self) -> bool:
        return bool(self.__core.channel.carrier_busy(self.index))

    def new_uid(self) -> int:
        return int(self.__core.channel.new_uid())

    def row(self, event: str, reason: str | None, dst: int | None, uid: int, kind: str, bits: int) -> None:
        self.__core.channel.mac_row(self.index, event, reason, dst, uid, kind, bits)
