"""The SimPy acoustic channel: who hears a transmission, when, and whether it survives.

On a transmission at true time t0 from position p_s = p_src(t0):

1. candidates: every node within ``max_range_m`` of p_s at t0. When the network bounds its
   nodes' speed (``max_speed``; always for a static one) a k-d tree of recent positions
   (:class:`~.neighbours.NeighbourIndex`) gives a superset and only those nodes' positions are
   evaluated, so the cost follows the neighbourhood, not the network; otherwise one
   vectorized distance computation over all node positions. The exact test is the same;
2. delay: the eigenray time from p_s to the receiver's position *at the arrival instant*,
   i.e. the fixed point t_a = t0 + T(p_s, p_rx(t_a)), iterated (vectorized over receivers)
   until it moves by less than 1e-10 s. The map contracts by about |v_rx| / c ~ 1e-3 per step.
   Iteration starts from the fixed point of the receivers' straight-line motion at t0 (no
   mobility queries): in closed form for a constant sound speed, else by a few secant steps
   seeded with the exact slope grad T . v. It is exact for constant velocity, so the exact
   iteration usually stops after one query (and one ray trace) per receiver; static
   receivers need none. Receivers without a speed bound (the current-driven models) accelerate
   enough to miss the tolerance from that start; in a constant profile one Newton step with
   their estimated accelerations corrects it (``_accelerations``, ``_accelerated_root``). For
   a constant profile with every node on a box-folded straight line the whole computation is
   compiled (``channel/straight.py``, same bits);
3. losses: no eigenray (shadow zone) -> "no_path"; SNR below the threshold -> "snr";
   the receiver transmitting during any part of the reception -> "half_duplex"; another
   signal overlapping the reception at the receiver -> "collision" (with ``capture``, the
   packet survives if its SNR exceeds the total power of the overlapping signals by
   ``capture_threshold_db``).

Each delivery is decided at the instant its last bit arrives (the deliveries of one
transmission take turns as one entry on SimPy's queue, :class:`_Deliveries`, and consecutive
entries at the queue's head are decided in one loop, ``_next_delivery``): by then every signal
that can overlap the reception and every transmission of the receiver that can cut it are
known (they started before that instant), so the verdict needs no second event.

The per-reception part (the signal logs, the own-transmission logs, the verdicts, the exact
clocks' stamps, the rows and the queue entries) runs compiled (``channel/_delivery.c``) when
that module is built: the same operations on the same floats in the same order, the same
sequence numbers from SimPy's counter, so the same rows in the same order. The Python code here
is its reference and its fallback (``compiled_delivery = False``; tests compare the two).

MAC stamps: transmit stamped when the first bit leaves (t0), receive when the first bit
arrives (t_a), each in the node's local clock (``Clock.stamp``), plus ``jitter_std_s``.
"""

from __future__ import annotations

import math
from array import array
from bisect import bisect_left, bisect_right
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from functools import lru_cache
from heapq import heappop, heappush
from itertools import repeat
from operator import itemgetter
from typing import TYPE_CHECKING, Any, Literal, cast

import numpy as np
import simpy
from numpy.typing import NDArray
from simpy.events import NORMAL

from ..packet import Packet
from ..radio import NetworkView, PacketLog, RadioPort
from . import isogradient
from .neighbours import NeighbourIndex
from .obstacles import ObstacleConfig, ObstacleField
from .rays import Eigenray, PathKind
from .raytrace import Reflections, eigenray
from .ssp import Constant, Isogradient
from .uncertainty import SoundSpeedUncertainty

try:  # the compiled delivery (channel/_delivery.c); without a compiler the Python path runs
    from . import _delivery
except ImportError:  # pragma: no cover - every CI lane builds it
    _delivery = None  # type: ignore[assignment]
try:  # the kernel's compiled event queue (aquasim_py/_events.c), whose entries it may push
    from .._events import Queue
except ImportError:  # pragma: no cover - every CI lane builds it
    Queue = None  # type: ignore[assignment,misc]

if TYPE_CHECKING:  # pragma: no cover
    from .ssp import SoundSpeedProfile

__all__ = [
    "PATH_NAMES",
    "AcousticChannel",
    "ChannelConfig",
    "LossModel",
    "default_loss_model",
    "no_snr",
    "physical_snr",
]

#: path kind code -> name in the packets table
PATH_NAMES = {
    int(PathKind.NONE): "none",
    int(PathKind.DIRECT): "direct",
    int(PathKind.SURFACE): "surface",
    int(PathKind.BOTTOM): "bottom",
}

_DELAY = itemgetter(1)  # heard entries: (receiver id, delay, path, snr)
# signal records: (arrival, end, snr_db, receiver id, packet, tof, path, dst)
_Signal = tuple[float, float, float, int, Packet, float, str, int]

#: fixed-point tolerance on the arrival time (s)
FIXED_POINT_TOL_S = 1e-10
_MAX_ITER = 50
_FIELDS = tuple(Eigenray.__dataclass_fields__)
_FLOAT_FIELDS = tuple(f for f in _FIELDS if f != "path")


@dataclass(frozen=True)
class ChannelConfig:
    """Acoustic modem and channel parameters.

    max_range_m: straight-line range (m) at send time beyond which a node hears nothing.
    bitrate_bps: modem bit rate; a packet of b bits lasts b / bitrate_bps seconds.
    source_level_db: source level (dB re 1 uPa at 1 m), for the loss model.
    frequency_khz, bandwidth_khz: carrier and band, for the loss model.
    spreading: spreading exponent k (1 cylindrical, 1.5 practical, 2 spherical).
    shipping, wind_mps: ambient noise parameters (shipping activity 0..1, wind speed m/s).
    snr_threshold_db: receptions below this SNR are dropped ("snr").
    collision: "none" (signals never interfere), "destructive" (any overlap destroys both),
        "capture" (a signal survives if its SNR beats the summed power of the signals overlapping
        it by capture_threshold_db; without an SNR model nothing can be captured, so "capture"
        then acts as "destructive").
    jitter_std_s: std of Gaussian MAC timestamp jitter (s), on top of the clock's own.
    reflections: passed to ``eigenray`` ("none", "fallback", "all").
    pressure_kind: packets of this kind are sound emissions: each reception carries the received
        pressure (``channel.pressure``, eq 6 of MSWPF) plus N(0, pressure_noise_std^2) drawn from
        the receiver's ("node", id, "pressure") stream; None = off.
    pressure_source_level, pressure_exponent: S and k of h = S / D^k.
    obstacles: obstructed links' extra loss and excess delay (``channel.obstacles``; the random
        part of the delay is drawn per packet from each link's own stream); None = none.
    sound_speed_std_mps, sound_speed_corr_s: sound-speed uncertainty (channel/uncertainty.py):
        std (m/s) of the path-mean speed around the profile, and its per-link correlation time
        (s; 0 = independent per packet). std 0 leaves the channel exactly as without it.
    snr_estimate_std_db: std (dB) of the Gaussian error of the receiver's SNR estimate, the
        ``Reception.snr_db`` a node gets (0 = the exact SNR); drawn by the kernel from the
        receiver's own ("node", id, "snr_estimate") stream. The ``packets`` trace and the drop
        decisions use the true SNR. Without noise a node could invert the loss model for its
        exact range.
    """

    max_range_m: float = 5000.0
    bitrate_bps: float = 1000.0
    source_level_db: float = 170.0
    frequency_khz: float = 10.0
    bandwidth_khz: float = 5.0
    spreading: float = 1.5
    shipping: float = 0.5
    wind_mps: float = 0.0
    snr_threshold_db: float = 10.0
    collision: Literal["none", "destructive", "capture"] = "destructive"
    capture_threshold_db: float = 6.0
    jitter_std_s: float = 0.0
    reflections: Literal["none", "fallback", "all"] = "fallback"
    pressure_kind: str | None = None
    pressure_source_level: float = 5e4
    pressure_exponent: float = 1.0
    pressure_noise_std: float = 5.0
    obstacles: ObstacleConfig | None = None
    sound_speed_std_mps: float = 0.0
    sound_speed_corr_s: float = 0.0
    snr_estimate_std_db: float = 1.0

    def __post_init__(self) -> None:
        for name in ("max_range_m", "bitrate_bps", "frequency_khz", "bandwidth_khz"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"ChannelConfig.{name} must be positive and finite, got {v!r}")
        if self.collision not in ("none", "destructive", "capture"):
            raise ValueError(f"ChannelConfig.collision must be none/destructive/capture, got {self.collision!r}")
        if self.reflections not in ("none", "fallback", "all"):
            raise ValueError(f"ChannelConfig.reflections must be none/fallback/all, got {self.reflections!r}")
        if not self.jitter_std_s >= 0.0:
            raise ValueError(f"ChannelConfig.jitter_std_s must be >= 0, got {self.jitter_std_s!r}")
        if not (self.sound_speed_std_mps >= 0.0 and self.sound_speed_corr_s >= 0.0):
            raise ValueError("ChannelConfig.sound_speed_std_mps and sound_speed_corr_s must be >= 0")
        if not (math.isfinite(self.snr_estimate_std_db) and self.snr_estimate_std_db >= 0.0):
            raise ValueError(f"ChannelConfig.snr_estimate_std_db must be >= 0, got {self.snr_estimate_std_db!r}")


#: An SNR model: (eigenrays to the receivers, config) -> SNR in dB per receiver (NaN = unknown,
#: never dropped).
LossModel = Callable[[Eigenray, ChannelConfig], NDArray[np.float64]]


def no_snr(ray: Eigenray, config: ChannelConfig) -> NDArray[np.float64]:
    """The null loss model: SNR unknown (NaN), so nothing is dropped on SNR."""
    return np.full(np.shape(ray.time), np.nan)


def physical_snr(ray: Eigenray, config: ChannelConfig) -> NDArray[np.float64]:
    """SNR (dB) along each eigenray: SL - A(l, f) - N(f) - 10 log10 B (``channel.loss.snr_db``),
    with l the ray's arc length and the config's source level, carrier, band, spreading
    exponent and ambient-noise parameters.

    The same terms in the same order as ``loss.snr_db`` (so the same bits), with the two that
    depend only on the config (ambient noise N(f) and 10 log10 B) computed once per config:
    the noise sum is the costliest part and this runs once per transmission."""
    return _snr_of_length(np.asarray(ray.length, dtype=float), config)


def _snr_of_length(length: NDArray[np.float64], config: ChannelConfig) -> NDArray[np.float64]:
    """:func:`physical_snr` (dB) of rays of arc lengths ``length`` (m)."""
    noise, band, alpha, k10 = _snr_constants(config)
    # loss.path_loss_db(l, f, k, l0 = 1, alpha) term by term (the same operations, so the same
    # bits): 10 k log10(max(l, l0) / l0) + (max(l, l0) - l0) 1e-3 alpha, with l / 1.0 = l and
    # no divide-by-zero guard needed since max(l, 1) >= 1 (NaN stays NaN)
    length = np.maximum(length, 1.0)
    loss_db = k10 * np.log10(length) + (length - 1.0) * 1e-3 * alpha
    return config.source_level_db - loss_db - noise - band


@lru_cache(maxsize=64)
def _snr_constants(
    config: ChannelConfig,
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], float]:
    """(N(f) in dB re 1 uPa^2/Hz, 10 log10 B in dB-Hz, Thorp's alpha(f) in dB/km, 10 k) of a
    channel config (alpha is what ``loss.path_loss_db`` computes itself when not given, 10 k
    the factor ``loss.spreading_loss_db`` applies: the same bits)."""
    from . import loss

    noise = loss.noise_psd_db(config.frequency_khz, config.shipping, config.wind_mps)
    alpha = loss.thorp_absorption_db_per_km(config.frequency_khz)
    k10 = 10.0 * loss._spreading_k(config.spreading)
    return noise, 10.0 * np.log10(np.asarray(config.bandwidth_khz * 1e3, dtype=float)), alpha, k10


def default_loss_model() -> LossModel:
    """The channel's default: :func:`physical_snr` (use :func:`no_snr` to disable SNR drops)."""
    return physical_snr


class _Modem:
    """The channel's own state for one node's modem, and the node's port (its bound methods)."""

    __slots__ = (
        "busy_until",
        "clock_stamp",
        "deliver",
        "index",
        "jitter",
        "log_cap",
        "port",
        "pressure_rng",
        "rx_arr",
        "rx_end",
        "rx_log",
        "tx_end",
        "tx_free_at",
        "tx_start",
    )

    def __init__(self, port: RadioPort) -> None:
        self.port = port
        self.index = port.index
        # bound once: the per-reception path then makes one call per stamp / delivery
        self.clock_stamp = port.clock_stamp
        self.deliver = port.deliver
        self.jitter: np.random.Generator | None = None  # the port's jitter stream, asked on first use
        self.pressure_rng: np.random.Generator | None = None  # ("node", id, "pressure"), on first use
        self.tx_free_at = 0.0  # true time (s) the modem is free to start the next queued packet
        # start and end (true s) of own transmissions, in order of start (arrays: a reception's
        # half-duplex test reads a slice of doubles, not a tuple and two floats per entry)
        self.tx_start = array("d")
        self.tx_end = array("d")
        self.busy_until = -math.inf  # the latest of tx_end (true s)
        self.rx_log: list[_Signal] = []  # signals here, sorted by arrival (see _start)
        # their arrival and end times (true s), the collision scan's keys: contiguous doubles,
        # so a scan does not chase a tuple and two float objects per signal
        self.rx_arr = array("d")
        self.rx_end = array("d")
        self.log_cap = 8  # prune the own transmissions beyond this many (see _prune)

    def record(self, sig: _Signal, forget: float) -> None:
        """Keep ``sig`` in the signal log (rx_log with its arrival and end times, sorted by
        arrival; after equal arrivals, as ``insort``), first forgetting the signals that
        arrived before ``forget`` (true s)."""
        keys = self.rx_arr
        if keys and keys[0] < forget:
            j = bisect_left(keys, forget)
            del keys[:j], self.rx_end[:j], self.rx_log[:j]
        arr = sig[0]
        j = bisect_right(keys, arr)
        keys.insert(j, arr)
        self.rx_end.insert(j, sig[1])
        self.rx_log.insert(j, sig)


class _Deliveries:
    """The deliveries of one transmission, as one entry at a time on SimPy's event queue.

    ``sigs`` are the signal records in order of their last bit's arrival; the entry for
    delivery k is pushed when delivery k - 1 has been decided, at the true time
    t0 + (end_k - t0) (the instant a Timeout of delay end_k - t0 made at t0 would fire). So
    the queue holds one entry per transmission in flight, not one per receiver: at 5000 nodes
    with 16 neighbours the heap is 16 times smaller, and a delivery costs one heap push and no
    Timeout. Between deliveries of different transmissions at the same instant the order
    follows the push, so it can differ from one-Timeout-per-delivery only for exactly equal
    float times; it is deterministic either way. The object carries what
    ``Environment.step`` uses of an event (``callbacks``, ``_ok``)."""

    __slots__ = ("callbacks", "k", "sigs", "t0")
    _ok = True

    def __init__(self, sigs: list[_Signal], t0: float, callbacks: list[Callable[[_Deliveries], None]]) -> None:
        self.callbacks = callbacks
        self.sigs = sigs
        self.t0 = t0
        self.k = 0


class AcousticChannel:
    """Delivers packets between the nodes of a network (the SimPy side of the channel).

    env: the SimPy environment. network: ground truth of the nodes (:class:`~aquasim_py.radio.
    NetworkView`). packets: the ``packets`` trace table (:class:`~aquasim_py.radio.PacketLog`).
    Each node's :class:`~aquasim_py.radio.RadioPort` is attached with :meth:`attach` (ids 0, 1,
    ... in order); a node transmits with :meth:`transmit`.
    """

    #: use the compiled links (channel/straight.py) where they apply; False forces the numpy
    #: path (tests compare the two; the results are the same bits)
    compiled_links = True
    #: decide consecutive deliveries at the head of SimPy's queue in one loop (_next_delivery);
    #: False gives each its own Environment.step (tests compare: the same rows in the same order)
    drain_deliveries = True
    #: keep every node's channel-side state and decide the deliveries in C (channel/_delivery.c)
    #: when the module is built and SimPy's queue layout is the known one; False runs the
    #: Python reference below (tests compare the two: the same rows, the same receptions)
    compiled_delivery = True
    #: with the compiled delivery: the channel's entries on its own heap (contiguous keys), only
    #: its head on SimPy's queue with that entry's own key (time, priority, sequence number), so
    #: SimPy takes it exactly when it would have taken it among all of them; False puts every
    #: entry on SimPy's queue, as the Python path does. On the kernel's compiled queue
    #: (aquasim_py.events.Environment) the entries always go on that queue and this has no effect
    compiled_heap = True

    def __init__(
        self,
        env: simpy.Environment,
        network: NetworkView,
        packets: PacketLog,
        ssp: SoundSpeedProfile,
        config: ChannelConfig,
        loss_model: LossModel | None = None,
        streams: Callable[..., np.random.Generator] | None = None,
    ) -> None:
        self._net = network
        # the run's keyed random streams (Simulation.rng), for link-level draws (obstacles)
        self._streams = streams
        self._env = env
        self.ssp = ssp
        self.config = config
        self.loss_model: LossModel = loss_model if loss_model is not None else default_loss_model()
        self._modems: list[_Modem] = []
        self._jitter_std = float(config.jitter_std_s)
        self._uid = 0
        self._table = packets
        self._row = packets.row_buffer().append  # rows go in as tuples, moved to columns in batches
        self._range2 = float(config.max_range_m) ** 2
        self._max_duration = 0.0
        self._collision = config.collision
        self._static_links: dict[int, tuple[int, Any]] = {}
        self._layout_n = -1  # node count _static / _index were made for (see _new_layout)
        self._static = False
        self._all_moving = False
        # every node on a box-folded straight line, constant profile, no link hooks: the
        # compiled links of channel/straight.py ((records, links kernel, SNR-and-order kernel,
        # SNR constants), see _new_layout)
        self._lines: tuple[NDArray[np.float64], Callable[..., Any], Callable[..., Any], NDArray[np.float64]] | None = (
            None
        )
        self._direct = repeat(PATH_NAMES[int(PathKind.DIRECT)])  # the path name of every straight ray
        self._index: NeighbourIndex | None = None
        self._vel_at: Callable[[NDArray[np.intp], float], NDArray[np.float64]] | None = None
        # (time, velocity, estimated acceleration) of each node when last a candidate, for
        # the start of the fixed point on trajectories without a speed bound (_accelerations)
        self._motion: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None
        self._states_at: Callable[[NDArray[np.intp], float], tuple[NDArray[np.float64], NDArray[np.float64]]] | None = (
            None
        )
        self._destructive = config.collision == "destructive"
        self._capture = config.collision == "capture"
        self._emitter: tuple[int, Any] = (-1, None)  # (uid, source position) of the last emission heard
        # deliveries go straight onto SimPy's queue (see _Deliveries) when its layout is the
        # known one: a list heap of (time, priority, sequence number, event) and a counter
        self._next_cb: list[Callable[[_Deliveries], None]] = [self._next_delivery]
        # or the kernel's compiled queue (aquasim_py.events.Environment), whose own push and pop
        # the entries use
        queue: Any = getattr(env, "_queue", None)
        self._eid: Any = getattr(env, "_eid", None)
        known = isinstance(queue, list) and hasattr(self._eid, "__next__")
        self._events: Queue | None = queue if Queue is not None and isinstance(queue, Queue) else None
        self._queue: list[Any] = queue if known else []  # [] : _next_delivery leaves every pop to step
        self._push = (
            self._push_queue if known else self._push_events if self._events is not None else self._push_schedule
        )
        rows = packets.row_buffer()
        self._core: _delivery.Core | None = None  # the compiled state and delivery loop (_delivery.Core), or None
        self._packs: dict[int, tuple[list[Any], _delivery.Links]] = {}  # static links packed for the core, per sender
        usable = known or (self._events is not None and _delivery is not None and _delivery.EVENTS)
        if self.compiled_delivery and _delivery is not None and usable and type(rows) is list:
            self._core = _delivery.Core(
                env,
                queue,
                self._eid,
                NORMAL,
                rows,
                config.collision,
                float(config.capture_threshold_db),
                self._jitter_std > 0.0,
                self._stamp_of,
                self._pressure_of,
                config.pressure_kind,
                self.drain_deliveries,
                self.compiled_heap,
            )

        # obstacle hook (channel/obstacles.py): each link decided from its own keyed stream
        obs = config.obstacles
        self._obstacles: ObstacleField | None = None
        if obs is not None and obs.active:
            if streams is None:
                raise ValueError("AcousticChannel: obstacles need the run's keyed random streams (streams=)")
            self._obstacles = ObstacleField(
                obs,
                lambda a, b: float(streams("obstacle", a, b).random()),
                lambda a, b: streams("obstacle", a, b, "delay"),
            )

        # sound-speed uncertainty hook: its own keyed stream, so no other draw moves
        self._sound_speed: SoundSpeedUncertainty | None = None
        if config.sound_speed_std_mps > 0:
            if streams is None:
                raise ValueError("AcousticChannel: sound-speed uncertainty needs the run's keyed random streams")
            self._sound_speed = SoundSpeedUncertainty(
                config.sound_speed_std_mps, config.sound_speed_corr_s, streams("channel", "sound_speed")
            )
        # a static network's arrivals are cached per sender, unless a hook draws per packet
        self._cacheable = self._sound_speed is None and not (obs is not None and obs.per_packet)

    # -- nodes ------------------------------------------------------------------------------------

    def attach(self, port: RadioPort) -> None:
        """Give the channel the next node's modem port (its index must be the number attached so far)."""
        if port.index != len(self._modems):
            raise ValueError(f"attach: expected the port of node {len(self._modems)}, got node {port.index}")
        self._modems.append(_Modem(port))
        if self._core is not None:
            # an exact clock (affine, no jitter of its own) is stamped in C with its constants
            exact = bool(getattr(port, "exact_stamp", False))
            clock = getattr(port, "clock", None) if exact else None
            skew, offset = (float(clock.skew), float(clock.offset)) if clock is not None else (0.0, 0.0)
            self._core.attach(port.deliver, clock is not None, skew, offset)

    def signals_at(self, node: int) -> int:
        """How many past signals the channel still keeps at ``node`` for collision checks
        (bounded by the overlap window, not by the run length; for diagnostics and tests)."""
        if self._core is not None:
            return int(self._core.signals(node))
        return len(self._modems[node].rx_log)

    def packets_watermark(self) -> float:
        """A true time (s) no ``packets`` row written from now on precedes: a reception's row
        (time: its first bit's arrival) is written when its last bit arrives, at most the longest
        packet queued so far later; every other row is written at or before its time. Twice that
        plus 1 us, so the rounding of event times can never make the promise wrong (the trace
        streams the rows before it, sorted, :meth:`aquasim_py.trace.Table.order_by_time`)."""
        return self._env.now - 2.0 * self._max_duration - 1e-6

    # -- transmit ---------------------------------------------------------------------------------

    def transmit(self, src: int, dst: int | None, kind: str, payload: Any, bits: int) -> simpy.Event:
        """Queue a packet on node ``src``'s modem; the event fires when its last bit has left,
        with the sender's MAC transmit stamp (local s) as its value."""
        if bits <= 0:
            raise ValueError(f"a packet needs bits > 0, got {bits}")
        modem = self._modems[src]
        env = self._env
        now = env.now
        duration = bits / self.config.bitrate_bps
        if duration > self._max_duration:
            self._max_duration = duration
            if self._core is not None:
                self._core.max_duration = duration
        start = modem.tx_free_at if modem.tx_free_at > now else now
        modem.tx_free_at = start + duration
        if start == now:
            tx_local = self._start(modem, dst, kind, payload, bits, duration)
            return env.timeout(duration, tx_local)
        done = env.event()

        def later(_: simpy.Event) -> None:
            tx_local = self._start(modem, dst, kind, payload, bits, duration)

            def sent(_e: simpy.Event) -> None:
                done.succeed(tx_local)

            env.timeout(duration).callbacks.append(sent)

        env.timeout(start - now).callbacks.append(later)
        return done

    def _stamp(self, m: _Modem, t: float) -> float:
        """MAC stamp (local s) of true time ``t`` at modem ``m``: its clock's stamp plus jitter."""
        s = m.clock_stamp(t)
        if self._jitter_std > 0.0:
            rng = m.jitter
            if rng is None:
                rng = m.jitter = m.port.jitter_stream()
            s += float(rng.normal(0.0, self._jitter_std))
        return s

    def _start(self, modem: _Modem, dst: int | None, kind: str, payload: Any, bits: int, duration: float) -> float:
        """The first bit leaves now: stamp, trace, and schedule every reception."""
        env = self._env
        t0 = env.now
        src = modem.index
        uid = self._uid
        self._uid = uid + 1
        tx_local = self._stamp(modem, t0)
        pkt = Packet(uid, src, dst, kind, payload, bits, tx_local)
        dst_code = -1 if dst is None else dst
        nan = math.nan
        row = self._row
        self._table.flush_if_large()
        core = self._core
        if core is not None:  # the same own-transmission log, pruned the same way, in C
            core.transmit(src, t0, t0 + duration, t0)
        else:
            modem.tx_start.append(t0)
            modem.tx_end.append(t0 + duration)
            if modem.tx_end[-1] > modem.busy_until:
                modem.busy_until = modem.tx_end[-1]
            if len(modem.tx_start) > modem.log_cap:
                self._prune(modem)
        row((t0, "tx", None, src, src, dst_code, uid, kind, bits, nan, nan, None, tx_local))

        in_range, heard, lost = self._links(src, t0)
        if dst is not None and dst not in in_range:
            row((t0, "drop", "range", dst, src, dst, uid, kind, bits, nan, nan, None, nan))
        for rid, reason, T, path, s in lost:
            if dst is None or dst == rid:
                if reason == "no_path":
                    row((t0, "drop", reason, rid, src, dst_code, uid, kind, bits, nan, nan, path, nan))
                else:
                    row((t0 + T, "drop", reason, rid, src, dst_code, uid, kind, bits, T, s, path, nan))
        track = self._destructive or self._capture  # overlaps matter only with a collision model
        # A pending reception ends after now, so it began after now - longest packet, and a
        # signal arriving before now - 2 * longest packet cannot overlap it: forget those.
        forget = t0 - 2.0 * self._max_duration
        if core is not None:  # the loop below and the push, in C
            if heard:
                packed = self._packs.get(src)
                if packed is None or packed[0] is not heard:  # a static network's links are cached: so is their pack
                    packed = (heard, core.pack(heard))
                    if self._static and self._cacheable:
                        self._packs[src] = packed
                core.start(pkt, dst, t0, duration, packed[1], forget)
            return tx_local
        sigs: list[_Signal] = []
        modems = self._modems
        if dst is None:
            for rid, T, path, s in heard:
                arr = t0 + T
                end = arr + duration
                # one record is both the receiver's signal record (sorted by arrival) and the
                # delivery's context
                sig = (arr, end, s, rid, pkt, T, path, -1)
                if track:
                    modems[rid].record(sig, forget)
                sigs.append(sig)
        else:
            # a unicast is heard (and interferes) everywhere in range; only its addressee delivers
            for rid, T, path, s in heard:
                intended = rid == dst
                if not (track or intended):
                    continue
                arr = t0 + T
                end = arr + duration
                sig = (arr, end, s, rid, pkt, T, path, dst)
                if track:
                    modems[rid].record(sig, forget)
                if intended:
                    sigs.append(sig)
        if sigs:  # heard is sorted by delay, so sigs are in order of arrival
            self._push(_Deliveries(sigs, t0, self._next_cb), t0 + (sigs[0][1] - t0))
        return tx_local

    def _stamp_of(self, rid: int, t: float) -> float:
        """``_stamp`` of node ``rid`` (the compiled core's call for clocks it cannot stamp itself)."""
        return self._stamp(self._modems[rid], t)

    def _pressure_of(self, pkt: Packet, rid: int, t_send: float, t_arr: float) -> float:
        """``_pressure`` at node ``rid`` (the compiled core's call)."""
        return self._pressure(pkt, self._modems[rid], t_send, t_arr)

    def _links(
        self, src: int, t0: float
    ) -> tuple[list[int], list[tuple[int, float, str, float]], list[tuple[int, str, float, str, float]]]:
        """Who hears ``src`` transmitting at ``t0``: (ids in range, in any order; heard; lost).

        heard: (receiver id, delay s, path name, SNR dB) of signals that reach the receiver,
        sorted by delay (ids, not modems: a moving network makes these lists at every
        transmission, and each receiver's modem object would be one more cold line);
        lost: (id, "no_path" | "snr", delay, path name, SNR) of those that do not. When no node
        moves the answer never changes, so it is cached per sender (recomputed if nodes are
        added; the loss model must be a pure function of the eigenray and the config).
        """
        net = self._net
        n = len(self._modems)
        if n != self._layout_n:
            self._new_layout(n)
        static = self._static and self._cacheable
        if static:
            hit = self._static_links.get(src)
            if hit is not None and hit[0] == n:
                return hit[1]
        index = self._index
        v_cand: NDArray[np.float64] | None = None  # candidates' velocities at t0, when known
        v_near: NDArray[np.float64] | None
        if index is None:
            # no speed bound: the exact test on every node (one vectorized computation)
            pos = net.positions(t0)
            p_src = pos[src]
            diff = pos - p_src
            d2 = np.einsum("ij,ij->i", diff, diff)
            d2[src] = np.inf
            cand = np.flatnonzero(d2 <= self._range2)
            p_cand = pos[cand]
            v_cand = None
        else:
            # the sender and the k-d tree's superset of the nodes in range around it, then the
            # same exact test on that superset alone
            near = index.neighbourhood(src, t0, n, net.positions)
            if self._lines is not None:
                done = self._compiled_links(near, t0)
                if done is not None:
                    return done
            if static:
                p_near = net.positions(t0)[near]
                v_near = None
            else:
                # one trajectory evaluation (positions and velocities at t0) for all of them
                p_near, v_near = self._states(near, t0)
            p_src = p_near[0]
            diff = p_near[1:] - p_src
            keep = np.einsum("ij,ij->i", diff, diff) <= self._range2
            cand = near[1:][keep]
            p_cand = p_near[1:][keep]
            if v_near is not None:
                v_cand = v_near[1:][keep]
        if cand.size:
            times, paths, snr = self._arrivals(t0, p_src, cand, p_cand, v_cand)
            if self._sound_speed is not None:  # path-mean speed taken at the mid depth
                times = self._sound_speed.apply(times, t0, src, cand, self.ssp.speed((p_src[2] + p_cand[:, 2]) / 2))
            if self._obstacles is not None:  # obstacle hook: excess delay added, extra loss subtracted
                times, snr = self._obstacles.apply(src, cand, times, snr)
            out = self._sorted_links(cand.tolist(), times, map(PATH_NAMES.__getitem__, paths.tolist()), snr)
        else:
            out = ([], [], [])
        if static:
            self._static_links[src] = (n, out)
        return out

    def _sorted_links(
        self, ids: list[int], times: NDArray[np.float64], paths: Iterable[str], snr: NDArray[np.float64]
    ) -> tuple[list[int], list[tuple[int, float, str, float]], list[tuple[int, str, float, str, float]]]:
        """(ids, heard, lost) of ``_links`` from the candidates' delays (s), path names and SNR (dB)."""
        thr = self.config.snr_threshold_db
        heard: list[tuple[int, float, str, float]] = []
        lost: list[tuple[int, str, float, str, float]] = []
        # lost: no eigenray (NaN delay, shadow zone) or SNR below the threshold (a NaN SNR,
        # no loss model, compares False: never dropped on SNR)
        if not ((times != times) | (snr < thr)).any():  # the usual case: all heard, no loop
            heard = list(zip(ids, times.tolist(), paths, snr.tolist()))
        else:
            for rid, T, p, s in zip(ids, times.tolist(), paths, snr.tolist()):
                if T != T:
                    lost.append((rid, "no_path", T, p, s))
                elif s < thr:
                    lost.append((rid, "snr", T, p, s))
                else:
                    heard.append((rid, T, p, s))
        heard.sort(key=_DELAY)  # stable: equal delays keep the candidates' order
        return ids, heard, lost

    def _compiled_links(
        self, near: NDArray[np.intp], t0: float
    ) -> tuple[list[int], list[tuple[int, float, str, float]], list[tuple[int, str, float, str, float]]] | None:
        """``_links`` by the compiled kernel (``channel.straight``) for the sender ``near[0]``
        and its neighbourhood ``near[1:]``; None when the general path must decide."""
        assert self._lines is not None
        records, kernel, finish, terms = self._lines
        ssp = cast(Constant, self.ssp)
        bottom = math.inf if ssp.bottom is None else float(ssp.bottom)
        status, cand, times, length, diff = kernel(
            records, near, t0, ssp.speed_mps, bottom, self._range2, FIXED_POINT_TOL_S
        )
        if status:
            return None
        if not cand.size:
            return [], [], []
        model = self.loss_model
        if model is physical_snr:
            thr = self.config.snr_threshold_db
            snr, lost, ids, t_s, snr_s = finish(cand, times, length, np.log10(np.maximum(length, 1.0)), terms, thr)
            if not lost:  # the usual case: every receiver heard, already in order of arrival
                in_range = ids.tolist()
                return in_range, list(zip(in_range, t_s.tolist(), self._direct, snr_s.tolist())), []
        else:  # any other model gets the whole ray, as _straight_moving makes it
            ray = _direct_rays(times, length, np.arctan2(diff[:, 2], np.hypot(diff[:, 0], diff[:, 1])))
            snr = np.asarray(model(ray, self.config), dtype=float)
        return self._sorted_links(cand.tolist(), times, self._direct, snr)

    def _new_layout(self, n: int) -> None:
        """Nodes were added: whether the network is static, and the neighbour index (None when
        a moving node's model gives no speed bound: every transmission then tests every node)."""
        net = self._net
        self._layout_n = n
        self._static = not bool(net.is_moving().any())
        self._all_moving = bool(net.is_moving().all())
        bound = getattr(net, "max_speed", None)
        vmax = 0.0 if self._static else (float(bound()) if bound is not None else math.inf)
        self._index = NeighbourIndex(float(self.config.max_range_m), vmax) if math.isfinite(vmax) else None
        self._vel_at = getattr(net, "velocities_at", None)
        self._lines = None
        records = getattr(net, "line_records", None)
        if (
            self.compiled_links
            and self._all_moving
            and self._index is not None
            and isinstance(self.ssp, Constant)
            and self._sound_speed is None
            and self._obstacles is None
            and records is not None
            and (table := records()) is not None
        ):
            from .straight import by_arrival, straight_links  # numba: only runs that take this path pay for it

            noise, band, alpha, k10 = _snr_constants(self.config)
            terms = np.array([k10, alpha, self.config.source_level_db, noise, band], dtype=float)
            self._lines = (np.ascontiguousarray(table, dtype=float), straight_links, by_arrival, terms)
        self._states_at = getattr(net, "states_at", None)

    def _velocities(self, idx: NDArray[np.intp], t: float) -> NDArray[np.float64]:
        """True velocities (k, 3) of nodes ``idx`` at ``t``, evaluating only those when the network can."""
        if self._vel_at is not None:
            return np.asarray(self._vel_at(idx, t), dtype=float)
        return self._net.velocities(t)[idx]

    def _states(self, idx: NDArray[np.intp], t: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """True positions and velocities (k, 3) of nodes ``idx`` at ``t`` (one call if the network can)."""
        if self._states_at is not None:
            return self._states_at(idx, t)
        return self._net.positions_at(idx, np.full(idx.size, t)), self._velocities(idx, t)

    def _accelerations(self, cand: NDArray[np.intp], t0: float, v: NDArray[np.float64]) -> NDArray[np.float64]:
        """Estimated accelerations (m/s^2, (k, 3)) of the candidates at ``t0``: the change of
        each one's velocity ``v`` since the last transmission it was a candidate of, over the
        time between (0 before that; the last estimate again at the same instant). Only the
        start of the exact fixed point uses it, so a poor estimate (a wall bounce in between)
        costs an iteration, never accuracy."""
        n = len(self._modems)
        if self._motion is None or len(self._motion[0]) != n:
            self._motion = (np.full(n, np.nan), np.zeros((n, 3)), np.zeros((n, 3)))
        t_last, v_last, a_last = self._motion
        dt = t0 - t_last[cand]
        a = a_last[cand]
        new = dt > 0.0  # NaN (never seen) compares False
        if new.any():
            a[new] = (v[new] - v_last[cand[new]]) / dt[new, None]
        a_last[cand] = a
        t_last[cand] = t0
        v_last[cand] = v
        return a

    def _arrivals(
        self,
        t0: float,
        p_src: NDArray[np.float64],
        cand: NDArray[np.intp],
        p_rx: NDArray[np.float64],
        v_rx: NDArray[np.float64] | None = None,
    ) -> tuple[NDArray[np.float64], NDArray[np.int8], NDArray[np.float64]]:
        """Arrival delays (s), path kinds and SNR (dB) at the candidates (moving-receiver fixed point).

        v_rx: the candidates' velocities (m/s) at t0 if already known (else asked for)."""
        ssp = self.ssp
        refl = self.config.reflections
        net = self._net
        fast = None
        if self._all_moving and v_rx is not None and isinstance(ssp, Constant):
            fast = _straight_moving(ssp, p_src, p_rx, v_rx, t0, lambda t: net.positions_at(cand, t))
        if fast is not None:
            ray = fast
        elif not (moving := net.is_moving()[cand]).any():
            ray = eigenray(ssp, p_src, p_rx, reflections=refl)
        else:
            start: tuple[dict[str, NDArray[Any]], NDArray[np.intp]] | None = None
            if isinstance(ssp, Constant):
                v = v_rx if v_rx is not None else self._velocities(cand, t0)
                # no speed bound (the current-driven models): their acceleration matters
                acc = self._accelerations(cand, t0, v) if self._index is None else None
                start = _constant_start(ssp, refl, p_src, p_rx, moving, v, acc)
            if start is None:
                ray = eigenray(ssp, p_src, p_rx, reflections=refl)
                fields = {f: np.array(getattr(ray, f)) for f in Eigenray.__dataclass_fields__}
                active = np.flatnonzero(moving & np.isfinite(fields["time"]))
                # Start from the fixed point of the receivers' straight-line motion at t0
                # (vectorized, no mobility queries): for constant velocity it is already the
                # answer, and the exact iteration below then stops after one query per receiver.
                v0 = v_rx[active] if v_rx is not None else self._velocities(cand[active], t0)
                fields["time"][active] = _linear_fixed_point(
                    ssp,
                    refl,
                    p_src,
                    p_rx[active],
                    v0,
                    fields["time"][active],
                    fields["arrival_angle"][active],
                    fields["path"][active],
                )
            else:
                fields, active = start
            time = fields["time"]
            straight = _straight_rays(ssp, p_src) if isinstance(ssp, Constant) else None
            # exact fixed point t_a = t0 + T(p_src(t0), p_rx(t_a)) on the true trajectories
            for _ in range(_MAX_ITER):
                if active.size == 0:
                    break
                # every receiver active (the usual first step): whole arrays, no gathers
                whole = active.size == time.size
                t_act = time if whole else time[active]
                p_new = net.positions_at(cand if whole else cand[active], t0 + t_act)
                r = straight(p_new) if straight is not None else eigenray(ssp, p_src, p_new, reflections=refl)
                step = np.abs(r.time - t_act)
                if whole:
                    fields = {f: np.asarray(getattr(r, f)) for f in _FIELDS}
                    time = fields["time"]
                else:
                    for f in _FIELDS:
                        fields[f][active] = getattr(r, f)
                # converged (or lost the path: NaN stays NaN and leaves the loop)
                active = active[step > FIXED_POINT_TOL_S]
            ray = Eigenray(**fields)
            if active.size:
                raise RuntimeError(f"arrival-time fixed point did not converge for {active.size} receivers")
        snr = np.asarray(self.loss_model(ray, self.config), dtype=float)
        return np.asarray(ray.time, dtype=float), np.asarray(ray.path), snr

    # -- receive ----------------------------------------------------------------------------------

    def _next_delivery(self, ev: _Deliveries) -> None:
        """The last bit of a packet has arrived at a receiver: decide, stamp, deliver, trace;
        then queue the transmission's next delivery. And while the head of SimPy's queue is
        another delivery entry of this channel, take it off the queue and do the same here, as
        ``Environment.step`` would have next (the same pop of the same heap: the same order
        and times), without a step and its callback loop each."""
        heap = self._queue
        drain = heap if self.drain_deliveries else []  # whose head the loop may take
        events = self._events if self.drain_deliveries else None  # or the compiled queue's
        cb = self._next_cb
        # _push_queue's push written out (one call less per delivery), unless the fallback
        # _push_schedule is in use
        eid = self._eid if self._push == self._push_queue else None
        push = self._push
        row = self._row
        modems = self._modems
        scan = self._scan
        plain = self._jitter_std <= 0.0  # without jitter the clock's stamp is the MAC stamp
        pressure_kind = self.config.pressure_kind
        nan = math.nan
        while True:
            sigs = ev.sigs
            k = ev.k
            sig = sigs[k]
            arr, _end, snr, rid, pkt, tof, path, dst_code = sig
            reason = scan(sig)
            if reason is None:
                rx = modems[rid]
                rx_local = rx.clock_stamp(arr) if plain else self._stamp(rx, arr)
                p = self._pressure(pkt, rx, arr - tof, arr) if pkt.kind == pressure_kind else nan
                rx.deliver(pkt, rx_local, snr, p)
                row((arr, "rx", None, rid, pkt.src, dst_code, pkt.uid, pkt.kind, pkt.bits, tof, snr, path, rx_local))
            else:
                row((arr, "drop", reason, rid, pkt.src, dst_code, pkt.uid, pkt.kind, pkt.bits, tof, snr, path, nan))
            k += 1
            if k < len(sigs):  # queued after the delivery's own events (their sequence numbers)
                ev.k = k
                ev.callbacks = cb  # Environment.step set it to None (the loop below leaves it)
                t0 = ev.t0
                if eid is not None:
                    heappush(heap, (t0 + (sigs[k][1] - t0), NORMAL, next(eid), ev))
                else:
                    push(ev, t0 + (sigs[k][1] - t0))
            if events is not None:
                nxt = events.first()
                if nxt is None or nxt.callbacks is not cb:
                    return
                ev = events.pop()  # and env._now is its time
                continue
            if not drain:  # empty, or no access to SimPy's queue (_push_schedule)
                return
            head = drain[0]
            ev = head[3]
            if ev.callbacks is not cb:  # an event of SimPy's or of a node: step() takes it
                return
            heappop(drain)
            self._env._now = head[0]

    def _push_queue(self, ev: _Deliveries, at: float) -> None:
        """Queue ``ev`` at true time ``at`` exactly, as ``Environment.schedule`` would with
        priority NORMAL (same entry layout, next sequence number)."""
        heappush(self._queue, (at, NORMAL, next(self._eid), ev))

    def _push_events(self, ev: _Deliveries, at: float) -> None:
        """Queue ``ev`` at true time ``at`` exactly on the kernel's compiled queue (priority
        NORMAL, its next sequence number)."""
        cast(Queue, self._events).push(at, NORMAL, ev)

    def _push_schedule(self, ev: _Deliveries, at: float) -> None:
        """Fallback for a SimPy without ``_queue`` / ``_eid``: the public ``schedule`` (its
        time now + (at - now) can differ from ``at`` by an ulp early in a run)."""
        self._env.schedule(cast(simpy.Event, ev), NORMAL, at - self._env.now)

    def _scan(self, sig: _Signal) -> str | None:
        """The verdict of a delivery from the receiver's logs at the delivery: "half_duplex",
        "collision" or None."""
        arr, end, snr, rx = sig[0], sig[1], sig[2], self._modems[sig[3]]
        reason = None
        # own transmissions overlapping [arr, end): started before end and, lasting at most
        # the longest packet, after arr - longest packet (twice that here, so the rounding of
        # start + duration cannot hide one); the exact test decides within that slice; none
        # when every own transmission ended by arr
        if rx.busy_until > arr:
            starts = rx.tx_start
            i = bisect_left(starts, arr - 2.0 * self._max_duration)
            n = len(starts)
            while i < n and starts[i] < end:
                if rx.tx_end[i] > arr:
                    reason = "half_duplex"
                    break
                i += 1
        if reason is None and (self._destructive or self._capture):
            # rx_log is sorted by arrival; a signal overlapping [arr, end) arrived in
            # (arr - longest packet, end), so only that slice is examined
            keys = rx.rx_arr
            ends = rx.rx_end
            i = bisect_left(keys, arr - self._max_duration)
            n = len(keys)
            power = 0.0
            hit = False
            while i < n:
                if keys[i] >= end:
                    break
                if ends[i] > arr:
                    e = rx.rx_log[i]
                    if e is not sig:
                        hit = True
                        if self._destructive:
                            break
                        power += 10.0 ** (e[2] / 10.0)
                i += 1
            if hit and (self._destructive or not (snr - 10.0 * math.log10(power) >= self.config.capture_threshold_db)):
                reason = "collision"
        return reason

    def _pressure(self, pkt: Packet, rx: _Modem, t_send: float, t_arr: float) -> float:
        """Hydrophone reading of a sound emission (sender at send time, receiver at arrival),
        with the noise drawn from the receiver's own ("node", id, "pressure") stream."""
        from .pressure import received_pressure

        if self._emitter[0] != pkt.uid:  # one source position per emission, shared by its receivers
            src = self._net.positions_at(np.array([pkt.src]), np.array([t_send]))[0]
            self._emitter = (pkt.uid, src)
        c = self.config
        here = self._net.positions_at(np.array([rx.index]), np.array([t_arr]))[0]
        h = float(received_pressure(self._emitter[1], here, c.pressure_source_level, c.pressure_exponent))
        if c.pressure_noise_std <= 0.0:
            return h
        if rx.pressure_rng is None:
            rx.pressure_rng = rx.port.stream("pressure")
        return h + float(rx.pressure_rng.normal(0.0, c.pressure_noise_std))

    def _prune(self, modem: _Modem) -> None:
        """Forget own transmissions that can no longer overlap a pending reception.

        A pending reception ends at or after now and lasts at most the longest packet so far,
        so it began after now - max_duration; anything that ended before cannot touch it.
        """
        cutoff = self._env.now - self._max_duration
        keep = [i for i, b in enumerate(modem.tx_end) if b >= cutoff]
        modem.tx_start = array("d", [modem.tx_start[i] for i in keep])
        modem.tx_end = array("d", [modem.tx_end[i] for i in keep])
        # next prune when the log has doubled: amortized O(1) per entry, short scans
        modem.log_cap = max(8, 2 * len(keep))


# -- straight-line start of the moving-receiver fixed point -----------------------------------------


def _linear_fixed_point(
    ssp: SoundSpeedProfile,
    refl: Reflections,
    p_src: NDArray[np.float64],
    p0: NDArray[np.float64],
    v: NDArray[np.float64],
    t_start: NDArray[np.float64],
    arrival_angle: NDArray[np.float64],
    path: NDArray[np.int8],
) -> NDArray[np.float64]:
    """Delay t (s) solving t = T(p_src, p0 + v t) for receivers at p0 (m, (k, 3)) moving in
    straight lines at v (m/s), given t_start = T(p_src, p0) and the arrival angle of that ray.

    Only the starting point of the exact iteration on the true trajectories (which decides
    the result), so it may be NaN / inexact where the straight line leaves the water.
    Constant profile: the closed-form root of |p0 + v t - p_src| = c t (no ray tracing).
    Other profiles: secant iteration on f(t) = t - T(p0 + v t), seeded with the exact slope
    dT/dt = grad T . v (the slowness vector at the receiver, Fermat), about 2 travel-time
    evaluations instead of the 4-5 of plain iteration (which contracts only by |v|/c per step).
    """
    if t_start.size == 0:
        return t_start
    if isinstance(ssp, Constant):
        t = _constant_moving_root(ssp.speed_mps, p0 - p_src, v)
        if np.isfinite(t).all():
            return t
    slope = _slope_along(ssp, p_src, p0, v, arrival_angle)
    return _secant_fixed_point(_travel_time_fn(ssp, refl, p_src, path), p0, v, t_start, slope)


def _direct_rays(time: NDArray[np.float64], length: NDArray[np.float64], ang: NDArray[np.float64]) -> Eigenray:
    """Straight rays (constant profile) with delays ``time`` (s), lengths (m) and elevation
    ``ang`` (rad, launch = arrival); the arrival angle is its own array because the fixed point
    writes rows of each field."""
    return Eigenray(
        time=time,
        length=length,
        launch_angle=ang,
        arrival_angle=ang.copy(),
        turning_depth=np.full(length.shape, np.nan),
        path=np.full(length.shape, np.int8(PathKind.DIRECT)),
    )


def _straight_rays(ssp: Constant, p_src: NDArray[np.float64]) -> Callable[[NDArray[np.float64]], Eigenray]:
    """``eigenray(ssp, p_src, dst)`` for a constant profile and one source, as a function of
    the receivers dst (k, 3): the same arithmetic as ``raytrace._constant_direct`` (so the same
    bits; a straight line is the first arrival in every ``reflections`` mode), without
    broadcasting the source to every receiver, and the source's own checks done once."""
    c = ssp.speed_mps
    bottom = ssp.bottom
    z_s = float(p_src[2])
    src_ok = z_s >= 0.0 and (bottom is None or z_s <= bottom) and bool(np.isfinite(p_src).all())
    none, direct = np.int8(PathKind.NONE), np.int8(PathKind.DIRECT)

    def rays(d: NDArray[np.float64]) -> Eigenray:
        diff = d - p_src
        dist = np.linalg.norm(diff, axis=-1)
        horiz = np.hypot(diff[..., 0], diff[..., 1])
        ang = np.arctan2(diff[..., 2], horiz)
        z = d[..., 2]
        ok = (z >= 0.0) & np.isfinite(d).all(axis=-1)
        if bottom is not None:
            ok &= z <= bottom
        if not src_ok:
            ok[...] = False
        bad = ~ok
        if not bad.any():  # the usual case: the np.where below would change nothing
            return _direct_rays(dist / c, dist, ang)
        return Eigenray(
            time=np.where(bad, np.nan, dist / c),
            length=np.where(bad, np.nan, dist),
            launch_angle=np.where(bad, np.nan, ang),
            arrival_angle=np.where(bad, np.nan, ang),
            turning_depth=np.full(dist.shape, np.nan),
            path=np.where(bad, none, direct),
        )

    return rays


def _straight_moving(
    ssp: Constant,
    p_src: NDArray[np.float64],
    p_rx: NDArray[np.float64],
    v: NDArray[np.float64],
    t0: float,
    positions_at: Callable[[NDArray[np.float64]], NDArray[np.float64]],
) -> Eigenray | None:
    """Constant profile, every receiver moving: the eigenrays to the receivers at their arrival
    instants, or None when anything is unusual (a point out of the water, a receiver faster
    than c/2, a step of the exact iteration larger than the tolerance: the general fixed point
    in ``_arrivals`` then runs, with the same result).

    The same operations, in the same order, as the general path's usual course (the
    closed-form start of ``_constant_start``, one exact step, the ray of ``_straight_rays``),
    so the same bits, with the per-row checks done as a few reductions over the whole
    neighbourhood instead of masks and gathers: this runs once per transmission.
    positions_at(times): the receivers' true positions (k, 3) at true times (k,)."""
    c = ssp.speed_mps
    bottom = ssp.bottom
    z_s = float(p_src[2])
    if not (z_s >= 0.0 and (bottom is None or z_s <= bottom) and math.isfinite(float(p_src.sum()))):
        return None
    z = p_rx[:, 2]
    if not (z.min() >= 0.0 and (bottom is None or z.max() <= bottom)):  # NaN fails too
        return None
    t = _constant_moving_root(c, p_rx - p_src, v)  # NaN / inf for a non-finite receiver or speed
    if not math.isfinite(float(t.sum())):
        return None
    p_new = positions_at(t0 + t)
    diff = p_new - p_src
    dist = np.sqrt(np.add.reduce(diff * diff, axis=-1))  # np.linalg.norm(diff, axis=-1), same bits
    z = p_new[:, 2]
    if not (math.isfinite(float(dist.sum())) and z.min() >= 0.0 and (bottom is None or z.max() <= bottom)):
        return None
    time = dist / c
    if not bool((np.abs(time - t) <= FIXED_POINT_TOL_S).all()):
        return None
    return _direct_rays(time, dist, np.arctan2(diff[:, 2], np.hypot(diff[:, 0], diff[:, 1])))


def _constant_start(
    ssp: Constant,
    refl: Reflections,
    p_src: NDArray[np.float64],
    p_rx: NDArray[np.float64],
    moving: NDArray[np.bool_],
    v: NDArray[np.float64],
    acc: NDArray[np.float64] | None = None,
) -> tuple[dict[str, NDArray[Any]], NDArray[np.intp]] | None:
    """Constant profile: the eigenray fields of the candidates before the exact iteration, and
    the moving receivers to iterate (``active``), without tracing rays to their send-time
    positions: a straight ray exists iff both ends are in the water (the ray tracer's own
    test), and the start delay is the closed-form straight-line root. Only the other
    candidates (static, or out of the water) are traced. None if the closed form fails."""
    z_s = float(p_src[2])
    z = p_rx[:, 2]
    inside = (z >= 0.0) & np.isfinite(p_rx).all(axis=1)
    ok_src = z_s >= 0.0 and bool(np.isfinite(p_src).all())
    if ssp.bottom is not None:
        inside &= z <= ssp.bottom
        ok_src = ok_src and z_s <= ssp.bottom
    act = moving & inside if ok_src else np.zeros_like(moving)
    active = np.flatnonzero(act)
    t = _constant_moving_root(ssp.speed_mps, p_rx[active] - p_src, v[active])
    if not np.isfinite(t).all():
        return None
    if acc is not None:
        t = _accelerated_root(ssp.speed_mps, p_rx[active] - p_src, v[active], acc[active], t)
    n = len(p_rx)
    if active.size == n:  # every row is overwritten by the first exact step, which reads only time
        return {"time": t}, active
    # every row is filled below: traced (rest) or overwritten by the first exact step (active)
    fields: dict[str, NDArray[Any]] = {f: np.empty(n) for f in _FLOAT_FIELDS}
    fields["path"] = np.empty(n, dtype=np.int8)
    rest = np.flatnonzero(~act)
    if rest.size:
        r = eigenray(ssp, p_src, p_rx[rest], reflections=refl)
        for f in fields:
            fields[f][rest] = getattr(r, f)
    fields["time"][active] = t  # the start delay: the only active field read before it is overwritten
    return fields, active


def _constant_moving_root(c: float, d: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """Positive root t (s) of |d + v t| = c t (receiver offset d (m) from the source, velocity v).

    (c^2 - |v|^2) t^2 - 2 (d.v) t - |d|^2 = 0, t = (d.v + sqrt((d.v)^2 + (c^2 - |v|^2) |d|^2))
    / (c^2 - |v|^2). With |v| <= c/2 the sum never cancels (|d.v| <= |v||d| is at most half the
    root), so this is accurate to a few ulps; NaN for faster receivers (the caller iterates).
    """
    dv = np.einsum("ij,ij->i", d, v)
    vv = np.einsum("ij,ij->i", v, v)
    if not bool((vv <= 0.25 * c * c).all()):
        return np.full(len(d), np.nan)
    a = c * c - vv
    return (dv + np.sqrt(dv * dv + a * np.einsum("ij,ij->i", d, d))) / a


def _accelerated_root(
    c: float, d: NDArray[np.float64], v: NDArray[np.float64], a: NDArray[np.float64], t: NDArray[np.float64]
) -> NDArray[np.float64]:
    """One Newton step from the straight-line root t (s) towards the root of
    |d + v t + a t^2 / 2| = c t (offset d in m, velocity v in m/s, acceleration a in m/s^2),
    for the rows with a != 0; t where the step fails. The straight-line root misses by about
    |a| t^2 / (2 c) (1e-9 s for a current's 1e-3 m/s^2 over 80 m), more than the fixed point's
    tolerance, so the exact iteration would need a second step; from this start it needs one."""
    use = np.flatnonzero((a != 0.0).any(axis=1))
    if not use.size:
        return t
    tu, du, vu, au = t[use], d[use], v[use], a[use]
    q = du + vu * tu[:, None] + (0.5 * tu * tu)[:, None] * au
    dq = vu + au * tu[:, None]
    nq = np.sqrt(np.einsum("ij,ij->i", q, q))
    with np.errstate(invalid="ignore", divide="ignore"):
        t_new = tu - (nq - c * tu) / (np.einsum("ij,ij->i", q, dq) / nq - c)
    out = t.copy()
    # a correction is tiny (|a| t^2 / 2c); a large one comes from a poor estimate (e.g. a
    # wall bounce since the last one) and is not taken
    out[use] = np.where(np.abs(t_new - tu) <= 1e-3 * tu, t_new, tu)
    return out


def _slope_along(
    ssp: SoundSpeedProfile,
    p_src: NDArray[np.float64],
    p0: NDArray[np.float64],
    v: NDArray[np.float64],
    arrival_angle: NDArray[np.float64],
) -> NDArray[np.float64]:
    """d/dt T(p_src, p0 + v t) at t = 0: grad T . v, with grad T the slowness vector at the
    receiver, (cos th e_h + sin th e_z) / c(z) (th the arrival grazing angle, positive down,
    e_h the horizontal direction of travel). 0 where unknown (plain iteration then)."""
    dx = p0[:, 0] - p_src[0]
    dy = p0[:, 1] - p_src[1]
    r = np.hypot(dx, dy)
    with np.errstate(invalid="ignore", divide="ignore"):
        cos = np.cos(arrival_angle)
        vh = np.where(r > 0.0, (dx * v[:, 0] + dy * v[:, 1]) / r, 0.0)
        k = (cos * vh + np.sin(arrival_angle) * v[:, 2]) / ssp.speed(p0[:, 2])
    return np.where(np.isfinite(k) & (np.abs(k) < 0.5), k, 0.0)


def _travel_time_fn(
    ssp: SoundSpeedProfile, refl: Reflections, p_src: NDArray[np.float64], path: NDArray[np.int8]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """The cheapest exact first-arrival time (s) from ``p_src`` to receivers (k, 3) whose current
    arrival has kind ``path``: the isogradient closed form directly when every arrival is the
    direct arc and reflections cannot be earlier, else the full eigenray."""
    if isinstance(ssp, Isogradient) and refl in ("none", "fallback") and bool((path == PathKind.DIRECT).all()):
        b, a, bottom = ssp.surface_speed, ssp.gradient, ssp.bottom
        return lambda dst: isogradient.travel_time(b, a, p_src, dst, bottom=bottom)
    return lambda dst: eigenray(ssp, p_src, dst, reflections=refl).time


def _secant_fixed_point(
    travel: Callable[[NDArray[np.float64]], NDArray[np.float64]],
    p0: NDArray[np.float64],
    v: NDArray[np.float64],
    t_start: NDArray[np.float64],
    slope: NDArray[np.float64],
) -> NDArray[np.float64]:
    """Fixed point of t = G(t) = travel(p0 + v t) by secant steps on t - G(t), vectorized.

    The first secant uses the known point (0, t_start) and ``slope`` = G'(0); later ones the
    last two evaluations. A receiver stops when a step moves t by <= FIXED_POINT_TOL_S / 10
    (secant convergence is superlinear, so the remaining error is far smaller), or when G is
    NaN (the straight line leaves the water: t is kept and the exact iteration decides).
    """
    out = t_start / (1.0 - slope)
    idx = np.arange(t_start.size)
    t = out.copy()
    x_prev = np.zeros_like(t)
    y_prev = t_start.copy()
    s = slope.copy()
    for _ in range(_MAX_ITER):
        y = travel(p0[idx] + v[idx] * t[:, None])
        ok = np.isfinite(y)
        with np.errstate(invalid="ignore", divide="ignore"):
            s_new = (y - y_prev) / (t - x_prev)
            s = np.where(ok & np.isfinite(s_new), s_new, s)
            t_new = np.where(ok, (y - s * t) / (1.0 - s), t)
        out[idx] = t_new
        go = ok & (np.abs(t_new - t) > 0.1 * FIXED_POINT_TOL_S)
        if not go.any():
            break
        idx, x_prev, y_prev, s, t = idx[go], t[go], y[go], s[go], t_new[go]
    return out
