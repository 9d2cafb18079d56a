"""Which nodes can be in range of a sender, without a distance to every node (issue 19 item 3).

A k-d tree (``scipy.spatial.cKDTree``) of the node positions at a build time t_b answers "who
is within r of p" in O(log N + k). Between rebuilds the nodes move: a node at q(t_b) is at
q(t) with |q(t) - q(t_b)| <= v_max (t - t_b) (mirror folding into the box is 1-Lipschitz, so
it cannot add distance). The channel's range test is |q(t0) - p_src(t0)| <= R at the send
time t0, so every node in range of the sender at t0 lies within R + 2 v_max (t0 - t_b) of
the sender's own position in the tree (both ends moved). At each build every node's list of
the nodes within R + 2 v_max staleness_s of it is made in one batched query
(:meth:`NeighbourIndex.neighbourhood` then only slices it); the channel's exact distance test
filters that superset. The packet's flight time does not enter the margin because the range
test is at the send time (the arrival positions come from the exact fixed point on the
candidates, not from the tree).

The tree is rebuilt when it is older than ``staleness_s`` (default: the time to move 2.5 % of
the range at v_max, so the lists exceed the true neighbours by about 10 % in area); a static
network (v_max = 0) builds once. A rebuild costs O(N log N) and happens once per staleness_s,
during which every node transmits many times, so its share per transmission does not grow
with N beyond the tree's log N.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from itertools import chain
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

__all__ = ["NeighbourIndex"]

#: relative and absolute slack (m) on the query radius: the tree's distance arithmetic may round
#: differently from the channel's exact test, so the ball is widened by far more than that
_REL_SLACK = 1e-9
_ABS_SLACK_M = 1e-6


class NeighbourIndex:
    """Candidate receivers within ``range_m`` of a sender, from a periodically rebuilt k-d tree.

    range_m: the exact test's range (m). max_speed: upper bound on any node's speed (m/s,
    finite). staleness_s: rebuild the tree when it is older than this (s); default 0.025 *
    range_m / max_speed (never, for a static network).
    """

    def __init__(self, range_m: float, max_speed: float, staleness_s: float | None = None) -> None:
        if not (math.isfinite(max_speed) and max_speed >= 0.0):
            raise ValueError(f"NeighbourIndex needs a finite max_speed >= 0, got {max_speed!r}")
        self.range_m = float(range_m)
        self.max_speed = float(max_speed)
        if staleness_s is None:
            staleness_s = 0.025 * self.range_m / self.max_speed if self.max_speed > 0.0 else math.inf
        self.staleness_s = float(staleness_s)
        self._tree: cKDTree | None = None
        self._built_at = -math.inf
        self._count = -1
        self._flat = np.zeros(0, dtype=np.intp)  # every node's neighbourhood, concatenated
        self._offsets = np.zeros(1, dtype=np.intp)
        self.rebuilds = 0  # diagnostics and tests

    def neighbourhood(
        self, src: int, t: float, count: int, positions: Callable[[float], NDArray[np.float64]]
    ) -> NDArray[np.intp]:
        """Node ``src`` followed by the sorted ids of every other node that may be within range
        of it at true time ``t`` (s): a superset of the in-range set. ``count``: number of nodes
        now (a change rebuilds); ``positions(t)``: all positions (count, 3) at ``t``, called
        only to rebuild.

        Both ends have moved since the build, so the ball around ``src``'s position in the tree
        has radius R + 2 v_max (t - t_b) <= R + 2 v_max staleness_s; the lists of every node
        are made at the build with that largest radius (one batched query), so a transmission
        only slices a precomputed array."""
        self._refresh(t, count, positions)
        off = self._offsets
        return self._flat[off[src] : off[src + 1]]

    def _refresh(self, t: float, count: int, positions: Callable[[float], NDArray[np.float64]]) -> None:
        """Rebuild the tree and the neighbourhoods if too old or the node count changed."""
        age = t - self._built_at
        if self._tree is None or count != self._count or not (0.0 <= age <= self.staleness_s):
            self._build(positions(t))
            self._built_at, self._count = t, count
            self.rebuilds += 1

    def _build(self, pos: NDArray[np.float64]) -> None:
        """The tree of ``pos`` (n, 3) and every node's neighbourhood (itself first, then the
        others sorted) as one flat array with offsets: no per-node work at query time."""
        from scipy.spatial import cKDTree

        self._tree = tree = cKDTree(pos)
        n = len(pos)
        reach = self.range_m + (2.0 * self.max_speed * self.staleness_s if self.max_speed > 0.0 else 0.0)
        reach += _REL_SLACK * reach + _ABS_SLACK_M
        lists = tree.query_ball_point(pos, reach, return_sorted=True)
        lengths = np.fromiter(map(len, lists), dtype=np.intp, count=n)
        flat = np.fromiter(chain.from_iterable(lists), dtype=np.intp, count=int(lengths.sum()))
        offsets = np.zeros(n + 1, dtype=np.intp)
        np.cumsum(lengths, out=offsets[1:])
        # every list holds its own node exactly once (distance 0): move it to the front; the
        # other entries keep their sorted order
        owner = np.repeat(np.arange(n, dtype=np.intp), lengths)
        out = np.empty_like(flat)
        first = np.zeros(flat.size, dtype=bool)
        first[offsets[:-1]] = True
        out[first] = np.arange(n, dtype=np.intp)
        others = flat[flat != owner]
        if others.size != flat.size - n:
            raise ValueError("NeighbourIndex: node positions must be finite")
        out[~first] = others
        self._flat, self._offsets = out, offsets
