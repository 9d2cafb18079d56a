"""The links of a transmission in a range-dependent environment: every arrival, and the modem's
stamp at the first one it detects.

Pure numpy, no SimPy. :class:`ArrivalLinkModel` is the :class:`~.links.LinkModel` of an
:class:`~.environment.Environment` whose sound speed or sea floor changes with position (the
channel picks it, :class:`~.acoustic.AcousticChannel`). The candidates (every node within
``max_range_m`` of the sender at t0), the hooks (obstacles, sound-speed uncertainty) and the
order of the answer are the link model's; what differs is the arrival of each link:

1. the arrival structure (:func:`.arrivals.arrivals`: every eigenray with at most
   ``max_bounces`` surface and bottom bounces, its delay and level) from the sender at t0 to the
   receiver at its arrival instant;
2. the modem's time stamp is the first arrival whose SNR (source level + the arrival's level -
   the noise in the band, :func:`.arrivals.detection_snr_db`) reaches ``detection_threshold_db``
   (:func:`.arrivals.first_detectable`), and that arrival's SNR is the reception's (a packet
   below ``snr_threshold_db`` is lost, "snr"). Where the direct path is blocked by the floor, or
   too weak, the stamp is a later (reflected) arrival: the range is biased late, as at sea. No
   detectable arrival: lost, "undetected" (no arrival at all: "no_path"). ``direct_only``
   (an analysis switch) loses a reception stamped on a reflected arrival ("indirect");
3. moving receivers: the stamp solves t_a = t0 + T(p_src(t0), p_rx(t_a)), T the delay of the
   first detectable arrival, iterated on the receiver's true trajectory until it moves by less
   than 1e-10 s. The first iterate starts from the straight-line time at the mean of the two
   end speeds (its error, ~1e-3 of the delay, moves a drifting receiver by a millimetre); the
   second is a Newton step from it, the slope grad T . v - 1 from the stamped eigenray's
   slowness vector at the receiver (Fermat) and the receiver's velocity at the first iterate's
   instant (a forward difference of its trajectory over 1 ms), which leaves an error of second
   order in the first one's (one request of the link fewer than plain iteration, which
   contracts by |v_rx| / c ~ 1e-3 per step); each later iterate is plain. Every
   iterate after the first follows the eigenrays found there (:mod:`.arrival_cache`, exact), and
   the answer is the iterate that moved by less than the tolerance, as in plain iteration. A
   stamp that keeps jumping between two arrivals (a receiver exactly where one crosses the
   threshold) stops after ``MAX_ITER`` steps at the last one.

The arrivals of each link are kept between transmissions in an :class:`~.arrival_cache.
ArrivalCache` without its Taylor tier (every delay exact): a link whose ends are where they
were last solved is served as it is (moored nodes), one whose ends moved less than
``follow_radius_m`` (default 1 m) since its last search is followed there (each eigenray from
its launch angle, exact, with the fold check of the search's watched intervals; a path that
enters a family across its edge within that radius is not found, see docs/channel.md for how
often that changes the arrival set and the stamp), others are searched again.

The ``packets`` table of a range-dependent run carries, after the schema's columns,
:data:`ARRIVAL_FIELDS` (NaN on rows without a link: "tx", "range"): the number of arrivals of
the link, their delay spread (last minus first, s), the first arrival's delay whatever its
level (s) and the first direct or refracted arrival's (s; NaN: the direct path is blocked
within ``max_bounces``). Its ``path`` column holds the stamped arrival's class
(:class:`.arrivals.ArrivalClass`: direct, refracted, surface, bottom, surface-bottom; "none").
A node's :class:`~aquasim_py.packet.Reception` gets the stamp only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..radio import NetworkView
from .arrival_cache import ArrivalCache
from .arrivals import ArrivalClass, Arrivals, detection_snr_db, first_detectable, slowness
from .config import ChannelConfig, LossModel, _snr_constants, no_snr, physical_snr
from .environment import Environment
from .fixed_point import FIXED_POINT_TOL_S, MAX_ITER
from .links import LinkModel, Links

__all__ = ["ARRIVAL_FIELDS", "ArrivalLinkModel", "ArrivalPath", "arrival_row_writer"]

#: the packets table's columns after the schema's in a range-dependent run (see the module docstring)
ARRIVAL_FIELDS = ("n_arrivals", "delay_spread", "first_tof", "direct_tof")
_LABELS = tuple(ArrivalClass(i).label for i in range(len(ArrivalClass)))
_DIRECT = (int(ArrivalClass.DIRECT), int(ArrivalClass.REFRACTED))
#: the step (s) of the receiver velocity's forward difference for the Newton step: its error
#: (the step times half the acceleration, ~1e-8 m/s in an ocean current) and the positions'
#: rounding over it (~1e-10 m/s at kilometres) both leave the slope right to 1e-11
_DT_V_S = 1e-3


class ArrivalPath(NamedTuple):
    """What the packets table records of a link's arrivals (the ``path`` slot of a signal)."""

    label: str  #: class of the stamped arrival, "none" without one
    n_arrivals: int
    delay_spread: float  #: s, NaN without arrivals
    first_tof: float  #: s, the first arrival whatever its level
    direct_tof: float  #: s, the first direct or refracted arrival; NaN: blocked


class ArrivalLinkModel(LinkModel):
    """The links of each transmission of a network in a range-dependent environment (see the
    module docstring). network, config, streams: as :class:`~.links.LinkModel`'s. env: the
    environment. loss_model: :func:`~.config.physical_snr` (levels of the arrivals, the SNR
    of the stamped one) or :func:`~.config.no_snr` (no SNR: the stamp is the first arrival)."""

    def __init__(
        self,
        network: NetworkView,
        env: Environment,
        config: ChannelConfig,
        loss_model: LossModel,
        streams: Callable[..., np.random.Generator] | None = None,
    ) -> None:
        if loss_model is not physical_snr and loss_model is not no_snr:
            raise ValueError(
                "a range-dependent environment takes its SNR from the arrivals' levels: loss_model must be "
                "physical_snr or no_snr"
            )
        super().__init__(network, None, config, loss_model, streams)
        self.env = env
        self._snr = loss_model is physical_snr
        noise, band, _alpha, _k10 = _snr_constants(config)
        self._noise_db = float(noise) + float(band)
        self._detect_db = (
            config.detection_threshold_db if config.detection_threshold_db is not None else config.snr_threshold_db
        )
        self._cache: ArrivalCache | None = None

    def _new_layout(self, n: int) -> None:
        super()._new_layout(n)
        c = self.config
        # link id src * n + dst: a new node count renumbers them, so the cache starts afresh
        self._cache = ArrivalCache(
            self.env,
            max(1, n * n),
            max_bounces=c.max_bounces,
            tol_s=0.0,
            frequency_khz=c.frequency_khz,
            spreading="ray",
            follow_m=c.follow_radius_m,
            n_nodes=n,
        )

    # -- the hooks of LinkModel.links ---------------------------------------------------------------

    def _mid_speed(self, p_src: NDArray[np.float64], p_rx: NDArray[np.float64]) -> NDArray[np.float64]:
        mid = 0.5 * (p_src + p_rx)
        return self.env.speed(mid[:, 0], mid[:, 1], mid[:, 2])

    def _path_names(self, paths: Any) -> Iterable[Any]:
        return paths  # already ArrivalPath records

    def _sorted_links(
        self, ids: list[int], times: NDArray[np.float64], paths: Iterable[Any], snr: NDArray[np.float64]
    ) -> Links:
        ids, heard, lost = super()._sorted_links(ids, times, paths, snr)
        # no stamp although the link has arrivals: none detected ("none"), or (direct_only) a
        # reflected one
        lost = [
            (rid, "undetected" if p.label == "none" else "indirect", T, p, s)
            if reason == "no_path" and p.n_arrivals > 0
            else (rid, reason, T, p, s)
            for rid, reason, T, p, s in lost
        ]
        return ids, heard, lost

    # -- arrivals -----------------------------------------------------------------------------------

    def arrivals(  # type: ignore[override]
        self,
        t0: float,
        p_src: NDArray[np.float64],
        cand: NDArray[np.intp],
        p_rx: NDArray[np.float64],
        v_rx: NDArray[np.float64] | None = None,
        src: int = -1,
    ) -> tuple[NDArray[np.float64], list[ArrivalPath], NDArray[np.float64]]:
        """Stamp delays (s; NaN: none), arrival records and SNR (dB) of the links from ``src``
        (at ``p_src``, true time t0) to the candidates ``cand`` (at ``p_rx`` at t0). ``v_rx``
        (their velocities at t0) is not needed: the Newton step takes each receiver's velocity
        at its first iterate's instant."""
        net = self._net
        cache = self._cache
        assert cache is not None  # made by _new_layout
        k = cand.size
        ids = src * self._layout_n + cand.astype(np.int64)
        p_src_k = np.broadcast_to(p_src, (k, 3))
        moving = np.flatnonzero(net.is_moving()[cand])
        p = np.array(p_rx, dtype=float)
        guess = np.zeros(k)  # the delay at whose instant each receiver is placed
        if moving.size:
            # first iterate: the straight-line time at the mean of the end speeds
            pm = p[moving]
            c0 = self.env.speed(p_src[0], p_src[1], p_src[2])
            c1 = self.env.speed(pm[:, 0], pm[:, 1], pm[:, 2])
            guess[moving] = np.linalg.norm(pm - p_src, axis=1) / (0.5 * (c0 + c1))
            p[moving] = net.positions_at(cand[moving], t0 + guess[moving])
        arr = cache.get(ids, p_src_k, p)
        rec = self._records(arr)
        time = rec[0]
        active = moving[np.abs(time[moving] - guess[moving]) > FIXED_POINT_TOL_S]  # NaN: no stamp, done
        if active.size:
            # then one Newton step on T(p_rx(t0 + g)) - g, its slope grad T . v - 1 with the
            # stamped eigenray's slowness vector at the receiver (Fermat) and the receiver's
            # velocity at the first iterate's instant (a forward difference of its trajectory
            # over _DT_V_S): the next iterate is then usually within the tolerance. (Its velocity
            # at t0 instead leaves the step 1e-10 s or more off on most links of a drifting
            # network: the slope must be right to 1e-7 when the first iterate is 1e-3 s off.)
            ta = t0 + guess[active] + _DT_V_S
            v = (net.positions_at(cand[active], ta) - p[active]) / _DT_V_S
            slope = np.einsum("ij,ij->i", _stamp_slowness(arr, rec[7][active], p_src, p[active]), v)
            guess[active] += (time[active] - guess[active]) / (1.0 - slope)
        for _ in range(MAX_ITER):
            if not active.size:
                break
            p_new = net.positions_at(cand[active], t0 + guess[active])
            sub = self._records(cache.get(ids[active], p_src_k[: active.size], p_new))
            step = np.abs(sub[0] - guess[active])
            for full, part in zip(rec, sub):
                full[active] = part
            guess[active] = sub[0]
            active = active[step > FIXED_POINT_TOL_S]
        else:
            if active.size:
                self.unconverged += 1
        time, label, count, spread, first, direct, snr, _row = rec
        paths = [
            ArrivalPath(_LABELS[c] if c >= 0 else "none", n, sp, f, dr)
            for c, n, sp, f, dr in zip(label.tolist(), count.tolist(), spread.tolist(), first.tolist(), direct.tolist())
        ]
        return time, paths, snr

    def _records(self, arr: Arrivals) -> list[NDArray[Any]]:
        """Per link of ``arr``: [stamp delay (s, NaN: none), stamped class code (-1: none),
        arrival count, delay spread (s), first delay (s), first direct delay (s), SNR (dB), the
        stamped arrival's row of ``arr`` (-1: none)]."""
        n = arr.offsets.size - 1
        if self._snr:
            idx, stamp = first_detectable(arr, self.config.source_level_db, self._noise_db, self._detect_db)
            snr_rows = detection_snr_db(arr, self.config.source_level_db, self._noise_db)
        else:
            idx, stamp = first_detectable(arr, 0.0, 0.0, -math.inf)
            snr_rows = np.full(arr.delay.size, np.nan)
        has = idx >= 0
        cls = np.where(has, arr.path_class[np.maximum(idx, 0)] if arr.delay.size else -1, -1).astype(np.int64)
        snr = np.where(has, snr_rows[np.maximum(idx, 0)] if arr.delay.size else np.nan, np.nan)
        stamp = np.asarray(stamp, dtype=float).reshape(n)
        if self.config.direct_only:  # the analysis switch: a reflected stamp is lost
            stamp = np.where(np.isin(cls, _DIRECT), stamp, np.nan)
        # the first direct or refracted arrival of each link (rows are by link, then delay)
        direct = np.full(n, np.nan)
        rows = np.flatnonzero(np.isin(arr.path_class, _DIRECT))
        if rows.size:
            links, first_row = np.unique(arr.link[rows], return_index=True)
            direct[links] = arr.delay[rows[first_row]]
        return [
            stamp,
            cls,
            np.diff(arr.offsets),
            arr.delay_spread().reshape(n),
            arr.first_delay.reshape(n),
            direct,
            snr,
            np.asarray(idx, dtype=np.int64).reshape(n),
        ]


def _stamp_slowness(
    arr: Arrivals, rows: NDArray[np.int64], p_src: NDArray[np.float64], p_rx: NDArray[np.float64]
) -> NDArray[np.float64]:
    """(k, 3) the gradient (s/m) of each stamped arrival's delay with respect to its receiver's
    position (:func:`.arrivals.slowness` at the arrival angle); zero where there is no stamp."""
    has = rows >= 0
    r = np.maximum(rows, 0)
    th = np.where(has, arr.arrival_angle[r], 0.0) if arr.delay.size else np.zeros(rows.size)
    c = np.where(has, arr.receiver_speed[r], np.inf) if arr.delay.size else np.full(rows.size, np.inf)
    dx = p_rx[:, :2] - np.asarray(p_src, dtype=float)[:2]
    hr = np.hypot(dx[:, 0], dx[:, 1])
    with np.errstate(invalid="ignore", divide="ignore"):
        u = np.where(hr[:, None] > 0.0, dx / hr[:, None], 0.0)
    return slowness(u[:, 0], u[:, 1], th, c)


def arrival_row_writer(append: Callable[..., None]) -> Callable[[tuple[Any, ...]], None]:
    """A ``packets`` row writer for a range-dependent run: rows in :data:`~aquasim_py.radio.
    PACKET_FIELDS` order whose ``path`` may be an :class:`ArrivalPath` go to ``append`` with
    its class in ``path`` and its numbers in :data:`ARRIVAL_FIELDS` after the schema's columns
    (NaN where the row has no link), so every row names the same columns (the table's fast
    path)."""
    from ..radio import PACKET_FIELDS

    columns = PACKET_FIELDS + ARRIVAL_FIELDS
    none = (math.nan,) * len(ARRIVAL_FIELDS)

    def row(values: tuple[Any, ...]) -> None:
        p = values[11]
        if isinstance(p, ArrivalPath):
            append((*values[:11], p.label, *values[12:], *p[1:]), columns)
        else:
            append(values + none, columns)

    return row
