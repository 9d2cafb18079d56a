"""Who hears a transmission, when, and how loud: the link geometry of one transmission.

Pure numpy, no SimPy. :class:`LinkModel` answers, for a sender at true time t0, which nodes are
within range, the delay of each link (the eigenray from the sender at t0 to the receiver at its
arrival instant, a fixed point for a moving receiver, :mod:`.fixed_point`), its path kind and
SNR (the loss model), and which links are lost (no eigenray, SNR below the threshold). It sees
the network only through :class:`~aquasim_py.radio.NetworkView`.

1. candidates: every node within ``max_range_m`` of p_s at t0. When the network bounds its
   nodes' speed (``max_speed``; always for a static one) a k-d tree of recent positions
   (:class:`~.neighbours.NeighbourIndex`) gives a superset and only those nodes' positions are
   evaluated, so the cost follows the neighbourhood, not the network; otherwise one
   vectorized distance computation over all node positions. The exact test is the same;
2. delay: the eigenray time from p_s to the receiver's position *at the arrival instant*,
   i.e. the fixed point t_a = t0 + T(p_s, p_rx(t_a)), iterated (vectorized over receivers)
   until it moves by less than 1e-10 s. The map contracts by about |v_rx| / c ~ 1e-3 per step;
   where the first eigenray switches paths across the receiver's track it may have no fixed
   point, and the stamp is the last of ``MAX_ITER`` iterates (counted in ``unconverged``).
   Iteration starts from the fixed point of the receivers' straight-line motion at t0 (no
   mobility queries): in closed form for a constant sound speed, else by a few secant steps
   seeded with the exact slope grad T . v. It is exact for constant velocity, so the exact
   iteration usually stops after one query (and one ray trace) per receiver; static
   receivers need none. Receivers without a speed bound (the current-driven models) accelerate
   enough to miss the tolerance from that start; in a constant profile one Newton step with
   their estimated accelerations corrects it (``_accelerations``, ``accelerated_root``);
3. losses: no eigenray (shadow zone) -> "no_path"; SNR below the threshold -> "snr".
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from operator import itemgetter
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from ..radio import NetworkView
from .config import ChannelConfig, LossModel
from .fixed_point import (
    FIELDS,
    FIXED_POINT_TOL_S,
    MAX_ITER,
    constant_start,
    linear_fixed_point,
    straight_moving,
    straight_rays,
)
from .neighbours import NeighbourIndex
from .obstacles import ObstacleField
from .rays import Eigenray, PathKind
from .raytrace import eigenray
from .ssp import Constant
from .uncertainty import SoundSpeedUncertainty

if TYPE_CHECKING:  # pragma: no cover
    from .ssp import SoundSpeedProfile

__all__ = ["PATH_NAMES", "Heard", "LinkModel", "Links", "Lost"]

#: path kind code -> name in the packets table
PATH_NAMES = {
    int(PathKind.NONE): "none",
    int(PathKind.DIRECT): "direct",
    int(PathKind.SURFACE): "surface",
    int(PathKind.BOTTOM): "bottom",
}

#: a link that reaches its receiver: (receiver id, delay s, path, SNR dB); path: its name, or
#: a subclass's record of it (:class:`~.arrival_links.ArrivalPath`)
Heard = tuple[int, float, Any, float]
#: a link that does not: (receiver id, "no_path" | "snr" | a subclass's reason, delay s, path, SNR dB)
Lost = tuple[int, str, float, Any, float]
#: the links of one transmission: (ids in range, in any order; heard, by delay; lost)
Links = tuple[list[int], list[Heard], list[Lost]]

_DELAY = itemgetter(1)  # heard entries: (receiver id, delay, path, snr)


class LinkModel:
    """The links of each transmission of a network (see the module docstring).

    network: ground truth of the nodes. ssp: the sound-speed profile (None only for a subclass
    that traces its own medium, :class:`~.arrival_links.ArrivalLinkModel`). config: the channel's
    parameters. loss_model: SNR per receiver from the eigenrays. streams: the run's keyed
    random streams (``Simulation.rng``), for the link-level hooks (obstacles, sound-speed
    uncertainty), each drawing from streams of its own.
    """

    def __init__(
        self,
        network: NetworkView,
        ssp: SoundSpeedProfile | None,
        config: ChannelConfig,
        loss_model: LossModel,
        streams: Callable[..., np.random.Generator] | None = None,
    ) -> None:
        self._net = network
        self.ssp = ssp
        self.config = config
        self.loss_model = loss_model
        #: transmissions whose stamp still moved by more than the tolerance after MAX_ITER steps
        #: at some receiver (kept at the last iterate)
        self.unconverged = 0
        self._range2 = float(config.max_range_m) ** 2
        self._static_links: dict[int, tuple[int, Links]] = {}
        self._layout_n = -1  # node count _static / _index were made for (see _new_layout)
        self._static = False
        self._all_moving = False
        self._index: NeighbourIndex | None = None
        self._vel_at: Callable[[NDArray[np.intp], float], NDArray[np.float64]] | None = None
        # (time, velocity, estimated acceleration) of each node when last a candidate, for
        # the start of the fixed point on trajectories without a speed bound (_accelerations)
        self._motion: tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]] | None = None
        self._states_at: Callable[[NDArray[np.intp], float], tuple[NDArray[np.float64], NDArray[np.float64]]] | None = (
            None
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

    def links(self, src: int, t0: float, n: int) -> Links:
        """Who hears ``src`` transmitting at ``t0`` in a network of ``n`` nodes: (ids in range,
        in any order; heard; lost).

        heard: (receiver id, delay s, path name, SNR dB) of signals that reach the receiver,
        sorted by delay;
        lost: (id, "no_path" | "snr", delay, path name, SNR) of those that do not. When no node
        moves the answer never changes, so it is cached per sender (recomputed if nodes are
        added; the loss model must be a pure function of the eigenray and the config).
        """
        net = self._net
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
            times, paths, snr = self.arrivals(t0, p_src, cand, p_cand, v_cand, src=src)
            if self._sound_speed is not None:  # path-mean speed taken at the mid depth
                times = self._sound_speed.apply(times, t0, src, cand, self._mid_speed(p_src, p_cand))
            if self._obstacles is not None:  # obstacle hook: excess delay added, extra loss subtracted
                times, snr = self._obstacles.apply(src, cand, times, snr)
            out = self._sorted_links(cand.tolist(), times, self._path_names(paths), snr)
        else:
            out = ([], [], [])
        if static:
            self._static_links[src] = (n, out)
        return out

    def _mid_speed(self, p_src: NDArray[np.float64], p_rx: NDArray[np.float64]) -> NDArray[np.float64]:
        """Sound speed (m/s) the uncertainty hook takes as each link's path mean: at the mid depth."""
        assert self.ssp is not None
        return self.ssp.speed((p_src[2] + p_rx[:, 2]) / 2)

    def _path_names(self, paths: Any) -> Iterable[Any]:
        """The packets table's ``path`` values of the links' path kinds."""
        return map(PATH_NAMES.__getitem__, paths.tolist())

    def _sorted_links(
        self, ids: list[int], times: NDArray[np.float64], paths: Iterable[str], snr: NDArray[np.float64]
    ) -> Links:
        """(ids, heard, lost) of ``_links`` from the candidates' delays (s), path names and SNR (dB)."""
        thr = self.config.snr_threshold_db
        heard: list[Heard] = []
        lost: list[Lost] = []
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
        n = self._layout_n
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

    def arrivals(
        self,
        t0: float,
        p_src: NDArray[np.float64],
        cand: NDArray[np.intp],
        p_rx: NDArray[np.float64],
        v_rx: NDArray[np.float64] | None = None,
        src: int = -1,
    ) -> tuple[NDArray[np.float64], NDArray[np.int8], NDArray[np.float64]]:
        """Arrival delays (s), path kinds and SNR (dB) at the candidates (moving-receiver fixed point).

        v_rx: the candidates' velocities (m/s) at t0 if already known (else asked for). src:
        the sender's id (unused here; a subclass may key its links by it)."""
        ssp = self.ssp
        assert ssp is not None
        refl = self.config.reflections
        net = self._net
        fast = None
        if self._all_moving and v_rx is not None and isinstance(ssp, Constant):
            fast = straight_moving(ssp, p_src, p_rx, v_rx, t0, lambda t: net.positions_at(cand, t))
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
                start = constant_start(ssp, refl, p_src, p_rx, moving, v, acc)
            if start is None:
                ray = eigenray(ssp, p_src, p_rx, reflections=refl)
                fields = {f: np.array(getattr(ray, f)) for f in Eigenray.__dataclass_fields__}
                active = np.flatnonzero(moving & np.isfinite(fields["time"]))
                # Start from the fixed point of the receivers' straight-line motion at t0
                # (vectorized, no mobility queries): for constant velocity it is already the
                # answer, and the exact iteration below then stops after one query per receiver.
                v0 = v_rx[active] if v_rx is not None else self._velocities(cand[active], t0)
                fields["time"][active] = linear_fixed_point(
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
            straight = straight_rays(ssp, p_src) if isinstance(ssp, Constant) else None
            # exact fixed point t_a = t0 + T(p_src(t0), p_rx(t_a)) on the true trajectories
            for _ in range(MAX_ITER):
                if active.size == 0:
                    break
                # every receiver active (the usual first step): whole arrays, no gathers
                whole = active.size == time.size
                t_act = time if whole else time[active]
                p_new = net.positions_at(cand if whole else cand[active], t0 + t_act)
                r = straight(p_new) if straight is not None else eigenray(ssp, p_src, p_new, reflections=refl)
                step = np.abs(r.time - t_act)
                if whole:
                    fields = {f: np.asarray(getattr(r, f)) for f in FIELDS}
                    time = fields["time"]
                else:
                    for f in FIELDS:
                        fields[f][active] = getattr(r, f)
                # converged (or lost the path: NaN stays NaN and leaves the loop)
                active = active[step > FIXED_POINT_TOL_S]
            ray = Eigenray(**fields)
            if active.size:
                # no fixed point: the eigenray switches paths across the receiver's track (the
                # direct one and a reflection, say); the stamp is the last iterate's
                self.unconverged += 1
        snr = np.asarray(self.loss_model(ray, self.config), dtype=float)
        return np.asarray(ray.time, dtype=float), np.asarray(ray.path), snr

    # -- receive ----------------------------------------------------------------------------------
