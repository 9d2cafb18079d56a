"""Which nodes can be in range of a sender, without a distance to every node (issue 19 item 3).

A k-d tree (``scipy.spatial.cKDTree``) of the node positions at a build time t_b answers "who
is within r of p" in O(log N + k). Between rebuilds the nodes move: a node at q(t_b) is at
q(t) with |q(t) - q(t_b)| <= v_max (t - t_b) (mirror folding into the box is 1-Lipschitz, so
it cannot add distance). The channel's range test is |q(t0) - p_src(t0)| <= R at the send
time t0, with p_src(t0) exact (queried, not from the tree), so every node in range at t0 lies
within R + v_max (t0 - t_b) of p_src(t0) in the tree (R + 2 v_max (t0 - t_b) of the sender's
own position in the tree, :meth:`NeighbourIndex.candidates_of`): the ball query with that
radius returns a superset of the in-range set, and the channel's exact distance test then
filters it. The
packet's flight time does not enter the margin because the range test is at the send time
(the arrival positions come from the exact fixed point on the candidates, not from the tree).

The tree is rebuilt when it is older than ``staleness_s`` (default: the time to move 5 % of
the range at v_max, so candidates exceed the true neighbours by about 15 % in area); a static
network (v_max = 0) builds once.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

__all__ = ["NeighbourIndex"]

#: relative and absolute slack (m) on the query radius: the tree's distance arithmetic may round
#: differently from the channel's exact test, so the ball is widened by far more than that
_REL_SLACK = 1e-9
_ABS_SLACK_M = 1e-6


class NeighbourIndex:
    """Candidate receivers within ``range_m`` of a sender, from a periodically rebuilt k-d tree.

    range_m: the exact test's range (m). max_speed: upper bound on any node's speed (m/s,
    finite). staleness_s: rebuild the tree when it is older than this (s); default 0.05 *
    range_m / max_speed (never, for a static network).
    """

    def __init__(self, range_m: float, max_speed: float, staleness_s: float | None = None) -> None:
        if not (math.isfinite(max_speed) and max_speed >= 0.0):
            raise ValueError(f"NeighbourIndex needs a finite max_speed >= 0, got {max_speed!r}")
        self.range_m = float(range_m)
        self.max_speed = float(max_speed)
        if staleness_s is None:
            staleness_s = 0.05 * self.range_m / self.max_speed if self.max_speed > 0.0 else math.inf
        self.staleness_s = float(staleness_s)
        self._tree: cKDTree | None = None
        self._built_at = -math.inf
        self._count = -1
        self.rebuilds = 0  # diagnostics and tests

    def candidates(
        self, p_src: NDArray[np.float64], t: float, count: int, positions: Callable[[float], NDArray[np.float64]]
    ) -> NDArray[np.intp]:
        """Sorted ids of the nodes that may be within range of ``p_src`` (m) at true time ``t``
        (s): a superset of the in-range set (the sender itself included if it is in the tree).
        ``count``: number of nodes now (a change rebuilds); ``positions(t)``: all positions
        (count, 3) at ``t``, called only to rebuild."""
        age = self._refresh(t, count, positions)
        return self._query(p_src, self.range_m + self.max_speed * age)

    def candidates_of(
        self, src: int, t: float, count: int, positions: Callable[[float], NDArray[np.float64]]
    ) -> NDArray[np.intp]:
        """As :meth:`candidates`, around node ``src``'s position *in the tree* (so the sender's
        own position need not be evaluated first): the sender has moved too since the build,
        so the margin is 2 v_max (t - t_b). The result contains ``src`` itself."""
        age = self._refresh(t, count, positions)
        assert self._tree is not None
        return self._query(self._tree.data[src], self.range_m + 2.0 * self.max_speed * age)

    def _refresh(self, t: float, count: int, positions: Callable[[float], NDArray[np.float64]]) -> float:
        """Rebuild the tree if it is too old or the node count changed; its age (s) at ``t``."""
        age = t - self._built_at
        if self._tree is None or count != self._count or not (0.0 <= age <= self.staleness_s):
            self._tree = cKDTree(positions(t))
            self._built_at, self._count, age = t, count, 0.0
            self.rebuilds += 1
        return age

    def _query(self, p: NDArray[np.float64], r: float) -> NDArray[np.intp]:
        assert self._tree is not None
        r += _REL_SLACK * r + _ABS_SLACK_M
        return np.asarray(self._tree.query_ball_point(p, r, return_sorted=True), dtype=np.intp)
