"""The SimPy acoustic channel: who hears a transmission, when, and whether it survives.

On a transmission at true time t0 from position p_s = p_src(t0):

1. candidates: every node within ``max_range_m`` of p_s at t0 (one vectorized distance
   computation over all node positions);
2. delay: the eigenray time from p_s to the receiver's position *at the arrival instant*,
   i.e. the fixed point t_a = t0 + T(p_s, p_rx(t_a)), iterated (vectorized over receivers)
   until it moves by less than 1e-10 s. The map contracts by about |v_rx| / c ~ 1e-3 per step,
   so a few iterations suffice; static receivers need none;
3. losses: no eigenray (shadow zone) -> "no_path"; SNR below the threshold -> "snr";
   the receiver transmitting during any part of the reception -> "half_duplex"; another
   signal overlapping the reception at the receiver -> "collision" (with ``capture``, the
   packet survives if its SNR exceeds the total power of the overlapping signals by
   ``capture_threshold_db``).

Each delivery is one timeout callback, scheduled at the instant the last bit arrives: by then
every signal that can overlap the reception and every transmission of the receiver that can
cut it are known (they started before that instant), so the verdict needs no second event.

MAC stamps: transmit stamped when the first bit leaves (t0), receive when the first bit
arrives (t_a), each in the node's local clock (``Clock.stamp``), plus ``jitter_std_s``.
"""

from __future__ import annotations

import math
from bisect import bisect_left, insort
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import simpy
from numpy.typing import NDArray

from ..packet import Packet, Reception
from .rays import Eigenray, PathKind
from .raytrace import eigenray

if TYPE_CHECKING:  # pragma: no cover
    from ..kernel import Simulation, _NodeCore
    from .ssp import SoundSpeedProfile

__all__ = ["ChannelConfig", "AcousticChannel", "LossModel", "no_snr", "default_loss_model", "PATH_NAMES"]

#: path kind code -> name in the packets table
PATH_NAMES = {int(PathKind.NONE): "none", int(PathKind.DIRECT): "direct",
              int(PathKind.SURFACE): "surface", int(PathKind.BOTTOM): "bottom"}

#: fixed-point tolerance on the arrival time (s)
FIXED_POINT_TOL_S = 1e-10
_MAX_ITER = 50


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
        "capture" (a signal survives if it beats the others' total power by capture_threshold_db).
    jitter_std_s: std of Gaussian MAC timestamp jitter (s), on top of the clock's own.
    reflections: passed to ``eigenray`` ("none", "fallback", "all").
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


#: An SNR model: (eigenrays to the receivers, config) -> SNR in dB per receiver (NaN = unknown,
#: never dropped).
LossModel = Callable[[Eigenray, ChannelConfig], NDArray[np.float64]]


def no_snr(ray: Eigenray, config: ChannelConfig) -> NDArray[np.float64]:
    """The null loss model: SNR unknown (NaN), so nothing is dropped on SNR."""
    return np.full(np.shape(ray.time), np.nan)


def default_loss_model() -> LossModel:
    """``aquasim_py.channel.loss`` when it provides an SNR model for the channel, else :func:`no_snr`."""
    try:
        from . import loss
    except ImportError:
        return no_snr
    fn = getattr(loss, "channel_snr_db", None)
    return fn if callable(fn) else no_snr


class AcousticChannel:
    """Delivers packets between the nodes of a :class:`~aquasim_py.kernel.Simulation`."""

    def __init__(self, sim: Simulation, ssp: SoundSpeedProfile, config: ChannelConfig,
                 loss_model: LossModel | None = None) -> None:
        self._sim = sim
        self._env = sim.env
        self.ssp = ssp
        self.config = config
        self.loss_model: LossModel = loss_model if loss_model is not None else default_loss_model()
        self._uid = 0
        self._table = sim.trace.table("packets")
        self._row = self._table.row_buffer().append  # rows go in as tuples, moved to columns in batches
        self._range2 = float(config.max_range_m) ** 2
        self._max_duration = 0.0
        self._collision = config.collision
        self._static_links: dict[int, tuple[int, Any]] = {}
        self._destructive = config.collision == "destructive"
        self._capture = config.collision == "capture"

    # -- transmit ---------------------------------------------------------------------------------

    def transmit(self, core: _NodeCore, dst: int | None, kind: str, payload: Any, bits: int) -> simpy.Event:
        """Queue a packet on ``core``'s modem; the event fires when its last bit has left."""
        if bits <= 0:
            raise ValueError(f"a packet needs bits > 0, got {bits}")
        env = self._env
        now = env.now
        duration = bits / self.config.bitrate_bps
        if duration > self._max_duration:
            self._max_duration = duration
        start = core.tx_free_at if core.tx_free_at > now else now
        core.tx_free_at = start + duration
        if start == now:
            tx_local = self._start(core, dst, kind, payload, bits, duration)
            return env.timeout(duration, tx_local)
        done = env.event()

        def later(_: simpy.Event) -> None:
            tx_local = self._start(core, dst, kind, payload, bits, duration)
            env.timeout(duration).callbacks.append(lambda _e: done.succeed(tx_local))

        env.timeout(start - now).callbacks.append(later)
        return done

    def _start(self, core: _NodeCore, dst: int | None, kind: str, payload: Any, bits: int,
               duration: float) -> float:
        """The first bit leaves now: stamp, trace, and schedule every reception."""
        env = self._env
        sim = self._sim
        t0 = env.now
        src = core.index
        uid = self._uid
        self._uid = uid + 1
        tx_local = core.stamp(t0)
        pkt = Packet(uid, src, dst, kind, payload, bits, tx_local)
        dst_code = -1 if dst is None else dst
        nan = math.nan
        row = self._row
        self._table.flush_if_large()
        core.tx_log.append((t0, t0 + duration))
        if len(core.tx_log) > core.log_cap:
            self._prune(core)
        row((t0, "tx", None, src, src, dst_code, uid, kind, bits, nan, nan, None, tx_local))

        in_range, links = self._links(src, t0)
        if dst is not None and dst not in in_range:
            row((t0, "drop", "range", dst, src, dst, uid, kind, bits, nan, nan, None, nan))
        # a unicast is heard (and interferes) everywhere in range, but only its addressee delivers
        only_dst = dst is not None and self._collision == "none"
        track = self._destructive or self._capture

        cores = sim._cores
        thr = self.config.snr_threshold_db
        finish = self._finish
        for rid, T, path, s in links:
            intended = dst is None or dst == rid
            if only_dst and not intended:
                continue
            if T != T:  # NaN: no eigenray (shadow zone)
                if intended:
                    row((t0, "drop", "no_path", rid, src, dst_code, uid, kind, bits, nan, nan, path, nan))
                continue
            arr = t0 + T
            if s < thr:  # NaN (no loss model) compares False: never dropped on SNR
                if intended:
                    row((arr, "drop", "snr", rid, src, dst_code, uid, kind, bits, T, s, path, nan))
                continue
            end = arr + duration
            rcore = cores[rid]
            entry = (arr, end, s)
            if track:  # overlaps matter only with a collision model
                insort(rcore.rx_log, entry)
            if intended:
                env.timeout(end - t0).callbacks.append(
                    partial(finish, rcore, pkt, entry, T, path, dst_code))
        return tx_local

    def _links(self, src: int, t0: float) -> tuple[frozenset[int], list[tuple[int, float, str, float]]]:
        """Nodes in range of ``src`` at ``t0`` and, per candidate, (id, delay s, path name, SNR dB).

        When no node moves the answer never changes, so it is cached per sender (and recomputed
        if nodes are added).
        """
        sim = self._sim
        n = len(sim.nodes)
        static = not sim.is_moving().any()
        if static:
            hit = self._static_links.get(src)
            if hit is not None and hit[0] == n:
                return hit[1]
        pos = sim.positions(t0)
        p_src = pos[src]
        diff = pos - p_src
        d2 = np.einsum("ij,ij->i", diff, diff)
        d2[src] = np.inf
        cand = np.flatnonzero(d2 <= self._range2)
        if cand.size:
            times, paths, snr = self._arrivals(t0, p_src, cand, pos[cand])
            links = list(zip(cand.tolist(), times.tolist(), [PATH_NAMES[p] for p in paths.tolist()], snr.tolist()))
        else:
            links = []
        out = (frozenset(cand.tolist()), links)
        if static:
            self._static_links[src] = (n, out)
        return out

    def _arrivals(self, t0: float, p_src: NDArray[np.float64], cand: NDArray[np.intp],
                  p_rx: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.int8], NDArray[np.float64]]:
        """Arrival delays (s), path kinds and SNR (dB) at the candidates (moving-receiver fixed point)."""
        ssp = self.ssp
        refl = self.config.reflections
        ray = eigenray(ssp, p_src, p_rx, reflections=refl)
        moving = self._sim.is_moving()[cand]
        if moving.any():
            time = np.array(ray.time, dtype=float)
            fields = {f: np.array(getattr(ray, f)) for f in Eigenray.__dataclass_fields__}
            active = np.flatnonzero(moving & np.isfinite(time))
            for _ in range(_MAX_ITER):
                if active.size == 0:
                    break
                p_new = self._sim.positions_at(cand[active], t0 + time[active])
                r = eigenray(ssp, p_src, p_new, reflections=refl)
                step = np.abs(r.time - time[active])
                for f in fields:
                    fields[f][active] = getattr(r, f)
                time[active] = r.time
                # converged (or lost the path: NaN stays NaN and leaves the loop)
                active = active[step > FIXED_POINT_TOL_S]
            ray = Eigenray(**fields)
            if active.size:
                raise RuntimeError(f"arrival-time fixed point did not converge for {active.size} receivers")
        snr = np.asarray(self.loss_model(ray, self.config), dtype=float)
        return np.asarray(ray.time, dtype=float), np.asarray(ray.path), snr

    # -- receive ----------------------------------------------------------------------------------

    def _finish(self, rcore: _NodeCore, pkt: Packet, entry: tuple[float, float, float], tof: float,
                path: str, dst_code: int, _ev: simpy.Event) -> None:
        """The last bit of ``pkt`` has arrived at ``rcore``: decide, stamp, deliver, trace."""
        arr, end, snr = entry
        reason = None
        for a, b in rcore.tx_log:
            if a < end and b > arr:
                reason = "half_duplex"
                break
        if reason is None and (self._destructive or self._capture):
            # rx_log is sorted by arrival; a signal overlapping [arr, end) arrived in
            # (arr - longest packet, end), so only that slice is examined
            log = rcore.rx_log
            i = bisect_left(log, (arr - self._max_duration,))
            n = len(log)
            power = 0.0
            hit = False
            while i < n:
                e = log[i]
                i += 1
                if e[0] >= end:
                    break
                if e[1] > arr and e is not entry:
                    hit = True
                    if self._destructive:
                        break
                    power += 10.0 ** (e[2] / 10.0)
            if hit and (self._destructive or
                        not (snr - 10.0 * math.log10(power) >= self.config.capture_threshold_db)):
                reason = "collision"
            # forget signals that ended before anything still pending could start: arrival
            # earlier than now - 2 * longest packet implies that
            k = bisect_left(log, (self._env.now - 2.0 * self._max_duration,))
            if k:
                del log[:k]
        if reason is not None:
            self._row((arr, "drop", reason, rcore.index, pkt.src, dst_code, pkt.uid, pkt.kind, pkt.bits,
                       tof, snr, path, math.nan))
            return
        rx_local = rcore.stamp(arr)
        rcore.deliver(Reception(pkt, rx_local, snr))
        self._row((arr, "rx", None, rcore.index, pkt.src, dst_code, pkt.uid, pkt.kind, pkt.bits,
                   tof, snr, path, rx_local))

    def _prune(self, core: _NodeCore) -> None:
        """Forget own transmissions that can no longer overlap a pending reception.

        A pending reception ends at or after now and lasts at most the longest packet so far,
        so it began after now - max_duration; anything that ended before cannot touch it.
        """
        cutoff = self._env.now - self._max_duration
        core.tx_log = [e for e in core.tx_log if e[1] >= cutoff]
        # next prune when the log has doubled: amortized O(1) per entry, short scans
        core.log_cap = max(8, 2 * len(core.tx_log))
