"""The SimPy acoustic channel: who hears a transmission, when, and whether it survives.

On a transmission at true time t0 the channel asks its :class:`~.links.LinkModel` which nodes
are within range and the delay, path and SNR of each link (the eigenray from the sender at t0
to the receiver at its arrival instant; no eigenray -> "no_path", SNR below the threshold ->
"snr"). Each reception is then decided at the instant its last bit arrives: the receiver
transmitting during any part of it -> "half_duplex"; another signal overlapping it ->
"collision" (with ``capture``, the packet survives if its SNR exceeds the total power of the
overlapping signals by ``capture_threshold_db``; :func:`~.modem.verdict`). By then every
signal that can overlap the reception and every transmission of the receiver that can cut it
are known (they started before that instant), so the verdict needs no second event. With
``reception = "sinr"`` the verdict is the SINR receiver's (:mod:`.sinr`: acquisition, SINR in
pieces, a packet-error draw; "collision" or "per"), and signals too weak to decode but above
``interference_floor_db`` are recorded at their receivers too, where they interfere.

Sleep and energy: a node's modem may sleep (:meth:`AcousticChannel.sleep`) and, when the kernel
counts energy, has a meter (``RadioPort.energy``, :mod:`aquasim_py.energy`) the channel reports
each transmission and each detected signal to. A modem asleep or with an empty battery sends
nothing (its packet is dropped at its first bit, reason "sleep" or "energy", and the event the
node waits on still fires after the packet's airtime) and receives nothing (reason "sleep" or
"energy" for a reception any part of which falls in its sleep or after its depletion).

The deliveries of one transmission take turns as one SimPy timeout at a time
(:class:`_Deliveries`), so the queue holds one event per transmission in flight, not one per
receiver. SimPy is used through its public API only (``timeout``, ``event``, callbacks).

MAC stamps: transmit stamped when the first bit leaves (t0), receive when the first bit
arrives (t_a), each in the node's local clock (``RadioPort.clock_stamp``), plus
``jitter_std_s``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np
import simpy

from ..packet import Packet
from ..radio import NetworkView, PacketLog, RadioPort
from .config import ChannelConfig, LossModel, default_loss_model, no_snr
from .environment import Environment
from .links import LinkModel
from .modem import Modem, Signal, verdict
from .sinr import SinrReceiver

if TYPE_CHECKING:  # pragma: no cover
    from .ssp import SoundSpeedProfile

__all__ = ["AcousticChannel"]


class _Deliveries:
    """The deliveries of one transmission, taking turns as one SimPy timeout at a time.

    ``sigs`` are the signal records in order of their last bit's arrival; delivery k is
    scheduled when delivery k - 1 has been decided, for the true time at = t0 + (end_k - t0)
    (the instant a Timeout of delay end_k - t0 made at t0 would fire), as a Timeout of delay
    at - now: SimPy's now + (at - now) is ``at`` itself whenever any delay gives ``at`` (when
    none does, a rounding tie, an ulp from it; tests/channel/test_acoustic.py)."""

    __slots__ = ("fire", "k", "sigs", "t0")

    def __init__(self, sigs: list[Signal], t0: float, deliver: Callable[[_Deliveries, object], None]) -> None:
        self.sigs = sigs
        self.t0 = t0
        self.k = 0
        self.fire = partial(deliver, self)  # each delivery's timeout callback (one per transmission)


class AcousticChannel:
    """Delivers packets between the nodes of a network (the SimPy side of the channel).

    env: the SimPy environment. network: ground truth of the nodes (:class:`~aquasim_py.radio.
    NetworkView`). packets: the ``packets`` trace table (:class:`~aquasim_py.radio.PacketLog`).
    ssp, config, loss_model, streams: the link model's (:class:`~.links.LinkModel`); ``ssp`` may
    be an :class:`~.environment.Environment`: a range-dependent one gets every arrival of each
    link and the modem's stamp at the first detected (:class:`~.arrival_links.ArrivalLinkModel`,
    whose numbers the ``packets`` rows carry after the schema's columns), a range-independent
    one its profile's link model, as a profile would. Each
    node's :class:`~aquasim_py.radio.RadioPort` is attached with :meth:`attach` (ids 0, 1, ...
    in order); a node transmits with :meth:`transmit`.
    """

    def __init__(
        self,
        env: simpy.Environment,
        network: NetworkView,
        packets: PacketLog,
        ssp: SoundSpeedProfile | Environment,
        config: ChannelConfig,
        loss_model: LossModel | None = None,
        streams: Callable[..., np.random.Generator] | None = None,
    ) -> None:
        self._env = env
        self._net = network
        self.config = config
        loss = loss_model if loss_model is not None else default_loss_model()
        # a row tuple in the table's column order
        self._row: Callable[[tuple[Any, ...]], None] = packets.append
        if isinstance(ssp, Environment) and not ssp.range_independent:
            from .arrival_links import ArrivalLinkModel, arrival_row_writer

            self.links: LinkModel = ArrivalLinkModel(network, ssp, config, loss, streams)
            self._row = arrival_row_writer(packets.append)
        else:
            self.links = LinkModel(
                network, ssp.profile() if isinstance(ssp, Environment) else ssp, config, loss, streams
            )
        self._modems: list[Modem] = []
        self._jitter_std = float(config.jitter_std_s)
        self._uid = 0
        self._max_duration = 0.0  # the longest packet so far (s)
        # the SINR receiver, or None: the threshold model
        self._sinr = SinrReceiver(config) if config.reception == "sinr" else None
        if self._sinr is not None and loss is no_snr:
            raise ValueError("AcousticChannel: reception 'sinr' needs an SNR loss model (not no_snr)")
        # overlaps matter only with a collision model or the SINR receiver
        self._track = config.collision in ("destructive", "capture") or self._sinr is not None
        # signals are recorded at the receivers for the reception model, or for carrier sense
        self._record = self._track
        self._energy = False  # some node has an energy meter
        self._gate = False  # some modem may be asleep or dead: check before sending or receiving
        self._pressure_kind = config.pressure_kind
        # (packet, source position) of the last emission heard: keyed by the packet object, not
        # its uid, which a MAC's retransmission repeats from another position
        self._emitter: tuple[Packet | None, Any] = (None, None)

    @property
    def ssp(self) -> SoundSpeedProfile | None:
        """The sound-speed profile the links are traced in (None in a range-dependent environment)."""
        return self.links.ssp

    # -- nodes ------------------------------------------------------------------------------------

    def attach(self, port: RadioPort) -> None:
        """Give the channel the next node's modem port (its index must be the number attached so far)."""
        if port.index != len(self._modems):
            raise ValueError(f"attach: expected the port of node {len(self._modems)}, got node {port.index}")
        modem = Modem(port, sinr=self._sinr is not None)
        if modem.energy is not None:
            self._energy = self._gate = True
        self._modems.append(modem)

    def sleep(self, node: int) -> None:
        """Put ``node``'s modem to sleep once its transmit queue has emptied (now if it is
        idle): until :meth:`wake` it sends and receives nothing and draws sleep power."""
        m = self._modems[node]
        now = self._env.now
        t = m.tx_free_at if m.tx_free_at > now else now
        m.forget_sleeps(now - 2.0 * self._max_duration)
        m.sleep(t)
        if m.energy is not None:
            m.energy.sleep(t)
        self._gate = True

    def wake(self, node: int) -> None:
        """Wake ``node``'s modem now (a sleep still waiting for the queue to empty is cancelled)."""
        m = self._modems[node]
        now = self._env.now
        m.wake(now)
        if m.energy is not None:
            m.energy.wake(now)

    def asleep(self, node: int) -> bool:
        """Whether ``node``'s modem is asleep, or will be once its transmit queue empties."""
        sleeps = self._modems[node].sleeps
        return bool(sleeps) and sleeps[-1][1] == math.inf

    def sense_carrier(self) -> None:
        """Record every signal at its receivers, so that their modems can sense it
        (:meth:`carrier_busy`), also without a collision model (called before the run by a
        node whose MAC senses the carrier)."""
        self._record = True

    def carrier_busy(self, node: int) -> bool:
        """Whether node ``node``'s own modem senses a carrier now: it is transmitting, or a
        signal recorded at it is arriving (:meth:`~.modem.Modem.busy_at`)."""
        return self._modems[node].busy_at(self._env.now)

    def airtime(self, bits: int) -> float:
        """How long a packet of ``bits`` bits lasts on the air (s): :meth:`.ChannelConfig.airtime`."""
        return self.config.airtime(bits)

    def new_uid(self) -> int:
        """A packet uid not used before (a MAC numbers a frame when it is offered; its
        transmissions, the first and any retransmission, carry it)."""
        uid = self._uid
        self._uid = uid + 1
        return uid

    def mac_row(
        self, node: int, event: str, reason: str | None, dst: int | None, uid: int, kind: str, bits: int
    ) -> None:
        """A ``packets`` row a node's MAC writes now about a frame of its own: ``"offer"`` (the
        protocol handed it the frame) or ``"drop"`` with the reason it gave the frame up."""
        nan = math.nan
        self._row(
            (self._env.now, event, reason, node, node, -1 if dst is None else dst, uid, kind, bits, nan, nan, None, nan)
        )

    def signals_at(self, node: int) -> int:
        """How many past signals the channel still keeps at ``node`` for collision checks
        (bounded by the overlap window, not by the run length; for diagnostics and tests)."""
        return len(self._modems[node].rx_log)

    def packets_watermark(self) -> float:
        """A true time (s) no ``packets`` row written from now on precedes: a reception's row
        (time: its first bit's arrival) is written when its last bit arrives, at most the longest
        packet queued so far later; every other row is written at or before its time. Twice that
        plus 1 us, so the rounding of event times can never make the promise wrong (the trace
        streams the rows before it, sorted, :meth:`aquasim_py.trace.Table.order_by_time`)."""
        return self._env.now - 2.0 * self._max_duration - 1e-6

    # -- transmit ---------------------------------------------------------------------------------

    def transmit(
        self,
        src: int,
        dst: int | None,
        kind: str,
        payload: Any,
        bits: int,
        uid: int | None = None,
        overhear: bool = False,
    ) -> simpy.Event:
        """Queue a packet on node ``src``'s modem; the event fires when its last bit has left,
        with the sender's MAC transmit stamp (local s) as its value.

        ``uid``: the packet's uid (a MAC's frame, :meth:`new_uid`); None: the next one when its
        first bit leaves. ``overhear``: a unicast that every node decoding it is handed, not
        only ``dst`` (a MAC's RTS / CTS, which the nodes around must hear to defer)."""
        if bits <= 0:
            raise ValueError(f"a packet needs bits > 0, got {bits}")
        modem = self._modems[src]
        env = self._env
        now = env.now
        duration = self.airtime(bits)
        if duration > self._max_duration:
            self._max_duration = duration
        start = modem.tx_free_at if modem.tx_free_at > now else now
        modem.tx_free_at = start + duration
        if start == now:
            tx_local = self._start(modem, dst, kind, payload, bits, duration, uid, overhear)
            return env.timeout(duration, tx_local)
        done = env.event()

        def later(_: simpy.Event) -> None:
            tx_local = self._start(modem, dst, kind, payload, bits, duration, uid, overhear)

            def sent(_e: simpy.Event) -> None:
                done.succeed(tx_local)

            env.timeout(duration).callbacks.append(sent)

        env.timeout(start - now).callbacks.append(later)
        return done

    def _stamp(self, m: Modem, t: float) -> float:
        """MAC stamp (local s) of true time ``t`` at modem ``m``: its clock's stamp plus jitter."""
        s = m.clock_stamp(t)
        if self._jitter_std > 0.0:
            rng = m.jitter
            if rng is None:
                rng = m.jitter = m.port.jitter_stream()
            s += float(rng.normal(0.0, self._jitter_std))
        return s

    def _start(
        self,
        modem: Modem,
        dst: int | None,
        kind: str,
        payload: Any,
        bits: int,
        duration: float,
        uid: int | None = None,
        overhear: bool = False,
    ) -> float:
        """The first bit leaves now: stamp, trace, and schedule every reception."""
        t0 = self._env.now
        src = modem.index
        if uid is None:
            uid = self._uid
            self._uid = uid + 1
        tx_local = self._stamp(modem, t0)
        dst_code = -1 if dst is None else dst
        nan = math.nan
        row = self._row
        if self._gate:
            why = modem.offline(t0, t0)
            if why is not None:  # asleep or dead: nothing leaves
                row((t0, "drop", why, src, src, dst_code, uid, kind, bits, nan, nan, None, nan))
                return tx_local
            if modem.energy is not None:
                modem.energy.transmit(t0, t0 + duration)
        pkt = Packet(uid, src, dst, kind, payload, bits, tx_local)
        if self._sinr is not None:
            self._sinr.transmitting(modem, t0, self._max_duration)
        modem.transmitting(t0, t0 + duration, t0, self._max_duration)
        row((t0, "tx", None, src, src, dst_code, uid, kind, bits, nan, nan, None, tx_local))

        in_range, heard, lost = self.links.links(src, t0, len(self._modems))
        if dst is not None and dst not in in_range:
            row((t0, "drop", "range", dst, src, dst, uid, kind, bits, nan, nan, None, nan))
        for rid, reason, T, path, s in lost:
            if dst is None or dst == rid or overhear:
                if reason == "no_path":
                    row((t0, "drop", reason, rid, src, dst_code, uid, kind, bits, nan, nan, path, nan))
                else:
                    row((t0 + T, "drop", reason, rid, src, dst_code, uid, kind, bits, T, s, path, nan))
        track = self._record
        # A pending reception ends after now, so it began after now - longest packet, and a
        # signal arriving before now - 2 * longest packet cannot overlap it: forget those.
        forget = t0 - 2.0 * self._max_duration
        sigs: list[Signal] = []
        modems = self._modems
        if self._energy:  # each receiver's modem receives (draws rx power) while a signal it detects arrives
            for rid, T, _path, _s in heard:
                meter = modems[rid].energy
                if meter is not None:
                    meter.receive(t0 + T, t0 + T + duration, t0)
        if self._sinr is not None:
            sigs = self._record_sinr(pkt, dst, heard, lost, t0, duration, forget, overhear)
        elif dst is None:
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
            # a unicast is heard (and interferes) everywhere in range; only its addressee
            # delivers (every node decoding it, where it is to be overheard)
            for rid, T, path, s in heard:
                intended = rid == dst or overhear
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
            self._schedule(_Deliveries(sigs, t0, self._deliver))
        return tx_local

    def _record_sinr(
        self,
        pkt: Packet,
        dst: int | None,
        heard: list[Any],
        lost: list[Any],
        t0: float,
        duration: float,
        forget: float,
        overhear: bool = False,
    ) -> list[Signal]:
        """Record the signals of a transmission at every receiver under the SINR model, with
        their power in noise units (the weak ones, below the detection threshold but not below
        the interference floor, too: they interfere but are never decoded); the deliveries'
        records, in order of arrival."""
        rx = self._sinr
        assert rx is not None
        lock = rx.lock != "none"
        md = self._max_duration
        modems = self._modems
        dst_code = -1 if dst is None else dst
        sigs: list[Signal] = []
        for rid, T, path, snr in heard:
            arr = t0 + T
            sig = (arr, arr + duration, snr, rid, pkt, T, path, dst_code)
            m = modems[rid]
            if lock:  # decide what arrived before now, before the log forgets any of it
                rx.advance(m, t0, md)
            m.record(sig, forget, 10.0 ** (snr / 10.0))
            if dst is None or rid == dst or overhear:
                sigs.append(sig)
        floor = rx.floor
        for rid, reason, T, path, snr in lost:
            if reason == "snr" and snr >= floor:
                arr = t0 + T
                m = modems[rid]
                if lock:
                    rx.advance(m, t0, md)
                m.record((arr, arr + duration, snr, rid, pkt, T, path, dst_code), forget, 10.0 ** (snr / 10.0))
        return sigs

    # -- receive ----------------------------------------------------------------------------------

    def _schedule(self, d: _Deliveries) -> None:
        """Queue the next delivery of ``d`` at its last bit's arrival (true s)."""
        env = self._env
        t0 = d.t0
        env.timeout((t0 + (d.sigs[d.k][1] - t0)) - env.now).callbacks.append(d.fire)

    def _deliver(self, d: _Deliveries, _event: object = None) -> None:
        """The last bit of a packet has arrived at a receiver: decide, stamp, deliver, trace;
        then queue the transmission's next delivery (after the events this one made, as their
        sequence numbers order them)."""
        sig = d.sigs[d.k]
        arr, end, snr, rid, pkt, tof, path, dst_code = sig
        rx = self._modems[rid]
        # asleep or dead during any of it, else the reception model's verdict
        reason = rx.offline(arr, end) if self._gate else None
        if reason is None:
            if self._sinr is not None:
                reason = self._sinr.verdict(sig, rx, self._max_duration)
            # no verdict to take where signals cannot collide and the receiver sent nothing lately
            elif self._track or rx.busy_until > arr:
                c = self.config
                reason = verdict(sig, rx, self._max_duration, c.collision, c.capture_threshold_db)
        if reason is None:
            rx_local = rx.clock_stamp(arr) if self._jitter_std <= 0.0 else self._stamp(rx, arr)
            p = self._pressure(pkt, rx, arr - tof, arr) if pkt.kind == self._pressure_kind else math.nan
            rx.deliver(pkt, rx_local, snr, p)
            self._row((arr, "rx", None, rid, pkt.src, dst_code, pkt.uid, pkt.kind, pkt.bits, tof, snr, path, rx_local))
        else:
            self._row(
                (arr, "drop", reason, rid, pkt.src, dst_code, pkt.uid, pkt.kind, pkt.bits, tof, snr, path, math.nan)
            )
        d.k += 1
        if d.k < len(d.sigs):
            self._schedule(d)

    def _pressure(self, pkt: Packet, rx: Modem, t_send: float, t_arr: float) -> float:
        """Hydrophone reading of a sound emission (sender at send time, receiver at arrival),
        with the noise drawn from the receiver's own ("node", id, "pressure") stream."""
        from .pressure import received_pressure

        if self._emitter[0] is not pkt:  # one source position per emission, shared by its receivers
            src = self._net.positions_at(np.array([pkt.src]), np.array([t_send]))[0]
            self._emitter = (pkt, src)
        c = self.config
        here = self._net.positions_at(np.array([rx.index]), np.array([t_arr]))[0]
        h = float(received_pressure(self._emitter[1], here, c.pressure_source_level, c.pressure_exponent))
        if c.pressure_noise_std <= 0.0:
            return h
        if rx.pressure_rng is None:
            rx.pressure_rng = rx.port.stream("pressure")
        return h + float(rx.pressure_rng.normal(0.0, c.pressure_noise_std))
