"""Obstacles between nodes: obstructed links get extra propagation loss and excess delay.

The physics of SVL-PF's "excessive sensing noise" (Li et al., Sensors 18:8, 2018, Problem 2
and Fig. 2): an obstacle on the line of sight between two nodes lengthens the acoustic path
(a diffracted / detoured arrival, so the measured time of arrival is *late*) and attenuates it
(the propagation loss exceeds the one of the direct path).

Which links are obstructed is decided per undirected link {a, b}:

- ``links``: an explicit list of node-id pairs, always obstructed;
- ``probability``: every other link is obstructed with this probability, decided by one
  uniform draw from the link's *own* random stream (key ("obstacle", min(a, b), max(a, b))),
  so the decision does not depend on which other links exist or in which order they are
  queried, and no other random stream of the run changes;
- ``nodes``: if given, the probability applies only to links with an end at one of these ids
  (e.g. the target's links only, so that the sensor-to-fusion uplink stays clear).

An obstructed link of true time of flight T (s) arrives ``excess_delay_s + excess_delay_ratio
* T + excess_delay_sigma_ratio * T * |g|`` seconds later, g ~ N(0, 1) drawn anew for every
packet, and its SNR drops by ``extra_loss_db``. The random part is a half-normal (a folded
Gaussian of std ``excess_delay_sigma_ratio * T``: mean 0.80 and rms 1.0 times that std): an
obstacle can only lengthen the path, so the measured ToA is late, never early (SVL-PF's
Fig. 2b and Problem 2: the distorted measurement exceeds the undistorted one). Each link draws
its g from its *own* stream (key ("obstacle", min(a, b), max(a, b), "delay")), in the order of
the packets on that link, so no other stream of the run changes. Obstruction itself is static
(a link is either blocked or not for the whole run).

Pure: no SimPy. :class:`ObstacleField` caches the per-link decisions of one run.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["ObstacleConfig", "ObstacleField"]

Array = NDArray[np.float64]


@dataclass(frozen=True)
class ObstacleConfig:
    """Obstacle model of a scenario (see the module docstring); hashable (part of ChannelConfig)."""

    links: tuple[tuple[int, int], ...] = ()
    probability: float = 0.0
    nodes: tuple[int, ...] | None = None
    extra_loss_db: float = 0.0
    excess_delay_s: float = 0.0
    excess_delay_ratio: float = 0.0
    excess_delay_sigma_ratio: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 <= self.probability <= 1.0:
            raise ValueError(f"obstacles.probability must be in [0, 1], got {self.probability!r}")
        for name in ("extra_loss_db", "excess_delay_s", "excess_delay_ratio", "excess_delay_sigma_ratio"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0.0):
                raise ValueError(f"obstacles.{name} must be >= 0 and finite, got {v!r}")
        for pair in self.links:
            if len(pair) != 2 or pair[0] == pair[1]:
                raise ValueError(f"obstacles.links: {pair!r} is not a pair of two different node ids")

    @property
    def active(self) -> bool:
        """Whether any link can be obstructed at all."""
        return bool(self.links) or self.probability > 0.0

    @property
    def per_packet(self) -> bool:
        """Whether an obstructed link's delay is drawn anew for every packet (no caching)."""
        return self.excess_delay_sigma_ratio > 0.0


class ObstacleField:
    """Per-link obstruction of one run: ``apply`` changes a sender's arrivals.

    ``link_uniform(a, b)`` (a < b) returns the link's one uniform draw in [0, 1) from its own
    keyed stream (the kernel passes ``lambda a, b: sim.rng("obstacle", a, b).random()``);
    ``delay_stream(a, b)`` (a < b) returns the link's own Generator of excess-delay draws (the
    kernel passes ``lambda a, b: sim.rng("obstacle", a, b, "delay")``); it is asked once per
    link and needed only with ``excess_delay_sigma_ratio`` > 0.
    """

    def __init__(
        self,
        config: ObstacleConfig,
        link_uniform: Callable[[int, int], float],
        delay_stream: Callable[[int, int], np.random.Generator] | None = None,
    ) -> None:
        if config.per_packet and delay_stream is None:
            raise ValueError("ObstacleField: obstacles.excess_delay_sigma_ratio needs per-link delay streams")
        self.config = config
        self._uniform = link_uniform
        self._delay_stream = delay_stream
        self._listed = frozenset((min(a, b), max(a, b)) for a, b in config.links)
        self._nodes = None if config.nodes is None else frozenset(config.nodes)
        self._memo: dict[tuple[int, int], bool] = {}
        self._delay_rngs: dict[tuple[int, int], np.random.Generator] = {}

    def obstructed(self, a: int, b: int) -> bool:
        """Whether the undirected link {a, b} is obstructed (decided once, then remembered)."""
        key = (a, b) if a < b else (b, a)
        hit = self._memo.get(key)
        if hit is None:
            cfg = self.config
            hit = key in self._listed
            if not hit and cfg.probability > 0.0 and (self._nodes is None or a in self._nodes or b in self._nodes):
                hit = self._uniform(*key) < cfg.probability
            self._memo[key] = hit
        return hit

    def mask(self, src: int, receivers: NDArray[np.intp]) -> NDArray[np.bool_]:
        """Obstructed flags of the links from ``src`` to each receiver id."""
        return np.fromiter((self.obstructed(src, int(r)) for r in receivers), dtype=bool, count=len(receivers))

    def apply(self, src: int, receivers: NDArray[np.intp], times: Array, snr_db: Array) -> tuple[Array, Array]:
        """(delays s, SNR dB) with the obstructed links' excess delay added and extra loss
        subtracted; unobstructed links (and NaN delays: no path) are returned unchanged."""
        m = self.mask(src, receivers)
        if not m.any():
            return times, snr_db
        cfg = self.config
        t = np.array(times, dtype=float)
        s = np.array(snr_db, dtype=float)
        tof = t[m]
        excess = cfg.excess_delay_s + cfg.excess_delay_ratio * tof
        if cfg.per_packet:
            excess = excess + cfg.excess_delay_sigma_ratio * tof * self._folded_normals(src, receivers[m])
        t[m] = tof + excess
        s[m] = s[m] - cfg.extra_loss_db
        return t, s

    def _folded_normals(self, src: int, receivers: NDArray[np.intp]) -> Array:
        """|g|, g ~ N(0, 1): one draw per obstructed link of this packet, each from its link's
        own stream (a loop over the packet's few obstructed links: the streams are separate)."""
        out = np.empty(len(receivers))
        rngs = self._delay_rngs
        for i, r in enumerate(receivers.tolist()):
            key = (src, r) if src < r else (r, src)
            rng = rngs.get(key)
            if rng is None:
                assert self._delay_stream is not None
                rng = rngs[key] = self._delay_stream(*key)
            out[i] = abs(rng.standard_normal())
        return out
